//! Lyapunov exponents of any flow, through contacts, on a mechanism's constraint manifold.
//!
//! **Spectrum** (Benettin, Galgani, Giorgilli & Strelcyn, Meccanica 15, 1980; method "H2" of
//! Geist, Parlitz & Lauterborn, Prog. Theor. Phys. 83, 1990). The state is extended by `k`
//! tangent vectors `v_j` that obey `v_j' = J v_j (+ df/dm w_j)` ([`crate::flow::tangent`]); the
//! extended system is integrated by the flow's own integrator *in the same steps*: the error
//! control measures the physical state only ([`OdeSystem::error_dim`]), so the state follows
//! exactly the trajectory of a plain run stopped at the same times. Every `interval` seconds the
//! vectors are projected onto the tangent space of the phase space (a mechanism's constraint
//! manifold) and re-orthonormalised by modified Gram-Schmidt (a QR factorisation `V = Q R`); the
//! memory tangents `w_j` are carried through the same linear combination. Then
//!
//! ```text
//! lambda_j = (1 / T) sum over intervals of ln R_jj      (1/s),
//! ```
//!
//! T the averaging time. A forced flow is non-autonomous: time is not a state, so the spectrum
//! has no exponent for it. The exponents of the stroboscopic (period-T_d) map are
//! `mu_j = lambda_j T_d` (per iteration of the map): the map's Jacobian over `n` periods is the
//! flow's tangent map over `n T_d`, whose growth rates are the same numbers per unit time.
//! Both are stored.
//!
//! **Two-trajectory estimate** (Benettin et al., Meccanica 15, 1980, the original method). A
//! second copy of the flow starts at a distance `d0` along the first tangent vector and runs in
//! the first's steps (a step sequence of its own would add its own integration error to a small
//! separation) with its own contact history; every interval its separation `d` from the first
//! (projected onto the manifold's tangent space for a mechanism) is measured, `ln(d / d0)` is
//! accumulated, and the copy is pulled back to distance `d0` along the same direction (its onset
//! memories likewise). It is independent of the tangent code: no Jacobian, no saltation.
//!
//! **Convergence.** The averaging window is cut into batches of `batch` intervals; the batch
//! estimates give a batch-means standard error `s / sqrt(B)` (B batches, s their standard
//! deviation; Flegal & Jones, Ann. Statist. 38, 2010). With `until_stderr` the run stops at the
//! first batch end where the standard error of lambda_1 is at most that value (and at least 10
//! batches are done), or after the requested periods. The running estimate of every exponent at
//! every re-orthonormalisation is kept (the convergence figure).
//!
//! **Drift.** The standard error assumes one stationary motion. A chaotic transient that settles
//! on a periodic orbit (or a regular stretch that turns chaotic) breaks it: the mean of the
//! batches then belongs to neither motion. The batch estimates of lambda_1 are tested for one
//! change of their mean by the CUSUM statistic (Page, Biometrika 41, 1954; Csorgo & Horvath,
//! *Limit Theorems in Change-Point Analysis*, 1997):
//!
//! ```text
//! D = max_m |S_m| / (s sqrt(B)),   S_m = sum_{i <= m} (x_i - mean x),
//! ```
//!
//! with `s` the pooled standard deviation of the batches within the two segments split at the
//! maximising `m` (so that a change does not inflate it). Above the critical value
//! ([`drift`]: 0.1 % false alarms on independent normal batch means of that count) the run
//! reports [`Drift`]: where the change lies and lambda_1 before and after it.

use jointplay_solver::ode::{self, Events, Flow as Step, Method, OdeSystem, event_count};
use jointplay_solver::state::HybridState;
use nalgebra::DMatrix;
use serde::Deserialize;

use crate::Result;
use crate::flow::tangent::{Difference, Tangent};
use crate::progress::Stop;

/// Settings of a Lyapunov computation (the `[lyapunov]` table of an analysis study).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LyapunovSpec {
    /// Number of exponents, from the largest (1 up to the phase-space dimension).
    #[serde(default = "one")]
    pub exponents: usize,
    /// Periods run before the tangent vectors start (default: the analysis's transient).
    #[serde(default)]
    pub transient: Option<usize>,
    /// Periods averaged over (the most when `until_stderr` is given).
    pub periods: usize,
    /// Re-orthonormalisations per period.
    #[serde(default = "one")]
    pub per_period: usize,
    /// Re-orthonormalisations per batch of the batch-means standard error.
    #[serde(default)]
    pub batch: Option<usize>,
    /// Stop once the standard error of lambda_1 is at most this (1/s).
    #[serde(default)]
    pub until_stderr: Option<f64>,
    /// Also estimate lambda_1 from two nearby trajectories.
    #[serde(default)]
    pub two_trajectory: bool,
    /// Initial separation of the two trajectories (2-norm of the state difference, SI units).
    #[serde(default = "default_separation")]
    pub separation: f64,
    /// The difference quotient of a mechanism's Jacobian-vector products ("forward", the default,
    /// or "central"; built-in systems have analytic ones). Forward differences halve the
    /// tangent's cost; the exponents are time averages, and forward and central ones agree far
    /// inside their standard errors (book/src/explanation/lyapunov.md).
    #[serde(default = "forward")]
    pub difference: Difference,
}

