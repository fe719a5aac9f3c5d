//! Periodic orbits of forced flows by shooting, and their Floquet multipliers.
//!
//! **Shooting.** A flow forced with period `T` has the stroboscopic map `P(y) = phi(t_s + T; t_s,
//! y)`; a period-`k` orbit (a subharmonic of order `k` when `k > 1`) is a fixed point of the
//! k-fold map, a root of
//!
//! ```text
//! G(y) = P^k(y) - y = 0 .
//! ```
//!
//! Newton's method solves it (Seydel, Practical Bifurcation and Stability Analysis, 3rd ed. 2010,
//! sec. 7.3): `(M - I) dy = -G(y)`, where the monodromy matrix `M = dP^k/dy` is the flow's
//! tangent map over `kT` ([`crate::measures::lyapunov::tangent_map`]: the variational equations
//! integrated in the same steps as the state, through contact onsets with the onset-velocity
//! derivative, and through impacts with the saltation matrix). Each map evaluation starts with a
//! fresh integrator memory ([`HybridState::for_new_run`]), so that `P` is a function of `y` alone;
//! its contact-onset memory is taken from the previous evaluation's end, which is the memory the
//! orbit carries once it has converged.
//!
//! **On a mechanism's constraint manifold: reduced coordinates.** A mechanism's state (positions
//! with Euler parameters, velocities) lives on the manifold of its position and velocity
//! constraints and unit Euler-parameter norms, of dimension `m = 2 x` free degrees of freedom,
//! inside the state space of dimension `n = 13 x` bodies. On the full state `M - I` is singular or
//! nearly so: Baumgarte stabilisation pulls perturbations normal to the manifold back at rates set
//! by its gains (multipliers near 0, which is harmless) and the Euler-parameter norm is neutral
//! (a multiplier 1, which makes `M - I` singular). So Newton works in **reduced coordinates**:
//! with `B` an orthonormal basis of the manifold's tangent space at the iterate
//! ([`crate::flow::tangent::Tangent::manifold_basis`]), the step is `dy = B dz` with
//!
//! ```text
//! (B^T M B - I_m) dz = -B^T G(y),
//! ```
//!
//! and the updated state is assembled back onto the manifold
//! ([`crate::flow::tangent::Tangent::onto_manifold`]), the second-order correction of a step along the
//! tangent space. This was chosen over a projected Newton step on the full state (a least-squares
//! solve of the singular `M - I` followed by projection) because the reduced system is square
//! and regular exactly when the orbit is isolated on the manifold, its condition number then says
//! something about the orbit and not about the stabilisation gains, and its eigenvalues are the
//! multipliers without the spurious ones (below). A built-in system has `B = I`.
//!
//! Convergence: the largest component of `G(y)` (SI units of the state) at most `tolerance`.
//! A Newton step that increases it is halved up to four times (a damped Newton method, Deuflhard,
//! Newton Methods for Nonlinear Problems, 2004, ch. 3, in its simplest form). The tolerance must
//! be above the integration error of one map evaluation, which bounds how well `G` is known.
//!
//! **Floquet multipliers** (Kuznetsov, Elements of Applied Bifurcation Theory, 3rd ed. 2004,
//! sec. 1.5) are the eigenvalues of the monodromy matrix on the manifold, `B^T M B` (`m` of them):
//! the orbit is asymptotically stable when all lie inside the unit circle. For a smooth flow their
//! product is `exp(int_0^{kT} div f dt)` (Liouville): `exp(-delta k T)` for the Duffing oscillator.
//! An impact with restitution `e` multiplies it by the determinant of its saltation matrix, `e^2`
//! for the Newton impact oscillator (di Bernardo et al., Piecewise-smooth Dynamical Systems, 2008,
//! sec. 2.5). The `n - m` multipliers of the full monodromy matrix in the directions normal to the
//! manifold are **spurious** and left out: the constraint drift decays at the Baumgarte rates and
//! the Euler-parameter norms are neutral; they describe the stabilised integration, not the
//! mechanism. [`Orbit::spurious`] counts them.
//!
//! A contact that is open at the strobe time carries its onset velocity as memory; the Jacobian
//! holds that memory fixed, so for the multipliers to be exact the strobe phase should fall
//! outside contact (`analysis.phase`).

