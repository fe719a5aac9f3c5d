//! Pseudo-arclength continuation of periodic orbits in a parameter, with the detection and
//! location of their bifurcations and of grazing.
//!
//! **Branches.** With `s = (p - from) / (to - from)` the scaled parameter (0 at `from`, 1 at
//! `to`), a branch of period-`k` orbits is a curve of roots of `G(y, s) = P^k(y; s) - y`
//! ([`crate::periodic`]). From a point `(y0, s0)` with unit tangent `(t_y, t_s)` the next point
//! is predicted at `(y0 + h t_y, s0 + h t_s)` and corrected by Newton's method on
//!
//! ```text
//! G(y, s) = 0,     t_y . (y - y0) + t_s (s - s0) = h
//! ```
//!
//! (Keller's pseudo-arclength condition; Seydel, Practical Bifurcation and Stability Analysis,
//! 2010, sec. 4.4; Dankowicz & Schilder, Recipes for Continuation, 2013, ch. 10). On a mechanism
//! the state is corrected in the reduced coordinates of its constraint manifold, `dy = B dz`,
//! as in shooting, so the bordered Jacobian is
//!
//! ```text
//! [ B^T M B - I    B^T dG/ds ]
//! [ (B^T t_y)^T    t_s       ] ,
//! ```
//!
//! `dG/ds` by central differences of the map (step `1e-4` of the parameter range: the
//! truncation error `~1e-8` relative, the integration error divided by the step well below it).
//! The new tangent solves the same matrix with the right-hand side `(0, 1)` (its last row the old
//! tangent: the branch keeps its direction through folds). The state is in SI units and the
//! parameter scaled to its range, so steps `h` are given in parameter units and converted; a step
//! moves the parameter by at most that much.
//!
//! **Step control.** A corrector that does not converge in the Newton iterations halves the step,
//! down to `min_step` (then the branch ends, its last good point kept); one that converges in at
//! most 3 iterations lets the next step grow by 1.5 up to `max_step`.
//!
//! **Test functions** (Seydel sec. 7.4; Kuznetsov, Elements of Applied Bifurcation Theory, 2004,
//! sec. 10.3), evaluated at every point from the multipliers `mu_i` and the tangent:
//!
//! | kind | test function | zero when |
//! |---|---|---|
//! | fold | `t_s` | the parameter turns (a multiplier through +1) |
//! | period doubling | `prod (mu_i + 1)` | a real multiplier through -1 |
//! | Neimark-Sacker | `prod_{i<j} (mu_i mu_j - 1)` | a complex pair through the unit circle (also a neutral saddle, `mu_i mu_j = 1` real, which is not reported) |
//! | grazing | `level - max over the orbit of the contact observable` | contact begins or ends |
//!
//! A sign change between two points is located by the Illinois variant of regula falsi on the
//! arclength from the first point (each trial a corrector solve) until the arclength bracket,
//! in parameter units, is below `locate`: a bound on the error of the located parameter.
//! Grazing (di Bernardo et al., Piecewise-smooth Dynamical Systems, 2008, ch. 7): the gap is the
//! smallest clearance along the orbit, sampled `samples` times per period with a parabola through
//! the largest sample and its neighbours (error `~h^4`); for a flow with impacts the impacting
//! side has no gap to extrapolate, so it is located by secant steps from the contact-free side
//! alternated with bisection. The contact-free and the contacting segments are different
//! branches: the branch ends at a grazing, and the first point past it starts a new one.
//!
//! **Branch switching at a period doubling.** The period-`2k` orbits leave the located point
//! `(y*, s*)` tangent to the eigenvector `v` of the multiplier -1 at fixed parameter (a pitchfork
//! of the `2k`-fold map; Seydel sec. 7.6.3). The new branch starts with the tangent `(v, 0)` and
//! the pseudo-arclength corrector on the `2k`-fold map, which the period-`k` branch (also a
//! solution) meets only at `h = 0`.

use jointplay_solver::ode::{self, Flow as Step};
use jointplay_solver::state::HybridState;
use nalgebra::{Complex, DMatrix, DVector};

use crate::Result;
use crate::flow::{Flow, Target};
use crate::lyapunov::tangent_map;
use crate::periodic::{MapEval, Newton, Orbit, evaluate, map_distance, orbit_of, shoot};
use crate::sections::Observed;
use crate::tangent::Tangent;

/// What a continuation needs besides the flow.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Start and end of the parameter range.
    pub from: f64,
    pub to: f64,
    /// First, smallest and largest step (parameter units, see the module overview).
    pub step: f64,
    pub min_step: f64,
    pub max_step: f64,
    /// Points per branch at most.
    pub max_points: usize,
    /// Drive periods per orbit of the first branch.
    pub k: usize,
    pub newton: Newton,
    /// Bracket (parameter units) special points are located to.
    pub locate: f64,
    /// Follow the period-2k branch from every period doubling.
    pub switch_period_doubling: bool,
    /// Branches at most (the first one and those switched to).
    pub max_branches: usize,
    /// Grazing: the index of the contact observable and the level at which contact begins (the
    /// gap is `level - max` of the observable over the orbit).
    pub grazing: Option<(usize, f64)>,
    /// Samples per drive period for the gap.
    pub samples: usize,
}

/// The kinds of special points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Fold = 1,
    PeriodDoubling = 2,
    NeimarkSacker = 3,
    Grazing = 4,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Fold => "fold",
            Kind::PeriodDoubling => "period-doubling",
            Kind::NeimarkSacker => "neimark-sacker",
            Kind::Grazing => "grazing",
        }
    }
    const ALL: [Kind; 4] = [
        Kind::Fold,
        Kind::PeriodDoubling,
        Kind::NeimarkSacker,
        Kind::Grazing,
    ];
}

/// One point of a branch.
#[derive(Debug, Clone)]
pub struct Point {
    pub parameter: f64,
    pub orbit: Orbit,
    /// Corrector iterations.
    pub iterations: usize,
    /// The observables at the orbit's `k` strobe points (`[k][observables]`).
    pub strobe: Vec<Vec<f64>>,
    /// The smallest gap along the orbit, when grazing is followed.
    pub gap: Option<f64>,
    /// Unit tangent: state part and scaled-parameter part.
    tangent_y: Vec<f64>,
    tangent_s: f64,
    s: f64,
}

/// A located special point.
#[derive(Debug, Clone)]
pub struct Special {
    pub kind: Kind,
    pub branch: usize,
    /// Index of the branch point before it.
    pub after: usize,
    pub parameter: f64,
    /// The arclength bracket reached (parameter units): the error bound of `parameter`.
    pub bracket: f64,
    /// The strobe point and the multipliers there (of the nearest corrected orbit).
    pub state: Vec<f64>,
    pub multipliers: Vec<Complex<f64>>,
    /// The observables at its strobe points.
    pub strobe: Vec<Vec<f64>>,
}

/// One branch.
#[derive(Debug, Clone)]
pub struct Branch {
    pub k: usize,
    /// Where it starts: "start" or the special point it was switched from.
    pub origin: String,
    pub points: Vec<Point>,
    /// Why it ended.
    pub end: String,
    /// It ended because a step failed (the last good point is kept).
    pub failed: bool,
}

/// A continuation's result.
#[derive(Debug, Clone, Default)]
pub struct Continuation {
    pub branches: Vec<Branch>,
    pub specials: Vec<Special>,
    /// Seconds of wall time.
    pub wall: f64,
    /// Units of the observables (set by [`run_study`]).
    pub units: Vec<String>,
    /// Set when the continuation stopped before its end (a progress report returned `false`):
    /// what [`resume`] needs to go on. The last branch is then the one being followed.
    pub unfinished: Option<Unfinished>,
}

/// Where an interrupted continuation stands: the step of the branch being followed (its last
/// branch, whose last point is the next step's anchor), the branches still to follow, and the
/// points done (for the progress fraction).
#[derive(Debug, Clone)]
pub struct Unfinished {
    pub step: f64,
    queue: Vec<Pending>,
    pub points_done: usize,
}

/// What the continuation reports after every point it adds.
pub struct Report {
    /// The fraction done (by points, against `max_branches * max_points`).
    pub fraction: f64,
    /// One line on the point just added.
    pub line: String,
    /// Everything so far, marked unfinished: written as a checkpoint it can be resumed.
    pub snapshot: Continuation,
}

/// A branch waiting to be followed: its first point, its periods per orbit, where it comes from,
/// and the first step's tangent when it is not the point's own (branch switching).
#[derive(Debug, Clone)]
struct Pending {
    start: Point,
    k: usize,
    origin: String,
    switch: Option<(Vec<f64>, f64)>,
}

/// A point of the corrector with what the next tangent needs.
struct Corrected {
    state: HybridState,
    s: f64,
    ev: MapEval,
    /// `B^T dG/ds`.
    gs: DVector<f64>,
    iterations: usize,
}