fn one() -> usize {
    1
}
fn forward() -> Difference {
    Difference::Forward
}
fn default_separation() -> f64 {
    1e-8
}

/// The least number of batches a standard error is computed from.
pub const MIN_BATCHES: usize = 10;

impl LyapunovSpec {
    /// Checks the settings against the flow's phase-space dimension; errors name the field of
    /// the `[lyapunov]` table.
    pub fn check(
        &self,
        phase_dim: usize,
        method: &Method,
    ) -> std::result::Result<(), (String, String)> {
        let bad = |f: &str, m: String| Err((format!("lyapunov.{f}"), m));
        if method.integrator().linearly_implicit() {
            return Err((
                "solver.integrator".into(),
                "the Lyapunov exponents need an explicit integrator (rk4, bs3, dopri5 or dop853): a linearly implicit one would differentiate the whole extended system".into(),
            ));
        }
        if self.exponents == 0 || self.exponents > phase_dim {
            return bad(
                "exponents",
                format!(
                    "{} asked, but the phase space has dimension {phase_dim} (twice the free degrees of freedom of a mechanism), so 1 to {phase_dim} exponents exist",
                    self.exponents
                ),
            );
        }
        if self.per_period == 0 {
            return bad("per_period", "must be at least 1".into());
        }
        let intervals = self.periods * self.per_period;
        let batch = self.batch_len();
        if intervals < MIN_BATCHES * batch.max(1) || batch == 0 {
            return bad(
                "periods",
                format!(
                    "{} periods of {} re-orthonormalisations give {intervals} intervals: too short for a standard error from {MIN_BATCHES} batches of {batch}; run at least {} periods or set a shorter lyapunov.batch",
                    self.periods,
                    self.per_period,
                    (MIN_BATCHES * batch.max(1)).div_ceil(self.per_period)
                ),
            );
        }
        if let Some(s) = self.until_stderr
            && !(s.is_finite() && s > 0.0)
        {
            return bad("until_stderr", "must be a positive rate (1/s)".into());
        }
        if !(self.separation.is_finite() && self.separation > 0.0) {
            return bad("separation", "must be positive and finite".into());
        }
        Ok(())
    }

    /// Intervals per batch: the given one, or a twentieth of the run.
    pub fn batch_len(&self) -> usize {
        self.batch
            .unwrap_or_else(|| (self.periods * self.per_period / 20).max(1))
    }
}

/// The result of a Lyapunov computation.
#[derive(Debug, Clone)]
pub struct Spectrum {
    /// Exponents of the flow, largest first (1/s).
    pub exponents: Vec<f64>,
    /// Their batch-means standard errors (1/s).
    pub stderr: Vec<f64>,
    /// The period the stroboscopic map is taken at (s).
    pub period: f64,
    /// Averaging time (s).
    pub time: f64,
    /// Dimension of the phase space.
    pub phase_dim: usize,
    /// Time of every re-orthonormalisation (s) and the running estimate of every exponent there.
    pub history_t: Vec<f64>,
    pub history: Vec<Vec<f64>>,
    /// The two-trajectory estimate of lambda_1, when asked: value, standard error and running
    /// estimate at the same times.
    pub two_trajectory: Option<(f64, f64, Vec<f64>)>,
    /// Time average of the divergence of the vector field, when the flow knows it (1/s): the sum
    /// of the full spectrum equals it.
    pub mean_divergence: Option<f64>,
    /// Right-hand-side evaluations of the extended run (each one the state and k tangents).
    /// How the Jacobian-vector products were computed ("analytic", "central", "forward").
    pub jvp: &'static str,
    pub rhs_evals: u64,
    /// The standard-error target was met before the requested periods.
    pub stopped_early: bool,
    /// Events (impacts with a state reset) of the trajectory while averaging.
    pub events: u64,
    /// The flow's hybrid state at the end.
    pub end: HybridState,
    /// A change of lambda_1 during the averaging ([`drift`]), when the batches show one.
    pub drift: Option<Drift>,
}

/// A change of the largest exponent's batch estimates during the averaging: a transient that
/// settles, or a motion that changes character (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drift {
    /// The end of the last batch before the change (s).
    pub time: f64,
    /// lambda_1 averaged over the batches before and after it (1/s).
    pub before: f64,
    pub after: f64,
    /// The CUSUM statistic and the critical value it exceeds.
    pub statistic: f64,
    pub critical: f64,
}