use jointplay_solver::state::HybridState;
use nalgebra::{Complex, DMatrix, DVector};

use crate::flow::tangent::Tangent;
use crate::measures::lyapunov::tangent_map_counted;
use crate::{Error, Result};

/// Newton settings of a shooting solve.
#[derive(Debug, Clone, Copy)]
pub struct Newton {
    /// Largest component of `P^k(y) - y` accepted (SI units of the state).
    pub tolerance: f64,
    /// Newton iterations at most.
    pub max_iterations: usize,
}

/// Why the spurious multipliers are left out.
pub const SPURIOUS_REASON: &str = "directions normal to the constraint manifold: the position and velocity constraint drift, which Baumgarte stabilisation damps at rates set by its gains, and the Euler-parameter norms, which are neutral; they describe the stabilised integration, not the mechanism";

/// A periodic orbit found by shooting.
#[derive(Debug, Clone)]
pub struct Orbit {
    /// The strobe point (its contact-onset memory the orbit's own).
    pub state: HybridState,
    /// Drive periods per orbit.
    pub k: usize,
    /// The orbit's period `k T` (s).
    pub period: f64,
    /// Largest component of `P^k(y) - y` at `state`.
    pub residual: f64,
    /// Newton iterations taken.
    pub iterations: usize,
    /// Floquet multipliers on the manifold, largest modulus first.
    pub multipliers: Vec<Complex<f64>>,
    /// Multipliers of the full state left out (normal to the manifold; see [`SPURIOUS_REASON`]).
    pub spurious: usize,
    /// Events (impacts) along one orbit.
    pub events: u64,
    /// `B^T M B`: the monodromy matrix in reduced coordinates.
    pub monodromy: DMatrix<f64>,
    /// The basis `B` of the reduced coordinates (None: the identity).
    pub basis: Option<DMatrix<f64>>,
}

impl Orbit {
    /// The largest modulus of the multipliers.
    pub fn spectral_radius(&self) -> f64 {
        self.multipliers
            .iter()
            .map(|m| m.norm())
            .fold(0.0, f64::max)
    }
    /// Asymptotically stable: every multiplier inside the unit circle.
    pub fn stable(&self) -> bool {
        self.spectral_radius() < 1.0
    }
    /// Multipliers outside the unit circle.
    pub fn unstable_count(&self) -> usize {
        self.multipliers.iter().filter(|m| m.norm() > 1.0).count()
    }
    /// The product of the multipliers (real up to round-off).
    pub fn product(&self) -> f64 {
        self.multipliers
            .iter()
            .fold(Complex::new(1.0, 0.0), |a, b| a * b)
            .re
    }
    /// The full-state vector `B v` of the reduced vector `v`.
    pub fn lift(&self, v: &DVector<f64>) -> Vec<f64> {
        match &self.basis {
            Some(b) => (b * v).as_slice().to_vec(),
            None => v.as_slice().to_vec(),
        }
    }
    /// A unit eigenvector (full state) of the monodromy matrix for the real multiplier nearest
    /// `mu`: the right singular vector of `B^T M B - mu I` of the smallest singular value.
    pub fn eigenvector(&self, mu: f64) -> Vec<f64> {
        let m = self.monodromy.nrows();
        let a = &self.monodromy - DMatrix::identity(m, m) * mu;
        let svd = a.svd(false, true);
        let vt = svd.v_t.expect("requested");
        let j = (0..m)
            .min_by(|&x, &y| svd.singular_values[x].total_cmp(&svd.singular_values[y]))
            .unwrap_or(0);
        let v = DVector::from_iterator(m, (0..m).map(|c| vt[(j, c)]));
        self.lift(&v)
    }
}

