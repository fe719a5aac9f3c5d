//! N-period runs of any flow with stroboscopic and hyperplane Poincare sections.
//!
//! A [`Plan`] runs a flow from its start time `t0` to `t0 + phase + periods T` and keeps what
//! happens after the transient, i.e. after `t_w = t0 + phase + transient T`:
//!
//! * **stroboscopic section**: the observables at `t_k = t0 + phase + k T` for
//!   `k = transient + 1, ..., periods`, evaluated on the integrator's dense output at exactly that
//!   time (the step sequence does not depend on the sampling, and a fixed-step method whose grid
//!   contains `t_k` hands over the step end point itself);
//! * **time histories**: `samples_per_period` samples per period on `t0 + phase + (i / n) T`
//!   over the kept window (the strobe times are among them, computed by the same expression).
//!   The sample times are computed as the integrator reaches them, and a run given a
//!   [`HistorySink`] hands its histories over every [`HISTORY_BLOCK`] samples, so that its memory
//!   does not grow with them;
//! * **hyperplane sections**: the times where `g = sum_i c_i o_i(t) - value` of the observables
//!   `o_i` changes sign in the chosen direction. Every accepted step is checked at both ends; a
//!   sign change is refined by the Illinois variant of regula falsi (Dowell & Jarratt, BIT 11:168,
//!   1971) on the step's dense output, to `1e-13` of the step or an exact zero, and the
//!   observables are recorded at the crossing. Two crossings inside one step cancel and go
//!   unseen, so the step must resolve the motion (any useful accuracy setting does).
//!
//! The flow only has to be an [`jointplay_solver::ode::OdeSystem`] that can evaluate observables
//! ([`Observed`]);
//! nothing here knows mechanics.

use jointplay_solver::ode::{Flow, Method, SampleTimes, Stats, Step, advance_on};
use jointplay_solver::state::HybridState;

use crate::Result;
use crate::flow::observe::Observed;
use crate::progress::Stop;

/// Crossing direction of a hyperplane section.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// `g` increasing through zero.
    Up,
    /// `g` decreasing through zero.
    Down,
    Both,
}

/// A hyperplane `sum_i c_i o_i = value` in the observables, crossed in `direction`.
#[derive(Debug, Clone, PartialEq)]
pub struct Hyperplane {
    pub name: String,
    /// (observable index, coefficient).
    pub terms: Vec<(usize, f64)>,
    pub value: f64,
    pub direction: Direction,
}

impl Hyperplane {
    fn g(&self, obs: &[f64]) -> f64 {
        self.terms.iter().map(|&(i, c)| c * obs[i]).sum::<f64>() - self.value
    }
}

/// What to run and keep.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub method: Method,
    /// Start time t0 (s).
    pub start: f64,
    /// Drive period T (s).
    pub period: f64,
    /// Offset of the stroboscopic section from t0 (s).
    pub phase: f64,
    pub periods: usize,
    pub transient: usize,
    /// Time-history samples per period in the kept window (0: none).
    pub samples_per_period: usize,
    /// Record time histories over only the last this many periods (default: all kept).
    pub history_periods: Option<usize>,
    pub hyperplanes: Vec<Hyperplane>,
}

/// Points of one hyperplane section.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Crossings {
    pub time: Vec<f64>,
    /// Per observable, one value per crossing.
    pub values: Vec<Vec<f64>>,
}

/// What one run kept.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    pub history_time: Vec<f64>,
    /// Per observable, one value per history sample.
    pub history: Vec<Vec<f64>>,
    pub strobe_time: Vec<f64>,
    /// Per observable, one value per kept period.
    pub strobe: Vec<Vec<f64>>,
    /// One per hyperplane of the plan.
    pub crossings: Vec<Crossings>,
    pub stats: Stats,
    /// The hybrid state at the end time (at the failure, for a run that failed): a run
    /// continued from it is the same run as one that never stopped.
    pub final_state: HybridState,
}

impl Plan {
    /// End time of the run.
    pub fn end_time(&self) -> f64 {
        self.start + self.phase + self.periods as f64 * self.period
    }

    /// Start of the kept window.
    pub fn window_start(&self) -> f64 {
        self.start + self.phase + self.transient as f64 * self.period
    }

    /// Number of stroboscopic points kept.
    pub fn kept(&self) -> usize {
        self.periods - self.transient
    }

