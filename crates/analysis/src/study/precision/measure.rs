//! Work-precision: what accuracy costs in time, for one flow (a mechanism scene or a built-in
//! system) and every integrator.
//!
//! **Reference.** The flow is integrated period by period with the reference method (by default
//! DOP853 at a relative tolerance of 1e-12, far tighter than any setting tested), stopping exactly
//! at every strobe time `s_k = t0 + phase + k T`, where the full state `y_k` and the contact-onset
//! history are kept. A second method (the check, by default DOPRI5 at 1e-12) runs the same span; its
//! distance from the reference on every error measure is reported as the reference's own
//! uncertainty (`floor`): errors near it are not resolved.
//!
//! **Error measures**, for each tested run:
//!
//! * `position`: `max_k max_i |o_i(s_k) - o_i^ref(s_k)|` over the kept strobe times and the
//!   position observables `o_i` (by default every observable in m or rad; in the observables'
//!   unit). This is the measure a Poincare map needs.
//! * `restart`: the one-period error restarted from reference strobe states: from `(s_k, y_k)`
//!   (and the reference's contact-onset history) the tested method integrates one period and is
//!   compared with `o_i^ref(s_{k+1})`; the largest over `restarts` evenly spread periods. In a
//!   chaotic run the `position` error saturates at the size of the attractor once the two
//!   trajectories have separated; the restarted error still measures the integrator.
//! * `force`: the contact force over the last period, sampled `samples_per_period` times:
//!   `max_s max_i |F_i(t_s) - F_i^ref(t_s)| / max_s max_i |F_i^ref(t_s)|` over the force
//!   observables (by default every observable in N), relative (dimensionless).
//! * `restart_force`: the same over the restarted periods (each sampled `samples_per_period`
//!   times), relative to the largest reference force in them. Contact forces are impulsive: once
//!   two runs have separated, their impacts fall at different times and the `force` error is of
//!   the order of 1; the restarted one still measures the integrator.
//!
//! **Cost.** Wall time of the whole continuous run (with its samples), the right-hand-side
//! evaluations (an implicit method's Jacobian columns included) and the steps. A run shorter
//! than `min_time` is repeated until the repeats add up to it (at most 50 times) and the fastest
//! repeat is kept: the fastest is the least disturbed by the other work of a shared machine.
//! Runs are sequential so that no two share the cores.

use std::path::Path;
use std::time::Duration;

use jointplay_solver::model::Model;
use jointplay_solver::ode::{Flow, Method, Stats, advance};
use jointplay_solver::state::HybridState;

use crate::flow::observe::Observable;
use crate::flow::observe::Observed;
use crate::flow::{Flow as _, Target};
use crate::progress::{Progress, Stop};
use crate::storage::precision_file::*;
use crate::study::analysis::load::Loaded;
use crate::study::precision::spec::*;
use crate::study::spec::invalid;
use crate::{Error, Result};

/// A loaded flow, ready for repeated runs.
struct Runner {
    target: Target,
    /// The flow's initial state (assembled, for a mechanism).
    start: HybridState,
    period: f64,
}

/// What one integration produced.
struct Leg {
    /// Observables at each sample.
    samples: Vec<Vec<f64>>,
    stats: Stats,
    failure: Option<String>,
    warnings: Vec<String>,
    /// The hybrid state at the end (at the failure, for a leg that failed).
    state: HybridState,
}

fn observed_leg<F: Observed>(
    flow: &mut F,
    method: Method,
    state: &mut HybridState,
    t_end: f64,
    samples: &[f64],
) -> (Vec<Vec<f64>>, Stats, Option<String>) {
    let n = flow.n_obs();
    let mut out = Vec::with_capacity(samples.len());
    let mut buf = vec![0.0; n];
    let (stats, res) = advance(
        flow,
        method,
        state,
        t_end,
        samples,
        |f: &mut F, t, ys| {
            f.observe(t, ys, &mut buf);
            out.push(buf.clone());
            Flow::Continue
        },
        None,
    );
    (out, stats, res.err().map(|e| e.to_string()))
}

impl Runner {
    fn obs(&self) -> &[Observable] {
        self.target.observables()
    }