/// The continuation machinery over a family of flows `make(p)`.
struct Ctx<'a> {
    make: &'a dyn Fn(f64) -> Result<Target>,
    set: &'a Settings,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Ctx<'_> {
    fn p(&self, s: f64) -> f64 {
        self.set.from + s * (self.set.to - self.set.from)
    }
    fn range(&self) -> f64 {
        (self.set.to - self.set.from).abs()
    }

    fn eval(&self, s: f64, state: &HybridState, k: usize) -> Result<MapEval> {
        let target = (self.make)(self.p(s))?;
        let mut flow = target.flow();
        evaluate(&mut flow, state, k)
    }

    /// The point at the scaled parameter `end` (0 or 1) on the way from `cur` to `past`, which
    /// lies beyond it after a step `h`: the step shortened by secant steps on the arclength until
    /// the corrected point is at `end` to 1e-9 of the range (at most 4 tries).
    fn land(&self, k: usize, cur: &Point, end: f64, h: f64, past: &Point) -> Option<Point> {
        let (ty, ts) = (cur.tangent_y.clone(), cur.tangent_s);
        let (mut h0, mut s0) = (0.0, cur.s);
        let (mut h1, mut s1) = (h, past.s);
        for _ in 0..4 {
            if s1 == s0 {
                return None;
            }
            let trial = h0 + (end - s0) * (h1 - h0) / (s1 - s0);
            let c = self.correct(k, cur, &ty, ts, trial).ok()?;
            let tan = self.tangent(&c, &ty, ts)?;
            let p = self.point(k, c, tan).ok()?;
            if (p.s - end).abs() <= 1e-9 {
                return Some(p);
            }
            (h0, s0, h1, s1) = (h1, s1, trial, p.s);
        }
        None
    }

    /// Whether `p` lies in the parameter range (to its rounding).
    fn in_range(&self, p: f64) -> bool {
        let (lo, hi) = (
            self.set.from.min(self.set.to),
            self.set.from.max(self.set.to),
        );
        let slack = 1e-12 * self.range();
        (lo - slack..=hi + slack).contains(&p)
    }

    /// For a period-`k` orbit with `k` above the study's first period (a branch switched to at
    /// a period doubling): `max |P^(k/2)(y) - y|` when it is within 10 times the Newton
    /// tolerance, that is when the orbit is the period-`k/2` orbit it doubled from.
    fn period_halved(&self, k: usize, point: &Point) -> Result<Option<f64>> {
        if k <= self.set.k || !k.is_multiple_of(2) {
            return Ok(None);
        }
        let target = (self.make)(point.parameter)?;
        let mut flow = target.flow();
        let d = map_distance(&mut flow, &point.orbit.state, k / 2)?;
        Ok((d <= 10.0 * self.set.newton.tolerance).then_some(d))
    }

    fn onto(&self, s: f64, state: &mut HybridState) -> Result<()> {
        let target = (self.make)(self.p(s))?;
        let mut flow = target.flow();
        flow.onto_manifold(state.t, &mut state.y)
    }

    /// `B^T dP^k/ds` by central differences.
    fn gs(&self, s: f64, state: &HybridState, k: usize, ev: &MapEval) -> Result<DVector<f64>> {
        let h = 1e-4;
        let mut ends = Vec::new();
        for sg in [1.0, -1.0] {
            let target = (self.make)(self.p(s + sg * h))?;
            let mut flow = target.flow();
            let t_end = state.t + k as f64 * flow.period();
            let (end, _) = tangent_map(&mut flow, &state.for_new_run(), &[], t_end)?;
            ends.push(end.y);
        }
        let d: Vec<f64> = ends[0]
            .iter()
            .zip(&ends[1])
            .map(|(a, b)| (a - b) / (2.0 * h))
            .collect();
        Ok(ev.reduce(&d))
    }

    /// Corrects the prediction `anchor + h tangent` onto the branch.
    fn correct(&self, k: usize, anchor: &Point, ty: &[f64], ts: f64, h: f64) -> Result<Corrected> {
        let mut state = anchor.orbit.state.for_new_run();
        for (a, t) in state.y.iter_mut().zip(ty) {
            *a += h * t;
        }
        let mut s = anchor.s + h * ts;
        self.onto(s, &mut state)?;
        let y0 = &anchor.orbit.state.y;
        for it in 0..=self.set.newton.max_iterations {
            let ev = self.eval(s, &state, k)?;
            let res = ev.max_residual();
            if !res.is_finite() {
                break;
            }
            let gs = self.gs(s, &state, k, &ev)?;
            if res <= self.set.newton.tolerance {
                state.onset.clone_from(&ev.end.onset);
                return Ok(Corrected {
                    state,
                    s,
                    ev,
                    gs,
                    iterations: it,
                });
            }
            if it == self.set.newton.max_iterations {
                break;
            }
            let m = ev.reduced.nrows();
            let mut jac = DMatrix::zeros(m + 1, m + 1);
            jac.view_mut((0, 0), (m, m))
                .copy_from(&(&ev.reduced - DMatrix::identity(m, m)));
            jac.view_mut((0, m), (m, 1)).copy_from(&gs);
            let tz = ev.reduce(ty);
            for c in 0..m {
                jac[(m, c)] = tz[c];
            }
            jac[(m, m)] = ts;
            let dy: Vec<f64> = state.y.iter().zip(y0).map(|(a, b)| a - b).collect();
            let mut rhs = DVector::zeros(m + 1);
            rhs.rows_mut(0, m).copy_from(&-ev.reduce(&ev.residual));
            rhs[m] = -(dot(ty, &dy) + ts * (s - anchor.s) - h);
            let Some(x) = jac.lu().solve(&rhs) else {
                break;
            };
            let step = ev.lift(&x.rows(0, m).into_owned());
            for (a, d) in state.y.iter_mut().zip(&step) {
                *a += d;
            }
            s += x[m];
            state.onset.clone_from(&ev.end.onset);
            self.onto(s, &mut state)?;
        }
        Err(crate::Error::Orbit(format!(
            "the corrector did not converge at parameter {}",
            self.p(s)
        )))
    }

    /// The unit tangent at a corrected point, oriented along `(ty, ts)`.
    fn tangent(&self, c: &Corrected, ty: &[f64], ts: f64) -> Option<(Vec<f64>, f64)> {
        let m = c.ev.reduced.nrows();
        let mut jac = DMatrix::zeros(m + 1, m + 1);
        jac.view_mut((0, 0), (m, m))
            .copy_from(&(&c.ev.reduced - DMatrix::identity(m, m)));
        jac.view_mut((0, m), (m, 1)).copy_from(&c.gs);
        let tz = c.ev.reduce(ty);
        for col in 0..m {
            jac[(m, col)] = tz[col];
        }
        jac[(m, m)] = ts;
        let mut rhs = DVector::zeros(m + 1);
        rhs[m] = 1.0;
        let x = jac.lu().solve(&rhs)?;
        let norm = x.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return None;
        }
        let ty = c.ev.lift(&(x.rows(0, m) / norm).into_owned());
        Some((ty, x[m] / norm))
    }

    /// Observables at the orbit's strobe points and the smallest gap along it.
    fn sample(
        &self,
        s: f64,
        state: &HybridState,
        k: usize,
    ) -> Result<(Vec<Vec<f64>>, Option<f64>)> {
        let target = (self.make)(self.p(s))?;
        let mut flow = target.flow();
        let period = flow.period();
        let per = self.set.samples.max(4);
        let n = per * k;
        let times: Vec<f64> = (0..=n)
            .map(|i| state.t + i as f64 * k as f64 * period / n as f64)
            .collect();
        let n_obs = flow.n_obs();
        let mut all: Vec<Vec<f64>> = Vec::with_capacity(n + 1);
        let mut st = state.for_new_run();
        flow.prepare(&st)?;
        let method = flow.method();
        let (_, res) = ode::advance(
            &mut flow,
            method,
            &mut st,
            *times.last().expect("at least one"),
            &times,
            |f, t, y| {
                let mut out = vec![0.0; n_obs];
                f.observe(t, y, &mut out);
                all.push(out);
                Step::Continue
            },
            None,
        );
        res?;
        let strobe = (0..k).map(|j| all[j * per].clone()).collect();
        let gap = self.set.grazing.map(|(i, level)| {
            let x: Vec<f64> = all[..n].iter().map(|o| o[i]).collect();
            let (j, _) = x
                .iter()
                .enumerate()
                .fold((0, f64::NEG_INFINITY), |(bj, bv), (j, &v)| {
                    if v > bv { (j, v) } else { (bj, bv) }
                });
            // Parabola through the largest sample and its neighbours (periodic).
            let (a, b, c) = (x[(j + n - 1) % n], x[j], x[(j + 1) % n]);
            let den = a - 2.0 * b + c;
            let top = if den < 0.0 {
                b - (c - a).powi(2) / (8.0 * den)
            } else {
                b
            };
            level - top
        });
        Ok((strobe, gap))
    }

    /// A branch's first point: shooting at fixed scaled parameter `s` from `start`, its tangent
    /// oriented along `(ty, ts)`.
    fn start_point(
        &self,
        k: usize,
        s: f64,
        start: &HybridState,
        ty: &[f64],
        ts: f64,
    ) -> Result<Point> {
        let target = (self.make)(self.p(s))?;
        let mut flow = target.flow();
        let orbit = shoot(&mut flow, start, k, self.set.newton)?;
        let ev = self.eval(s, &orbit.state, k)?;
        let gs = self.gs(s, &orbit.state, k, &ev)?;
        let c = Corrected {
            state: orbit.state,
            s,
            ev,
            gs,
            iterations: orbit.iterations,
        };
        let tangent = self.tangent(&c, ty, ts).ok_or_else(|| {
            crate::Error::Orbit(format!(
                "no tangent at parameter {}: the orbit is singular there",
                self.p(s)
            ))
        })?;
        self.point(k, c, tangent)
    }

    fn point(&self, k: usize, c: Corrected, tangent: (Vec<f64>, f64)) -> Result<Point> {
        let (strobe, gap) = self.sample(c.s, &c.state, k)?;
        let target = (self.make)(self.p(c.s))?;
        let flow = target.flow();
        let orbit = orbit_of(&flow, c.state, c.ev, k, c.iterations);
        Ok(Point {
            parameter: self.p(c.s),
            orbit,
            iterations: c.iterations,
            strobe,
            gap,
            tangent_y: tangent.0,
            tangent_s: tangent.1,
            s: c.s,
        })
    }
}

