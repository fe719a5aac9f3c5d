//! The step loop behind [`integrate`] and [`advance`]: the initial step (Hairer's HINIT), the
//! error control of the adaptive methods (the PI controller of the module docs), the samples on
//! the dense output, event location by bisection on the dense output
//! (first crossing from positive to zero or below), the step observer, and the hybrid state's
//! memories carried in and out.

use std::ops::Range;
use std::time::Instant;

use super::*;
use crate::error::{Error, Result};
use crate::state::{HybridState, StepperMemory};

/// Initial step for an adaptive method whose local error estimate is O(h^q) (Hairer, Norsett &
/// Wanner, section II.4, HINIT; q = 5 for DOPRI5).
fn initial_step<S: OdeSystem>(
    sys: &mut S,
    t: f64,
    y: &[f64],
    f0: &[f64],
    (rtol, atol, max_step): (f64, f64, f64),
    q: f64,
    stats: &mut Stats,
) -> f64 {
    let n = sys.error_dim().min(y.len());
    let sc = |i: usize| atol + rtol * y[i].abs();
    let rms = |v: &dyn Fn(usize) -> f64| {
        ((0..n).map(|i| v(i) * v(i)).sum::<f64>() / n.max(1) as f64).sqrt()
    };
    let d0 = rms(&|i| y[i] / sc(i));
    let d1 = rms(&|i| f0[i] / sc(i));
    let mut h0 = if d0 < 1e-5 || d1 < 1e-5 {
        1e-6
    } else {
        0.01 * d0 / d1
    };
    h0 = h0.min(max_step);
    let y1: Vec<f64> = (0..y.len()).map(|i| y[i] + h0 * f0[i]).collect();
    let mut f1 = vec![0.0; y.len()];
    sys.rhs(t + h0, &y1, &mut f1);
    stats.rhs_evals += 1;
    let d2 = rms(&|i| (f1[i] - f0[i]) / sc(i)) / h0;
    let h1 = if d1.max(d2) <= 1e-15 {
        (h0 * 1e-3).max(1e-6)
    } else {
        (0.01 / d1.max(d2)).powf(1.0 / q)
    };
    (100.0 * h0).min(h1).min(max_step)
}

/// The step observer of [`integrate_steps`].
pub type StepObserver<'f, S> = &'f mut dyn FnMut(&mut S, &Step) -> Flow;

/// One accepted step and its continuous extension, handed to the step observer of
/// [`integrate_steps`] (for event location such as Poincare sections).
pub struct Step<'a> {
    /// Start and end time of the step (s).
    pub t0: f64,
    pub t1: f64,
    /// States at both ends.
    pub y0: &'a [f64],
    pub y1: &'a [f64],
    pub(super) stepper: &'a dyn Stepper,
    pub(super) w: &'a Work,
    /// The length of the integrator's step the dense output belongs to (longer than t1 - t0
    /// when an event ended the step early).
    pub(super) h: f64,
}

impl Step<'_> {
    /// The state at `t` in `[t0, t1]` on the integrator's dense output (the same interpolant as
    /// the samples).
    pub fn eval(&self, t: f64, out: &mut [f64]) {
        let h = self.h;
        let theta = ((t - self.t0) / h).clamp(0.0, 1.0);
        if theta == 1.0 {
            out.copy_from_slice(self.y1);
        } else {
            self.stepper.eval(self.y0, self.w, h, theta, out);
        }
    }
}

/// Integrates `sys` from `(t0, y)` to `t_end`, leaving the final state in `y`.
///
/// `samples` are the times (non-decreasing, within `[t0, t_end]`) at which `observer(sys, t, y_t)`
/// is called with the state evaluated on the dense output (or the step end point when it
/// coincides); the observer may evaluate the system there (its scratch memory is its own).
/// The observer may stop the run early by returning [`Flow::Stop`]; the state then stays at the
/// end of the step that contained the sample.
pub fn integrate<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    t0: f64,
    y: &mut [f64],
    t_end: f64,
    samples: &[f64],
    observer: impl FnMut(&mut S, f64, &[f64]) -> Flow,
) -> Result<Stats> {
    integrate_steps(sys, method, t0, y, t_end, samples, observer, None)
}