/// Critical values of the CUSUM statistic of [`drift`] for B batches: the 99.9 % quantile of
/// its distribution over 40 000 series of B independent standard normal values each (a
/// simulation; the asymptotic value, the Kolmogorov distribution's, is 1.95). Between the listed
/// counts the value is interpolated linearly in 1/B; below 10 batches there is no test.
const CUSUM_CRITICAL: [(f64, f64); 6] = [
    (10.0, 3.04),
    (15.0, 2.61),
    (20.0, 2.31),
    (40.0, 2.05),
    (100.0, 1.97),
    (400.0, 1.95),
];

/// The critical value of [`drift`]'s statistic for `b` batches; None below 10.
fn cusum_critical(b: usize) -> Option<f64> {
    let b = b as f64;
    let (first, last) = (CUSUM_CRITICAL[0], CUSUM_CRITICAL[CUSUM_CRITICAL.len() - 1]);
    if b < first.0 {
        return None;
    }
    if b >= last.0 {
        return Some(last.1);
    }
    CUSUM_CRITICAL.windows(2).find_map(|w| {
        let ((b0, c0), (b1, c1)) = (w[0], w[1]);
        (b >= b0 && b <= b1).then(|| {
            let f = (1.0 / b0 - 1.0 / b) / (1.0 / b0 - 1.0 / b1);
            c0 + f * (c1 - c0)
        })
    })
}

/// One change of mean in the batch estimates `batches` (in time order), batch `i` ending at
/// `end(i)` (s): the CUSUM test of the module documentation. The first batch is left out (it
/// holds the tangent vectors' turn towards the growing direction, not the motion), each side of
/// the change keeps two batches at least, and a change of `floor` (1/s) or less is none (the
/// classification's floor for a zero exponent). None when there is no change at the 0.1 %
/// level, or fewer than 10 batches besides the first.
pub fn drift(batches: &[f64], end: impl Fn(usize) -> f64, floor: f64) -> Option<Drift> {
    let x = batches.get(1..)?;
    let b = x.len();
    let critical = cusum_critical(b)?;
    if x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mean = x.iter().sum::<f64>() / b as f64;
    let (mut sum, mut best) = (0.0f64, (0usize, 0.0f64));
    for (i, v) in x[..b - 2].iter().enumerate() {
        sum += v - mean;
        if i >= 1 && sum.abs() > best.1 {
            best = (i + 1, sum.abs());
        }
    }
    let m = best.0;
    if m == 0 {
        return None;
    }
    let (left, right) = x.split_at(m);
    let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (before, after) = (avg(left), avg(right));
    if (before - after).abs() <= floor {
        return None;
    }
    let within = left.iter().map(|v| (v - before).powi(2)).sum::<f64>()
        + right.iter().map(|v| (v - after).powi(2)).sum::<f64>();
    let s = (within / (b - 2) as f64).sqrt();
    let statistic = best.1 / (s * (b as f64).sqrt());
    // Two constant segments (s = 0) at levels further apart than the floor: an infinite
    // statistic, a change.
    (statistic > critical).then(|| Drift {
        time: end(m),
        before,
        after,
        statistic,
        critical,
    })
}

impl Spectrum {
    /// Exponents of the stroboscopic map (per iteration): lambda_j times the period.
    pub fn map_exponents(&self) -> Vec<f64> {
        self.exponents.iter().map(|l| l * self.period).collect()
    }
}

/// The flow extended by `k` tangent vectors and, optionally, a second trajectory: state
/// `[y, v_1, ..., v_k, y2]`, memory tangents held beside it. The error control measures `y` alone,
/// so the whole extended state moves in the steps of the plain run; the second trajectory,
/// stepped in the same steps, differs from the first by its perturbation and not by a different
/// step sequence (whose own integration error would otherwise swamp a small separation).
struct Extended<'f, F: Tangent> {
    flow: &'f mut F,
    second: Option<&'f mut F>,
    n: usize,
    k: usize,
    /// Memory tangents, `k` rows of `memory_len`.
    w: Vec<Vec<f64>>,
    f0: Vec<f64>,
    before: Vec<f64>,
    /// Events (impacts) of the first trajectory so far.
    events: u64,
}

impl<F: Tangent> Extended<'_, F> {
    fn second_range(&self) -> std::ops::Range<usize> {
        self.n * (1 + self.k)..self.n * (2 + self.k)
    }
}