    /// Periods covered by the time histories.
    pub fn history_span(&self) -> usize {
        self.history_periods.unwrap_or(self.kept()).min(self.kept())
    }

    /// Number of time-history samples kept.
    pub fn history_len(&self) -> usize {
        if self.samples_per_period == 0 {
            0
        } else {
            self.history_span() * self.samples_per_period + 1
        }
    }

    /// The sample times, computed on demand: a long run holds none of them.
    fn samples(&self) -> Samples {
        let n = self.samples_per_period;
        let (first_history, strobe_only, history) = if n == 0 {
            (usize::MAX, self.kept(), 0)
        } else {
            let first = (self.periods - self.history_span()) * n;
            // Strobe points before the history window: k = transient + 1, ... while k n < first.
            let strobe_only =
                (self.periods - self.history_span()).saturating_sub(self.transient + 1);
            (first, strobe_only, self.periods * n - first + 1)
        };
        Samples {
            base: self.start + self.phase,
            period: self.period,
            n,
            transient: self.transient,
            first_history,
            strobe_only,
            history,
        }
    }
}

/// The sample times of a [`Plan`]: first the strobe times before the history window, then every
/// history sample (some of them strobe times too).
struct Samples {
    base: f64,
    period: f64,
    n: usize,
    transient: usize,
    first_history: usize,
    /// Strobe times before the history window.
    strobe_only: usize,
    /// History samples.
    history: usize,
}

impl Samples {
    /// Sample `i`: its time, whether it is a strobe time and whether a history sample.
    fn at(&self, i: usize) -> (f64, bool, bool) {
        if i < self.strobe_only {
            let k = self.transient + 1 + i;
            return (self.base + k as f64 * self.period, true, false);
        }
        let j = self.first_history + (i - self.strobe_only);
        let n = self.n;
        // (k n) / n is exactly k in floating point, so history samples at whole periods are
        // base + k T exactly, the strobe times.
        let strobe = j.is_multiple_of(n) && j > self.transient * n;
        (
            self.base + (j as f64 / n as f64) * self.period,
            strobe,
            true,
        )
    }
}

impl SampleTimes for Samples {
    fn count(&self) -> usize {
        self.strobe_only + self.history
    }

    fn time(&self, i: usize) -> f64 {
        self.at(i).0
    }
}

/// Hands the samples of `time` and `values` to `sink` as the block starting at sample `handed`,
/// and empties them.
fn hand_over(
    sink: &mut HistorySink,
    handed: &mut usize,
    time: &mut Vec<f64>,
    values: &mut [Vec<f64>],
) -> Result<()> {
    sink(*handed, time, values)?;
    *handed += time.len();
    time.clear();
    for v in values {
        v.clear();
    }
    Ok(())
}

fn nonfinite<S: Observed>(sys: &S, i: usize, t: f64) -> crate::Error {
    jointplay_solver::Error::Diverged {
        time: t,
        message: format!("observable '{}' became non-finite", sys.obs_name(i)),
    }
    .into()
}

/// Runs `sys` from the hybrid state `state` (whose time is `plan.start`, or later for a run that
/// continues) and keeps what the plan asks for; `state` ends at the final state. `progress`
/// receives the fraction of the span done after every accepted step.
pub fn trace<S: Observed>(
    sys: &mut S,
    plan: &Plan,
    state: &mut HybridState,
    progress: &mut dyn FnMut(f64),
) -> Result<Trace> {
    let (tr, res) = trace_partial(sys, plan, state, progress, &Stop::new(), None);
    res.map(|()| tr)
}

/// Samples of time history a run hands to its [`HistorySink`] at once: one chunk of each history
/// dataset of its file (64 kB of values, the HDF5 chunk size `crate::storage::h5::CHUNK_BYTES`,
/// which is defined from this block so that the two stay equal).
pub const HISTORY_BLOCK: usize = 8 * 1024;

/// Where a run's time histories go while it runs, so that a long run holds at most
/// [`HISTORY_BLOCK`] samples of them: called with the index of a block's first sample, the
/// block's times and, per observable, its values. An error stops the run with that error.
pub type HistorySink<'a> = &'a mut dyn FnMut(usize, &[f64], &[Vec<f64>]) -> Result<()>;

