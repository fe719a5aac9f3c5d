//! Pseudo-arclength continuation of periodic orbits in a parameter, with the detection and
//! location of their bifurcations and of grazing.
//!
//! **Branches.** With `s = (p - from) / (to - from)` the scaled parameter (0 at `from`, 1 at
//! `to`), a branch of period-`k` orbits is a curve of roots of `G(y, s) = P^k(y; s) - y`
//! ([`crate::measures::periodic`]). From a point `(y0, s0)` with unit tangent `(t_y, t_s)` the next point
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
use crate::flow::observe::Observed;
use crate::flow::tangent::Tangent;
use crate::flow::{Flow, Target};
use crate::measures::lyapunov::tangent_map;
use crate::measures::periodic::{MapEval, evaluate, map_distance, orbit_of, shoot};
use crate::storage::branches::*;
use crate::study::continuation::branch::Report;
use crate::study::continuation::spec::*;

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

/// Goes on with a continuation that stopped before its end (read back with [`read_unfinished`](crate::storage::continuation_file::read_unfinished)):
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
    out: Continuation,
    open: Option<(Branch, Point, f64)>,
    queue: Vec<Pending>,
    done_points: usize,
    progress: &mut dyn FnMut(&mut Report) -> bool,
) -> Result<Continuation> {
    let set = ctx.set;
    let wall0 = out.wall;
    Follower {
        ctx,
        t0: std::time::Instant::now(),
        wall0,
        total: (set.max_branches * set.max_points) as f64,
        hmin: set.min_step / ctx.range(),
        hmax: set.max_step / ctx.range(),
        out,
        queue,
        done_points,
        progress,
    }
    .run(open)
}

/// A continuation under way: the branches and special points so far, the branches waiting,
/// the points done, and the step bounds in scaled parameter units.
struct Follower<'a, 'p> {
    ctx: &'a Ctx<'a>,
    out: Continuation,
    queue: Vec<Pending>,
    done_points: usize,
    t0: std::time::Instant,
    /// The wall time of the work resumed (s).
    wall0: f64,
    /// Points at most: `max_branches * max_points`.
    total: f64,
    hmin: f64,
    hmax: f64,
    progress: &'p mut dyn FnMut(&mut Report) -> bool,
}

impl Follower<'_, '_> {
    /// Follows `open`, then each branch of the queue in turn, until the queue is empty or
    /// `max_branches` are done (or `progress` asks to stop: then the snapshot it was given).
    fn run(mut self, mut open: Option<(Branch, Point, f64)>) -> Result<Continuation> {
        loop {
            let (mut branch, h, cur) = if let Some(open) = open.take() {
                (open.0, open.2, open.1)
            } else {
                let Some(pending) = (!self.queue.is_empty()).then(|| self.queue.remove(0)) else {
                    break;
                };
                if self.out.branches.len() >= self.ctx.set.max_branches {
                    break;
                }
                match self.start_branch(pending)? {
                    Some(started) => started,
                    None => continue,
                }
            };
            if let Some(stopped) = self.follow_branch(&mut branch, h, cur)? {
                return Ok(stopped);
            }
            self.out.branches.push(branch);
        }
        self.out.wall = self.wall0 + self.t0.elapsed().as_secs_f64();
        Ok(self.out)
    }