/// [`integrate`] with a second observer called after every accepted step (after the samples
/// inside it) with the step's dense output; it may stop the run too.
#[allow(clippy::too_many_arguments)]
pub fn integrate_steps<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    t0: f64,
    y: &mut [f64],
    t_end: f64,
    samples: &[f64],
    observer: impl FnMut(&mut S, f64, &[f64]) -> Flow,
    on_step: Option<StepObserver<S>>,
) -> Result<Stats> {
    let (stats, res) = integrate_partial(sys, method, t0, y, t_end, samples, observer, on_step);
    res.map(|()| stats)
}

/// [`integrate_steps`] that returns its counters also when the run fails, for callers that keep
/// what was computed before the failure. On failure `y` holds the last accepted state.
#[allow(clippy::too_many_arguments)]
pub fn integrate_partial<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    t0: f64,
    y: &mut [f64],
    t_end: f64,
    samples: &[f64],
    observer: impl FnMut(&mut S, f64, &[f64]) -> Flow,
    on_step: Option<StepObserver<S>>,
) -> (Stats, Result<()>) {
    let start = Instant::now();
    let mut stats = Stats::default();
    let mut t = t0;
    let mut memory = StepperMemory::default();
    let res = step_loop(
        sys,
        method,
        &mut t,
        y,
        &mut memory,
        t_end,
        &samples,
        observer,
        on_step,
        &mut stats,
    );
    stats.wall = start.elapsed();
    (stats, res)
}

/// Advances the hybrid state `state` of `sys` to `t_end`: the system's memory is loaded from the
/// state, the integrator continues with the state's step memory (the same step grid, the same
/// controller state), and every memory is written back, also when the run fails (then `state`
/// holds the last accepted state). An observer's [`Flow::Stop`] leaves `state` at the end of the
/// step that contained the sample. Samples and the step observer as in [`integrate_steps`].
#[allow(clippy::too_many_arguments)]
pub fn advance<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    state: &mut HybridState,
    t_end: f64,
    samples: &[f64],
    observer: impl FnMut(&mut S, f64, &[f64]) -> Flow,
    on_step: Option<StepObserver<S>>,
) -> (Stats, Result<()>) {
    advance_on(sys, method, state, t_end, &samples, observer, on_step)
}

/// [`advance`] with sample times computed on demand, so that a long run holds none of them.
#[allow(clippy::too_many_arguments)]
pub fn advance_on<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    state: &mut HybridState,
    t_end: f64,
    samples: &dyn SampleTimes,
    observer: impl FnMut(&mut S, f64, &[f64]) -> Flow,
    on_step: Option<StepObserver<S>>,
) -> (Stats, Result<()>) {
    let start = Instant::now();
    let mut stats = Stats::default();
    if let Err(e) = sys.load_memory(state) {
        return (stats, Err(e));
    }
    let HybridState { t, y, stepper, .. } = state;
    let res = step_loop(
        sys, method, t, y, stepper, t_end, samples, observer, on_step, &mut stats,
    );
    sys.save_memory(state);
    stats.wall = start.elapsed();
    (stats, res)
}

/// Sample times for the step loop: the `i`-th of [`SampleTimes::count`], non-decreasing in `i`.
/// A slice is one; a long run computes its times instead of holding them.
pub trait SampleTimes {
    fn count(&self) -> usize;
    fn time(&self, i: usize) -> f64;
}

impl SampleTimes for &[f64] {
    fn count(&self) -> usize {
        self.len()
    }

    fn time(&self, i: usize) -> f64 {
        self[i]
    }
}