/// [`trace`] that returns what was recorded also when the run fails (with the error): samples,
/// strobe points and crossings up to the failure, and the last accepted state. It also ends,
/// with [`crate::Error::Interrupted`], after the first accepted step once `stop` is requested.
///
/// With a `sink` the time histories go to it block by block, the last (partial) block when the
/// run ends or fails, and the returned trace holds none (but a block the sink refused); without
/// one they are kept in the trace.
pub fn trace_partial<S: Observed>(
    sys: &mut S,
    plan: &Plan,
    state: &mut HybridState,
    progress: &mut dyn FnMut(f64),
    stop: &Stop,
    mut sink: Option<HistorySink>,
) -> (Trace, Result<()>) {
    let no = sys.n_obs();
    let samples = plan.samples();
    // History samples handed to the sink so far.
    let mut handed = 0usize;
    let mut history_time = Vec::new();
    let mut history = vec![Vec::new(); no];
    let mut strobe_time = Vec::new();
    let mut strobe = vec![Vec::new(); no];
    let mut obs = vec![0.0; no];
    let mut next = 0usize;
    let mut fail = None;
    let observer = |sys: &mut S, t: f64, y: &[f64]| {
        sys.observe(t, y, &mut obs);
        if let Some(i) = obs.iter().position(|v| !v.is_finite()) {
            fail = Some(nonfinite(sys, i, t));
            return Flow::Stop;
        }
        let (_, is_strobe, is_history) = samples.at(next);
        if is_history {
            history_time.push(t);
            for (h, v) in history.iter_mut().zip(&obs) {
                h.push(*v);
            }
            if let Some(sink) = sink.as_mut()
                && history_time.len() >= HISTORY_BLOCK
                && let Err(e) = hand_over(sink, &mut handed, &mut history_time, &mut history)
            {
                fail = Some(e);
                return Flow::Stop;
            }
        }
        if is_strobe {
            strobe_time.push(t);
            for (s, v) in strobe.iter_mut().zip(&obs) {
                s.push(*v);
            }
        }
        next += 1;
        Flow::Continue
    };

    // Hyperplane sections.
    let planes = &plan.hyperplanes;
    let mut crossings = vec![
        Crossings {
            time: Vec::new(),
            values: vec![Vec::new(); no],
        };
        planes.len()
    ];
    let (tw, t_end) = (plan.window_start(), plan.end_time());
    let span = t_end - plan.start;
    // The observables the section functions read, evaluated at every step end; g at the
    // previous step end is kept so each step costs one evaluation.
    let used = observables_used(planes);
    let mut g_prev: Option<f64> = None;
    let mut g0 = vec![0.0; planes.len()];
    let mut g1 = vec![0.0; planes.len()];
    let mut o1 = vec![0.0; no];
    let mut o = vec![0.0; no];
    let mut ys = vec![0.0; state.y.len()];
    let mut step_fail = None;
    let mut on_step = |sys: &mut S, st: &Step| -> Flow {
        progress((st.t1 - plan.start) / span);
        if stop.requested() {
            step_fail = Some(crate::Error::Interrupted { time: Some(st.t1) });
            return Flow::Stop;
        }
        if planes.is_empty() || st.t1 <= tw {
            return Flow::Continue;
        }
        if g_prev != Some(st.t0) {
            sys.observe_only(st.t0, st.y0, &used, &mut o1);
            for (g, p) in g0.iter_mut().zip(planes) {
                *g = p.g(&o1);
            }
        }
        sys.observe_only(st.t1, st.y1, &used, &mut o1);
        if let Some(&i) = used.iter().find(|&&i| !o1[i].is_finite()) {
            step_fail = Some(nonfinite(sys, i, st.t1));
            return Flow::Stop;
        }
        for (g, p) in g1.iter_mut().zip(planes) {
            *g = p.g(&o1);
        }
        for (k, p) in planes.iter().enumerate() {
            let (a, b) = (g0[k], g1[k]);
            if !crosses(p.direction, a, b) {
                continue;
            }
            let tc = crossing_time(sys, st, p, &used, (a, b), &mut ys, &mut o);
            if tc <= tw {
                continue;
            }
            st.eval(tc, &mut ys);
            sys.observe(tc, &ys, &mut o);
            let c = &mut crossings[k];
            c.time.push(tc);
            for (v, x) in c.values.iter_mut().zip(&o) {
                v.push(*x);
            }
        }
        std::mem::swap(&mut g0, &mut g1);
        g_prev = Some(st.t1);
        Flow::Continue
    };
    let (stats, res) = advance_on(
        sys,
        plan.method,
        state,
        t_end,
        &samples,
        observer,
        Some(&mut on_step),
    );
    let mut res = match fail.or(step_fail) {
        Some(e) => Err(e),
        None => res.map_err(Into::into),
    };
    // The last block, also of a run that failed: a sink that cannot take it fails a run that
    // had not failed before (a run's own failure is kept).
    if let Some(sink) = sink.as_mut()
        && !history_time.is_empty()
        && let Err(e) = hand_over(sink, &mut handed, &mut history_time, &mut history)
        && res.is_ok()
    {
        res = Err(e);
    }
    let tr = Trace {
        history_time,
        history,
        strobe_time,
        strobe,
        crossings,
        stats,
        final_state: state.clone(),
    };
    (tr, res)
}