    /// Integrates from `start` to `t_end` as a new run of `method` (the contact-onset history
    /// carries over, the integrator and the guards start afresh: [`HybridState::for_new_run`]).
    fn leg(&mut self, method: Method, start: &HybridState, t_end: f64, samples: &[f64]) -> Leg {
        let mut state = start.for_new_run();
        // The guards of a fixed-step method look at every stage: the flow must know which
        // method runs.
        self.target.set_method(method);
        let mut flow = self.target.flow();
        if let Err(e) = flow.prepare(&state) {
            return Leg {
                samples: Vec::new(),
                stats: Stats::default(),
                failure: Some(e.to_string()),
                warnings: Vec::new(),
                state,
            };
        }
        let (samples, stats, failure) = observed_leg(&mut flow, method, &mut state, t_end, samples);
        Leg {
            samples,
            stats,
            failure,
            warnings: flow.warnings(),
            state,
        }
    }

    /// The flow's own method (its step is the base of the default fixed steps).
    fn own_method(&self) -> Method {
        self.target.method()
    }
}

/// The times of the run: strobe times `s_0..s_periods` and the last period's samples.
#[derive(Clone)]
struct Times {
    start: f64,
    strobe: Vec<f64>,
    transient: usize,
    /// Samples per period.
    spp: usize,
}

impl Times {
    fn end(&self) -> f64 {
        *self.strobe.last().unwrap_or(&self.start)
    }
    /// The `spp` samples of period `k`, in `(s_k, s_{k+1}]`; the last is `s_{k+1}` itself.
    fn window(&self, k: usize) -> Vec<f64> {
        let (a, b) = (self.strobe[k], self.strobe[k + 1]);
        (1..=self.spp)
            .map(|i| {
                if i == self.spp {
                    b
                } else {
                    a + (b - a) * i as f64 / self.spp as f64
                }
            })
            .collect()
    }
    /// The samples of a continuous run: the kept strobe times, then the last period's samples
    /// (sorted and merged; indices of each kind into the merged list).
    fn merged(&self) -> (Vec<f64>, Vec<usize>, Vec<usize>) {
        let kept = &self.strobe[self.transient + 1..];
        let last = self.window(self.strobe.len() - 2);
        let mut all: Vec<(f64, u8, usize)> = kept
            .iter()
            .enumerate()
            .map(|(i, t)| (*t, 0, i))
            .chain(last.iter().enumerate().map(|(i, t)| (*t, 1, i)))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut strobe_idx = vec![0; kept.len()];
        let mut last_idx = vec![0; last.len()];
        for (j, (_, kind, i)) in all.iter().enumerate() {
            if *kind == 0 {
                strobe_idx[*i] = j;
            } else {
                last_idx[*i] = j;
            }
        }
        (all.iter().map(|a| a.0).collect(), strobe_idx, last_idx)
    }
}

/// The reference solution: kept strobe observables, the observables at the samples of every
/// period, and the hybrid state (with the contact-onset history) at every strobe time.
struct Reference {
    strobe: Vec<Vec<f64>>,
    windows: Vec<Vec<Vec<f64>>>,
    states: Vec<HybridState>,
    wall: f64,
}