/// The test function of `kind` at a point (None: not defined there, the contacting side of a
/// grazing with impacts).
fn test(kind: Kind, p: &Point) -> Option<f64> {
    let mu = &p.orbit.multipliers;
    match kind {
        Kind::Fold => Some(p.tangent_s),
        Kind::PeriodDoubling => Some(
            mu.iter()
                .fold(Complex::new(1.0, 0.0), |a, m| a * (m + 1.0))
                .re,
        ),
        Kind::NeimarkSacker => {
            let mut prod = Complex::new(1.0, 0.0);
            for i in 0..mu.len() {
                for j in i + 1..mu.len() {
                    prod *= mu[i] * mu[j] - 1.0;
                }
            }
            Some(prod.re)
        }
        Kind::Grazing => {
            let g = p.gap?;
            if p.orbit.events > 0 { None } else { Some(g) }
        }
    }
}

/// Whether `kind` changes between `a` and `b`.
fn changes(kind: Kind, a: &Point, b: &Point) -> bool {
    match (test(kind, a), test(kind, b)) {
        (Some(x), Some(y)) => (x > 0.0) != (y > 0.0),
        (Some(x), None) | (None, Some(x)) => kind == Kind::Grazing && x > 0.0 && a.gap.is_some(),
        (None, None) => false,
    }
}

/// A Neimark-Sacker test zero is reported only when a complex pair sits on the unit circle.
fn is_neimark_sacker(p: &Point) -> bool {
    p.orbit
        .multipliers
        .iter()
        .any(|m| m.im.abs() > 1e-6 && (m.norm() - 1.0).abs() < 0.05)
}

/// Follows the periodic orbits of the flows `make(p)` from the strobe point `start` (at
/// parameter `from`): the first branch, then the period-doubled branches when asked. `progress`
/// gets a [`Report`] after every point; when it returns `false` the continuation stops there and
/// returns what it has, marked [`Continuation::unfinished`]. A failure of the first shooting
/// solve is an error; a later failure ends its branch, with the reason and its last good point
/// kept.
pub fn continuation(
    make: &dyn Fn(f64) -> Result<Target>,
    set: &Settings,
    start: &HybridState,
    progress: &mut dyn FnMut(&mut Report) -> bool,
) -> Result<Continuation> {
    let ctx = Ctx { make, set };
    // The first point: shooting at `from`, its tangent oriented towards `to`.
    let zero = vec![0.0; start.y.len()];
    let first = ctx.start_point(set.k, 0.0, start, &zero, 1.0)?;
    let queue = vec![Pending {
        start: first,
        k: set.k,
        origin: "start".into(),
        switch: None,
    }];
    follow(&ctx, Continuation::default(), None, queue, 0, progress)
}

/// Goes on with a continuation that stopped before its end (read back with [`read_unfinished`]):
/// the branch being followed from its last point with the step it had, then the branches still
/// waiting. With the same settings the points are those an uninterrupted run computes.
pub fn resume(
    make: &dyn Fn(f64) -> Result<Target>,
    set: &Settings,
    mut prior: Continuation,
    progress: &mut dyn FnMut(&mut Report) -> bool,
) -> Result<Continuation> {
    let ctx = Ctx { make, set };
    let Some(u) = prior.unfinished.take() else {
        return Ok(prior);
    };
    // The branch being followed, and its last point: the next step's anchor.
    let open = prior.branches.pop().and_then(|b| {
        let cur = b.points.last()?.clone();
        Some((b, cur, u.step))
    });
    follow(&ctx, prior, open, u.queue, u.points_done, progress)
}

/// The branches: `open` (a branch followed up to its last point, that point and its step) first,
/// then the queue.
fn follow(
    ctx: &Ctx,
    mut out: Continuation,
    mut open: Option<(Branch, Point, f64)>,
    mut queue: Vec<Pending>,
    mut done_points: usize,
    progress: &mut dyn FnMut(&mut Report) -> bool,
) -> Result<Continuation> {
    let t0 = std::time::Instant::now();
    let wall0 = out.wall;
    let set = ctx.set;
    let total = (set.max_branches * set.max_points) as f64;
    let (hmin, hmax) = (set.min_step / ctx.range(), set.max_step / ctx.range());
    loop {
        let (mut branch, mut h, mut cur) = if let Some(open) = open.take() {
            (open.0, open.2, open.1)
        } else {
            let Some(Pending {
                start: p0,
                k,
                origin,
                switch,
            }) = (!queue.is_empty()).then(|| queue.remove(0))
            else {
                break;
            };
            if out.branches.len() >= set.max_branches {
                break;
            }
            let mut branch = Branch {
                k,
                origin,
                points: Vec::new(),
                end: String::new(),
                failed: false,
            };
            let h = set.step / ctx.range();
            // The first step of a switched branch: from the special point along its tangent.
            let mut current = if let Some((ty, ts)) = switch {
                let mut trial = h;
                loop {
                    match ctx.correct(k, &p0, &ty, ts, trial) {
                        Ok(c) => {
                            let tan = ctx.tangent(&c, &ty, ts);
                            match tan {
                                Some(tan) => break Some(ctx.point(k, c, tan)?),
                                None => break None,
                            }
                        }
                        Err(_) if trial / 2.0 >= hmin => trial /= 2.0,
                        Err(e) => {
                            branch.end = format!("could not leave the branch point: {e}");
                            branch.failed = true;
                            break None;
                        }
                    }
                }
            } else {
                Some(p0)
            };
            let Some(cur) = current.take() else {
                if branch.end.is_empty() {
                    branch.end = "no tangent at the branch point".into();
                    branch.failed = true;
                }
                out.branches.push(branch);
                continue;
            };
            branch.points.push(cur.clone());
            (branch, h, cur)
        };
        let bi = out.branches.len();
        let k = branch.k;
        let zero = vec![0.0; cur.orbit.state.y.len()];
        loop {
            if branch.points.len() >= set.max_points {
                branch.end = format!("{} points (continuation.max_points)", set.max_points);
                break;
            }
            if !(-1e-9..=1.0 + 1e-9).contains(&cur.s) {
                branch.end = "left the parameter range".into();
                break;
            }
            // A point landed on the range's end, heading out of it: the branch ends there.
            if (cur.s >= 1.0 - 1e-9 && cur.tangent_s > 0.0)
                || (cur.s <= 1e-9 && cur.tangent_s < 0.0)
            {
                branch.end = format!("reached the end of the parameter range ({})", cur.parameter);
                break;
            }
            let (ty, ts) = (cur.tangent_y.clone(), cur.tangent_s);
            let next = match ctx.correct(k, &cur, &ty, ts, h) {
                Ok(c) => match ctx.tangent(&c, &ty, ts) {
                    Some(tan) => ctx.point(k, c, tan),
                    None => Err(crate::Error::Orbit("singular tangent".into())),
                },
                Err(e) => Err(e),
            };
            let next = match next {
                Ok(p) => p,
                Err(e) => {
                    h /= 2.0;
                    if h < hmin {
                        branch.end =
                            format!("the step fell below continuation.min_step after: {e}");
                        branch.failed = true;
                        break;
                    }
                    continue;
                }
            };
            // Special points between cur and next.
            let mut graze = false;
            for kind in Kind::ALL {
                if kind == Kind::Grazing && set.grazing.is_none() {
                    continue;
                }
                if !changes(kind, &cur, &next) {
                    continue;
                }
                let Some(sp) = locate(ctx, kind, k, &cur, &next, h) else {
                    continue;
                };
                if kind == Kind::NeimarkSacker && !is_neimark_sacker(&sp.1) {
                    continue;
                }
                let (bracket, at, far) = sp;
                let special = Special {
                    kind,
                    branch: bi,
                    after: branch.points.len() - 1,
                    parameter: at.parameter,
                    bracket,
                    state: at.orbit.state.y.clone(),
                    multipliers: at.orbit.multipliers.clone(),
                    strobe: at.strobe.clone(),
                };
                let parameter = grazing_parameter(kind, &cur, &at).unwrap_or(at.parameter);
                // The step that passes `to` finds what lies beyond it too: not asked for.
                if !ctx.in_range(parameter) {
                    continue;
                }
                let special = Special {
                    parameter,
                    ..special
                };
                if kind == Kind::PeriodDoubling && set.switch_period_doubling {
                    let v = at.orbit.eigenvector(-1.0);
                    queue.push(Pending {
                        start: at.clone(),
                        k: 2 * k,
                        origin: format!(
                            "period doubling of branch {bi} at parameter {}",
                            special.parameter
                        ),
                        switch: Some((v, 0.0)),
                    });
                }
                if kind == Kind::Grazing {
                    graze = true;
                    // The other side: shooting a tenth of the first step past the grazing, from the
                    // converged orbit nearest it there, heading on away from the grazing; or the
                    // step's own point when that fails.
                    let dir = if cur.tangent_s >= 0.0 { 1.0 } else { -1.0 };
                    let s_past = ctx_s(ctx, special.parameter) + dir * 0.1 * set.step / ctx.range();
                    let other = ctx
                        .start_point(k, s_past, &far.orbit.state, &zero, dir)
                        .ok()
                        .filter(|p| test(kind, p).is_none_or(|g| g <= 0.0))
                        .or_else(|| test(kind, &next).is_none().then(|| next.clone()));
                    if let Some(other) = other {
                        queue.push(Pending {
                            start: other,
                            k,
                            origin: format!(
                                "the other side of the grazing of branch {bi} at parameter {}",
                                special.parameter
                            ),
                            switch: None,
                        });
                    }
                }
                out.specials.push(special);
            }
            if graze {
                branch.end = "grazing: the contact changes (the other side is a new branch)".into();
                break;
            }
            // A point past `from` or `to` is not kept: the step is shortened to end at the
            // range's end (secant steps on the arclength), and the branch ends there.
            let next = if (-1e-9..=1.0 + 1e-9).contains(&next.s) {
                next
            } else {
                let end = if next.s > 1.0 { 1.0 } else { 0.0 };
                match ctx.land(k, &cur, end, h, &next) {
                    Some(p) => p,
                    None => {
                        branch.end = format!(
                            "the parameter range ends before the next point ({}), and no \
                             shorter step landed on its end",
                            next.parameter
                        );
                        break;
                    }
                }
            };
            // A branch switched to at a period doubling whose orbit closes after half its
            // periods has fallen back onto the branch it left: no period-k orbit is there.
            if let Some(d) = ctx.period_halved(k, &next)? {
                branch.end = format!(
                    "the period-{k} orbit fell back onto a period-{} orbit (max |P^{}(y) - y| = \
                     {d:.3e}, within 10 times the tolerance): no period-{k} branch there",
                    k / 2,
                    k / 2
                );
                branch.failed = true;
                break;
            }
            if next.iterations <= 3 {
                h = (h * 1.5).min(hmax);
            }
            branch.points.push(next.clone());
            cur = next;
            done_points += 1;
            let mut snapshot = Continuation {
                branches: out.branches.clone(),
                specials: out.specials.clone(),
                wall: wall0 + t0.elapsed().as_secs_f64(),
                units: Vec::new(),
                unfinished: Some(Unfinished {
                    step: h,
                    queue: queue.clone(),
                    points_done: done_points,
                }),
            };
            snapshot.branches.push(branch.clone());
            let mut report = Report {
                fraction: (done_points as f64 / total).min(1.0),
                line: point_line(
                    bi,
                    branch.points.len() - 1,
                    &cur,
                    t0.elapsed().as_secs_f64(),
                ),
                snapshot,
            };
            if !progress(&mut report) {
                return Ok(report.snapshot);
            }
        }
        out.branches.push(branch);
    }
    out.wall = wall0 + t0.elapsed().as_secs_f64();
    Ok(out)
}

