//! One job of an analysis study: the flow of one parameter value (or the single run) run through
//! its transient and kept periods, its sections traced, and its chaos measures computed from its
//! final state.

use std::time::Instant;

use jointplay_solver::state::HybridState;

use crate::flow::{Flow, Target};
use crate::measures::sections::{HistorySink, Trace, trace_partial};
use crate::progress::{Progress, Stop};
use crate::storage::analysis_file::JobResult;
use crate::study::spec::invalid;
use crate::{Error, Result};

use crate::study::analysis::load::Loaded;

impl Loaded {
    /// Runs job `value` (None: the single run) from the flow's own start state or from `start`
    /// (a previous job's final state, for continuation). `progress` gets the fraction done.
    pub(crate) fn run_job(
        &self,
        value: Option<f64>,
        start: Option<&HybridState>,
        progress: &mut dyn FnMut(f64),
        stop: &Stop,
        history: Option<HistorySink>,
    ) -> Result<JobResult> {
        let (r, failure) = self.run_job_partial(value, start, progress, stop, history)?;
        match failure {
            Some(e) => Err(e),
            None => Ok(r),
        }
    }

    /// [`Loaded::run_job`] that keeps what a run recorded before it failed: errors before the
    /// integration (a bad value, the assembly) are returned as such; a failure during it comes
    /// back beside the partial result.
    ///
    /// A continuation job starts at the flow's start time from the previous job's continuous
    /// state and its contact-onset history (a contact that carries on through the hand-over
    /// keeps the approach velocity of its onset); the integrator's step memory and the guard's
    /// warnings start afresh, since each value is a run of its own with its own warnings.
    ///
    /// With `history` the time histories go there while the job runs (see [`trace_partial`]);
    /// without, they are kept in the result.
    pub(crate) fn run_job_partial(
        &self,
        value: Option<f64>,
        start: Option<&HybridState>,
        progress: &mut dyn FnMut(f64),
        stop: &Stop,
        history: Option<HistorySink>,
    ) -> Result<(JobResult, Option<Error>)> {
        let t0 = Instant::now();
        let target = self.target(value)?;
        let mut flow = target.flow();
        let mut state = flow.initial_state(start.map(|s| s.y.as_slice()))?;
        if let Some(s) = start {
            state.onset.clone_from(&s.onset);
        }
        flow.prepare(&state)?;
        let plan = self.plan(flow.method(), state.t, flow.period());
        // The job's progress: the analysis run, then the Lyapunov run, in proportion to their
        // periods.
        let share = match &self.spec.lyapunov {
            Some(l) => {
                let a = self.spec.analysis.periods as f64;
                a / (a + l.periods as f64)
            }
            None => 1.0,
        };
        let (tr, res) = trace_partial(
            &mut flow,
            &plan,
            &mut state,
            &mut |x| progress(x * share),
            stop,
            history,
        );
        let (chaos, res) = match res {
            Ok(()) => match self.chaos(
                &target,
                &mut flow,
                &tr,
                &mut |x| progress(share + x * (1.0 - share)),
                stop,
            ) {
                // Stopped in the Lyapunov run: the samples are whole, the measures are not.
                Err(e @ Error::Interrupted { .. }) => (None, Err(e)),
                other => (other?, Ok(())),
            },
            Err(e) => (None, Err(e)),
        };
        let r = JobResult {
            chaos,
            warnings: [flow.compile_warnings(), flow.warnings()].concat(),
            trace: tr,
            units: flow.observable_units(),
            integrator: plan.method.describe(),
            period: flow.period(),
            start: plan.start,
            wall: t0.elapsed().as_secs_f64(),
        };
        Ok((r, res.err()))
    }

    /// The chaos measures of a finished run `tr` of `flow`: the Lyapunov spectrum from its final
    /// state (the analysis's periods serve as the transient) and the 0-1 test on its section
    /// samples; None when the study asks for neither.
    fn chaos<'t>(
        &self,
        target: &'t Target,
        flow: &mut crate::flow::AnyFlow<'t>,
        tr: &Trace,
        progress: &mut dyn FnMut(f64),
        stop: &Stop,
    ) -> Result<Option<crate::measures::chaos::Chaos>> {
        use crate::flow::tangent::Tangent;
        let spec = &self.spec;
        if spec.lyapunov.is_none() && spec.asked().is_empty() {
            return Ok(None);
        }
        let spectrum = match &spec.lyapunov {
            Some(l) => {
                l.check(flow.phase_dim(), &flow.method())
                    .map_err(|(field, m)| invalid(&self.path, field, m))?;
                let mut second = l.two_trajectory.then(|| target.flow());
                let s = crate::measures::lyapunov::spectrum_until(
                    flow,
                    second.as_mut(),
                    &tr.final_state,
                    l,
                    0,
                    progress,
                    stop,
                )?;
                Some(s)
            }
            None => None,
        };
        let asked = spec.asked();
        let mut readings = Vec::with_capacity(asked.len());
        for x in &asked {
            let z = &x.series;
            let i = spec.observable(&z.observable).expect("checked when loaded");
            let series = if z.section == "strobe" {
                &tr.strobe[i]
            } else {
                let p = self
                    .planes
                    .iter()
                    .position(|p| p.name == z.section)
                    .expect("checked when loaded");
                &tr.crossings[p].values[i]
            };
            readings.push(
                x.indicator
                    .compute(series)
                    .map_err(|m| invalid(&self.path, x.key(), m))?,
            );
        }
        // The period is looked for in the first indicator's series (the first observable's
        // without one).
        let obs = asked
            .first()
            .and_then(|x| spec.observable(&x.series.observable))
            .unwrap_or(0);
        let period = crate::measures::chaos::strobe_period(&tr.strobe[obs]);
        let class = crate::measures::chaos::classify(spectrum.as_ref(), &readings, period);
        Ok(Some(crate::measures::chaos::Chaos {
            spectrum,
            readings,
            class,
        }))
    }

    /// The chaos settings of the study.
    pub fn chaos_spec(&self) -> crate::measures::chaos::ChaosSpec {
        crate::measures::chaos::ChaosSpec {
            lyapunov: self.spec.lyapunov.clone(),
            indicators: self.spec.asked(),
        }
    }

    /// Runs the single run of a study without a sweep and returns its result.
    pub fn run_single(&self, progress: &mut dyn FnMut(f64)) -> Result<JobResult> {
        self.run_job(None, None, progress, &Stop::new(), None)
    }

    /// Runs the job with parameter `value` alone (tests, scripting).
    pub fn run_value(&self, value: f64, progress: &mut dyn FnMut(f64)) -> Result<JobResult> {
        self.run_job(Some(value), None, progress, &Stop::new(), None)
    }

    /// Runs the job with parameter `value` from `start`, another job's final state, as a
    /// continuation sweep hands it over (its continuous state and contact-onset history, at the
    /// flow's start time).
    pub fn run_value_from(
        &self,
        value: f64,
        start: &HybridState,
        progress: &mut dyn FnMut(f64),
    ) -> Result<JobResult> {
        self.run_job(Some(value), Some(start), progress, &Stop::new(), None)
    }
}

/// Reports of one job's fraction done, at most one per thousandth of its span.
pub(crate) fn throttled(job: usize, progress: &(dyn Fn(Progress) + Sync)) -> impl FnMut(f64) + '_ {
    let mut last = 0.0;
    move |fraction| {
        if fraction - last >= 1e-3 {
            last = fraction;
            progress(Progress::Fraction { job, fraction });
        }
    }
}