impl<F: Tangent> OdeSystem for Extended<'_, F> {
    fn dim(&self) -> usize {
        self.n * (1 + self.k) + if self.second.is_some() { self.n } else { 0 }
    }
    fn error_dim(&self) -> usize {
        self.n
    }
    fn rhs(&mut self, t: f64, y: &[f64], d: &mut [f64]) {
        let n = self.n;
        let r2 = self.second_range();
        if let Some(g) = self.second.as_deref_mut() {
            g.rhs(t, &y[r2.clone()], &mut d[r2]);
        }
        let (ys, vs) = y.split_at(n);
        let (ds, dv) = d.split_at_mut(n);
        self.flow.rhs(t, ys, ds);
        self.f0.copy_from_slice(ds);
        for j in 0..self.k {
            let v = &vs[j * n..(j + 1) * n];
            let out = &mut dv[j * n..(j + 1) * n];
            self.flow.jvp(t, ys, &self.f0, v, &self.w[j], out);
        }
    }
    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        let n = self.n;
        let r2 = self.second_range();
        let mut changed = false;
        if let Some(g) = self.second.as_deref_mut() {
            changed |= g.step_accepted(t0, &y0[r2.clone()], t1, &y1[r2]);
        }
        let mem = self.flow.memory_len() > 0 && self.k > 0;
        if mem {
            self.before = self.flow.memory();
            self.flow.before_accept(t0, &y0[..n], t1, &y1[..n]);
        }
        changed |= self.flow.step_accepted(t0, &y0[..n], t1, &y1[..n]);
        if mem {
            for j in 0..self.k {
                let r = (j + 1) * n..(j + 2) * n;
                self.flow.memory_tangent(
                    t0,
                    &y0[..n],
                    &y0[r.clone()],
                    t1,
                    &y1[..n],
                    &y1[r],
                    &self.before,
                    &mut self.w[j],
                );
            }
        }
        changed
    }
    fn check_step(&mut self, t: f64, y: &[f64]) -> Option<String> {
        let r2 = self.second_range();
        if let Some(g) = self.second.as_deref_mut()
            && let Some(m) = g.check_step(t, &y[r2])
        {
            return Some(format!("the second trajectory: {m}"));
        }
        self.flow.check_step(t, &y[..self.n])
    }
    fn explain_non_finite(&mut self, t: f64, y: &[f64], component: usize) -> String {
        let n = self.n;
        if component < n {
            self.flow.explain_non_finite(t, &y[..n], component)
        } else if component < n * (1 + self.k) {
            format!(
                "tangent vector {} (component {}) became non-finite",
                component / n,
                component % n
            )
        } else {
            format!(
                "the second trajectory's state component {} became non-finite",
                component % n
            )
        }
    }
    fn load_memory(&mut self, state: &HybridState) -> jointplay_solver::Result<()> {
        // The flow checks the state against its own dimension: hand it the physical part. The
        // second trajectory keeps its memory in its own flow.
        let physical = HybridState {
            y: state.y[..self.n].to_vec(),
            ..state.clone()
        };
        self.flow.load_memory(&physical)
    }
    fn save_memory(&self, state: &mut HybridState) {
        self.flow.save_memory(state)
    }
    fn events(&mut self) -> Option<&mut dyn Events> {
        Some(self)
    }
}

impl<F: Tangent> Events for Extended<'_, F> {
    fn count(&mut self) -> usize {
        event_count(&mut *self.flow) + self.second.as_deref_mut().map_or(0, event_count)
    }
    fn restarts_step(&mut self, i: usize) -> bool {
        let ne = event_count(&mut *self.flow);
        if i < ne {
            self.flow.events().is_some_and(|e| e.restarts_step(i))
        } else {
            self.second
                .as_deref_mut()
                .and_then(|g| g.events())
                .is_some_and(|e| e.restarts_step(i - ne))
        }
    }
    fn values(&mut self, t: f64, y: &[f64], g: &mut [f64]) {
        let ne = event_count(&mut *self.flow);
        let r2 = self.second_range();
        if let Some(e) = self.flow.events() {
            e.values(t, &y[..self.n], &mut g[..ne]);
        }
        if let Some(e) = self.second.as_deref_mut().and_then(|s| s.events()) {
            e.values(t, &y[r2], &mut g[ne..]);
        }
    }
    /// A reset of the first trajectory maps every tangent vector with the saltation matrix
    /// `S = DR + (f+ - DR f-) n^T / (n^T f-)` (Mueller 1995), n the gradient of the event
    /// function and f-, f+ the vector field before and after the reset; the second trajectory's
    /// own events reset it alone.
    fn apply(&mut self, i: usize, t: f64, y: &mut [f64]) -> jointplay_solver::Result<()> {
        let (n, ne) = (self.n, event_count(&mut *self.flow));
        if i >= ne {
            let r2 = self.second_range();
            return match self.second.as_deref_mut().and_then(|s| s.events()) {
                Some(e) => e.apply(i - ne, t, &mut y[r2]),
                None => Ok(()),
            };
        }
        if self.flow.events().is_some_and(|e| e.restarts_step(i)) {
            // A contact onset: nothing in the state jumps (the compliant force is zero at zero
            // penetration), so the saltation matrix is the identity; the onset velocity's own
            // saltation was applied in `step_accepted`. Not an impact: not counted.
            return apply_event(&mut *self.flow, i, t, &mut y[..n]);
        }
        let y_minus = y[..n].to_vec();
        let mut f_minus = vec![0.0; n];
        self.flow.rhs(t, &y_minus, &mut f_minus);
        apply_event(&mut *self.flow, i, t, &mut y[..n])?;
        let mut f_plus = vec![0.0; n];
        self.flow.rhs(t, &y[..n], &mut f_plus);
        let mut grad = vec![0.0; n];
        self.flow.event_gradient(i, t, &y_minus, &mut grad);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let nf = dot(&grad, &f_minus);
        let mut dr_f = vec![0.0; n];
        self.flow.reset_jvp(i, t, &y_minus, &f_minus, &mut dr_f);
        let mut out = vec![0.0; n];
        for j in 0..self.k {
            let v = &mut y[(j + 1) * n..(j + 2) * n];
            let nv = dot(&grad, v);
            self.flow.reset_jvp(i, t, &y_minus, v, &mut out);
            for c in 0..n {
                v[c] = out[c]
                    + if nf != 0.0 {
                        (f_plus[c] - dr_f[c]) * nv / nf
                    } else {
                        0.0
                    };
            }
        }
        self.events += 1;
        Ok(())
    }
}