/// A line on point `i` of branch `bi`.
fn point_line(bi: usize, i: usize, p: &Point, elapsed: f64) -> String {
    format!(
        "branch {bi} point {i}: parameter {:.6e}, {} corrector iterations, {} ({} multipliers outside the unit circle), {elapsed:.0} s",
        p.parameter,
        p.iterations,
        if p.orbit.stable() {
            "stable"
        } else {
            "unstable"
        },
        p.orbit.unstable_count()
    )
}

fn ctx_s(ctx: &Ctx, p: f64) -> f64 {
    (p - ctx.set.from) / (ctx.set.to - ctx.set.from)
}

/// For a grazing: the parameter where the gap of the contact-free side extrapolates to zero
/// (secant through the contact-free point nearest it and the branch point before).
fn grazing_parameter(kind: Kind, before: &Point, at: &Point) -> Option<f64> {
    if kind != Kind::Grazing {
        return None;
    }
    let (g0, g1) = (before.gap?, at.gap?);
    if at.orbit.events > 0 || g0 == g1 {
        return None;
    }
    Some(at.parameter - g1 * (at.parameter - before.parameter) / (g1 - g0))
}

/// Locates the zero of `kind`'s test function between `a` (arclength 0) and `b` (arclength `h`
/// from `a` along `a`'s tangent): the arclength bracket reached (parameter units), the corrected
/// point nearest the zero (for grazing, on the contact-free side) and the last converged point on
/// the other side.
fn locate(
    ctx: &Ctx,
    kind: Kind,
    k: usize,
    a: &Point,
    b: &Point,
    h: f64,
) -> Option<(f64, Point, Point)> {
    let (ty, ts) = (a.tangent_y.clone(), a.tangent_s);
    let at = |x: f64| -> Option<Point> {
        let c = ctx.correct(k, a, &ty, ts, x).ok()?;
        let tan = ctx.tangent(&c, &ty, ts)?;
        ctx.point(k, c, tan).ok()
    };
    let fa0 = test(kind, a)?;
    let (mut xa, mut fa, mut pa) = (0.0, fa0, a.clone());
    let (mut xb, mut fb, mut pb) = (h, test(kind, b), b.clone());
    // Contact-free points for the grazing secant: (arclength, gap).
    let mut free: Vec<(f64, f64)> = vec![(0.0, fa0)];
    // Which end was replaced last (Illinois: 1 the first, -1 the second).
    let mut last = 0i8;
    let mut bisect_next = false;
    for _ in 0..60 {
        if (xb - xa).abs() * ctx.range() < ctx.set.locate {
            break;
        }
        let x = match fb {
            Some(fbv) if !bisect_next => xa - fa * (xb - xa) / (fbv - fa),
            None if !bisect_next && free.len() >= 2 => {
                let (x1, g1) = free[free.len() - 1];
                let (x0, g0) = free[free.len() - 2];
                if g1 != g0 {
                    x1 - g1 * (x1 - x0) / (g1 - g0)
                } else {
                    0.5 * (xa + xb)
                }
            }
            _ => 0.5 * (xa + xb),
        };
        let w = xb - xa;
        let x = if x.is_finite() {
            x.clamp(xa.min(xb) + 0.01 * w.abs(), xa.max(xb) - 0.01 * w.abs())
        } else {
            0.5 * (xa + xb)
        };
        bisect_next = false;
        let trial = at(x);
        let f = trial.as_ref().and_then(|p| test(kind, p));
        match (trial, f) {
            (Some(p), Some(fv)) if (fv > 0.0) == (fa > 0.0) => {
                if kind == Kind::Grazing {
                    free.push((x, fv));
                }
                if last == 1
                    && let Some(v) = fb.as_mut()
                {
                    *v /= 2.0;
                }
                last = 1;
                xa = x;
                fa = fv;
                pa = p;
            }
            (Some(p), f) => {
                if f.is_none() {
                    bisect_next = true;
                }
                if last == -1 {
                    fa /= 2.0;
                }
                last = -1;
                xb = x;
                fb = f;
                pb = p;
            }
            (None, _) => {
                // A failed corrector: the far side for grazing (the orbit touches the stop with
                // vanishing velocity there); otherwise the point cannot be located.
                if kind != Kind::Grazing {
                    return None;
                }
                xb = x;
                fb = None;
                bisect_next = true;
            }
        }
    }
    let bracket = (xb - xa).abs() * ctx.range();
    // The nearer end to the zero (grazing: the contact-free end), and the far end.
    Some(match (kind, fb) {
        (Kind::Grazing, _) => (bracket, pa, pb),
        (_, Some(fbv)) if fbv.abs() < fa.abs() => (bracket, pb, pa),
        _ => (bracket, pa, pb),
    })
}

/// The `[continuation]` table of an analysis study (format in book/src/reference/analysis.md, "Periodic orbits and
/// continuation").
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContinuationSpec {
    /// A scene path or a system parameter, as `sweep.parameter`.
    pub parameter: String,
    /// Further scene paths set to the same value.
    #[serde(default)]
    pub also: Vec<String>,
    /// Unit of the parameter, for labels.
    #[serde(default)]
    pub unit: String,
    /// The parameter's start value (the orbit the run settles on there) and end value.
    pub from: f64,
    pub to: f64,
    /// First step (parameter units; see [`crate::continuation`]); smallest and largest step
    /// (default a ten-thousandth of it and ten times it).
    pub step: f64,
    #[serde(default)]
    pub min_step: Option<f64>,
    #[serde(default)]
    pub max_step: Option<f64>,
    /// Points per branch at most.
    #[serde(default = "default_points")]
    pub max_points: usize,
    /// Drive periods per orbit of the first branch (1: period-1 orbits).
    #[serde(default = "one")]
    pub orbit_periods: usize,
    /// Newton tolerance: the largest component of `P^k(y) - y` (SI units of the state).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    #[serde(default = "default_iterations")]
    pub max_iterations: usize,
    /// Bracket special points are located to (parameter units; default 1e-6 of the range).
    #[serde(default)]
    pub locate: Option<f64>,
    /// Follow the period-2k branch from every period doubling.
    #[serde(default = "yes")]
    pub switch_period_doubling: bool,
    /// Branches at most, the first one included.
    #[serde(default = "default_branches")]
    pub max_branches: usize,
    /// Grazing: the contact observable and the level where contact begins.
    #[serde(default)]
    pub grazing: Option<GrazingSpec>,
    /// Samples per drive period for the gap and the observables along the orbit.
    #[serde(default = "default_samples")]
    pub samples: usize,
    /// Periods run at `from` before shooting (default `analysis.transient`, or none from a
    /// `start` state).
    #[serde(default)]
    pub transient: Option<usize>,
    /// The state to shoot from instead of the study's start after its transient.
    #[serde(default)]
    pub start: Option<StartSpec>,
}