/// The first event of the step from `(t, y)` over `h` whose function crosses from positive to
/// zero or below (`g0` at the start, `g1` at the end), located by bisection to round-off on the
/// step's dense output (`w` holds it), each crossing function read alone
/// ([`Events::value`]) from the components it reads, interpolated alone
/// ([`Events::components`], `parts` their scratch; `ys` is left with the others stale):
/// the event and the fraction of the step at the first point found at or past the crossing.
#[allow(clippy::too_many_arguments)]
fn first_crossing<S: OdeSystem>(
    sys: &mut S,
    stepper: &dyn Stepper,
    (t, y, h): (f64, &[f64], f64),
    w: &Work,
    (g0, g1): (&[f64], &[f64]),
    ys: &mut [f64],
    (gi, parts): (&mut [f64], &mut Vec<Range<usize>>),
) -> Option<(usize, f64)> {
    let mut first: Option<(usize, f64)> = None;
    let n = sys.dim();
    let events = sys.events()?;
    for i in 0..g0.len() {
        if !(g0[i] > 0.0 && g1[i] <= 0.0) {
            continue;
        }
        events.components(i, parts);
        if parts.is_empty() {
            parts.push(0..n);
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            // The midpoint rounds to one of the bracket's ends: no later halving moves `hi`
            // (an end tested before tests the same again, and `hi` = 1 stays the result).
            if mid == lo || mid == hi {
                break;
            }
            stepper.eval_parts(y, w, h, mid, ys, parts);
            if events.value(i, t + mid * h, ys, gi) > 0.0 {
                lo = mid
            } else {
                hi = mid
            }
        }
        if first.is_none_or(|(_, th)| hi < th) {
            first = Some((i, hi));
        }
    }
    first
}

/// Whether event `i` of `sys` restarts the step ([`Events::restarts_step`]).
fn restarts_step<S: OdeSystem>(sys: &mut S, i: usize) -> bool {
    sys.events().is_some_and(|e| e.restarts_step(i))
}