/// One evaluation of the k-fold map with its Jacobian.
pub(crate) struct MapEval {
    /// End state after `k T`.
    pub end: HybridState,
    /// `P^k(y) - y`.
    pub residual: Vec<f64>,
    /// `B^T M B` (m x m).
    pub reduced: DMatrix<f64>,
    /// `B` (None: identity).
    pub basis: Option<DMatrix<f64>>,
    pub events: u64,
}

impl MapEval {
    pub fn max_residual(&self) -> f64 {
        self.residual.iter().fold(0.0, |a: f64, b| a.max(b.abs()))
    }
    /// `B^T r` for a full-state vector `r`.
    pub fn reduce(&self, r: &[f64]) -> DVector<f64> {
        let r = DVector::from_column_slice(r);
        match &self.basis {
            Some(b) => b.tr_mul(&r),
            None => r,
        }
    }
    pub fn lift(&self, z: &DVector<f64>) -> Vec<f64> {
        match &self.basis {
            Some(b) => (b * z).as_slice().to_vec(),
            None => z.as_slice().to_vec(),
        }
    }
}

/// The k-fold map at `state` (strobe time `state.t`) with its reduced Jacobian.
pub(crate) fn evaluate<F: Tangent>(flow: &mut F, state: &HybridState, k: usize) -> Result<MapEval> {
    let n = flow.dim();
    let t_end = state.t + k as f64 * flow.period();
    let basis = flow.manifold_basis(state.t, &state.y)?;
    let vectors: Vec<Vec<f64>> = match &basis {
        Some(b) => (0..b.ncols())
            .map(|c| b.column(c).iter().copied().collect())
            .collect(),
        None => (0..n)
            .map(|c| {
                let mut e = vec![0.0; n];
                e[c] = 1.0;
                e
            })
            .collect(),
    };
    let start = state.for_new_run();
    let (mut end, mut images, events) = tangent_map_counted(flow, &start, &vectors, t_end)?;
    // A body that turned a whole number of turns comes back with its Euler parameters negated
    // (the quaternion double cover): the same orientation. The image is taken with the sign of
    // the argument's parameters, so that a crank's orbit is a fixed point (its residual would
    // otherwise be 2 in those components whatever the motion), and its tangent images with it.
    same_sign_as(flow, &state.y, &mut end.y, &mut images);
    let m = vectors.len();
    let mut mb = DMatrix::zeros(n, m);
    for (c, v) in images.iter().enumerate() {
        for r in 0..n {
            mb[(r, c)] = v[r];
        }
    }
    let reduced = match &basis {
        Some(b) => b.tr_mul(&mb),
        None => mb,
    };
    let residual = end.y.iter().zip(&state.y).map(|(a, b)| a - b).collect();
    Ok(MapEval {
        end,
        residual,
        reduced,
        basis,
        events,
    })
}

/// `max |P^k(y) - y|` at `state` (strobe time `state.t`), without the Jacobian; Euler
/// parameters compared up to their sign, as [`evaluate`] does.
pub(crate) fn map_distance<F: Tangent>(flow: &mut F, state: &HybridState, k: usize) -> Result<f64> {
    let t_end = state.t + k as f64 * flow.period();
    let (mut end, _) =
        crate::measures::lyapunov::tangent_map(flow, &state.for_new_run(), &[], t_end)?;
    same_sign_as(flow, &state.y, &mut end.y, &mut []);
    Ok(end
        .y
        .iter()
        .zip(&state.y)
        .fold(0.0, |m: f64, (a, b)| m.max((a - b).abs())))
}

/// Turns the Euler parameters of `end` (and the same rows of `images`) to the sign of those of
/// `start` where they differ in sign: one orientation either way (the quaternion double cover).
fn same_sign_as<F: Tangent>(flow: &F, start: &[f64], end: &mut [f64], images: &mut [Vec<f64>]) {
    for o in flow.euler_parameters() {
        let dot: f64 = (o..o + 4).map(|i| end[i] * start[i]).sum();
        if dot < 0.0 {
            for i in o..o + 4 {
                end[i] = -end[i];
                for v in images.iter_mut() {
                    v[i] = -v[i];
                }
            }
        }
    }
}