/// `[continuation] start`: a state from a file of the program. Without `branch`, the file's
/// final state (a run file of `jointplay run SCENE`, or an analysis file of a single run); with
/// it, a point of a branch of its `/continuation` (`point` counts from 0, negative from the end;
/// default the last), whose parameter must be `from`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartSpec {
    /// The HDF5 file, relative to the study file.
    pub file: String,
    #[serde(default)]
    pub branch: Option<usize>,
    #[serde(default)]
    pub point: Option<i64>,
}

/// Largest constraint residuals a `start` state may have (position m, velocity m/s, Euler norm):
/// a state written by a run keeps them near its integration tolerance (Baumgarte stabilisation),
/// so more than this is a state of another scene or an edited one, which the assembly would move
/// by an amount nobody asked for.
const START_OFF_MANIFOLD: [f64; 3] = [1e-6, 1e-6, 1e-6];

/// The contact observable of grazing detection: contact begins when its largest value along the
/// orbit reaches `level` (the gap is `level - max`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrazingSpec {
    pub observable: String,
    #[serde(default)]
    pub level: f64,
}

fn one() -> usize {
    1
}
fn yes() -> bool {
    true
}
fn default_points() -> usize {
    200
}
fn default_tolerance() -> f64 {
    1e-8
}
fn default_iterations() -> usize {
    10
}
fn default_branches() -> usize {
    4
}
fn default_samples() -> usize {
    100
}

impl ContinuationSpec {
    /// Checks the numbers; errors name the field of the `[continuation]` table.
    pub fn check(&self) -> std::result::Result<(), (String, String)> {
        let bad = |f: &str, m: &str| Err((format!("continuation.{f}"), m.to_string()));
        for (f, v) in [("from", self.from), ("to", self.to)] {
            if !v.is_finite() {
                return bad(f, "must be finite");
            }
        }
        if self.from == self.to {
            return bad("to", "must differ from continuation.from");
        }
        let range = (self.to - self.from).abs();
        for (f, v) in [
            ("step", Some(self.step)),
            ("min_step", self.min_step),
            ("max_step", self.max_step),
            ("locate", self.locate),
            ("tolerance", Some(self.tolerance)),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return bad(f, "must be positive and finite");
            }
        }
        if self.step > range {
            return bad(
                "step",
                "is larger than the range from continuation.from to .to",
            );
        }
        if self.min_step() > self.step || self.max_step() < self.step {
            return bad(
                "min_step",
                "min_step <= step <= max_step must hold (defaults: step / 1e4 and 10 step)",
            );
        }
        if self.max_points < 2 {
            return bad("max_points", "must be at least 2");
        }
        if self.orbit_periods == 0 {
            return bad("orbit_periods", "must be at least 1");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if self.max_branches == 0 {
            return bad("max_branches", "must be at least 1");
        }
        if self.samples < 8 {
            return bad("samples", "must be at least 8 per period");
        }
        if let Some(g) = &self.grazing
            && !g.level.is_finite()
        {
            return bad("grazing.level", "must be finite");
        }
        Ok(())
    }
    pub fn min_step(&self) -> f64 {
        self.min_step.unwrap_or(self.step * 1e-4)
    }
    pub fn max_step(&self) -> f64 {
        self.max_step.unwrap_or(self.step * 10.0)
    }
    /// The settings of [`continuation`], with the grazing observable's index.
    pub fn settings(&self, grazing: Option<usize>) -> Settings {
        Settings {
            from: self.from,
            to: self.to,
            step: self.step,
            min_step: self.min_step(),
            max_step: self.max_step(),
            max_points: self.max_points,
            k: self.orbit_periods,
            newton: Newton {
                tolerance: self.tolerance,
                max_iterations: self.max_iterations,
            },
            locate: self.locate.unwrap_or(1e-6 * (self.to - self.from).abs()),
            switch_period_doubling: self.switch_period_doubling,
            max_branches: self.max_branches,
            grazing: grazing.zip(self.grazing.as_ref().map(|g| g.level)),
            samples: self.samples,
        }
    }
}

/// Where a continuation begins.
pub enum Begin {
    /// From the study's start after `transient` periods at `from`, or from the `start` state
    /// read before with [`start_of`] (then `transient` periods from it, default none).
    Fresh(Option<HybridState>),
    /// Going on with an unfinished continuation read back with [`read_unfinished`].
    Resume(Continuation),
}

/// Runs the study's `[continuation]` from `begin`, then its branches. `progress` gets a
/// [`Report`] after every point and stops the continuation by returning `false`.
pub fn run_study(
    st: &crate::nonlinear::Loaded,
    begin: Begin,
    progress: &mut dyn FnMut(&mut Report) -> bool,
) -> Result<Continuation> {
    let spec = st.spec.continuation.as_ref().ok_or_else(|| {
        crate::study::invalid(&st.path, "continuation", "no [continuation] table")
    })?;
    let grazing = spec
        .grazing
        .as_ref()
        .and_then(|g| st.spec.observable(&g.observable));
    let make = |p: f64| st.continuation_target(p);
    let set = spec.settings(grazing);
    let units = st.continuation_target(spec.from)?.flow().observable_units();
    let mut forward = |r: &mut Report| {
        r.snapshot.units.clone_from(&units);
        progress(r)
    };
    let mut c = match begin {
        Begin::Resume(prior) => resume(&make, &set, prior, &mut forward)?,
        Begin::Fresh(start) => {
            let state = start_state(st, spec, start)?;
            continuation(&make, &set, &state, &mut forward)?
        }
    };
    c.units = units;
    Ok(c)
}

/// Runs the study's `[continuation]` ([`run_study`]) into its analysis file `file`: its state
/// is written after every point, marked unfinished, into the file of [`snapshot_path`]
/// ([`write_snapshot`]), so that a stop or a kill keeps what was computed, and into `file` once
/// at the end ([`write()`]), stopped or finished. `on_point` sees every [`Report`]; the
/// continuation stops early when it returns `false` or after `limit` points. The outer error is
/// one of writing the file; the inner one is a continuation that could not start, which is
/// written into the file too.
pub fn run_into(
    st: &crate::nonlinear::Loaded,
    file: &std::path::Path,
    begin: Begin,
    limit: Option<usize>,
    on_point: &mut dyn FnMut(&Report) -> bool,
) -> Result<std::result::Result<Continuation, crate::Error>> {
    let _lock = crate::storage::lock::Lock::acquire(file)?;
    if matches!(begin, Begin::Fresh(_)) {
        // The state of an earlier continuation into this file is not this one's.
        crate::storage::durable::remove(&snapshot_path(file))?;
    }
    let mut points = 0usize;
    let mut write_error = None;
    let res = run_study(st, begin, &mut |r| {
        let go = on_point(r);
        if let Err(e) = write_snapshot(file, st, &r.snapshot) {
            write_error = Some(e);
            return false;
        }
        points += 1;
        go && limit.is_none_or(|n| points < n)
    });
    if let Some(e) = write_error {
        return Err(e);
    }
    write(file, st, res.as_ref())?;
    Ok(res)
}

/// The strobe point the first branch is shot from (see [`run_study`]).
fn start_state(
    st: &crate::nonlinear::Loaded,
    spec: &ContinuationSpec,
    start: Option<HybridState>,
) -> Result<HybridState> {
    let target = st.continuation_target(spec.from)?;
    let mut flow = target.flow();
    let t_strobe = flow.start_time() + st.spec.analysis.phase;
    let (mut state, transient) = match start {
        None => (
            flow.initial_state(None)?,
            spec.transient.unwrap_or(st.spec.analysis.transient),
        ),
        Some(s) => {
            let mut s = s.for_new_run();
            s.t = t_strobe;
            (s, spec.transient.unwrap_or(0))
        }
    };
    flow.prepare(&state)?;
    // The drive is periodic: the settled state is taken back to the first strobe time, so that
    // when the parameter changes the period (a drive frequency) the strobe phase moves by
    // `t_strobe d(omega)`, not by `transient` periods' worth of it.
    // From a fresh start (at the flow's start time) the run goes on to the strobe phase, so
    // that the state labelled with the strobe time is the state at a strobe time.
    let t = t_strobe + transient as f64 * flow.period();
    let method = flow.method();
    let (_, res) = ode::advance(
        &mut flow,
        method,
        &mut state,
        t,
        &[],
        |_, _, _| Step::Continue,
        None,
    );
    res?;
    state.t = t_strobe;
    Ok(state)
}