/// The observables the section functions of `planes` read, each once, in order.
fn observables_used(planes: &[Hyperplane]) -> Vec<usize> {
    let mut used: Vec<usize> = planes
        .iter()
        .flat_map(|p| p.terms.iter().map(|t| t.0))
        .collect();
    used.sort_unstable();
    used.dedup();
    used
}

/// True when a section function going from `a` to `b` over a step crosses zero in `direction`.
fn crosses(direction: Direction, a: f64, b: f64) -> bool {
    match direction {
        Direction::Up => a < 0.0 && b >= 0.0,
        Direction::Down => a > 0.0 && b <= 0.0,
        Direction::Both => (a < 0.0 && b >= 0.0) || (a > 0.0 && b <= 0.0),
    }
}

/// The time in the step `st` at which plane `p`'s function crosses zero, from its values
/// `(a, b)` at the step's ends: the Illinois variant of regula falsi on the step's dense output
/// (the observables `used` evaluated at each trial into `o`, the state into `ys`), until the
/// bracket is below 1e-13 of the step or the function is 0.
fn crossing_time<S: Observed>(
    sys: &mut S,
    st: &Step,
    p: &Hyperplane,
    used: &[usize],
    (a, b): (f64, f64),
    ys: &mut [f64],
    o: &mut [f64],
) -> f64 {
    let (mut ta, mut tb, mut ga, mut gb) = (st.t0, st.t1, a, b);
    let mut side = 0i8;
    let tol = 1e-13 * (st.t1 - st.t0).max(f64::MIN_POSITIVE);
    let mut tc = tb;
    for _ in 0..100 {
        tc = (ta * gb - tb * ga) / (gb - ga);
        if !(tc > ta && tc < tb) {
            tc = 0.5 * (ta + tb);
        }
        st.eval(tc, ys);
        sys.observe_only(tc, ys, used, o);
        let gc = p.g(o);
        if gc == 0.0 || tb - ta < tol {
            break;
        }
        if (gc < 0.0) == (ga < 0.0) {
            ta = tc;
            ga = gc;
            if side == -1 {
                gb *= 0.5;
            }
            side = -1;
        } else {
            tb = tc;
            gb = gc;
            if side == 1 {
                ga *= 0.5;
            }
            side = 1;
        }
    }
    tc
}

#[cfg(test)]
mod tests {
    use jointplay_solver::ode::OdeSystem;
    use jointplay_solver::ode::dopri5::DOPRI5;

    use super::*;

    /// x'' = -x from (1, 0); observes x and x'.
    struct Oscillator;

    impl OdeSystem for Oscillator {
        fn dim(&self) -> usize {
            2
        }

        fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) {
            dydt[0] = y[1];
            dydt[1] = -y[0];
        }
    }

    impl Observed for Oscillator {
        fn n_obs(&self) -> usize {
            2
        }

        fn observe(&mut self, _t: f64, y: &[f64], out: &mut [f64]) {
            out.copy_from_slice(y);
        }

        fn obs_name(&self, i: usize) -> String {
            ["x", "v"][i].into()
        }
    }

    fn plan(periods: usize, transient: usize, n: usize, history: Option<usize>) -> Plan {
        Plan {
            method: Method::adaptive(&DOPRI5, 1e-8, 1e-10, f64::INFINITY).unwrap(),
            start: 0.25,
            period: std::f64::consts::TAU,
            phase: 0.5,
            periods,
            transient,
            samples_per_period: n,
            history_periods: history,
            hyperplanes: Vec::new(),
        }
    }

    /// The sample list as it reads in words: the strobe times t0 + phase + k T of the kept
    /// periods before the history window, then every history sample, a strobe time where it
    /// falls on a whole kept period.
    fn listed(p: &Plan) -> Vec<(f64, bool, bool)> {
        let base = p.start + p.phase;
        let n = p.samples_per_period;
        let first = p.periods - p.history_span();
        let mut v = Vec::new();
        for k in p.transient + 1..=p.periods {
            if n == 0 || k < first {
                v.push((base + k as f64 * p.period, true, false));
            }
        }
        if n > 0 {
            for i in first * n..=p.periods * n {
                let strobe = i % n == 0 && i > p.transient * n;
                v.push((base + (i as f64 / n as f64) * p.period, strobe, true));
            }
        }
        v
    }

    #[test]
    fn sample_times_computed_on_demand_are_the_listed_ones() {
        for (periods, transient, n, history) in [
            (10, 0, 0, None),
            (10, 3, 0, Some(2)),
            (10, 3, 7, None),
            (10, 3, 7, Some(2)),
            (10, 3, 7, Some(0)),
            (10, 3, 7, Some(7)),
            (10, 3, 7, Some(50)),
            (10, 0, 1, None),
            (5, 5, 4, None),
        ] {
            let p = plan(periods, transient, n, history);
            let s = p.samples();
            let list = listed(&p);
            let got: Vec<_> = (0..s.count()).map(|i| s.at(i)).collect();
            // Bit for bit: the integrator samples the same times.
            assert_eq!(got, list, "{periods} {transient} {n} {history:?}");
            assert_eq!(
                got.iter().filter(|x| x.1).count(),
                p.kept(),
                "one strobe time per kept period"
            );
            assert_eq!(got.iter().filter(|x| x.2).count(), p.history_len());
        }
    }

    /// The oscillator from (1, 0) run on `p`, its histories handed to `sink`.
    fn streamed(p: &Plan, sink: HistorySink) -> (Trace, Result<()>) {
        let mut st = HybridState::new(p.start, vec![1.0, 0.0]);
        trace_partial(
            &mut Oscillator,
            p,
            &mut st,
            &mut |_| {},
            &Stop::new(),
            Some(sink),
        )
    }

    #[test]
    fn histories_handed_over_in_blocks_are_those_kept_in_memory() {
        // 2.5 blocks of samples: two whole blocks and a partial one at the end.
        let n = 1000;
        let periods = 2 * HISTORY_BLOCK / n + HISTORY_BLOCK / (2 * n);
        let p = plan(periods, 0, n, None);
        let mut st = HybridState::new(p.start, vec![1.0, 0.0]);
        let kept = trace(&mut Oscillator, &p, &mut st, &mut |_| {}).unwrap();
        assert_eq!(kept.history_time.len(), p.history_len());

        let mut blocks = Vec::new();
        let (mut time, mut values) = (Vec::new(), vec![Vec::new(); 2]);
        let mut sink = |from: usize, t: &[f64], v: &[Vec<f64>]| -> Result<()> {
            assert_eq!(from, time.len(), "blocks follow each other");
            blocks.push(t.len());
            time.extend_from_slice(t);
            for (all, b) in values.iter_mut().zip(v) {
                all.extend_from_slice(b);
            }
            Ok(())
        };
        let (streamed, res) = streamed(&p, &mut sink);
        res.unwrap();
        let last = p.history_len() - 2 * HISTORY_BLOCK;
        assert_eq!(blocks, vec![HISTORY_BLOCK, HISTORY_BLOCK, last]);
        assert!(streamed.history_time.is_empty() && streamed.history.iter().all(Vec::is_empty));
        assert_eq!(time, kept.history_time);
        assert_eq!(values, kept.history);
        assert_eq!(streamed.strobe, kept.strobe);
    }

    #[test]
    fn a_sink_that_fails_stops_the_run_with_its_error() {
        let p = plan(30, 0, 1000, None);
        let mut sink = |_: usize, _: &[f64], _: &[Vec<f64>]| -> Result<()> {
            Err(crate::Error::Io {
                file: "h.h5".into(),
                message: "disk full".into(),
            })
        };
        let (tr, res) = streamed(&p, &mut sink);
        let err = res.unwrap_err().to_string();
        assert!(err.contains("disk full"), "{err}");
        // It stopped at the first block, not at the end.
        assert!(
            tr.final_state.t < p.end_time() / 2.0,
            "{}",
            tr.final_state.t
        );
    }
}