/// The larger of two measures, NaN (not finite) if either is.
fn worse(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// The largest `|a|` over the samples and the observables `which`; NaN when any is not finite.
fn max_abs(a: &[Vec<f64>], which: &[usize]) -> f64 {
    a.iter()
        .flat_map(|x| which.iter().map(move |&i| x[i].abs()))
        .fold(
            0.0,
            |e, d| if d.is_finite() { worse(e, d) } else { f64::NAN },
        )
}

/// The largest `|a - b|` over the samples and the observables `which`; NaN when any is not
/// finite.
fn max_abs_diff(a: &[Vec<f64>], b: &[Vec<f64>], which: &[usize]) -> f64 {
    let mut e: f64 = 0.0;
    for (x, y) in a.iter().zip(b) {
        for &i in which {
            let d = (x[i] - y[i]).abs();
            if !d.is_finite() {
                return f64::NAN;
            }
            e = e.max(d);
        }
    }
    e
}

/// Everything a work-precision run needs, resolved from the study.
pub struct Precision {
    study: Loaded,
    runner: Runner,
    times: Times,
    position: Vec<usize>,
    force: Vec<usize>,
    restart_at: Vec<usize>,
    reference: Method,
    check: Method,
    families: Vec<(String, Vec<Method>)>,
    min_time: f64,
}

/// The position and force observables of a work-precision run (indices into the study's
/// observables `obs`): those `[precision]` names, or by default every observable in m (else rad,
/// else the first one's unit) and every one in N. The position observables share one unit.
fn pick_observables(
    study: &Loaded,
    spec: &PrecisionSpec,
    obs: &[Observable],
) -> Result<(Vec<usize>, Vec<usize>)> {
    let path = &study.path;
    let names: Vec<&str> = study
        .spec
        .observables
        .iter()
        .map(|o| o.name.as_str())
        .collect();
    let pick = |field: &str, list: &[String]| -> Result<Vec<usize>> {
        list.iter()
            .enumerate()
            .map(|(i, n)| {
                names.iter().position(|m| m == n).ok_or_else(|| {
                    invalid(
                        path,
                        format!("precision.{field}[{i}]"),
                        format!("'{n}' is not an observable of this study"),
                    )
                })
            })
            .collect()
    };
    let mut position = pick("position", &spec.position)?;
    if position.is_empty() {
        // Every observable in m, else in rad, else in the first observable's unit: one unit.
        let unit = ["m", "rad"]
            .into_iter()
            .find(|u| obs.iter().any(|o| o.unit == *u))
            .unwrap_or(obs[0].unit.as_str());
        position = (0..obs.len()).filter(|&i| obs[i].unit == unit).collect();
    }
    let units: Vec<&str> = position.iter().map(|&i| obs[i].unit.as_str()).collect();
    if units.iter().any(|u| *u != units[0]) {
        return Err(invalid(
            path,
            "precision.position",
            format!(
                "the position observables mix units ({}): their largest error has no one unit",
                units.join(", ")
            ),
        ));
    }
    let mut force = pick("force", &spec.force)?;
    if spec.force.is_empty() {
        force = (0..obs.len()).filter(|&i| obs[i].unit == "N").collect();
    }
    Ok((position, force))
}

/// The integrators a work-precision study names, each checked as the field that names it.
struct Methods<'a> {
    path: &'a Path,
    /// The span of a run (s): `analysis.periods` periods and the phase.
    span: f64,
    /// Absolute tolerance per relative tolerance (`precision.atol_scale`).
    atol_scale: f64,
}