/// The study's `[continuation] start` state (None without one), read and checked: the file and
/// the point exist, the state has the flow's size, sits at a strobe time and on the constraint
/// manifold. Errors name the field.
pub fn start_of(st: &crate::nonlinear::Loaded) -> Result<Option<HybridState>> {
    let Some(spec) = st.spec.continuation.as_ref() else {
        return Ok(None);
    };
    let Some(s) = &spec.start else {
        return Ok(None);
    };
    let target = st.continuation_target(spec.from)?;
    let mut flow = target.flow();
    let t_strobe = flow.start_time() + st.spec.analysis.phase;
    read_start(st, spec, s, &mut flow, t_strobe).map(Some)
}

fn read_start(
    st: &crate::nonlinear::Loaded,
    spec: &ContinuationSpec,
    s: &StartSpec,
    flow: &mut crate::flow::AnyFlow,
    t_strobe: f64,
) -> Result<HybridState> {
    let bad =
        |f: &str, m: String| crate::study::invalid(&st.path, format!("continuation.start.{f}"), m);
    let path = st
        .path
        .parent()
        .unwrap_or(std::path::Path::new(""))
        .join(&s.file);
    let file = hdf5::File::open(&path)
        .map_err(|e| bad("file", format!("cannot open {}: {e}", path.display())))?;
    let state = match s.branch {
        None => {
            if s.point.is_some() {
                return Err(bad("point", "needs continuation.start.branch".into()));
            }
            let complete: u8 = crate::h5::read_attr(&file, "complete").unwrap_or(0);
            if complete != 1 {
                return Err(bad(
                    "file",
                    format!(
                        "{} is not a finished run of the program (attribute complete = 1): its last state is where it stopped",
                        path.display()
                    ),
                ));
            }
            crate::hybrid::read_state(&file).map_err(|e| {
                bad(
                    "file",
                    format!(
                        "{} has no final state ({e}); a sweep's file holds one per value: start from a run file or a branch point",
                        path.display()
                    ),
                )
            })?
        }
        Some(b) => {
            let g = file
                .group(&format!("continuation/branch_{b}"))
                .map_err(|_| {
                    bad(
                        "branch",
                        format!("{} has no /continuation/branch_{b}", path.display()),
                    )
                })?;
            let read = |name: &str| crate::h5::read_rows(&g, name);
            let e = |err: hdf5::Error| bad("branch", format!("{}: {err}", path.display()));
            let params = read("parameter").map_err(e)?;
            let n = params.len() as i64;
            let i = s.point.unwrap_or(-1);
            let j = if i < 0 { n + i } else { i };
            if !(0..n).contains(&j) {
                return Err(bad(
                    "point",
                    format!("branch {b} has {n} points: {i} is not one of them"),
                ));
            }
            let j = j as usize;
            let p = params[j][0];
            if (p - spec.from).abs() > 1e-9 * (spec.to - spec.from).abs() {
                return Err(bad(
                    "point",
                    format!(
                        "the point is at parameter {p:e}, continuation.from is {:e}: set from = {p:e}",
                        spec.from
                    ),
                ));
            }
            let t: f64 = crate::h5::read_attr(&g, "strobe_time").map_err(e)?;
            let y = read("state").map_err(e)?.swap_remove(j);
            let onset = read("onset")
                .ok()
                .and_then(|mut o| (o.len() > j).then(|| o.swap_remove(j)))
                .unwrap_or_default();
            let mut point = HybridState::new(t, y);
            point.onset = onset;
            point
        }
    };
    use crate::tangent::Tangent;
    let dim = jointplay_solver::ode::OdeSystem::dim(flow);
    if state.y.len() != dim {
        return Err(bad(
            "file",
            format!(
                "the state in {} has {} components, the flow at continuation.from {dim}: a state of another scene",
                path.display(),
                state.y.len()
            ),
        ));
    }
    let period = flow.period();
    let n = (state.t - t_strobe) / period;
    if !state.t.is_finite() || (n - n.round()).abs() > 1e-6 {
        return Err(bad(
            "file",
            format!(
                "the state is at t = {} s, not at a strobe time {t_strobe} + n {period} s (analysis.phase and the drive's period): shooting needs a state at the strobe phase",
                state.t
            ),
        ));
    }
    if state.y.iter().any(|v| !v.is_finite()) {
        return Err(bad("file", "the state has a non-finite component".into()));
    }
    let off = flow.off_manifold(state.t, &state.y);
    if off.iter().zip(START_OFF_MANIFOLD).any(|(r, lim)| *r > lim) {
        return Err(bad(
            "file",
            format!(
                "the state is off the constraint manifold (position residual {:.2e} m, velocity residual {:.2e} m/s, Euler-parameter norm off by {:.2e}; at most 1e-6 each): a state of another scene or parameter",
                off[0], off[1], off[2]
            ),
        ));
    }
    Ok(state)
}

/// The file a continuation's state goes to after every point, beside the analysis file `path`
/// (`out/s.h5` -> `out/s.continuation.h5`): a small HDF5 file with the root attribute `study` and
/// `/continuation`, replaced atomically after every point and removed once the state is in the
/// analysis file.
pub fn snapshot_path(path: &std::path::Path) -> std::path::PathBuf {
    path.with_extension("continuation.h5")
}

/// Writes `/continuation` into the analysis file `path` (replacing one written before); layout in
/// book/src/reference/hdf5.md. `failure` is the error of a continuation that could not start.
///
/// The file is never rewritten in place: a copy with the new `/continuation` is written
/// ([`crate::storage::durable::Unnamed`]) and moved over it ([`crate::storage::durable::replace`]); the state file of
/// [`snapshot_path`] is then removed.
pub fn write(
    path: &std::path::Path,
    st: &crate::nonlinear::Loaded,
    c: std::result::Result<&Continuation, &crate::Error>,
) -> Result<()> {
    use crate::storage::durable;
    let name = durable::with_suffix(path, ".partial");
    let e = crate::h5::h5err(&name);
    let file = crate::h5::open_in_memory(path).map_err(&e)?;
    if file.group("continuation").is_ok() {
        file.unlink("continuation").map_err(&e)?;
    }
    write_group(&file, &name, st, c)?;
    let bytes = crate::h5::image(&file).map_err(&e)?;
    file.close().map_err(&e)?;
    durable::write_new(path, &bytes)?;
    durable::remove(&snapshot_path(path))
}

/// Writes the state of a continuation that goes on into the file of [`snapshot_path`] of the
/// analysis file `path`: a new file, read back as [`read_unfinished`] reads it, then moved into
/// place, so that a kill at any moment leaves the previous point's state or this one's, whole.
pub fn write_snapshot(
    path: &std::path::Path,
    st: &crate::nonlinear::Loaded,
    c: &Continuation,
) -> Result<()> {
    use crate::storage::durable;
    let snap = snapshot_path(path);
    let name = durable::with_suffix(&snap, ".partial");
    let e = crate::h5::h5err(&name);
    let file = crate::h5::create_in_memory(&name).map_err(&e)?;
    crate::h5::str_attr(&file, "study", &st.text).map_err(&e)?;
    crate::h5::str_attr(&file, "program_version", env!("CARGO_PKG_VERSION")).map_err(&e)?;
    write_group(&file, &name, st, Ok(c))?;
    if c.unfinished.is_some() && read_group(&file, &name, st)?.is_none() {
        return Err(crate::Error::Write {
            file: name.clone(),
            message: "the continuation's state does not read back as written".into(),
        });
    }
    let bytes = crate::h5::image(&file).map_err(&e)?;
    file.close().map_err(&e)?;
    durable::write_new(&snap, &bytes)
}

/// Writes `/continuation` into `file` (named `path` in errors).
fn write_group(
    file: &hdf5::File,
    path: &std::path::Path,
    st: &crate::nonlinear::Loaded,
    c: std::result::Result<&Continuation, &crate::Error>,
) -> Result<()> {
    use crate::h5::{f64_attr, h5err, str_attr, u8_attr_set, u64_attr, write1};
    let e = h5err(path);
    let spec = st.spec.continuation.as_ref().expect("asked for");
    let obs = observable_names(st);
    (|| -> hdf5::Result<()> {
        let g = file.create_group("continuation")?;
        str_attr(&g, "parameter", &spec.parameter)?;
        str_attr(&g, "parameter_unit", &spec.unit)?;
        f64_attr(&g, "from", spec.from)?;
        f64_attr(&g, "to", spec.to)?;
        f64_attr(&g, "tolerance", spec.tolerance)?;
        f64_attr(&g, "locate", spec.settings(None).locate)?;
        str_attr(&g, "spurious_reason", crate::periodic::SPURIOUS_REASON)?;
        let c = match c {
            Ok(c) => c,
            Err(err) => {
                str_attr(&g, "error", &err.to_string())?;
                return u8_attr_set(&g, "complete", 0);
            }
        };
        f64_attr(&g, "wall_time", c.wall)?;
        u8_attr_set(
            &g,
            "complete",
            u8::from(c.unfinished.is_none() && c.branches.iter().all(|b| !b.failed)),
        )?;
        u8_attr_set(&g, "finished", u8::from(c.unfinished.is_none()))?;
        u64_attr(&g, "branches", c.branches.len() as u64)?;
        let gap_unit = spec
            .grazing
            .as_ref()
            .and_then(|gz| st.spec.observable(&gz.observable))
            .and_then(|i| c.units.get(i))
            .map_or("", String::as_str);
        for (i, b) in c.branches.iter().enumerate() {
            let bg = g.create_group(&format!("branch_{i}"))?;
            match c.unfinished.as_ref().filter(|_| i + 1 == c.branches.len()) {
                Some(u) => {
                    let open = Branch {
                        end: "not finished: the continuation stopped here (`jointplay run STUDY --out DIR --resume` goes on)".into(),
                        ..b.clone()
                    };
                    write_branch(&bg, &open, &obs, &c.units, &spec.unit, gap_unit)?;
                    f64_attr(&bg, "next_step", u.step)?;
                }
                None => write_branch(&bg, b, &obs, &c.units, &spec.unit, gap_unit)?,
            }
        }
        if let Some(u) = &c.unfinished {
            u64_attr(&g, "points_done", u.points_done as u64)?;
            u64_attr(&g, "pending", u.queue.len() as u64)?;
            for (i, p) in u.queue.iter().enumerate() {
                let pg = g.create_group(&format!("pending_{i}"))?;
                // Its first point is an orbit of the branch it leaves (of its own periods).
                let b = Branch {
                    k: p.start.orbit.k,
                    origin: p.origin.clone(),
                    points: vec![p.start.clone()],
                    end: "waiting".into(),
                    failed: false,
                };
                write_branch(&pg, &b, &obs, &c.units, &spec.unit, gap_unit)?;
                u64_attr(&pg, "branch_periods", p.k as u64)?;
                if let Some((ty, ts)) = &p.switch {
                    let mut v = ty.clone();
                    v.push(*ts);
                    write1(
                        &pg,
                        "switch",
                        &v,
                        "SI",
                        "the first step's tangent (state, then scaled parameter)",
                    )?;
                }
            }
        }
        write_specials(
            &g.create_group("special")?,
            &c.specials,
            &obs,
            &c.units,
            &spec.unit,
        )
    })()
    .map_err(&e)
}