/// The step loop. `(t, y, memory)` is the state it starts from and leaves at the last accepted
/// step (the end of the step of a stopping sample); the memory is written back on every exit.
#[allow(clippy::too_many_arguments)]
fn step_loop<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    t: &mut f64,
    y: &mut [f64],
    memory: &mut StepperMemory,
    t_end: f64,
    samples: &dyn SampleTimes,
    mut observer: impl FnMut(&mut S, f64, &[f64]) -> Flow,
    mut on_step: Option<StepObserver<S>>,
    stats: &mut Stats,
) -> Result<()> {
    let t_out = t;
    let n = sys.dim();
    assert_eq!(
        y.len(),
        n,
        "state length does not match the system dimension"
    );
    let t0 = *t_out;
    let integrator = method.integrator;
    let stepper = integrator.stepper;
    let mut w = Work::new(n, sys.error_dim(), integrator);
    let mut ys = vec![0.0; n];
    let mut next_sample = 0usize;
    // Samples at t0 itself.
    let mut stop_after_step = false;
    while next_sample < samples.count() && samples.time(next_sample) <= t0 {
        match observer(sys, t0, y) {
            Flow::Stop => return Ok(()),
            Flow::StopAfterStep => stop_after_step = true,
            Flow::Continue => {}
        }
        next_sample += 1;
    }
    if stop_after_step {
        return Ok(());
    }
    if t_end <= t0 {
        return Ok(());
    }
    sys.rhs(t0, y, &mut w.k[0]);
    stats.rhs_evals += 1;

    let (mut h, adaptive, rtol, atol, max_step) = match method.tolerances() {
        None => {
            let step = method.fixed_step().unwrap_or(f64::NAN);
            (step, false, 0.0, 0.0, step)
        }
        Some((rtol, atol, max_step)) => {
            let q = method.control_order();
            let h = if memory.next_step > 0.0 && memory.next_step.is_finite() {
                memory.next_step.min(max_step)
            } else {
                initial_step(sys, t0, y, &w.k[0], (rtol, atol, max_step), q, stats)
            };
            (h, true, rtol, atol, max_step)
        }
    };
    if !(h > 0.0 && h.is_finite()) {
        return Err(Error::Diverged {
            time: t0,
            message: format!("the step size must be positive and finite, got {h}"),
        });
    }
    // Fixed-step methods step on the grid origin + k h, continued from the memory when it was
    // laid with the same step; the final step is shortened to hit t_end.
    if adaptive || memory.grid_step != h || !memory.grid_origin.is_finite() {
        memory.grid_origin = t0;
        memory.grid_step = h;
        memory.grid_steps = 0;
    }
    let origin = memory.grid_origin;
    let mut err_old: f64 = memory.last_error;
    let mut last_rejected = false;
    let span = t_end - t0;
    let mut k_step: u64 = memory.grid_steps;
    let mut t = t0;
    // Event functions at the start of the current step and at its end.
    let n_events = event_count(sys);
    let (mut g0, mut g1) = (vec![0.0; n_events], vec![0.0; n_events]);
    let mut gi = vec![0.0; n_events];
    let mut parts = Vec::new();
    let mut y_event = vec![0.0; if n_events > 0 { n } else { 0 }];
    if let Some(events) = sys.events().filter(|_| n_events > 0) {
        events.values(t0, y, &mut g0);
    }
    let res = 'run: {
        while t < t_end {
            // The step that held a sample asking to stop after it is done, its event included.
            if stop_after_step {
                break 'run Ok(());
            }
            let t_next_grid = if adaptive {
                t + h
            } else {
                origin + (k_step + 1) as f64 * h
            };
            // Land exactly on t_end when within a small fraction of a step of it.
            let tol = 1e-9 * h.max(span * 1e-12);
            let (mut h_try, mut t_new) = if t_next_grid >= t_end - tol {
                (t_end - t, t_end)
            } else {
                (t_next_grid - t, t_next_grid)
            };
            // A step shortened to end at t_end does not reach the next grid point.
            let mut on_grid = t_next_grid <= t_end + tol;
            if let Err(e) = stepper.step(sys, t, y, h_try, &mut w, stats, last_rejected) {
                break 'run Err(e);
            }
            if adaptive {
                let err = stepper.error_norm(&w, y, h_try, rtol, atol);
                let q = method.control_order();
                if !err.is_finite() || err > 1.0 {
                    stats.rejected += 1;
                    let fac = if err.is_finite() {
                        (0.9 * err.powf(-1.0 / q)).clamp(0.2, 1.0)
                    } else {
                        0.2
                    };
                    h = h_try * fac;
                    last_rejected = true;
                    if h < 1e-14 * t.abs().max(1.0) {
                        break 'run Err(Error::Diverged {
                            time: t,
                            message: format!(
                                "step size underflow (h = {h:e} s) with error estimate {err:e}"
                            ),
                        });
                    }
                    continue;
                }
                // PI controller with exponents 0.7/q and 0.4/q (Gustafsson's form), step growth
                // limited to 10x.
                let e = err.max(1e-10);
                let mut fac = 0.9 * e.powf(-0.7 / q) * err_old.powf(0.4 / q);
                fac = fac.clamp(0.2, if last_rejected { 1.0 } else { 10.0 });
                err_old = e;
                last_rejected = false;
                h = (h_try * fac).min(max_step);
            }
            if let Some(i) = w.y_new.iter().position(|v| !v.is_finite()) {
                break 'run Err(Error::Diverged {
                    time: t_new,
                    message: sys.explain_non_finite(t, y, i),
                });
            }
            // An event inside the step ends it at the event (located on the dense output).
            let mut event = None;
            let mut dense_ready = false;
            if let Some(events) = sys.events().filter(|_| n_events > 0) {
                // The step's last right-hand side was f(t_new, y_new).
                events.values_at_rhs(t_new, &w.y_new, &mut g1);
                if g0.iter().zip(&g1).any(|(a, b)| *a > 0.0 && *b <= 0.0) {
                    stepper.dense(sys, t, y, h_try, &mut w, stats);
                    dense_ready = true;
                    let first = first_crossing(
                        sys,
                        stepper,
                        (t, y, h_try),
                        &w,
                        (&g0, &g1),
                        &mut ys,
                        (&mut gi, &mut parts),
                    );
                    if let Some((i, theta)) = first
                        && theta < 1.0
                    {
                        if !restarts_step(sys, i) {
                            stepper.eval(y, &w, h_try, theta, &mut y_event);
                            t_new = t + theta * h_try;
                            on_grid = false;
                            event = Some(i);
                        } else if theta > 1e-3 && theta < 1.0 - 1e-3 {
                            // The step's later stages, and so its dense output, saw the
                            // dynamics after the event (a contact force): step again from t to
                            // the event, with stages that stay before it.
                            h_try *= theta;
                            if let Err(e) = stepper.step(sys, t, y, h_try, &mut w, stats, false) {
                                break 'run Err(e);
                            }
                            t_new = t + h_try;
                            dense_ready = false;
                            on_grid = false;
                            event = Some(i);
                        } else if theta >= 1.0 - 1e-3 {
                            // At the step's end: the step stands.
                            event = Some(i);
                        }
                        // Within its first thousandth (typically: the previous step, taken again
                        // up to the event, ended a round-off short of it) the step stands as an
                        // ordinary one: a step cut a thousandth long would carry the onset's
                        // Hermite data at the level of the penetration's round-off (1e-16 m
                        // for coordinates of 1 m), and the onset velocity with it.
                    } else if let Some((i, _)) = first {
                        event = Some(i);
                    }
                }
            }
            // The step's end state: the event state when an event cut the step short.
            let at_event = event.is_some() && t_new < t + h_try;
            macro_rules! y_end {
                () => {
                    if at_event { &y_event[..] } else { &w.y_new[..] }
                };
            }
            stats.accepted += 1;
            if on_grid {
                k_step += 1;
            }
            let history_changed = sys.step_accepted(t, y, t_new, y_end!());
            if let Some(message) = sys.check_step(t_new, y_end!()) {
                y.copy_from_slice(y_end!());
                t = t_new;
                break 'run Err(Error::Diverged {
                    time: t_new,
                    message,
                });
            }
            let has_dense_sample =
                next_sample < samples.count() && samples.time(next_sample) < t_new;
            if (has_dense_sample || on_step.is_some()) && !dense_ready {
                stepper.dense(sys, t, y, h_try, &mut w, stats);
            }
            // Emit the samples inside (t, t_new].
            while next_sample < samples.count() && samples.time(next_sample) <= t_new {
                let ts = samples.time(next_sample);
                let theta = ((ts - t) / h_try).clamp(0.0, 1.0);
                let flow = if ts == t_new {
                    observer(sys, ts, y_end!())
                } else {
                    stepper.eval(y, &w, h_try, theta, &mut ys);
                    observer(sys, ts, &ys)
                };
                next_sample += 1;
                if flow == Flow::Stop {
                    y.copy_from_slice(y_end!());
                    t = t_new;
                    break 'run Ok(());
                }
                stop_after_step |= flow == Flow::StopAfterStep;
            }
            if let Some(f) = on_step.as_mut() {
                let step = Step {
                    t0: t,
                    t1: t_new,
                    y0: y,
                    y1: y_end!(),
                    stepper,
                    w: &w,
                    h: h_try,
                };
                if f(sys, &step) == Flow::Stop {
                    y.copy_from_slice(y_end!());
                    t = t_new;
                    break 'run Ok(());
                }
            }
            y.copy_from_slice(y_end!());
            t = t_new;
            if let Some(i) = event {
                // The reset, then a fresh first stage from the reset state.
                if let Some(Err(e)) = sys.events().map(|e| e.apply(i, t, y)) {
                    break 'run Err(e);
                }
                sys.rhs(t, y, &mut w.k[0]);
                stats.rhs_evals += 1;
                if adaptive && restarts_step(sys, i) {
                    let q = method.control_order();
                    let fresh = initial_step(sys, t, y, &w.k[0], (rtol, atol, max_step), q, stats);
                    h = h.min(fresh);
                    last_rejected = false;
                }
                stats.events += 1;
                if let Some(events) = sys.events() {
                    events.values(t, y, &mut g0);
                }
                continue;
            }
            if n_events > 0 {
                g0.copy_from_slice(&g1);
            }
            // The last stage is f(t_new, y_new): first stage of the next step (FSAL), unless the
            // system's history changed at the step end.
            w.k.swap(0, integrator.fsal);
            if history_changed {
                sys.rhs(t, y, &mut w.k[0]);
                stats.rhs_evals += 1;
            }
        }
        Ok(())
    };
    *t_out = t;
    memory.grid_steps = k_step;
    if adaptive {
        memory.next_step = h;
        memory.last_error = err_old;
    }
    res
}