impl Methods<'_> {
    /// The integrator `name` at the step or tolerance `setting` (given by `field`): the setting
    /// positive and finite, a fixed step taking at most 1e12 steps, the integrator known.
    fn method(&self, field: &str, name: &str, setting: f64) -> Result<Method> {
        let (path, atol_scale) = (self.path, self.atol_scale);
        if !(setting.is_finite() && setting > 0.0) {
            return Err(invalid(
                path,
                field,
                format!("{setting}: a step or tolerance must be positive and finite"),
            ));
        }
        // As for scenes: a fixed step that needs more than 1e12 steps would never finish.
        let span = self.span;
        if Method::of_family(name, setting, 1.0).is_some_and(|m| m.fixed_step().is_some())
            && span / setting > 1e12
        {
            return Err(invalid(
                path,
                field,
                format!(
                    "{setting:e} s over a span of {span} s means {:.3e} steps; at most 1e12 are allowed",
                    span / setting
                ),
            ));
        }
        // Rounded to 12 digits so that 1e-4 * 1e-3 reads 1e-7, not 1.0000000000000001e-7.
        let atol = format!("{:.12e}", setting * atol_scale)
            .parse()
            .unwrap_or(setting * atol_scale);
        Method::of_family(name, setting, atol).ok_or_else(|| {
            invalid(
                path,
                field,
                format!(
                    "unknown integrator '{name}' (known: {})",
                    Method::families().collect::<Vec<_>>().join(", ")
                ),
            )
        })
    }

    /// The reference method (by default DOP853 at 1e-12) and the check that confirms it (by
    /// default DOPRI5 at 1e-12, or at a tenfold looser tolerance when the reference is DOPRI5),
    /// which must differ.
    fn reference_and_check(&self, spec: &PrecisionSpec) -> Result<(Method, Method)> {
        let (rname, rset) = spec
            .reference
            .as_ref()
            .map(|m| (m.integrator.clone(), m.setting))
            .unwrap_or(("dop853".to_string(), 1e-12));
        let reference = self.method("precision.reference", &rname, rset)?;
        // The default check is a second method at the same tolerance; when the reference is
        // that method, the same method at a tenfold looser tolerance.
        let (cname, cset) = spec
            .check
            .as_ref()
            .map(|m| (m.integrator.clone(), m.setting))
            .unwrap_or(if reference.family() == "dopri5" {
                ("dopri5".to_string(), rset * 10.0)
            } else {
                ("dopri5".to_string(), 1e-12)
            });
        let check = self.method("precision.check", &cname, cset)?;
        if check == reference {
            return Err(invalid(
                self.path,
                "precision.check",
                "must differ from the reference: it confirms it",
            ));
        }
        Ok((reference, check))
    }

    /// The tested runs, family by family: `precision.methods`, or by default every registered
    /// integrator at settings about `base_step`.
    fn families(&self, spec: &PrecisionSpec, base_step: f64) -> Result<Vec<(String, Vec<Method>)>> {
        let mut families = Vec::new();
        if spec.methods.is_empty() {
            for (f, settings) in default_runs(base_step) {
                let ms = settings
                    .iter()
                    .map(|s| self.method("precision.methods", f, *s))
                    .collect::<Result<Vec<_>>>()?;
                families.push((f.to_string(), ms));
            }
        } else {
            for (i, f) in spec.methods.iter().enumerate() {
                if f.settings.is_empty() {
                    return Err(invalid(
                        self.path,
                        format!("precision.methods[{i}].settings"),
                        "give at least one step or tolerance",
                    ));
                }
                let ms = f
                    .settings
                    .iter()
                    .enumerate()
                    .map(|(j, s)| {
                        self.method(
                            &format!("precision.methods[{i}].settings[{j}]"),
                            &f.integrator,
                            *s,
                        )
                    })
                    .collect::<Result<Vec<_>>>()?;
                families.push((f.integrator.clone(), ms));
            }
        }
        Ok(families)
    }
}

impl Precision {
    /// Reads the work-precision settings of an analysis study (its `[precision]` table, or the
    /// defaults) and prepares the flow.
    pub fn new(study: Loaded) -> Result<Precision> {
        let path = study.path.clone();
        if study.spec.sweep.is_some() {
            return Err(invalid(
                &path,
                "sweep",
                "a work-precision run integrates one flow: remove the [sweep] (or set the value in the scene or system)",
            ));
        }
        let spec = study.spec.precision.clone().unwrap_or_default();
        let target = study.target(None)?;
        let (start, period) = {
            let flow = target.flow();
            (flow.initial_state(None)?, flow.period())
        };
        let t0 = start.t;
        let runner = Runner {
            target,
            start,
            period,
        };
        let a = &study.spec.analysis;
        if a.samples_per_period == 0 {
            return Err(invalid(
                &path,
                "analysis.samples_per_period",
                "a work-precision run compares the contact forces at samples inside each period: give at least 1",
            ));
        }
        let strobe: Vec<f64> = (0..=a.periods)
            .map(|k| t0 + a.phase + k as f64 * period)
            .collect();
        let times = Times {
            start: t0,
            strobe,
            transient: a.transient,
            spp: a.samples_per_period,
        };
        let (position, force) = pick_observables(&study, &spec, runner.obs())?;
        let kept = a.periods - a.transient;
        let restarts = spec.restarts.unwrap_or(kept.min(10)).min(kept);
        // Restart periods spread evenly over the kept window: from strobe k to k + 1.
        let restart_at: Vec<usize> = (0..restarts)
            .map(|j| a.transient + (j * kept) / restarts.max(1))
            .collect();
        let atol_scale = spec.atol_scale.unwrap_or(1e-3);
        if !(atol_scale.is_finite() && atol_scale > 0.0) {
            return Err(invalid(&path, "precision.atol_scale", "must be positive"));
        }
        let min_time = spec.min_time.unwrap_or(0.2);
        if !(min_time.is_finite() && min_time >= 0.0) {
            return Err(invalid(&path, "precision.min_time", "must not be negative"));
        }
        let methods = Methods {
            path: &path,
            span: period * a.periods as f64 + a.phase,
            atol_scale,
        };
        let (reference, check) = methods.reference_and_check(&spec)?;
        let base_step = runner.own_method().fixed_step().unwrap_or(period / 1000.0);
        let families = methods.families(&spec, base_step)?;
        Ok(Precision {
            study,
            runner,
            times,
            position,
            force,
            restart_at,
            reference,
            check,
            families,
            min_time,
        })
    }