    /// Starts the branch `pending` asks for: its first point, the start itself or (for a
    /// switched branch) the first step from the special point along its tangent, halved down to
    /// the smallest step. Returns the branch with that point, the step and the point; or None
    /// when the branch ends before its first point (pushed, with why, to the branches).
    fn start_branch(&mut self, pending: Pending) -> Result<Option<(Branch, f64, Point)>> {
        let ctx = self.ctx;
        let Pending {
            start: p0,
            k,
            origin,
            switch,
        } = pending;
        let mut branch = Branch {
            k,
            origin,
            points: Vec::new(),
            end: String::new(),
            failed: false,
        };
        let h = ctx.set.step / ctx.range();
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
                    Err(_) if trial / 2.0 >= self.hmin => trial /= 2.0,
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
            self.out.branches.push(branch);
            return Ok(None);
        };
        branch.points.push(cur.clone());
        Ok(Some((branch, h, cur)))
    }

    /// Follows `branch` from its last point `cur` with the step `h` until it ends (its `end`
    /// says why): each step corrected (halved when the corrector fails), the special points
    /// between two points located, a step past the range's end shortened onto it. Returns the
    /// snapshot `progress` was given when it asks to stop.
    fn follow_branch(
        &mut self,
        branch: &mut Branch,
        mut h: f64,
        mut cur: Point,
    ) -> Result<Option<Continuation>> {
        let ctx = self.ctx;
        let set = ctx.set;
        let bi = self.out.branches.len();
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
                    if h < self.hmin {
                        branch.end =
                            format!("the step fell below continuation.min_step after: {e}");
                        branch.failed = true;
                        break;
                    }
                    continue;
                }
            };
            if self.specials_between(bi, branch, &cur, &next, h, &zero) {
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
                h = (h * 1.5).min(self.hmax);
            }
            branch.points.push(next.clone());
            cur = next;
            self.done_points += 1;
            if let Some(stopped) = self.report(bi, branch, &cur, h) {
                return Ok(Some(stopped));
            }
        }
        Ok(None)
    }

    /// Locates the special points of each kind between `cur` and `next` (a step `h` apart) on
    /// branch `bi`, keeps those in the parameter range, and queues the branches they start: the
    /// period-doubled branch when asked, the other side of a grazing. True at a grazing (the
    /// branch ends there).
    fn specials_between(
        &mut self,
        bi: usize,
        branch: &Branch,
        cur: &Point,
        next: &Point,
        h: f64,
        zero: &[f64],
    ) -> bool {
        let ctx = self.ctx;
        let set = ctx.set;
        let k = branch.k;
        let mut graze = false;
        for kind in Kind::ALL {
            if kind == Kind::Grazing && set.grazing.is_none() {
                continue;
            }
            if !changes(kind, cur, next) {
                continue;
            }
            let Some(sp) = locate(ctx, kind, k, cur, next, h) else {
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
            let parameter = grazing_parameter(kind, cur, &at).unwrap_or(at.parameter);
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
                self.queue.push(Pending {
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
                    .start_point(k, s_past, &far.orbit.state, zero, dir)
                    .ok()
                    .filter(|p| test(kind, p).is_none_or(|g| g <= 0.0))
                    .or_else(|| test(kind, next).is_none().then(|| next.clone()));
                if let Some(other) = other {
                    self.queue.push(Pending {
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
            self.out.specials.push(special);
        }
        graze
    }

    /// Reports the point `cur` just added to `branch` (number `bi`, next step `h`) with a
    /// snapshot of everything so far, marked unfinished; returns the snapshot when `progress`
    /// asks to stop.
    fn report(&mut self, bi: usize, branch: &Branch, cur: &Point, h: f64) -> Option<Continuation> {
        let mut snapshot = Continuation {
            branches: self.out.branches.clone(),
            specials: self.out.specials.clone(),
            wall: self.wall0 + self.t0.elapsed().as_secs_f64(),
            units: Vec::new(),
            unfinished: Some(Unfinished {
                step: h,
                queue: self.queue.clone(),
                points_done: self.done_points,
            }),
        };
        snapshot.branches.push(branch.clone());
        let mut report = Report {
            fraction: (self.done_points as f64 / self.total).min(1.0),
            line: point_line(
                bi,
                branch.points.len() - 1,
                cur,
                self.t0.elapsed().as_secs_f64(),
            ),
            snapshot,
        };
        if !(self.progress)(&mut report) {
            return Some(report.snapshot);
        }
        None
    }
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