/// The multipliers of a reduced monodromy matrix, largest modulus first.
pub fn multipliers(reduced: &DMatrix<f64>) -> Vec<Complex<f64>> {
    let mut mu: Vec<Complex<f64>> = reduced.complex_eigenvalues().iter().copied().collect();
    mu.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
    mu
}

/// The orbit at a converged evaluation.
pub(crate) fn orbit_of<F: Tangent>(
    flow: &F,
    state: HybridState,
    ev: MapEval,
    k: usize,
    iterations: usize,
) -> Orbit {
    let m = ev.reduced.nrows();
    Orbit {
        residual: ev.max_residual(),
        multipliers: multipliers(&ev.reduced),
        spurious: flow.dim() - m,
        events: ev.events,
        monodromy: ev.reduced,
        basis: ev.basis,
        period: k as f64 * flow.period(),
        k,
        iterations,
        state,
    }
}

fn orbit_error(message: String) -> Error {
    Error::Orbit(message)
}

/// Finds the period-`k` orbit through a strobe point near `start` (at strobe time `start.t`) by
/// Newton's method on `P^k(y) - y` in reduced coordinates (module overview). The error says what
/// failed: the residual history when it does not converge, a singular Jacobian, or the run that
/// failed.
pub fn shoot<F: Tangent>(
    flow: &mut F,
    start: &HybridState,
    k: usize,
    newton: Newton,
) -> Result<Orbit> {
    if k == 0 {
        return Err(orbit_error(
            "the number of periods k must be at least 1".into(),
        ));
    }
    if flow.phase_dim() == 0 {
        return Err(orbit_error(
            "the flow has no free degree of freedom: the drives prescribe its whole motion, so there is no orbit to find".into(),
        ));
    }
    let mut state = start.for_new_run();
    flow.onto_manifold(state.t, &mut state.y)?;
    let mut ev = evaluate(flow, &state, k)?;
    let mut history = vec![ev.max_residual()];
    for it in 0..=newton.max_iterations {
        let res = ev.max_residual();
        if !res.is_finite() {
            return Err(orbit_error(format!(
                "the map P^{k} gave a non-finite state after {it} Newton iterations"
            )));
        }
        if res <= newton.tolerance {
            state.onset.clone_from(&ev.end.onset);
            return Ok(orbit_of(flow, state, ev, k, it));
        }
        if it == newton.max_iterations {
            break;
        }
        let m = ev.reduced.nrows();
        let a = &ev.reduced - DMatrix::identity(m, m);
        let rhs = -ev.reduce(&ev.residual);
        let Some(dz) = a.lu().solve(&rhs) else {
            return Err(orbit_error(format!(
                "the Jacobian B^T (M - I) B is singular after {it} Newton iterations (residual {res:.3e}): a multiplier is 1, a fold or a degenerate orbit"
            )));
        };
        let dy = ev.lift(&dz);
        // Damped: halve a step that increases the residual (at most four times).
        let mut lambda = 1.0;
        let mut accepted = None;
        for _ in 0..5 {
            let mut trial = state.clone();
            for (a, d) in trial.y.iter_mut().zip(&dy) {
                *a += lambda * d;
            }
            trial.onset.clone_from(&ev.end.onset);
            let tried = flow
                .onto_manifold(trial.t, &mut trial.y)
                .and_then(|_| evaluate(flow, &trial, k));
            match tried {
                Ok(e) if e.max_residual() < res => {
                    accepted = Some((trial, e));
                    break;
                }
                Ok(e) if lambda < 0.1 => {
                    accepted = Some((trial, e));
                    break;
                }
                Err(err) if lambda < 0.1 => return Err(err),
                _ => lambda *= 0.5,
            }
        }
        let (s, e) = accepted.expect("the last trial is always taken");
        state = s;
        ev = e;
        history.push(ev.max_residual());
    }
    Err(orbit_error(format!(
        "Newton did not converge in {} iterations to the tolerance {:e}: residuals {}",
        newton.max_iterations,
        newton.tolerance,
        history
            .iter()
            .map(|r| format!("{r:.3e}"))
            .collect::<Vec<_>>()
            .join(", ")
    )))
}