    /// Number of tested runs.
    pub fn total_runs(&self) -> usize {
        self.families.iter().map(|f| f.1.len()).sum()
    }

    /// The reference: period by period, stopping exactly at every strobe time.
    fn reference(&mut self) -> Result<Reference> {
        let t = self.times.clone();
        let method = self.reference;
        let mut state = self.runner.start.clone();
        let mut states = Vec::with_capacity(t.strobe.len());
        let mut strobe = Vec::new();
        let mut windows = Vec::new();
        let mut wall = Duration::ZERO;
        let mut t_prev = t.start;
        for k in 0..t.strobe.len() {
            let s_k = t.strobe[k];
            // The leg before s_0 (a phase offset) has no samples; the others end a period.
            let samples = if k > 0 { t.window(k - 1) } else { Vec::new() };
            if s_k > t_prev {
                let leg = self.runner.leg(method, &state, s_k, &samples);
                wall += leg.stats.wall;
                if let Some(f) = leg.failure {
                    return Err(invalid(
                        &self.study.path,
                        "precision.reference",
                        format!(
                            "the reference run ({}) failed: {f}",
                            self.reference.describe()
                        ),
                    ));
                }
                state = leg.state;
                if k > 0 {
                    if k > t.transient {
                        // The window's last sample is s_k itself.
                        strobe.push(leg.samples.last().cloned().unwrap_or_default());
                    }
                    windows.push(leg.samples);
                }
            }
            // The strobe time exactly, as the restarts start from it.
            state.t = s_k;
            states.push(state.clone());
            t_prev = s_k;
        }
        Ok(Reference {
            strobe,
            windows,
            states,
            wall: wall.as_secs_f64(),
        })
    }