fn observable_names(st: &crate::nonlinear::Loaded) -> Vec<&str> {
    st.spec
        .observables
        .iter()
        .map(|o| o.name.as_str())
        .collect()
}

/// Reads back the continuation of the analysis file `path` when it stopped before its end
/// (`finished = 0`, written by [`write()`] from a [`Report`]'s snapshot or an interrupted run): the
/// branches, the special points and where it stands. None when the file has no continuation or
/// a finished one.
///
/// The state written after the last point ([`write_snapshot`]) is read when there is one, else
/// the analysis file's `/continuation`.
pub fn read_unfinished(
    path: &std::path::Path,
    st: &crate::nonlinear::Loaded,
) -> Result<Option<Continuation>> {
    let snap = snapshot_path(path);
    if snap.exists() {
        return read_from(&snap, st);
    }
    read_from(path, st)
}

fn read_from(
    path: &std::path::Path,
    st: &crate::nonlinear::Loaded,
) -> Result<Option<Continuation>> {
    let file = hdf5::File::open(path).map_err(crate::h5::h5err(path))?;
    read_group(&file, path, st)
}

/// Whether a continuation into the analysis file `path` has begun: its state file
/// ([`snapshot_path`]) exists, or the file holds `/continuation` (finished or not).
pub fn begun(path: &std::path::Path) -> bool {
    snapshot_path(path).exists()
        || hdf5::File::open(path).is_ok_and(|f| f.group("continuation").is_ok())
}

/// Whether the analysis file `path` holds a finished continuation (and no state of one that
/// goes on beside it, [`snapshot_path`]).
pub fn is_finished(path: &std::path::Path) -> Result<bool> {
    if snapshot_path(path).exists() {
        return Ok(false);
    }
    let file = hdf5::File::open(path).map_err(crate::h5::h5err(path))?;
    Ok(match file.group("continuation") {
        Ok(g) => crate::h5::read_attr::<u8>(&g, "finished").unwrap_or(1) == 1,
        Err(_) => false,
    })
}

/// The unfinished continuation of `file` (named `path` in errors), as [`read_unfinished`].
fn read_group(
    file: &hdf5::File,
    path: &std::path::Path,
    st: &crate::nonlinear::Loaded,
) -> Result<Option<Continuation>> {
    use crate::h5::{read_attr, read_rows, read_strings};
    let Ok(g) = file.group("continuation") else {
        return Ok(None);
    };
    if read_attr::<u8>(&g, "finished").unwrap_or(1) == 1 {
        return Ok(None);
    }
    let text = crate::h5::read_str(file, "study").unwrap_or_default();
    if text != st.text {
        return Err(crate::Error::Io {
            file: path.to_path_buf(),
            message: "written by another study text: a continuation goes on only with the study that began it".into(),
        });
    }
    let obs = observable_names(st);
    (|| -> hdf5::Result<Option<Continuation>> {
        let n: u64 = read_attr(&g, "branches")?;
        let mut branches = Vec::new();
        for i in 0..n {
            branches.push(read_branch(&g.group(&format!("branch_{i}"))?, &obs)?);
        }
        let step: f64 = match n.checked_sub(1) {
            Some(last) => {
                let bg = g.group(&format!("branch_{last}"))?;
                read_attr(&bg, "next_step")?
            }
            None => 0.0,
        };
        let mut queue = Vec::new();
        for i in 0..read_attr::<u64>(&g, "pending")? {
            let pg = g.group(&format!("pending_{i}"))?;
            let b = read_branch(&pg, &obs)?;
            let switch = match pg.dataset("switch") {
                Ok(d) => {
                    let mut v: Vec<f64> = d.read_raw()?;
                    let ts = v.pop().unwrap_or(0.0);
                    Some((v, ts))
                }
                Err(_) => None,
            };
            let start = b
                .points
                .into_iter()
                .next()
                .ok_or("a pending branch without its point")?;
            queue.push(Pending {
                start,
                k: read_attr::<u64>(&pg, "branch_periods")? as usize,
                origin: b.origin,
                switch,
            });
        }
        let sg = g.group("special")?;
        let kinds = read_strings(&sg, "kind")?;
        let col = |name: &str| read_rows(&sg, name);
        let (branch, after, param, bracket) = (
            sg.dataset("branch")?.read_raw::<u64>()?,
            sg.dataset("after")?.read_raw::<u64>()?,
            sg.dataset("parameter")?.read_raw::<f64>()?,
            sg.dataset("bracket")?.read_raw::<f64>()?,
        );
        let (states, re, im) = (
            col("state")?,
            col("multipliers_re")?,
            col("multipliers_im")?,
        );
        let strobe: Vec<Vec<f64>> = obs
            .iter()
            .map(|o| sg.dataset(&format!("strobe/{o}"))?.read_raw::<f64>())
            .collect::<hdf5::Result<_>>()?;
        let mut specials = Vec::new();
        for (i, kind) in kinds.iter().enumerate() {
            let kind = Kind::ALL
                .into_iter()
                .find(|k| k.name() == kind)
                .ok_or_else(|| format!("unknown special point '{kind}'"))?;
            specials.push(Special {
                kind,
                branch: branch[i] as usize,
                after: after[i] as usize,
                parameter: param[i],
                bracket: bracket[i],
                state: states[i].clone(),
                multipliers: re[i]
                    .iter()
                    .zip(&im[i])
                    .map(|(a, b)| Complex::new(*a, *b))
                    .collect(),
                strobe: vec![strobe.iter().map(|v| v[i]).collect()],
            });
        }
        Ok(Some(Continuation {
            branches,
            specials,
            wall: read_attr(&g, "wall_time")?,
            units: Vec::new(),
            unfinished: Some(Unfinished {
                step,
                queue,
                points_done: read_attr::<u64>(&g, "points_done")? as usize,
            }),
        }))
    })()
    .map_err(|err| crate::Error::Io {
        file: path.to_path_buf(),
        message: format!("cannot read the unfinished continuation to resume it: {err}"),
    })
}

/// One branch as [`write_branch`] wrote it (the points' monodromy matrices are not kept: a
/// resumed continuation needs only their multipliers).
fn read_branch(g: &hdf5::Group, obs: &[&str]) -> hdf5::Result<Branch> {
    use crate::h5::{read_attr, read_rows, read_str};
    let k = read_attr::<u64>(g, "orbit_periods")? as usize;
    let parameter: Vec<f64> = g.dataset("parameter")?.read_raw()?;
    let n = parameter.len();
    let mut points = Vec::with_capacity(n);
    if n > 0 {
        let t: f64 = read_attr(g, "strobe_time")?;
        let period: f64 = read_attr(g, "period")?;
        let spurious = read_attr::<u64>(g, "spurious")? as usize;
        let scaled: Vec<f64> = g.dataset("scaled")?.read_raw()?;
        let state = read_rows(g, "state")?;
        let tangent = read_rows(g, "tangent")?;
        let onset = read_rows(g, "onset").ok();
        let (re, im) = (
            read_rows(g, "multipliers_re")?,
            read_rows(g, "multipliers_im")?,
        );
        let residual: Vec<f64> = g.dataset("residual")?.read_raw()?;
        let iterations: Vec<u64> = g.dataset("iterations")?.read_raw()?;
        let events: Vec<u64> = g.dataset("events")?.read_raw()?;
        let gap: Option<Vec<f64>> = g.dataset("gap").and_then(|d| d.read_raw()).ok();
        let strobe: Vec<Vec<Vec<f64>>> = obs
            .iter()
            .map(|o| read_rows(g, &format!("strobe/{o}")))
            .collect::<hdf5::Result<_>>()?;
        for i in 0..n {
            let mut tan = tangent[i].clone();
            let ts = tan.pop().unwrap_or(0.0);
            let mut st = HybridState::new(t, state[i].clone());
            st.onset = onset.as_ref().map(|o| o[i].clone()).unwrap_or_default();
            let orbit = Orbit {
                state: st,
                k,
                period,
                residual: residual[i],
                iterations: iterations[i] as usize,
                multipliers: re[i]
                    .iter()
                    .zip(&im[i])
                    .map(|(a, b)| Complex::new(*a, *b))
                    .collect(),
                spurious,
                events: events[i],
                monodromy: DMatrix::zeros(0, 0),
                basis: None,
            };
            points.push(Point {
                parameter: parameter[i],
                orbit,
                iterations: iterations[i] as usize,
                strobe: (0..k)
                    .map(|j| strobe.iter().map(|o| o[i][j]).collect())
                    .collect(),
                gap: gap.as_ref().map(|g| g[i]).filter(|g| !g.is_nan()),
                tangent_y: tan,
                tangent_s: ts,
                s: scaled[i],
            });
        }
    }
    Ok(Branch {
        k,
        origin: read_str(g, "origin")?,
        points,
        end: read_str(g, "end")?,
        failed: read_attr::<u8>(g, "failed")? == 1,
    })
}