/// Event `i` of `flow` applied at `(t, y)` (nothing without events).
fn apply_event<F: OdeSystem>(
    flow: &mut F,
    i: usize,
    t: f64,
    y: &mut [f64],
) -> jointplay_solver::Result<()> {
    flow.events().map_or(Ok(()), |e| e.apply(i, t, y))
}

/// Projects the columns of `v` (n x k, column-major in `y[n..]`) onto the span of `basis`.
fn project(basis: &DMatrix<f64>, x: &mut [f64]) {
    let n = basis.nrows();
    let c = basis.tr_mul(&nalgebra::DVectorView::from_slice(x, n));
    let p = basis * c;
    x.copy_from_slice(p.as_slice());
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// A deterministic pseudo-random unit-scale vector (SplitMix64): the initial tangent directions,
/// the same on every run so that results are reproducible bit for bit.
fn pseudo_random(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1);
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

/// Modified Gram-Schmidt on the `k` vectors of length `n` in `v` (consecutive), with the memory
/// tangents `w` carried through the same combinations; returns the diagonal of R.
fn orthonormalise(v: &mut [f64], n: usize, w: &mut [Vec<f64>]) -> Vec<f64> {
    let k = w.len();
    let mut r = vec![0.0; k];
    for j in 0..k {
        for i in 0..j {
            let (head, tail) = v.split_at_mut(j * n);
            let qi = &head[i * n..(i + 1) * n];
            let vj = &mut tail[..n];
            let rij: f64 = qi.iter().zip(vj.iter()).map(|(a, b)| a * b).sum();
            for (b, a) in vj.iter_mut().zip(qi) {
                *b -= rij * a;
            }
            let (wh, wt) = w.split_at_mut(j);
            for (b, a) in wt[0].iter_mut().zip(&wh[i]) {
                *b -= rij * a;
            }
        }
        let vj = &mut v[j * n..(j + 1) * n];
        let rjj = norm(vj);
        r[j] = rjj;
        if rjj > 0.0 {
            for b in vj.iter_mut() {
                *b /= rjj;
            }
            for b in w[j].iter_mut() {
                *b /= rjj;
            }
        }
    }
    r
}

/// Batch means: the mean of the per-batch estimates and its standard error (NaN below two
/// batches).
fn batch_stderr(batches: &[f64]) -> f64 {
    let b = batches.len();
    if b < 2 {
        return f64::NAN;
    }
    let mean = batches.iter().sum::<f64>() / b as f64;
    let var = batches.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (b - 1) as f64;
    (var / b as f64).sqrt()
}

/// Carries the tangent vectors `vectors` (each of the flow's dimension; memory tangents zero) from
/// the hybrid state `start` to `t_end` with the flow's integrator, in the steps of the plain run:
/// the derivative of the flow map along each vector, through contact onsets. Returns the final
/// state and the carried vectors.
pub fn tangent_map<F: Tangent>(
    flow: &mut F,
    start: &HybridState,
    vectors: &[Vec<f64>],
    t_end: f64,
) -> Result<(HybridState, Vec<Vec<f64>>)> {
    tangent_map_counted(flow, start, vectors, t_end).map(|(s, v, _)| (s, v))
}

/// [`tangent_map`] that also counts the events (impacts with a state reset) on the way.
pub fn tangent_map_counted<F: Tangent>(
    flow: &mut F,
    start: &HybridState,
    vectors: &[Vec<f64>],
    t_end: f64,
) -> Result<(HybridState, Vec<Vec<f64>>, u64)> {
    let n = flow.dim();
    let k = vectors.len();
    let method = flow.method();
    flow.prepare(start)?;
    let mut ext_state = HybridState {
        y: [start.y.clone(), vectors.concat()].concat(),
        ..start.clone()
    };
    let mut ext = Extended {
        n,
        k,
        w: vec![vec![0.0; flow.memory_len()]; k],
        second: None,
        flow,
        f0: vec![0.0; n],
        before: Vec::new(),
        events: 0,
    };
    let (_, res) = ode::advance(
        &mut ext,
        method,
        &mut ext_state,
        t_end,
        &[],
        |_, _, _| Step::Continue,
        None,
    );
    res?;
    let events = ext.events;
    let out = (0..k)
        .map(|j| ext_state.y[(j + 1) * n..(j + 2) * n].to_vec())
        .collect();
    ext_state.y.truncate(n);
    Ok((ext_state, out, events))
}

/// Computes the Lyapunov spectrum of `flow` from the hybrid state `start` (whose memory the flow
/// has been prepared with), after `spec.transient` periods (`transient` when the spec gives
/// none). `second` is an independent copy of the flow for the two-trajectory estimate.
/// `progress` gets the fraction done.
pub fn spectrum<F: Tangent>(
    flow: &mut F,
    second: Option<&mut F>,
    start: &HybridState,
    spec: &LyapunovSpec,
    transient: usize,
    progress: &mut dyn FnMut(f64),
) -> Result<Spectrum> {
    spectrum_until(flow, second, start, spec, transient, progress, &Stop::new())
}

/// [`spectrum`] that ends with [`crate::Error::Interrupted`] at the first re-orthonormalisation
/// after `stop` is requested.
pub fn spectrum_until<F: Tangent>(
    flow: &mut F,
    second: Option<&mut F>,
    start: &HybridState,
    spec: &LyapunovSpec,
    transient: usize,
    progress: &mut dyn FnMut(f64),
    stop: &Stop,
) -> Result<Spectrum> {
    let method = flow.method();
    let period = flow.period();
    let n = flow.dim();
    let k = spec.exponents;
    let phase_dim = flow.phase_dim();
    let transient = spec.transient.unwrap_or(transient);
    let t0 = start.t;
    let mut state = start.clone();
    flow.prepare(&state)?;
    flow.set_difference(spec.difference);
    // The transient, plain.
    let t_start = t0 + transient as f64 * period;
    if transient > 0 {
        let (_, res) = ode::advance(
            flow,
            method,
            &mut state,
            t_start,
            &[],
            |_, _, _| Step::Continue,
            None,
        );
        res?;
    }
    let (v, mut w) = initial_vectors(flow, &state, k)?;
    let mut second = second;
    let second_state = match second.as_deref_mut() {
        Some(g) => Some(second_start(g, &state, &v[..n], spec.separation)?),
        None => None,
    };
    let interval = period / spec.per_period as f64;
    let max_intervals = spec.periods * spec.per_period;
    let batch = spec.batch_len();
    let mut sums = vec![0.0; k];
    let mut batch_sums = vec![0.0; k];
    let mut batches: Vec<Vec<f64>> = vec![Vec::new(); k];
    let (mut sum2, mut batch2, mut batches2) = (0.0, 0.0, Vec::new());
    let mut history_t = Vec::new();
    let mut history = Vec::new();
    let mut history2 = Vec::new();
    let mut div_sum = 0.0;
    let mut div_known = flow.divergence(state.t, &state.y).is_some();
    let mut rhs_evals = 0;
    let mut events = 0;
    let mut stopped_early = false;
    let mut done = 0;
    let mut ext_state = HybridState {
        y: [state.y.clone(), v, second_state.clone().unwrap_or_default()].concat(),
        ..state.clone()
    };
    while done < max_intervals {
        let t_next = t_start + (done + 1) as f64 * interval;
        let mut ext = Extended {
            flow: &mut *flow,
            second: second.as_deref_mut(),
            n,
            k,
            w: std::mem::take(&mut w),
            f0: vec![0.0; n],
            before: Vec::new(),
            events: 0,
        };
        let (stats, res) = advance_extended(
            &mut ext,
            method,
            &mut ext_state,
            t_next,
            (&mut div_known, &mut div_sum),
        );
        events += ext.events;
        w = ext.w;
        rhs_evals += stats.rhs_evals;
        res?;
        let t = ext_state.t;
        if stop.requested() {
            return Err(crate::Error::Interrupted { time: Some(t) });
        }
        let (ys, rest) = ext_state.y.split_at_mut(n);
        let (vs, y2) = rest.split_at_mut(n * k);
        let basis = flow.manifold_basis(t, ys)?;
        if let Some(b) = &basis {
            for j in 0..k {
                project(b, &mut vs[j * n..(j + 1) * n]);
            }
        }
        let r = orthonormalise(vs, n, &mut w);
        for j in 0..k {
            let l = r[j].ln();
            sums[j] += l;
            batch_sums[j] += l;
        }
        if let Some(g) = second.as_deref_mut() {
            let l = pull_back(&*flow, g, ys, y2, basis.as_ref(), spec.separation);
            sum2 += l;
            batch2 += l;
        }
        done += 1;
        let elapsed = done as f64 * interval;
        history_t.push(t);
        history.push(sums.iter().map(|s| s / elapsed).collect::<Vec<_>>());
        if second_state.is_some() {
            history2.push(sum2 / elapsed);
        }
        if done % batch == 0 {
            let bt = batch as f64 * interval;
            close_batch(&mut batches, &mut batch_sums, bt);
            close_batch(
                std::slice::from_mut(&mut batches2),
                std::slice::from_mut(&mut batch2),
                bt,
            );
            if let Some(target) = spec.until_stderr
                && batches[0].len() >= MIN_BATCHES
                && batch_stderr(&batches[0]) <= target
            {
                stopped_early = done < max_intervals;
                break;
            }
        }
        progress(done as f64 / max_intervals as f64);
    }
    let time = done as f64 * interval;
    let mut end = ext_state;
    end.y.truncate(n);
    Ok(Spectrum {
        end,
        exponents: sums.iter().map(|s| s / time).collect(),
        stderr: batches.iter().map(|b| batch_stderr(b)).collect(),
        period,
        time,
        phase_dim,
        history_t,
        history,
        two_trajectory: second_state
            .is_some()
            .then(|| (sum2 / time, batch_stderr(&batches2), history2)),
        mean_divergence: div_known.then(|| div_sum / time),
        jvp: flow.jvp_kind(),
        rhs_evals,
        stopped_early,
        events,
        drift: drift(
            &batches[0],
            |i| t_start + ((i + 1) * batch) as f64 * interval,
            1e-3 / period,
        ),
    })
}

/// The initial tangent vectors at `state`: `k` pseudo-random vectors projected on the tangent
/// space of the constraint manifold and orthonormalised (`n * k` values, vector after vector),
/// with their memory tangents (`k` rows of the flow's memory length).
fn initial_vectors<F: Tangent>(
    flow: &mut F,
    state: &HybridState,
    k: usize,
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    let n = flow.dim();
    let basis = flow.manifold_basis(state.t, &state.y)?;
    let mut v = Vec::with_capacity(n * k);
    for j in 0..k {
        let mut x = pseudo_random(j as u64 + 1, n);
        if let Some(b) = &basis {
            project(b, &mut x);
        }
        v.extend(x);
    }
    let mem = flow.memory_len();
    let mut w = vec![vec![0.0; mem]; k];
    orthonormalise(&mut v, n, &mut w);
    Ok((v, w))
}

/// Advances the extended system (the state, its tangent vectors and the second trajectory) to
/// `t_next`. While the flow's divergence is known (`div.0`), it is integrated by the trapezoid
/// rule on the accepted steps into `div.1`; a step where it is not known clears `div.0`.
fn advance_extended<F: Tangent>(
    ext: &mut Extended<'_, F>,
    method: Method,
    ext_state: &mut HybridState,
    t_next: f64,
    div: (&mut bool, &mut f64),
) -> (ode::Stats, jointplay_solver::Result<()>) {
    let n = ext.n;
    let (div_known, div_sum) = div;
    let use_div = *div_known;
    let mut div_lost = false;
    let mut on_step = |s: &mut Extended<F>, st: &ode::Step| {
        if let (Some(a), Some(b)) = (
            s.flow.divergence(st.t0, &st.y0[..n]),
            s.flow.divergence(st.t1, &st.y1[..n]),
        ) {
            *div_sum += 0.5 * (a + b) * (st.t1 - st.t0);
        } else {
            div_lost = true;
        }
        Step::Continue
    };
    let out = ode::advance(
        ext,
        method,
        ext_state,
        t_next,
        &[],
        |_, _, _| Step::Continue,
        if use_div { Some(&mut on_step) } else { None },
    );
    *div_known &= !div_lost;
    out
}

/// Brings the second trajectory `y2` back to the distance `separation` from the first, `ys`,
/// along their difference (projected on the tangent space `basis` when the flow has
/// constraints), its contact history pulled back with it where both are in contact; returns
/// the logarithm of the stretch since the last pull-back.
fn pull_back<F: Tangent>(
    flow: &F,
    g: &mut F,
    ys: &[f64],
    y2: &mut [f64],
    basis: Option<&DMatrix<f64>>,
    separation: f64,
) -> f64 {
    let mut d: Vec<f64> = y2.iter().zip(ys.iter()).map(|(a, b)| a - b).collect();
    if let Some(b) = basis {
        project(b, &mut d);
    }
    let dist = norm(&d);
    let l = (dist / separation).ln();
    let scale = separation / dist;
    for (a, b) in y2.iter_mut().zip(ys.iter()) {
        *a = b + scale * (*a - b);
    }
    let m1 = flow.memory();
    let mut m2 = g.memory();
    for (a, b) in m2.iter_mut().zip(&m1) {
        if a.is_finite() && b.is_finite() {
            *a = b + scale * (*a - b);
        }
    }
    g.set_memory(&m2);
    l
}

/// Ends a batch of the batch-means error estimate: each sum of logarithms over the batch's
/// duration `bt` (s) becomes the batch's mean exponent, and the sum starts again from 0.
fn close_batch(batches: &mut [Vec<f64>], sums: &mut [f64], bt: f64) {
    for (b, s) in batches.iter_mut().zip(sums.iter_mut()) {
        b.push(*s / bt);
        *s = 0.0;
    }
}

/// The second trajectory's start: `separation` away from `state` along the first tangent
/// vector `v1`, with the first one's contact history (`g` prepared with it).
fn second_start<F: Tangent>(
    g: &mut F,
    state: &HybridState,
    v1: &[f64],
    separation: f64,
) -> Result<Vec<f64>> {
    let mut s2 = state.clone();
    for (a, b) in s2.y.iter_mut().zip(v1) {
        *a += separation * b;
    }
    g.prepare(&s2)?;
    Ok(s2.y)
}

#[cfg(test)]
mod tests {
    use super::{cusum_critical, drift, pseudo_random};

    /// `n` standard normal values (Box-Muller on the pseudo-random uniforms of `seed`).
    fn normals(seed: u64, n: usize) -> Vec<f64> {
        let u = pseudo_random(seed, 2 * n);
        u.chunks_exact(2)
            .map(|p| {
                let (a, b) = (p[0] + 0.5, p[1] + 0.5);
                (-2.0 * (1.0f64 - a).ln()).sqrt() * (std::f64::consts::TAU * b).cos()
            })
            .collect()
    }

    #[test]
    fn stationary_batches_rarely_drift() {
        // 4000 stationary series per batch count, at the 0.1 % level: 4 false alarms expected;
        // 16 is beyond the binomial's 99.99 % quantile (mean 4, sd 2), so a test that fails
        // here has critical values too small for that count.
        for b in [10, 14, 20, 30, 40, 100] {
            let alarms = (0..4000u64)
                .filter(|s| {
                    drift(&normals(s * 1000 + b as u64, b + 1), |i| i as f64, 0.0).is_some()
                })
                .count();
            assert!(alarms <= 16, "{b} batches: {alarms} false alarms in 4000");
        }
        assert_eq!(cusum_critical(9), None);
        assert_eq!(cusum_critical(10), Some(3.04));
        assert_eq!(cusum_critical(1000), Some(1.95));
        let c = cusum_critical(30).unwrap();
        assert!(c < 2.31 && c > 2.05, "{c}");
    }

    #[test]
    fn a_transient_that_settles_is_a_drift_with_its_time_and_both_values() {
        // 30 batches of a chaotic transient (0.2 1/s) then 30 of the periodic orbit it settles on
        // (-0.05 1/s), each with a scatter of 0.02; the first batch (the tangent vectors
        // turning) far off, and left out.
        let noise = normals(7, 60);
        let mut x: Vec<f64> = (0..60)
            .map(|i| if i < 30 { 0.2 } else { -0.05 } + 0.02 * noise[i])
            .collect();
        x[0] = 5.0;
        let d = drift(&x, |i| 10.0 * (i + 1) as f64, 1e-3).expect("a drift");
        assert_eq!(d.time, 300.0);
        // Each mean of 30 batches of scatter 0.02 is within 4 standard errors (0.015).
        assert!(
            (d.before - 0.2).abs() < 0.015 && (d.after + 0.05).abs() < 0.015,
            "{d:?}"
        );
        assert!(d.statistic > d.critical);
        // Two exact plateaus; one constant level after a first batch far off (a periodic
        // orbit); a change below the floor; too few batches.
        let steps: Vec<f64> = (0..20).map(|i| if i < 5 { 1.0 } else { 0.0 }).collect();
        assert_eq!(drift(&steps, |i| i as f64, 1e-3).map(|d| d.time), Some(4.0));
        let mut periodic = vec![-0.0855; 40];
        periodic[0] = -0.07;
        assert!(drift(&periodic, |i| i as f64, 1e-3).is_none());
        let small: Vec<f64> = (0..40).map(|i| if i < 20 { 1e-4 } else { 0.0 }).collect();
        assert!(drift(&small, |i| i as f64, 1e-3).is_none());
        assert!(drift(&x[..10], |i| i as f64, 1e-3).is_none());
    }
}