    /// One tested method: the continuous run (repeated while short) and the restarts.
    fn measure(&mut self, method: Method, r: &Reference, timed: bool) -> RunRecord {
        let (samples, strobe_idx, last_idx) = self.times.merged();
        let t_end = self.times.end();
        let start = self.runner.start.clone();
        let mut leg = self.runner.leg(method, &start, t_end, &samples);
        let mut best = leg.stats.wall.as_secs_f64();
        let mut total = best;
        let mut repeats = 1;
        // Repeats only time the run: it is deterministic, so the first one's results stand.
        while timed && leg.failure.is_none() && total < self.min_time && repeats < 50 {
            let w = self
                .runner
                .leg(method, &start, t_end, &samples)
                .stats
                .wall
                .as_secs_f64();
            best = best.min(w);
            total += w;
            repeats += 1;
        }
        // Every sample is emitted on a run that finishes; anything else is a failure.
        if leg.failure.is_none() && leg.samples.len() != samples.len() {
            leg.failure = Some(format!(
                "{} of {} samples recorded",
                leg.samples.len(),
                samples.len()
            ));
        }
        let mut errors = Errors {
            position: f64::NAN,
            restart: f64::NAN,
            force: f64::NAN,
            restart_force: f64::NAN,
        };
        let peak = |windows: &[&Vec<Vec<f64>>], force: &[usize]| {
            windows.iter().map(|w| max_abs(w, force)).fold(0.0, worse)
        };
        // Relative to the reference's peak; a force where the reference has none is an
        // infinite relative error, and no force in either is no error.
        let relative = |e: f64, scale: f64| {
            if scale > 0.0 || e.is_nan() || scale.is_nan() {
                e / scale
            } else if e > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        };
        let empty = Vec::new();
        let r_last = r.windows.last().unwrap_or(&empty);
        if leg.failure.is_none() {
            let strobe: Vec<Vec<f64>> =
                strobe_idx.iter().map(|&j| leg.samples[j].clone()).collect();
            errors.position = max_abs_diff(&strobe, &r.strobe, &self.position);
            if !self.force.is_empty() {
                let last: Vec<Vec<f64>> =
                    last_idx.iter().map(|&j| leg.samples[j].clone()).collect();
                let scale = peak(&[r_last], &self.force);
                errors.force = relative(max_abs_diff(&last, r_last, &self.force), scale);
            }
        }
        let mut failure = leg.failure.clone();
        let (mut restart, mut restart_force): (f64, f64) = (0.0, 0.0);
        for &k in &self.restart_at.clone() {
            let (s0, s1) = (self.times.strobe[k], self.times.strobe[k + 1]);
            let l = self
                .runner
                .leg(method, &r.states[k], s1, &self.times.window(k));
            let w = &r.windows[k];
            let failed = l.failure.or_else(|| {
                (l.samples.len() != w.len() || w.is_empty())
                    .then(|| format!("{} of {} samples recorded", l.samples.len(), w.len()))
            });
            if let Some(f) = failed {
                failure.get_or_insert(format!("restart at {s0} s: {f}"));
                (restart, restart_force) = (f64::NAN, f64::NAN);
                break;
            }
            // The window's last sample is the strobe time s_{k+1}.
            restart = worse(
                restart,
                max_abs_diff(
                    &l.samples[l.samples.len() - 1..],
                    &w[w.len() - 1..],
                    &self.position,
                ),
            );
            restart_force = worse(restart_force, max_abs_diff(&l.samples, w, &self.force));
        }
        if !self.restart_at.is_empty() {
            errors.restart = restart;
            let windows: Vec<&Vec<Vec<f64>>> =
                self.restart_at.iter().map(|&k| &r.windows[k]).collect();
            if !self.force.is_empty() {
                errors.restart_force = relative(restart_force, peak(&windows, &self.force));
            }
        }
        // A measure that is not finite although the run finished: an observable went non-finite.
        let restarts = !self.restart_at.is_empty();
        let forces = !self.force.is_empty();
        let bad: Vec<&str> = [
            (errors.position, true, "position"),
            (errors.restart, restarts, "restart"),
            (errors.force, forces, "force"),
            (errors.restart_force, forces && restarts, "restart force"),
        ]
        .into_iter()
        .filter(|(e, measured, _)| *measured && e.is_nan())
        .map(|(_, _, name)| name)
        .collect();
        if failure.is_none() && !bad.is_empty() {
            failure = Some(format!(
                "an observable became non-finite: the {} error is not finite",
                bad.join(", ")
            ));
        }
        let mut stats = leg.stats;
        stats.wall = Duration::from_secs_f64(best);
        RunRecord {
            family: method.family().to_string(),
            setting: method.setting(),
            integrator: method.describe(),
            errors,
            wall: best,
            repeats,
            stats,
            failure,
            warnings: leg.warnings,
        }
    }

    /// Runs the reference, the check and every tested method.
    pub fn execute(&mut self, progress: &mut dyn FnMut(Progress)) -> Result<Outcome> {
        self.execute_until(progress, &Stop::new())
    }

    /// [`Precision::execute`] that ends with [`Error::Interrupted`] when `stop` is requested,
    /// checked before each run (a run, timed as a whole, is not cut short); nothing is kept.
    pub fn execute_until(
        &mut self,
        progress: &mut dyn FnMut(Progress),
        stop: &Stop,
    ) -> Result<Outcome> {
        let check_stop = || {
            if stop.requested() {
                Err(Error::Interrupted { time: None })
            } else {
                Ok(())
            }
        };
        check_stop()?;
        progress(Progress::Reference);
        let r = self.reference()?;
        check_stop()?;
        progress(Progress::Check);
        let check = self.measure(self.check, &r, false);
        if let Some(f) = &check.failure {
            return Err(invalid(
                &self.study.path,
                "precision.check",
                format!("the check run ({}) failed: {f}", self.check.describe()),
            ));
        }
        let mut runs = Vec::new();
        let total = self.total_runs();
        for (_, ms) in self.families.clone() {
            for m in ms {
                check_stop()?;
                let what = m.describe();
                progress(Progress::Run {
                    done: runs.len(),
                    total,
                    what: &what,
                });
                runs.push(self.measure(m, &r, true));
            }
        }
        let obs = &self.study.spec.observables;
        let a = &self.study.spec.analysis;
        Ok(Outcome {
            name: self.study.spec.study.name.clone(),
            reference: self.reference.describe(),
            check: self.check.describe(),
            floor: check.errors,
            reference_wall: r.wall,
            runs,
            position: self.position.iter().map(|&i| obs[i].name.clone()).collect(),
            force: self.force.iter().map(|&i| obs[i].name.clone()).collect(),
            position_unit: self.runner.obs()[self.position[0]].unit.clone(),
            restarts: self.restart_at.len(),
            periods: a.periods,
            kept: a.periods - a.transient,
            period: self.runner.period,
        })
    }