fn write_branch(
    g: &hdf5::Group,
    b: &Branch,
    obs: &[&str],
    units: &[String],
    unit: &str,
    gap_unit: &str,
) -> hdf5::Result<()> {
    use crate::h5::{f64_attr, str_attr, u8_attr_set, u64_attr, write_column, write_table, write1};
    u64_attr(g, "orbit_periods", b.k as u64)?;
    str_attr(g, "origin", &b.origin)?;
    str_attr(g, "end", &b.end)?;
    u8_attr_set(g, "failed", u8::from(b.failed))?;
    if let Some(p) = b.points.first() {
        f64_attr(g, "strobe_time", p.orbit.state.t)?;
        f64_attr(g, "period", p.orbit.period)?;
        u64_attr(g, "spurious", p.orbit.spurious as u64)?;
    }
    let col = |f: &dyn Fn(&Point) -> f64| b.points.iter().map(f).collect::<Vec<f64>>();
    write1(
        g,
        "parameter",
        &col(&|p| p.parameter),
        unit,
        "the parameter",
    )?;
    let n = b.points.first().map_or(0, |p| p.orbit.state.y.len());
    let state: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.orbit.state.y.clone())
        .collect();
    write_table(
        g,
        "state",
        &state,
        n.max(1),
        "SI",
        "the strobe point (continuous state)",
    )?;
    let m = b.points.first().map_or(0, |p| p.orbit.multipliers.len());
    let re: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.orbit.multipliers.iter().map(|z| z.re))
        .collect();
    let im: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.orbit.multipliers.iter().map(|z| z.im))
        .collect();
    write_table(
        g,
        "multipliers_re",
        &re,
        m.max(1),
        "1",
        "Floquet multipliers on the manifold, largest modulus first: real parts",
    )?;
    write_table(
        g,
        "multipliers_im",
        &im,
        m.max(1),
        "1",
        "their imaginary parts",
    )?;
    let stable: Vec<u8> = b
        .points
        .iter()
        .map(|p| u8::from(p.orbit.stable()))
        .collect();
    write_column(
        g,
        "stable",
        &stable,
        None,
        "1: every multiplier inside the unit circle",
    )?;
    let unstable: Vec<u64> = b
        .points
        .iter()
        .map(|p| p.orbit.unstable_count() as u64)
        .collect();
    write_column(
        g,
        "unstable",
        &unstable,
        None,
        "multipliers outside the unit circle",
    )?;
    write1(
        g,
        "residual",
        &col(&|p| p.orbit.residual),
        "SI",
        "largest component of P^k(y) - y",
    )?;
    let it: Vec<u64> = b.points.iter().map(|p| p.iterations as u64).collect();
    write_column(
        g,
        "iterations",
        &it,
        None,
        "Newton iterations of the corrector",
    )?;
    let ev: Vec<u64> = b.points.iter().map(|p| p.orbit.events).collect();
    write_column(g, "events", &ev, None, "impacts along one orbit")?;
    // What a resumed continuation needs: the scaled parameter, the tangent and the contacts'
    // onset memory of each point.
    write1(
        g,
        "scaled",
        &col(&|p| p.s),
        "1",
        "the scaled parameter (p - from) / (to - from) the continuation steps in",
    )?;
    let tangent: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.tangent_y.iter().copied().chain([p.tangent_s]))
        .collect();
    write_table(
        g,
        "tangent",
        &tangent,
        n + 1,
        "SI",
        "unit tangent of the branch: the state part, then the scaled parameter's",
    )?;
    let nc = b.points.first().map_or(0, |p| p.orbit.state.onset.len());
    if nc > 0 {
        let onset: Vec<f64> = b
            .points
            .iter()
            .flat_map(|p| p.orbit.state.onset.clone())
            .collect();
        write_table(
            g,
            "onset",
            &onset,
            nc,
            "m/s",
            "approach velocity at the onset of each contact at the strobe point (NaN: out of contact)",
        )?;
    }
    if b.points.iter().any(|p| p.gap.is_some()) {
        write1(
            g,
            "gap",
            &col(&|p| p.gap.unwrap_or(f64::NAN)),
            gap_unit,
            "grazing level minus the largest value of the contact observable along the orbit",
        )?;
    }
    let s = g.create_group("strobe")?;
    for (j, name) in obs.iter().enumerate() {
        let v: Vec<f64> = b
            .points
            .iter()
            .flat_map(|p| p.strobe.iter().map(|row| row[j]))
            .collect();
        let u = units.get(j).map_or("", String::as_str);
        write_table(
            &s,
            name,
            &v,
            b.k,
            u,
            "the observable at the orbit's strobe points, one column per drive period",
        )?;
    }
    Ok(())
}

fn write_specials(
    g: &hdf5::Group,
    sp: &[Special],
    obs: &[&str],
    units: &[String],
    unit: &str,
) -> hdf5::Result<()> {
    use crate::h5::{write_column, write_strings, write_table, write1};
    let kinds: Vec<String> = sp.iter().map(|s| s.kind.name().to_string()).collect();
    write_strings(
        g,
        "kind",
        &kinds,
        "fold, period-doubling, neimark-sacker or grazing",
    )?;
    let branch: Vec<u64> = sp.iter().map(|s| s.branch as u64).collect();
    write_column(g, "branch", &branch, None, "the branch it was found on")?;
    let after: Vec<u64> = sp.iter().map(|s| s.after as u64).collect();
    write_column(
        g,
        "after",
        &after,
        None,
        "index of the branch point before it",
    )?;
    write1(
        g,
        "parameter",
        &sp.iter().map(|s| s.parameter).collect::<Vec<_>>(),
        unit,
        "located parameter",
    )?;
    write1(
        g,
        "bracket",
        &sp.iter().map(|s| s.bracket).collect::<Vec<_>>(),
        unit,
        "arclength bracket reached: the bound on the parameter's error",
    )?;
    let n = sp.first().map_or(1, |s| s.state.len());
    let st: Vec<f64> = sp.iter().flat_map(|s| s.state.clone()).collect();
    write_table(
        g,
        "state",
        &st,
        n,
        "SI",
        "strobe point of the orbit nearest it",
    )?;
    let m = sp.first().map_or(1, |s| s.multipliers.len());
    let re: Vec<f64> = sp
        .iter()
        .flat_map(|s| s.multipliers.iter().map(|z| z.re))
        .collect();
    let im: Vec<f64> = sp
        .iter()
        .flat_map(|s| s.multipliers.iter().map(|z| z.im))
        .collect();
    write_table(
        g,
        "multipliers_re",
        &re,
        m,
        "1",
        "multipliers there: real parts",
    )?;
    write_table(g, "multipliers_im", &im, m, "1", "imaginary parts")?;
    let s = g.create_group("strobe")?;
    for (j, name) in obs.iter().enumerate() {
        let v: Vec<f64> = sp.iter().map(|x| x.strobe[0][j]).collect();
        let u = units.get(j).map_or("", String::as_str);
        write1(&s, name, &v, u, "the observable at the first strobe point")?;
    }
    Ok(())
}

/// Lines for the terminal: each branch and each special point.
pub fn summary(c: &Continuation) -> Vec<String> {
    let mut out = Vec::new();
    for (i, b) in c.branches.iter().enumerate() {
        let (Some(a), Some(z)) = (b.points.first(), b.points.last()) else {
            out.push(format!(
                "branch {i}      period {}, from {}: no point ({})",
                b.k, b.origin, b.end
            ));
            continue;
        };
        let stable = b.points.iter().filter(|p| p.orbit.stable()).count();
        out.push(format!(
            "branch {i}      period {}, {} points from {} to {} ({stable} stable), from {}; ended: {}",
            b.k,
            b.points.len(),
            a.parameter,
            z.parameter,
            b.origin,
            b.end
        ));
    }
    for s in &c.specials {
        out.push(format!(
            "special      {} on branch {} at {} (within {:.1e})",
            s.kind.name(),
            s.branch,
            s.parameter,
            s.bracket
        ));
    }
    out.push(format!("continuation {:.3} s", c.wall));
    out
}