    /// The study this run was read from.
    pub fn study(&self) -> &Loaded {
        &self.study
    }
}

/// The synthesised analysis study of a scene file: every body's position, every clearance
/// joint's contact force, the scene's own span in whole periods.
pub fn scene_study(scene: &Path) -> Result<Loaded> {
    let file = jointplay_solver::scene::SceneSpec::load(scene)?;
    let (model, _) = Model::compile(&file)?;
    let Some(period) = model.settings.period else {
        return Err(invalid(
            scene,
            "drives",
            "a work-precision run strobes once per drive period: the scene has no periodic drive (write an analysis study with analysis.period)",
        ));
    };
    let span = model.settings.end_time - model.settings.start_time;
    let periods = ((span / period) - 1e-9).ceil().max(1.0) as usize;
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    let mut text = format!(
        "[study]\nname = \"{}-precision\"\nscene = {:?}\n\n[analysis]\nperiods = {periods}\nsamples_per_period = 400\n\n",
        clean(&model.name),
        scene
            .file_name()
            .map(|f| f.to_string_lossy().to_string())
            .unwrap_or_default(),
    );
    for b in &model.bodies {
        for c in ["x", "y", "z"] {
            text += &format!(
                "[[observables]]\nname = \"{}_{c}\"\npath = \"bodies.{}.position.{c}\"\n\n",
                clean(&b.name),
                b.name
            );
        }
    }
    for c in &model.clearances {
        text += &format!(
            "[[observables]]\nname = \"{}_force\"\npath = \"joints.{}.contact_force.magnitude\"\n\n",
            clean(&c.name),
            c.name
        );
    }
    Loaded::parse(&text, scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointplay_solver::ode::INTEGRATORS;

    /// Every registered integrator is in the default runs, and the defaults of the published
    /// work-precision tables are kept: rk4 at 4 to 1/8 times the flow's own step, dopri5 at rtol
    /// 1e-3 to 1e-10, dop853 at 1e-4 to 1e-11, rosenbrock23 at 1e-2 to 1e-6, in this order; the
    /// fixed-step dopri5 is left out.
    #[test]
    fn every_registered_integrator_is_in_the_default_runs() {
        let runs = default_runs(2e-3);
        for integrator in INTEGRATORS {
            assert!(
                runs.iter().any(|(f, _)| std::ptr::eq(
                    Method::of_family(f, 1e-3, 1e-9).unwrap().integrator(),
                    *integrator
                )),
                "{} is in no default run",
                integrator.name
            );
        }
        let decades = |a: i32, b: i32| (a..=b).map(|e| 10f64.powi(-e)).collect::<Vec<_>>();
        let want: Vec<(&str, Vec<f64>)> = vec![
            (
                "rk4",
                [4.0, 2.0, 1.0, 0.5, 0.25, 0.125]
                    .iter()
                    .map(|f| f * 2e-3)
                    .collect(),
            ),
            ("dopri5", decades(3, 10)),
            ("dop853", decades(4, 11)),
            ("rosenbrock23", decades(2, 6)),
        ];
        let known = ["rk4", "dopri5", "dopri5_fixed", "dop853", "rosenbrock23"];
        let kept: Vec<_> = runs
            .into_iter()
            .filter(|(f, _)| known.contains(f))
            .collect();
        assert_eq!(kept, want);
    }
}
