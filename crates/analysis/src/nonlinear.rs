//! Nonlinear-analysis studies: N-period runs, Poincare sections and bifurcation sweeps of a
//! mechanism scene or a built-in reference system, written to one HDF5 file.
//!
//! A study file with an `[analysis]` table (format in book/src/reference/analysis.md) names a
//! flow (`study.scene`, edited like a comparison study's cases, or `study.system`), the run
//! ([`Plan`]: periods, transient, phase, samples per period), the observables by path
//! ([`crate::observe`]), hyperplane sections, an optional sweep and the figures.
//!
//! **Sweeps.** Each value of the swept parameter is one job. Independent jobs run in parallel on
//! rayon's pool; with `continuation = true` the jobs run in order up the list and back down, each
//! starting from the previous job's final state. Every job's results go into the sweep's journal
//! as soon as it finishes (the jobs run on the caller's rayon pool and send their results through
//! a channel to one writer thread, which forces each record to disk), and the file is written
//! from the journal when the sweep ends or stops ([`crate::storage::sweep`]), so an interrupted
//! sweep keeps every finished job: the file's `complete` attribute is 0 until all jobs are done, `/sweep/done` marks each job (0 not run,
//! 1 done, 2 failed, its message in `/sweep/errors`), and `resume` runs only the jobs not done.
//! Each job's result depends only on its inputs, so the datasets are bit-identical whatever the
//! number of threads and whether the sweep was interrupted.
//!
//! **Shards.** With [`Options::shard`], a sweep computes only the values of one shard into its
//! own file ([`crate::shards`]: assignment, shard files, the merge); the file is written by the
//! same code, its rows being the shard's jobs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use jointplay_solver::model::Model;
use jointplay_solver::scene::{SceneFile, SceneSpec};
use jointplay_solver::state::HybridState;
use rayon::prelude::*;
use serde::Deserialize;
use toml::{Table, Value};

use crate::flow::{Flow, Target};
use crate::h5::{
    PartialFile, append, create_extendable, create_nan, create_nan_chunked, describe, f64_attr,
    h5err, mark_bits, read_attr, read_str, str_attr, u8_attr_set, u64_attr, write_column, write1,
};
use crate::hybrid;
use crate::observe::Observable;
use crate::progress::{Progress, Stop};
use crate::sections::{
    Direction, HISTORY_BLOCK, HistorySink, Hyperplane, Plan, Trace, trace_partial,
};
use crate::shards::Shard;
use crate::storage::rows::Outcome as Kept;
use crate::storage::sweep as storage;
use crate::study::{edit, edited_scene, invalid};
use crate::systems::SystemSpec;
use crate::{Error, Result};
use jointplay_solver::ode::OdeSystem;

/// A nonlinear-analysis study file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisStudy {
    pub study: Header,
    pub analysis: AnalysisSpec,
    /// Default for a built-in system: its state names (see [`AnalysisStudy::parse_spec`]).
    #[serde(default)]
    pub observables: Vec<ObservableSpec>,
    #[serde(default)]
    pub sections: Vec<SectionSpec>,
    #[serde(default)]
    pub sweep: Option<SweepSpec>,
    #[serde(default)]
    pub figures: Vec<FigureSpec>,
    /// Work-precision settings, read by `jointplay precision` (see [`crate::precision`]).
    #[serde(default)]
    pub precision: Option<crate::precision::PrecisionSpec>,
    /// Lyapunov exponents of the run or of every sweep value (see [`crate::chaos`]).
    #[serde(default)]
    pub lyapunov: Option<crate::lyapunov::LyapunovSpec>,
    /// The 0-1 test for chaos on one observable's section samples.
    #[serde(default)]
    pub zero_one: Option<crate::chaos::ZeroOneSpec>,
    /// Periodic orbits followed in a parameter (see [`crate::continuation`]).
    #[serde(default)]
    pub continuation: Option<crate::continuation::ContinuationSpec>,
}

/// The `[study]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// A mechanism scene (relative to the study file) ...
    #[serde(default)]
    pub scene: Option<PathBuf>,
    /// ... or a built-in system (see [`crate::systems`]).
    #[serde(default)]
    pub system: Option<Table>,
    /// Scene edits (as in comparison studies).
    #[serde(default)]
    pub set: BTreeMap<String, Value>,
    #[serde(default)]
    pub remove: Vec<String>,
}

/// The `[analysis]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisSpec {
    /// Drive periods simulated.
    pub periods: usize,
    /// Leading periods discarded.
    #[serde(default)]
    pub transient: usize,
    /// Offset of the stroboscopic section from the start time (s).
    #[serde(default)]
    pub phase: f64,
    /// Time-history samples per period over the kept window (0: none).
    #[serde(default = "default_spp")]
    pub samples_per_period: usize,
    /// Record time histories over only the last this many periods (default: all kept ones).
    #[serde(default)]
    pub history_periods: Option<usize>,
    /// The period (s); default the drive period of the scene or the system's forcing period.
    #[serde(default)]
    pub period: Option<f64>,
    /// Mantissa bits the time histories' values keep in the file (1 to 52; see
    /// [`crate::bitround`]); default every bit. The sample times, strobe points, crossings and
    /// final states are never rounded.
    #[serde(default)]
    pub significant_bits: Option<u32>,
}

impl AnalysisSpec {
    /// The mantissa bits the histories are rounded to; `None` when every bit is kept (52 too).
    pub fn history_bits(&self) -> Option<u32> {
        self.significant_bits.filter(|&b| b < 52)
    }
}

fn default_spp() -> usize {
    100
}

/// One observable: a dataset name and a path.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObservableSpec {
    pub name: String,
    pub path: String,
}

/// A hyperplane section.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionSpec {
    pub name: String,
    /// Coefficients of the observables (by name) in the linear function.
    pub terms: BTreeMap<String, f64>,
    #[serde(default)]
    pub value: f64,
    #[serde(default = "up")]
    pub direction: Direction,
}

fn up() -> Direction {
    Direction::Up
}

/// The `[sweep]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// A scene path (`joints.*.clearance.radial_clearance`) or a system parameter (`gamma`).
    pub parameter: String,
    /// Further scene paths set to the same value (e.g. an axial clearance kept equal to the
    /// radial one).
    #[serde(default)]
    pub also: Vec<String>,
    /// Unit of the parameter, for labels (default none).
    #[serde(default)]
    pub unit: String,
    #[serde(default)]
    pub values: Vec<f64>,
    /// Or an evenly spaced range: `from`, `to` (inclusive) and `count`.
    #[serde(default)]
    pub from: Option<f64>,
    #[serde(default)]
    pub to: Option<f64>,
    #[serde(default)]
    pub count: Option<usize>,
    /// Run the values in order, each from the previous one's final state, up and back down.
    #[serde(default)]
    pub continuation: bool,
}

/// Figure kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FigureKind {
    /// Observable `y` against time.
    Time,
    /// `y` against `x` over the kept window, with the stroboscopic points.
    Phase,
    /// Section points of `y` against `x`, with the trajectory faint and a zoomed inset when the
    /// points cluster.
    Poincare,
    /// Stroboscopic points of `y` against the swept parameter.
    Bifurcation,
    /// `y` against `x` with a clearance circle of radius `circle` (or the swept value).
    Orbit,
    /// The branches of periodic orbits of the `[continuation]` (`y` at their strobe points
    /// against the parameter), over the bifurcation diagram when there is a sweep.
    Branches,
}

/// One figure.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FigureSpec {
    pub kind: FigureKind,
    /// File name stem (default: study name, kind and observables).
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub x: Option<String>,
    pub y: String,
    #[serde(default)]
    pub title: Option<String>,
    /// Section for `poincare` (default the stroboscopic one).
    #[serde(default)]
    pub section: Option<String>,
    /// Sweep values to draw (one panel each; default every value, up to 6).
    #[serde(default)]
    pub values: Vec<f64>,
    /// Orbit: circle radius in the unit of the observables, or the swept value when
    /// `circle_from_parameter`.
    #[serde(default)]
    pub circle: Option<f64>,
    #[serde(default)]
    pub circle_from_parameter: bool,
    /// Scale factor for both axes' values and their unit label, e.g. 1000 and "mm".
    #[serde(default)]
    pub scale: Option<f64>,
    #[serde(default)]
    pub unit: Option<String>,
}

/// A loaded study: its text, spec and base tree.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub path: PathBuf,
    pub text: String,
    pub spec: AnalysisStudy,
    /// The scene file or the system table after the study's edits.
    base: Base,
    /// Observable names; hyperplanes resolved to observable indices.
    pub planes: Vec<Hyperplane>,
    /// The parameter values of each job and its direction (+1 up, -1 down).
    pub jobs: Vec<(f64, i8)>,
}

#[derive(Debug, Clone)]
enum Base {
    Scene { path: PathBuf, tree: Table },
    System(Table),
}

/// True when the study text is a nonlinear-analysis study (has an `[analysis]` table).
pub fn is_analysis(text: &str) -> bool {
    text.parse::<Table>()
        .map(|t| t.contains_key("study") && t.contains_key("analysis"))
        .unwrap_or(false)
}

const RESERVED: [&str; 12] = [
    "chaos",
    "continuation",
    "parameter",
    "direction",
    "done",
    "strobe_time",
    "history",
    "final_state",
    "rhs_evals",
    "wall_time",
    "errors",
    "sections",
];

fn check_name(file: &Path, field: &str, name: &str) -> Result<()> {
    if !crate::plain_name(name, "-_.") || name == "time" || RESERVED.contains(&name) {
        return Err(invalid(
            file,
            field,
            format!(
                "'{name}': use letters, digits, '-', '_' or '.', and not 'time' or {} (it names an HDF5 dataset)",
                RESERVED.join(", ")
            ),
        ));
    }
    Ok(())
}

fn finite(file: &Path, field: &str, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(file, field, "must be finite"))
    }
}

/// The parameter value and direction (+1 up, -1 down) of each job of the study's sweep (none
/// without a sweep): the values in order, and with `continuation` back down again.
pub(crate) fn sweep_jobs(spec: &AnalysisStudy, path: &Path) -> Result<Vec<(f64, i8)>> {
    let mut jobs = Vec::new();
    let Some(sw) = &spec.sweep else {
        return Ok(jobs);
    };
    // Each value is a whole simulation; a million is beyond any sweep that can finish.
    if let Some(n) = sw.count
        && n > 1_000_000
    {
        return Err(invalid(
            path,
            "sweep.count",
            format!("{n} values; at most 1000000 are allowed"),
        ));
    }
    let values = match (&sw.values[..], sw.from, sw.to, sw.count) {
        (v, None, None, None) if !v.is_empty() => v.to_vec(),
        ([], Some(a), Some(b), Some(n)) if n >= 2 => (0..n)
            .map(|i| a + (b - a) * (i as f64) / ((n - 1) as f64))
            .collect(),
        _ => {
            return Err(invalid(
                path,
                "sweep",
                "give either values = [...] or from, to and count (count at least 2)",
            ));
        }
    };
    for (i, v) in values.iter().enumerate() {
        finite(path, &format!("sweep.values[{i}]"), *v)?;
    }
    jobs.extend(values.iter().map(|v| (*v, 1i8)));
    if sw.continuation {
        jobs.extend(values.iter().rev().map(|v| (*v, -1i8)));
    }
    Ok(jobs)
}

/// One parameter set by path, with the field that asked for it (for error messages).
struct Edit {
    field: String,
    path: String,
    value: f64,
}

impl AnalysisStudy {
    /// Parses the spec alone (no scene is read): what `plot` needs. A built-in system without
    /// `[[observables]]` observes its state, each component under its own name.
    pub fn parse_spec(text: &str, path: &Path) -> Result<AnalysisStudy> {
        let mut spec: AnalysisStudy = jointplay_solver::scene::parse_toml(text, path)?;
        if spec.observables.is_empty()
            && let Some(Ok(sys)) = spec.study.system.as_ref().map(SystemSpec::parse)
        {
            spec.observables = sys
                .builtin
                .state_names()
                .iter()
                .map(|n| ObservableSpec {
                    name: n.to_string(),
                    path: n.to_string(),
                })
                .collect();
        }
        Ok(spec)
    }

    /// The observable index of `name`.
    pub fn observable(&self, name: &str) -> Option<usize> {
        self.observables.iter().position(|o| o.name == name)
    }
}

impl Loaded {
    /// Reads and checks a study file and its scene.
    pub fn load(path: &Path) -> Result<Loaded> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Loaded::parse(&text, path)
    }

    /// Parses study text; scene paths are relative to `path`'s directory.
    pub fn parse(text: &str, path: &Path) -> Result<Loaded> {
        let spec = AnalysisStudy::parse_spec(text, path)?;
        let a = &spec.analysis;
        check_name(path, "study.name", &spec.study.name)?;
        if a.periods == 0 {
            return Err(invalid(path, "analysis.periods", "must be at least 1"));
        }
        if a.transient >= a.periods {
            return Err(invalid(
                path,
                "analysis.transient",
                format!(
                    "must be less than analysis.periods ({}), so that some periods are kept",
                    a.periods
                ),
            ));
        }
        if let Some(b) = a.significant_bits
            && !(1..=52).contains(&b)
        {
            return Err(invalid(
                path,
                "analysis.significant_bits",
                format!("{b} is not between 1 and 52 (the mantissa bits of a double)"),
            ));
        }
        finite(path, "analysis.phase", a.phase)?;
        if a.phase < 0.0 {
            return Err(invalid(path, "analysis.phase", "must not be negative"));
        }
        if let Some(p) = a.period
            && !(p.is_finite() && p > 0.0)
        {
            return Err(invalid(
                path,
                "analysis.period",
                "must be a positive number of seconds",
            ));
        }
        if spec.observables.is_empty() {
            return Err(invalid(
                path,
                "observables",
                "name at least one observable ([[observables]] with name and path; only a \
                 built-in system has a default, its state)",
            ));
        }
        let mut names = BTreeMap::new();
        for (i, o) in spec.observables.iter().enumerate() {
            check_name(path, &format!("observables[{i}].name"), &o.name)?;
            if names.insert(o.name.clone(), i).is_some() {
                return Err(invalid(
                    path,
                    format!("observables[{i}].name"),
                    format!("duplicate name '{}'", o.name),
                ));
            }
        }
        let mut planes = Vec::new();
        for (i, s) in spec.sections.iter().enumerate() {
            check_name(path, &format!("sections[{i}].name"), &s.name)?;
            if s.name == "strobe" || spec.sections[..i].iter().any(|o| o.name == s.name) {
                return Err(invalid(
                    path,
                    format!("sections[{i}].name"),
                    format!(
                        "'{}' is taken ('strobe' is the stroboscopic section)",
                        s.name
                    ),
                ));
            }
            finite(path, &format!("sections[{i}].value"), s.value)?;
            if s.terms.is_empty() {
                return Err(invalid(
                    path,
                    format!("sections[{i}].terms"),
                    "give at least one term",
                ));
            }
            let mut terms = Vec::new();
            for (k, c) in &s.terms {
                let j = *names.get(k).ok_or_else(|| {
                    invalid(
                        path,
                        format!("sections[{i}].terms.{k}"),
                        "not an observable of this study",
                    )
                })?;
                finite(path, &format!("sections[{i}].terms.{k}"), *c)?;
                terms.push((j, *c));
            }
            planes.push(Hyperplane {
                name: s.name.clone(),
                terms,
                value: s.value,
                direction: s.direction,
            });
        }
        if let Some(z) = &spec.zero_one {
            if !names.contains_key(&z.observable) {
                return Err(invalid(
                    path,
                    "zero_one.observable",
                    format!("'{}' is not an observable of this study", z.observable),
                ));
            }
            if z.section != "strobe" && !planes.iter().any(|p| p.name == z.section) {
                return Err(invalid(
                    path,
                    "zero_one.section",
                    format!(
                        "'{}' is neither 'strobe' nor a section of this study",
                        z.section
                    ),
                ));
            }
            let kept = a.periods - a.transient;
            if z.section == "strobe" && kept < crate::zero_one::MIN_SAMPLES {
                return Err(invalid(
                    path,
                    "zero_one",
                    format!(
                        "the strobe section keeps {kept} samples (analysis.periods - analysis.transient), but the 0-1 test needs at least {}",
                        crate::zero_one::MIN_SAMPLES
                    ),
                ));
            }
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let base = match (&spec.study.scene, &spec.study.system) {
            (Some(scene), None) => {
                let sp = dir.join(scene);
                let (_, tree) = edited_scene(
                    path,
                    &sp,
                    "study.scene",
                    &[("study", &spec.study.set, &spec.study.remove)],
                )?;
                Base::Scene { path: sp, tree }
            }
            (None, Some(sys)) => {
                if spec.sweep.as_ref().is_some_and(|s| !s.also.is_empty()) {
                    return Err(invalid(
                        path,
                        "sweep.also",
                        "applies to scenes, not to systems",
                    ));
                }
                if !spec.study.set.is_empty() || !spec.study.remove.is_empty() {
                    return Err(invalid(
                        path,
                        "study.set",
                        "edits apply to scenes; give a system's parameters in study.system",
                    ));
                }
                // The base table must be valid even where a sweep overrides a value.
                SystemSpec::parse(sys)
                    .map_err(|(k, m)| invalid(path, format!("study.system.{k}"), m))?;
                Base::System(sys.clone())
            }
            _ => {
                return Err(invalid(
                    path,
                    "study",
                    "give either scene = \"FILE\" or system = { kind = ... }",
                ));
            }
        };
        let jobs = sweep_jobs(&spec, path)?;
        let loaded = Loaded {
            path: path.to_path_buf(),
            text: text.to_string(),
            spec,
            base,
            planes,
            jobs,
        };
        // Build the first job (or the single run) now, so that a bad scene, path or observable
        // fails before anything runs.
        let first = loaded.jobs.first().map(|j| j.0);
        let target = loaded.target(first)?;
        loaded.check_span(&target)?;
        if let Some(c) = &loaded.spec.continuation {
            loaded.check_continuation(c)?;
        }
        for (i, f) in loaded.spec.figures.iter().enumerate() {
            for (k, &v) in f.values.iter().enumerate() {
                finite(&loaded.path, &format!("figures[{i}].values[{k}]"), v)?;
                // A panel is drawn for each value the sweep has: one it lacks would be left out
                // without a word.
                if loaded.spec.sweep.is_none() {
                    return Err(invalid(
                        &loaded.path,
                        format!("figures[{i}].values"),
                        "the study has no [sweep] whose values it could pick",
                    ));
                }
                if !loaded
                    .jobs
                    .iter()
                    .any(|j| (j.0 - v).abs() <= 1e-9 * v.abs().max(1e-300))
                {
                    let shown: Vec<String> = loaded
                        .jobs
                        .iter()
                        .take(8)
                        .map(|j| j.0.to_string())
                        .collect();
                    return Err(invalid(
                        &loaded.path,
                        format!("figures[{i}].values[{k}]"),
                        format!(
                            "{v} is not a value of the sweep ({}{})",
                            shown.join(", "),
                            if loaded.jobs.len() > 8 { ", ..." } else { "" }
                        ),
                    ));
                }
            }
            if let Some(c) = f.circle {
                finite(&loaded.path, &format!("figures[{i}].circle"), c)?;
            }
            if let Some(sc) = f.scale
                && !(sc.is_finite() && sc != 0.0)
            {
                return Err(invalid(
                    &loaded.path,
                    format!("figures[{i}].scale"),
                    format!("{sc}: must be a finite, non-zero factor"),
                ));
            }
            for (what, name) in [("x", f.x.as_deref()), ("y", Some(f.y.as_str()))] {
                if let Some(n) = name
                    && loaded.spec.observable(n).is_none()
                {
                    return Err(invalid(
                        &loaded.path,
                        format!("figures[{i}].{what}"),
                        format!("'{n}' is not an observable of this study"),
                    ));
                }
            }
            let needs_x = matches!(
                f.kind,
                FigureKind::Phase | FigureKind::Poincare | FigureKind::Orbit
            );
            if needs_x && f.x.is_none() {
                return Err(invalid(
                    &loaded.path,
                    format!("figures[{i}].x"),
                    "this kind needs x",
                ));
            }
            if f.kind == FigureKind::Branches && loaded.spec.continuation.is_none() {
                return Err(invalid(
                    &loaded.path,
                    format!("figures[{i}].kind"),
                    "a branches figure needs a [continuation]",
                ));
            }
            if f.kind == FigureKind::Bifurcation && loaded.spec.sweep.is_none() {
                return Err(invalid(
                    &loaded.path,
                    format!("figures[{i}].kind"),
                    "a bifurcation diagram needs a [sweep]",
                ));
            }
            if let Some(s) = &f.section
                && !loaded.planes.iter().any(|p| &p.name == s)
                && s != "strobe"
            {
                return Err(invalid(
                    &loaded.path,
                    format!("figures[{i}].section"),
                    format!("no section '{s}'"),
                ));
            }
        }
        Ok(loaded)
    }

    /// Refuses a run that could never finish, as scenes do (`solver.step`): `analysis.periods`
    /// periods of `analysis.period` (or the drive's) that take more than 1e12 steps of the
    /// fixed step or the step bound, or of the drive period, which an adaptive method resolves
    /// with a step at least.
    fn check_span(&self, target: &Target) -> Result<()> {
        use jointplay_solver::ode::Accuracy;
        let (period, own) = match target {
            Target::Scene { model, period, .. } => (*period, model.settings.period),
            Target::System { sys, period, .. } => (*period, sys.builtin.period()),
        };
        let step = match target.method().accuracy() {
            Accuracy::Fixed { step } => step,
            Accuracy::Adaptive { max_step, .. } => max_step,
        };
        let step = own.map_or(step, |p| step.min(p));
        let a = &self.spec.analysis;
        let span = a.periods as f64 * period + a.phase;
        if span / step > 1e12 {
            let field = if a.period.is_some() {
                "analysis.period"
            } else {
                "analysis.periods"
            };
            return Err(invalid(
                &self.path,
                field,
                format!(
                    "{} periods of {period:e} s with steps of at most {step:.3e} s (the step bound or the drive period) mean at least {:.3e} steps; at most 1e12 are allowed",
                    a.periods,
                    span / step
                ),
            ));
        }
        Ok(())
    }

    /// Text of the flow (the edited scene or the system table) for the file.
    fn base_text(&self) -> String {
        match &self.base {
            Base::Scene { tree, .. } | Base::System(tree) => {
                toml::to_string(tree).unwrap_or_default()
            }
        }
    }

    /// The flow with the swept parameter set to `value`, ready to run.
    pub(crate) fn target(&self, value: Option<f64>) -> Result<Target> {
        let edits: Vec<Edit> = match (value, &self.spec.sweep) {
            (Some(v), Some(sw)) => std::iter::once(Edit {
                field: format!("sweep.parameter ('{}')", sw.parameter),
                path: sw.parameter.clone(),
                value: v,
            })
            .chain(sw.also.iter().enumerate().map(|(i, p)| Edit {
                field: format!("sweep.also[{i}] ('{p}')"),
                path: p.clone(),
                value: v,
            }))
            .collect(),
            _ => Vec::new(),
        };
        self.compile_edited(&edits)
    }

    /// The study's flow with parameters set by path: for a scene, scene paths as in a sweep
    /// (`joints.*.clearance.radial_clearance`; `*` sets every element), for a built-in system its
    /// parameter names (`gamma`, `omega`, ...). The study file is not changed; each call compiles
    /// a new flow from the study's source. Errors name the path.
    pub fn target_with(&self, edits: &[(&str, f64)]) -> Result<Target> {
        let edits: Vec<Edit> = edits
            .iter()
            .map(|&(path, value)| Edit {
                field: format!("parameter '{path}'"),
                path: path.to_string(),
                value,
            })
            .collect();
        self.compile_edited(&edits)
    }

    /// Compiles the study's source with `edits` applied (the first one names the edited scene in
    /// messages).
    fn compile_edited(&self, edits: &[Edit]) -> Result<Target> {
        match &self.base {
            Base::Scene { path: sp, tree } => {
                let mut tree = tree.clone();
                for ed in edits {
                    edit(&mut tree, &ed.path, Some(&Value::Float(ed.value))).map_err(|m| {
                        invalid(&self.path, &ed.field, format!("{m} in {}", sp.display()))
                    })?;
                }
                let text = toml::to_string(&tree)
                    .map_err(|e| invalid(&self.path, "study.scene", e.to_string()))?;
                let named = match edits.first() {
                    // The value as `{:?}` writes it (1e308, not 309 digits) and the path
                    // clipped, so that the message clipping keeps the study's name.
                    Some(ed) => PathBuf::from(format!(
                        "{} ({} = {:?} in {})",
                        sp.display(),
                        crate::clip(&ed.path),
                        ed.value,
                        self.path.display()
                    )),
                    // A value the study's own `set` put there is named with the study, as a
                    // comparison case's scene is.
                    None if !self.spec.study.set.is_empty()
                        || !self.spec.study.remove.is_empty() =>
                    {
                        PathBuf::from(format!(
                            "{} (edited by {})",
                            sp.display(),
                            self.path.display()
                        ))
                    }
                    None => sp.clone(),
                };
                let spec = SceneSpec::parse(&text, &named)?;
                let scene = SceneFile {
                    path: named,
                    text,
                    spec,
                };
                let (model, state) = Model::compile(&scene)?;
                let mut obs = Vec::new();
                for (i, o) in self.spec.observables.iter().enumerate() {
                    obs.push(
                        Observable::for_model(&model, &o.path).map_err(|m| {
                            invalid(&self.path, format!("observables[{i}].path"), m)
                        })?,
                    );
                }
                let period = self.period(model.settings.period)?;
                Ok(Target::Scene {
                    model: Box::new(model),
                    state,
                    obs,
                    period,
                })
            }
            Base::System(table) => {
                let mut table = table.clone();
                for ed in edits {
                    if !table.contains_key(&ed.path) && ed.path != "start_time" {
                        // Let the parser name the allowed parameters.
                        let probe = SystemSpec::parse(&{
                            let mut t = table.clone();
                            t.insert(ed.path.clone(), Value::Float(ed.value));
                            t
                        });
                        if let Err((_, m)) = probe {
                            return Err(invalid(&self.path, &ed.field, m));
                        }
                    }
                    table.insert(ed.path.clone(), Value::Float(ed.value));
                }
                let sys = SystemSpec::parse(&table)
                    .map_err(|(k, m)| invalid(&self.path, format!("study.system.{k}"), m))?;
                let mut obs = Vec::new();
                for (i, o) in self.spec.observables.iter().enumerate() {
                    obs.push(
                        Observable::for_system(&sys.builtin, &o.path).map_err(|m| {
                            invalid(&self.path, format!("observables[{i}].path"), m)
                        })?,
                    );
                }
                let period = self.period(sys.builtin.period())?;
                Ok(Target::System { sys, obs, period })
            }
        }
    }

    /// The flow with the continuation parameter (and its `also` paths) set to `value`.
    pub fn continuation_target(&self, value: f64) -> Result<Target> {
        let Some(c) = &self.spec.continuation else {
            return Err(invalid(
                &self.path,
                "continuation",
                "no [continuation] table",
            ));
        };
        let edits: Vec<Edit> = std::iter::once(Edit {
            field: format!("continuation.parameter ('{}')", c.parameter),
            path: c.parameter.clone(),
            value,
        })
        .chain(c.also.iter().enumerate().map(|(i, p)| Edit {
            field: format!("continuation.also[{i}] ('{p}')"),
            path: p.clone(),
            value,
        }))
        .collect();
        self.compile_edited(&edits)
    }

    /// Checks the `[continuation]` table against the study: its numbers, its paths (the flow is
    /// compiled at both ends of the range), its grazing observable, and the period (a periodic
    /// orbit of a forced flow is one of the drive: `analysis.period`, when given, must be the
    /// drive's own).
    fn check_continuation(&self, c: &crate::continuation::ContinuationSpec) -> Result<()> {
        c.check().map_err(|(f, m)| invalid(&self.path, f, m))?;
        if let Some(g) = &c.grazing
            && self.spec.observable(&g.observable).is_none()
        {
            return Err(invalid(
                &self.path,
                "continuation.grazing.observable",
                format!("'{}' is not an observable of this study", g.observable),
            ));
        }
        if matches!(self.base, Base::System(_)) && !c.also.is_empty() {
            return Err(invalid(
                &self.path,
                "continuation.also",
                "applies to scenes, not to systems",
            ));
        }
        for v in [c.from, c.to] {
            let own = match self.continuation_target(v)? {
                Target::Scene { model, .. } => model.settings.period,
                Target::System { sys, .. } => sys.builtin.period(),
            };
            let Some(own) = own else {
                return Err(invalid(
                    &self.path,
                    "continuation",
                    "the flow has no drive: periodic orbits are followed on the stroboscopic map of a periodic drive",
                ));
            };
            if let Some(p) = self.spec.analysis.period
                && (p - own).abs() > 1e-12 * own
            {
                return Err(invalid(
                    &self.path,
                    "analysis.period",
                    format!(
                        "{p} s is not the drive's period ({own} s at {} = {v}): a continuation shoots on the drive's stroboscopic map (use continuation.orbit_periods for a subharmonic)",
                        c.parameter
                    ),
                ));
            }
        }
        crate::continuation::start_of(self)?;
        Ok(())
    }

    fn period(&self, own: Option<f64>) -> Result<f64> {
        self.spec.analysis.period.or(own).ok_or_else(|| {
            invalid(
                &self.path,
                "analysis.period",
                "the flow has no drive period: give analysis.period (s)",
            )
        })
    }

    fn plan(&self, method: jointplay_solver::ode::Method, start: f64, period: f64) -> Plan {
        let a = &self.spec.analysis;
        Plan {
            method,
            start,
            period,
            phase: a.phase,
            periods: a.periods,
            transient: a.transient,
            samples_per_period: a.samples_per_period,
            history_periods: a.history_periods,
            hyperplanes: self.planes.clone(),
        }
    }
}

/// What one job produced, with the units of the observables.
#[derive(Debug, Clone)]
pub struct JobResult {
    pub trace: Trace,
    /// The scene's warnings and the step-size guard's.
    pub warnings: Vec<String>,
    pub units: Vec<String>,
    pub integrator: String,
    pub period: f64,
    pub start: f64,
    pub wall: f64,
    /// The chaos measures, when the study asks for them.
    pub chaos: Option<crate::chaos::Chaos>,
}

impl Loaded {
    /// Runs job `value` (None: the single run) from the flow's own start state or from `start`
    /// (a previous job's final state, for continuation). `progress` gets the fraction done.
    fn run_job(
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
    fn run_job_partial(
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
    ) -> Result<Option<crate::chaos::Chaos>> {
        use crate::tangent::Tangent;
        let spec = &self.spec;
        if spec.lyapunov.is_none() && spec.zero_one.is_none() {
            return Ok(None);
        }
        let spectrum = match &spec.lyapunov {
            Some(l) => {
                l.check(flow.phase_dim(), &flow.method())
                    .map_err(|(field, m)| invalid(&self.path, field, m))?;
                let mut second = l.two_trajectory.then(|| target.flow());
                let s = crate::lyapunov::spectrum_until(
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
        let zero_one = match &spec.zero_one {
            Some(z) => {
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
                Some(
                    crate::zero_one::zero_one(series)
                        .map_err(|m| invalid(&self.path, "zero_one", m))?,
                )
            }
            None => None,
        };
        let obs = spec
            .zero_one
            .as_ref()
            .and_then(|z| spec.observable(&z.observable))
            .unwrap_or(0);
        let period = crate::chaos::strobe_period(&tr.strobe[obs]);
        let class = crate::chaos::classify(spectrum.as_ref(), zero_one.as_ref(), period);
        Ok(Some(crate::chaos::Chaos {
            spectrum,
            zero_one,
            class,
        }))
    }

    /// The chaos settings of the study.
    pub fn chaos_spec(&self) -> crate::chaos::ChaosSpec {
        crate::chaos::ChaosSpec {
            lyapunov: self.spec.lyapunov.clone(),
            zero_one: self.spec.zero_one.clone(),
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
fn throttled(job: usize, progress: &(dyn Fn(Progress) + Sync)) -> impl FnMut(f64) + '_ {
    let mut last = 0.0;
    move |fraction| {
        if fraction - last >= 1e-3 {
            last = fraction;
            progress(Progress::Fraction { job, fraction });
        }
    }
}

/// Summary of an executed study.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub file: PathBuf,
    /// Jobs in the file: every value of the sweep, or a shard's values.
    pub jobs: usize,
    pub ran: usize,
    /// Every job of the file done (or failed); false when stopped by `max_jobs` or on request.
    pub complete: bool,
    /// Stopped on request ([`execute_until`]): a single run written incomplete, or a sweep with
    /// values left to run.
    pub interrupted: bool,
    /// Failed jobs: their index in the whole sweep and the message.
    pub failed: Vec<(usize, String)>,
    /// Warnings of a single run (the scene's and the step-size guard's).
    pub warnings: Vec<String>,
    pub wall: f64,
    pub rhs_evals: u64,
    /// Wall time the jobs of this call took, summed over the threads that ran them (s).
    pub busy: f64,
    /// Threads of the pool the jobs ran on (1 for a single run or a continuation).
    pub threads: usize,
    /// The sweep's table beside its file, `<stem>.md` and `<stem>.csv` ([`crate::sweep_table`];
    /// none for a single run or a shard).
    pub tables: Vec<PathBuf>,
}

impl Outcome {
    /// Parallel efficiency: the jobs' summed wall time over the threads' wall time,
    /// `busy / (threads * wall)`; 1 when every thread ran a job from start to end. What it misses
    /// is the time threads waited (the last jobs of a sweep running alone) and the time outside
    /// the jobs (reading the study, writing the file).
    pub fn efficiency(&self) -> f64 {
        self.busy / (self.threads.max(1) as f64 * self.wall.max(1e-9))
    }
}

/// How [`execute`] treats an existing file and how much it runs.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Keep the finished jobs of an existing file and run only the rest.
    pub resume: bool,
    /// Stop after this many jobs have finished (the file stays incomplete; resume later).
    pub max_jobs: Option<usize>,
    /// Run only this shard of the sweep's values, into its shard file (see [`crate::shards`]).
    pub shard: Option<Shard>,
}

/// Runs the study and writes `dir/<name>.h5`: for a single run under `<name>.h5.partial`, renamed
/// once complete; for a sweep job by job (with `resume`, only the jobs the existing file lacks).
/// Time histories go to the file block by block while each run goes. With a shard, only the
/// shard's values, into `dir/<name>.shard-I-of-N.h5`. A history block that cannot be written
/// ends the study with that error, as any other write does.
pub fn execute(
    st: &Loaded,
    dir: &Path,
    opts: Options,
    version: &str,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Outcome> {
    execute_until(st, dir, opts, version, progress, &Stop::new())
}

/// [`execute`] that ends early when `stop` is requested. A single run is then written with what
/// it recorded, marked incomplete with the time it stopped (`stopped_at`); a sweep keeps the
/// values finished before, leaves the interrupted ones not run (`/sweep/done` 0, for `resume`)
/// and starts no other. [`Outcome::interrupted`] says so.
pub fn execute_until(
    st: &Loaded,
    dir: &Path,
    opts: Options,
    version: &str,
    progress: &(dyn Fn(Progress) + Sync),
    user_stop: &Stop,
) -> Result<Outcome> {
    let start = Instant::now();
    let name = &st.spec.study.name;
    let Some(sw) = &st.spec.sweep else {
        if let Some(sh) = opts.shard {
            return Err(invalid(
                &st.path,
                "sweep",
                format!("--shard {sh}: shards split a sweep's values; this study has no [sweep]"),
            ));
        }
        progress(Progress::Start {
            total: 1,
            pending: 1,
        });
        // A run that fails keeps what it recorded, in a file marked incomplete. The time
        // histories are appended to the file while the run goes.
        let mut out = PartialFile::create(dir, name, version)?;
        let partial = out.partial().to_path_buf();
        let e = h5err(&partial);
        let history = if st.spec.analysis.samples_per_period > 0 {
            if let Err(err) = SingleHistory::create(&out.file, &st.spec.observables) {
                return Err(out.fail(err));
            }
            // On disk whole (h5::create_streamed), then the histories opened there.
            if let Err(err) = out.materialize() {
                out.discard();
                return Err(err);
            }
            match SingleHistory::open(
                &out.file,
                &st.spec.observables,
                st.spec.analysis.history_bits(),
            ) {
                Ok(h) => Some(h),
                Err(err) => return Err(out.fail(err)),
            }
        } else {
            None
        };
        // A block that cannot be written stops the run and, below, the study: it is the file
        // that failed, not the run.
        let mut write_failure = None;
        let mut append = |from: usize, time: &[f64], values: &[Vec<f64>]| -> Result<()> {
            match &history {
                Some(h) => h.append(from, time, values).map_err(|err| {
                    write_failure = Some(e(err));
                    Error::Interrupted { time: None }
                }),
                None => Ok(()),
            }
        };
        let job_start = Instant::now();
        let ran = st.run_job_partial(
            None,
            None,
            &mut throttled(0, progress),
            user_stop,
            history.is_some().then_some(&mut append as HistorySink),
        );
        let (r, failure) = match (ran, write_failure) {
            (Ok(x), None) => x,
            (_, Some(err)) | (Err(err), None) => {
                drop(history);
                out.discard();
                return Err(err);
            }
        };
        progress(Progress::Done {
            job: 0,
            ok: failure.is_none(),
        });
        let written = (|| -> hdf5::Result<()> {
            let file = &out.file;
            Root::of(st, &r.integrator, r.start, r.period)
                .write(file, u8::from(failure.is_none()))?;
            if st.spec.analysis.samples_per_period > 0 {
                mark_bits(file, st.spec.analysis.history_bits())?;
            }
            if !r.warnings.is_empty() {
                str_attr(file, "warnings", &r.warnings.join("\n"))?;
            }
            if let Some(e) = &failure {
                str_attr(file, "error", &e.to_string())?;
                if let Error::Solver(jointplay_solver::Error::Diverged { time, .. })
                | Error::Interrupted {
                    time: Some(time), ..
                } = e
                {
                    f64_attr(file, "stopped_at", *time)?;
                }
            }
            write_single(file, st, &r)
        })();
        drop(history);
        if let Err(err) = written {
            return Err(out.fail(err));
        }
        let file = out.finish()?;
        let interrupted = matches!(failure, Some(Error::Interrupted { .. }));
        return Ok(Outcome {
            file,
            jobs: 1,
            ran: 1,
            complete: !interrupted,
            interrupted,
            failed: failure.map(|e| (0, e.to_string())).into_iter().collect(),
            warnings: r.warnings,
            wall: start.elapsed().as_secs_f64(),
            rhs_evals: r.trace.stats.rhs_evals,
            busy: job_start.elapsed().as_secs_f64(),
            threads: 1,
            tables: Vec::new(),
        });
    };
    // The jobs this file holds, by their index in the whole sweep; row r of every dataset is
    // job rows[r] (the identity without a shard).
    let rows: Vec<usize> = match opts.shard {
        Some(sh) => {
            sh.check(st)?;
            sh.jobs(st.jobs.len())
        }
        None => (0..st.jobs.len()).collect(),
    };
    crate::storage::durable::create_dir(dir)?;
    let path = match opts.shard {
        Some(sh) => dir.join(sh.file_name(name)),
        None => dir.join(format!("{name}.h5")),
    };
    // Taken before anything under the file's name is touched (crate::storage::lock).
    let _lock = crate::storage::lock::Lock::acquire(&path)?;
    let n = rows.len();
    let layout = st.layout(sw)?;
    let mut warnings = Vec::new();
    let mut store = storage::open(
        &path,
        &st.text,
        opts.shard,
        &layout,
        n,
        opts.resume,
        &mut |w| warnings.push(w),
    )?;
    let journal = store.journal.path().to_path_buf();
    let pending = store.values.iter().filter(|v| v.is_none()).count();
    progress(Progress::Start { total: n, pending });
    let mut failed: Vec<(usize, String)> = Vec::new();
    let mut rhs = 0u64;
    let limit = opts.max_jobs.unwrap_or(usize::MAX);
    let mut finished = 0usize;
    let stop = AtomicBool::new(limit == 0);
    // Nanoseconds the jobs took, summed over the threads.
    let busy = AtomicU64::new(0);
    let mut threads = 1;
    // Keeps the results of jobs in rows `batch`: appended to the journal, forced to disk once for
    // all of them, and only then counted. An interrupted value is left to run again; values
    // past `max_jobs` are dropped.
    let mut keep =
        |batch: Vec<(usize, Result<JobResult>)>, store: &mut storage::Store| -> Result<()> {
            let mut counted = Vec::new();
            for (r, res) in batch {
                if finished + counted.len() >= limit {
                    break;
                }
                let j = rows[r];
                let outcome = match res {
                    Err(Error::Interrupted { .. }) => continue,
                    Ok(res) => {
                        rhs += res.trace.stats.rhs_evals;
                        counted.push((j, true));
                        Kept::Done(storage::job_row(&layout, &res))
                    }
                    Err(err) => {
                        let msg = err.to_string();
                        failed.push((j, msg.clone()));
                        counted.push((j, false));
                        Kept::Failed(msg)
                    }
                };
                store.add(crate::storage::rows::Value { row: r, outcome })?;
            }
            store.commit()?;
            for (job, ok) in counted {
                progress(Progress::Done { job, ok });
                finished += 1;
            }
            if finished >= limit {
                stop.store(true, Ordering::SeqCst);
            }
            Ok(())
        };
    if sw.continuation {
        // In order; each job starts from the previous job's final state (read back from the
        // values kept when resuming, so a resumed run continues from exactly the same state).
        // Never sharded: rows are jobs.
        let mut prev: Option<HybridState> = None;
        for j in 0..n {
            if stop.load(Ordering::SeqCst) || user_stop.requested() {
                break;
            }
            if let Some(v) = &store.values[j] {
                prev = match &v.outcome {
                    Kept::Done(row) => Some(storage::row_state(row).map_err(|m| Error::Io {
                        file: journal.clone(),
                        message: format!("value {j}: {m}"),
                    })?),
                    Kept::Failed(_) => None,
                };
                continue;
            }
            let job_start = Instant::now();
            let res = st.run_job(
                Some(st.jobs[j].0),
                prev.as_ref(),
                &mut throttled(j, progress),
                user_stop,
                None,
            );
            busy.fetch_add(job_start.elapsed().as_nanos() as u64, Ordering::Relaxed);
            prev = res.as_ref().ok().map(|r| r.trace.final_state.clone());
            keep(vec![(j, res)], &mut store)?;
        }
    } else {
        // The jobs run on the caller's rayon pool (the global one, or one it installed); a
        // thread of its own keeps each result as it comes.
        threads = rayon::current_num_threads();
        // Bounded, so that finished jobs wait for the writer instead of piling up in memory.
        let (tx, rx) = mpsc::sync_channel::<(usize, Box<Result<JobResult>>)>(2 * threads);
        // The costs of the values kept already seed the estimate.
        let known: Vec<Option<f64>> = store
            .values
            .iter()
            .map(|v| match v.as_ref().map(|v| &v.outcome) {
                Some(Kept::Done(row)) => row.f64s("wall_time").first().copied(),
                _ => None,
            })
            .collect();
        let todo: Vec<bool> = store.values.iter().map(|v| v.is_none()).collect();
        let queue = std::sync::Mutex::new(crate::schedule::Queue::new(
            rows.iter().map(|&j| st.jobs[j].0).collect(),
            &todo,
            &known,
        ));
        let busy = &busy;
        let write_err = std::thread::scope(|scope| {
            let (stop, store) = (&stop, &mut store);
            let writer = scope.spawn(move || {
                let mut write_err = None;
                while let Ok(first) = rx.recv() {
                    // The results that came meanwhile are kept together: one commit for all.
                    let mut batch = vec![(first.0, *first.1)];
                    while let Ok((r, res)) = rx.try_recv() {
                        batch.push((r, *res));
                    }
                    if write_err.is_some() || stop.load(Ordering::SeqCst) {
                        continue;
                    }
                    if let Err(err) = keep(batch, store) {
                        // Stop the other jobs: their results could not be kept.
                        stop.store(true, Ordering::SeqCst);
                        write_err = Some(err);
                    }
                }
                write_err
            });
            // Each thread takes the value the queue estimates costliest (crate::schedule).
            let queue = &queue;
            (0..threads).into_par_iter().for_each_with(tx, |tx, _| {
                loop {
                    if stop.load(Ordering::SeqCst) || user_stop.requested() {
                        return;
                    }
                    let next = queue.lock().map(|mut q| q.take_next()).unwrap_or(None);
                    let Some(r) = next else { return };
                    let j = rows[r];
                    let job_start = Instant::now();
                    let res = st.run_job(
                        Some(st.jobs[j].0),
                        None,
                        &mut throttled(j, progress),
                        user_stop,
                        None,
                    );
                    let took = job_start.elapsed();
                    busy.fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
                    // A failed or interrupted run's time says little about the value's cost.
                    if res.is_ok()
                        && let Ok(mut q) = queue.lock()
                    {
                        q.finished(r, took.as_secs_f64());
                    }
                    // The writer lives until every sender is gone.
                    let _ = tx.send((r, Box::new(res)));
                }
            });
            writer.join()
        });
        match write_err {
            Ok(None) => {}
            Ok(Some(err)) => return Err(err),
            Err(_) => {
                return Err(Error::Io {
                    file: journal.clone(),
                    message: "the thread keeping the sweep's results stopped unexpectedly".into(),
                });
            }
        }
    }
    // The file, written from the values kept; a complete one ends the journal.
    let wall = start.elapsed().as_secs_f64();
    let jobs: Vec<(f64, i8)> = rows.iter().map(|&j| st.jobs[j]).collect();
    let shard = opts.shard.map(|sh| (sh, rows.as_slice()));
    let complete = storage::write_file(&path, &layout, version, &jobs, shard, &store.values, wall)?;
    if complete {
        drop(store);
        crate::storage::durable::remove(&journal)?;
    }
    // A shard's rows are part of a sweep: its table comes with the merge.
    let tables = if opts.shard.is_none() {
        crate::sweep_table::write_beside(&path)?
    } else {
        Vec::new()
    };
    Ok(Outcome {
        file: path.clone(),
        jobs: n,
        ran: finished,
        complete,
        interrupted: user_stop.requested() && !complete,
        failed,
        warnings,
        wall,
        rhs_evals: rhs,
        busy: busy.load(Ordering::Relaxed) as f64 * 1e-9,
        threads,
        tables,
    })
}

/// The root attributes of an analysis file besides `program`, `program_version`, `units` and
/// `complete`: what a merge checks to be the same in every shard and writes once.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Root {
    pub study_name: String,
    pub study_file: String,
    pub study: String,
    pub description: String,
    pub flow: String,
    pub flow_text: String,
    pub integrator: String,
    pub start_time: f64,
    pub period: f64,
    pub phase: f64,
    pub periods: u64,
    pub transient: u64,
    pub samples_per_period: u64,
    pub history_periods: u64,
}

impl Root {
    fn of(st: &Loaded, integrator: &str, start: f64, period: f64) -> Root {
        let a = &st.spec.analysis;
        let flow = match &st.base {
            Base::Scene { path, .. } => format!("scene {}", path.display()),
            Base::System(_) => "system".to_string(),
        };
        Root {
            study_name: st.spec.study.name.clone(),
            study_file: st.path.display().to_string(),
            study: st.text.clone(),
            description: st.spec.study.description.clone(),
            flow,
            flow_text: st.base_text(),
            integrator: integrator.to_string(),
            start_time: start,
            period,
            phase: a.phase,
            periods: a.periods as u64,
            transient: a.transient as u64,
            samples_per_period: a.samples_per_period as u64,
            history_periods: a.history_periods.unwrap_or(a.periods - a.transient) as u64,
        }
    }

    /// Writes the attributes, with `kind` and `complete`.
    fn write(&self, file: &hdf5::File, complete: u8) -> hdf5::Result<()> {
        str_attr(file, "kind", "analysis")?;
        str_attr(file, "study_name", &self.study_name)?;
        str_attr(file, "study_file", &self.study_file)?;
        str_attr(file, "study", &self.study)?;
        str_attr(file, "description", &self.description)?;
        str_attr(file, "flow", &self.flow)?;
        str_attr(file, "flow_text", &self.flow_text)?;
        str_attr(file, "integrator", &self.integrator)?;
        f64_attr(file, "start_time", self.start_time)?;
        f64_attr(file, "period", self.period)?;
        f64_attr(file, "phase", self.phase)?;
        u64_attr(file, "periods", self.periods)?;
        u64_attr(file, "transient", self.transient)?;
        u64_attr(file, "samples_per_period", self.samples_per_period)?;
        u64_attr(file, "history_periods", self.history_periods)?;
        u8_attr_set(file, "complete", complete)
    }

    /// Reads what [`Root::write`] wrote.
    pub(crate) fn read(file: &hdf5::File) -> hdf5::Result<Root> {
        let s = |n: &str| read_str(file, n);
        let f = |n: &str| read_attr::<f64>(file, n);
        let u = |n: &str| read_attr::<u64>(file, n);
        Ok(Root {
            study_name: s("study_name")?,
            study_file: s("study_file")?,
            study: s("study")?,
            description: s("description")?,
            flow: s("flow")?,
            flow_text: s("flow_text")?,
            integrator: s("integrator")?,
            start_time: f("start_time")?,
            period: f("period")?,
            phase: f("phase")?,
            periods: u("periods")?,
            transient: u("transient")?,
            samples_per_period: u("samples_per_period")?,
            history_periods: u("history_periods")?,
        })
    }

    /// The names of the attributes whose values differ between `self` and `other`.
    pub(crate) fn differences(&self, other: &Root) -> Vec<&'static str> {
        let strings = [
            ("study_name", &self.study_name, &other.study_name),
            ("study_file", &self.study_file, &other.study_file),
            ("study", &self.study, &other.study),
            ("description", &self.description, &other.description),
            ("flow", &self.flow, &other.flow),
            ("flow_text", &self.flow_text, &other.flow_text),
            ("integrator", &self.integrator, &other.integrator),
        ];
        let floats = [
            ("start_time", self.start_time, other.start_time),
            ("period", self.period, other.period),
            ("phase", self.phase, other.phase),
        ];
        let counts = [
            ("periods", self.periods, other.periods),
            ("transient", self.transient, other.transient),
            (
                "samples_per_period",
                self.samples_per_period,
                other.samples_per_period,
            ),
            (
                "history_periods",
                self.history_periods,
                other.history_periods,
            ),
        ];
        strings
            .iter()
            .filter(|(_, a, b)| a != b)
            .map(|(n, ..)| *n)
            .chain(
                floats
                    .iter()
                    .filter(|(_, a, b)| a.to_bits() != b.to_bits())
                    .map(|(n, ..)| *n),
            )
            .chain(counts.iter().filter(|(_, a, b)| a != b).map(|(n, ..)| *n))
            .collect()
    }
}

/// Everything that fixes the datasets of a sweep file apart from its jobs: its root attributes,
/// the observables with their units, the sections and the sizes of the rows. Taken from the
/// study for a run, read back from a shard for a merge, so both write the same file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SweepLayout {
    pub root: Root,
    /// Observable names and paths, and their units.
    pub observables: Vec<ObservableSpec>,
    pub units: Vec<String>,
    /// Names of the hyperplane sections.
    pub sections: Vec<String>,
    /// The swept parameter's path and unit, and whether the sweep is a continuation.
    pub parameter: String,
    pub unit: String,
    pub continuation: bool,
    /// Strobe points and history samples per job.
    pub kept: usize,
    pub history: usize,
    pub shape: hybrid::StateShape,
    /// The chaos measures each value stores.
    pub chaos: crate::chaos::ChaosSpec,
    /// [`AnalysisSpec::history_bits`].
    pub bits: Option<u32>,
}

impl SweepLayout {
    /// The layout of the sweep file `file`, whose study text parses to `spec`.
    pub(crate) fn read(file: &hdf5::File, spec: &AnalysisStudy) -> hdf5::Result<SweepLayout> {
        let root = Root::read(file)?;
        let sw = spec
            .sweep
            .as_ref()
            .ok_or_else(|| hdf5::Error::from("its study text has no [sweep]"))?;
        let g = file.group("sweep")?;
        let cols = |g: &hdf5::Group, name: &str| -> hdf5::Result<usize> {
            Ok(g.dataset(name)?.shape().get(1).copied().unwrap_or(0))
        };
        let units = spec
            .observables
            .iter()
            .map(|o| {
                let ds = g.dataset(&o.name)?;
                read_str(&ds, "unit")
            })
            .collect::<hdf5::Result<Vec<_>>>()?;
        let history = match g.group("history") {
            Ok(h) => cols(&h, "time")?,
            Err(_) => 0,
        };
        Ok(SweepLayout {
            root,
            observables: spec.observables.clone(),
            units,
            sections: spec.sections.iter().map(|s| s.name.clone()).collect(),
            parameter: sw.parameter.clone(),
            unit: sw.unit.clone(),
            continuation: sw.continuation,
            kept: cols(&g, "strobe_time")?,
            history,
            shape: hybrid::StateShape {
                dim: cols(&g, "final_state")?,
                contacts: cols(&g, "final_onset")?,
                clearances: cols(&g, "final_warned")?,
            },
            chaos: crate::chaos::ChaosSpec {
                lyapunov: spec.lyapunov.clone(),
                zero_one: spec.zero_one.clone(),
            },
            bits: spec.analysis.history_bits(),
        })
    }
}

impl Loaded {
    /// The layout of this study's sweep file, from a probe of job 0 (its flow is built, not run).
    fn layout(&self, sw: &SweepSpec) -> Result<SweepLayout> {
        let target = self.target(Some(self.jobs[0].0))?;
        let flow = target.flow();
        // The memory of a new run has the sizes of the flow's memory (contacts, clearance joints).
        let mut memory = HybridState::default();
        flow.save_memory(&mut memory);
        let (method, period, start) = (flow.method(), flow.period(), flow.start_time());
        let plan = self.plan(method, start, period);
        Ok(SweepLayout {
            root: Root::of(self, &method.describe(), start, period),
            observables: self.spec.observables.clone(),
            units: flow.observable_units(),
            sections: self.planes.iter().map(|p| p.name.clone()).collect(),
            parameter: sw.parameter.clone(),
            unit: sw.unit.clone(),
            continuation: sw.continuation,
            kept: plan.kept(),
            history: plan.history_len(),
            shape: hybrid::StateShape {
                dim: flow.dim(),
                contacts: memory.onset.len(),
                clearances: memory.warned.len(),
            },
            chaos: self.chaos_spec(),
            bits: self.spec.analysis.history_bits(),
        })
    }
}

fn obs_datasets(
    g: &hdf5::Group,
    observables: &[ObservableSpec],
    units: &[String],
    values: &[Vec<f64>],
    what: &str,
) -> hdf5::Result<()> {
    for ((o, u), v) in observables.iter().zip(units).zip(values) {
        write1(g, &o.name, v, u, &format!("{} {what}", o.path))?;
        {
            let ds = g.dataset(&o.name)?;
            str_attr(&ds, "path", &o.path)?;
        }
    }
    Ok(())
}

/// Writes one hyperplane section's crossings (times and observables) into a new group `name`.
pub(crate) fn write_crossings(
    g: &hdf5::Group,
    name: &str,
    observables: &[ObservableSpec],
    units: &[String],
    time: &[f64],
    values: &[Vec<f64>],
) -> hdf5::Result<()> {
    let gp = g.create_group(name)?;
    write1(&gp, "time", time, "s", "crossing times")?;
    obs_datasets(&gp, observables, units, values, "at the crossings")
}

/// The time histories of a single run's file, `/history/time` and `/history/<observable>`:
/// extendable, appended block by block while the run goes, described by [`write_single`] once it
/// is over (the units are the flow's).
struct SingleHistory {
    time: hdf5::Dataset,
    values: Vec<hdf5::Dataset>,
    /// [`AnalysisSpec::history_bits`].
    bits: Option<u32>,
}

impl SingleHistory {
    /// Creates the empty histories in `file` (in memory: see h5::create_streamed); they are
    /// written through [`SingleHistory::open`] once the file is on disk.
    fn create(file: &hdf5::File, observables: &[ObservableSpec]) -> hdf5::Result<()> {
        let g = file.create_group("history")?;
        // One chunk per block, written whole.
        let create = |name: &str| create_extendable::<f64>(&g, name, 1, true, HISTORY_BLOCK);
        create("time")?;
        for o in observables {
            create(&o.name)?;
        }
        Ok(())
    }

    /// The histories [`SingleHistory::create`] made in `file`, opened again (after the file was
    /// moved from memory to disk).
    fn open(
        file: &hdf5::File,
        observables: &[ObservableSpec],
        bits: Option<u32>,
    ) -> hdf5::Result<SingleHistory> {
        let g = file.group("history")?;
        Ok(SingleHistory {
            time: g.dataset("time")?,
            values: observables
                .iter()
                .map(|o| g.dataset(&o.name))
                .collect::<hdf5::Result<_>>()?,
            bits,
        })
    }

    /// Appends the samples `from..` of a block. A block that starts a chunk (every block but
    /// after a short one) has its chunks compressed by [`crate::chunk`], by the threads of
    /// rayon's pool: the run waits for its block to be written, so the other core is free.
    fn append(&self, from: usize, time: &[f64], values: &[Vec<f64>]) -> hdf5::Result<()> {
        let n = time.len();
        if from.is_multiple_of(HISTORY_BLOCK) {
            use crate::chunk::{Rows, Store};
            let row = |ds, values, store| Rows {
                ds,
                values,
                width: 1,
                chunk_rows: HISTORY_BLOCK,
                store,
            };
            let rows: Vec<_> = std::iter::once(row(&self.time, time, Store::F64(None)))
                .chain(
                    self.values
                        .iter()
                        .zip(values)
                        .map(|(ds, v)| row(ds, &v[..], Store::F64(self.bits))),
                )
                .collect();
            crate::chunk::append_all(&rows, from, true)?;
        } else {
            append(&self.time, from, n, 1, true, time.to_vec())?;
            for (ds, v) in self.values.iter().zip(values) {
                let v = crate::bitround::rounded(v, self.bits).into_owned();
                append(ds, from, n, 1, true, v)?;
            }
        }
        // Not flushed: see h5::create_streamed.
        Ok(())
    }
}

fn write_single(file: &hdf5::File, st: &Loaded, r: &JobResult) -> hdf5::Result<()> {
    let t = &r.trace;
    let obs = &st.spec.observables;
    u64_attr(file, "rhs_evals", t.stats.rhs_evals)?;
    u64_attr(file, "accepted_steps", t.stats.accepted)?;
    f64_attr(file, "wall_time", r.wall)?;
    if st.spec.analysis.samples_per_period > 0 {
        // Written while the run went (SingleHistory).
        let g = file.group("history")?;
        describe(
            &g.dataset("time")?,
            Some("s"),
            "sample times over the kept window",
        )?;
        for (o, u) in obs.iter().zip(&r.units) {
            let ds = g.dataset(&o.name)?;
            describe(&ds, Some(u), &format!("{} over the kept window", o.path))?;
            str_attr(&ds, "path", &o.path)?;
            mark_bits(&ds, st.spec.analysis.history_bits())?;
        }
    }
    let g = file.create_group("sections")?;
    let s0 = g.create_group("strobe")?;
    write1(
        &s0,
        "time",
        &t.strobe_time,
        "s",
        "t0 + phase + k T, one per kept period",
    )?;
    obs_datasets(&s0, obs, &r.units, &t.strobe, "at the strobe times")?;
    for (p, c) in st.planes.iter().zip(&t.crossings) {
        write_crossings(&g, &p.name, obs, &r.units, &c.time, &c.values)?;
    }
    if let Some(c) = &r.chaos {
        crate::chaos::write_single(file, c)?;
    }
    hybrid::write_state(file, &t.final_state)
}

/// Creates the sweep file `path` of `layout`, in memory ([`crate::h5::create_in_memory`]), with one row per job of `jobs` (parameter value
/// and direction), every row not done. A shard file also records its shard (root attributes
/// `shard` and `shards`) and the index of each row's job in the whole sweep (`/sweep/job`).
pub(crate) fn create_sweep_file(
    path: &Path,
    layout: &SweepLayout,
    version: &str,
    jobs: &[(f64, i8)],
    shard: Option<(Shard, &[usize])>,
) -> Result<hdf5::File> {
    let e = h5err(path);
    let l = layout;
    let n = jobs.len();
    let (kept, hl) = (l.kept, l.history);
    let file = crate::h5::create_in_memory(path).map_err(&e)?;
    (|| -> hdf5::Result<()> {
        str_attr(&file, "program", "jointplay")?;
        str_attr(&file, "program_version", version)?;
        str_attr(&file, "units", "SI: m, kg, s, rad, N, N m, J")?;
        l.root.write(&file, 0)?;
        if hl > 0 {
            mark_bits(&file, l.bits)?;
        }
        let g = file.create_group("sweep")?;
        let params: Vec<f64> = jobs.iter().map(|j| j.0).collect();
        write1(
            &g,
            "parameter",
            &params,
            &l.unit,
            "swept parameter value of each job",
        )?;
        {
            let ds = g.dataset("parameter")?;
            str_attr(&ds, "path", &l.parameter)?;
        }
        let dirs: Vec<i8> = jobs.iter().map(|j| j.1).collect();
        write_column(
            &g,
            "direction",
            &dirs,
            None,
            "+1: up the list, -1: back down (continuation)",
        )?;
        write_column(
            &g,
            "done",
            &vec![0u8; n],
            None,
            "0 not run, 1 done, 2 failed (message in /sweep/errors)",
        )?;
        g.create_group("errors")?;
        let d = g.new_dataset::<u32>().shape(n).create("checksum")?;
        str_attr(
            &d,
            "description",
            "CRC-32 of each done value's row data (its rows of every dataset here and its section crossings), by which resume and merge check it; 0 for a value not done",
        )?;
        str_attr(&d, "unit", "1")?;
        u8_attr_set(&g, "continuation", u8::from(l.continuation))?;
        create_nan(&g, "strobe_time", &[n, kept], "s", "strobe times of each job")?;
        for (o, u) in l.observables.iter().zip(&l.units) {
            create_nan(
                &g,
                &o.name,
                &[n, kept],
                u,
                &format!("{} at the strobe times, per job", o.path),
            )?;
            {
                let ds = g.dataset(&o.name)?;
                str_attr(&ds, "path", &o.path)?;
            }
        }
        if hl > 0 {
            let h = g.create_group("history")?;
            // Chunks of one block of a row: each job writes its histories block by block.
            create_nan_chunked(
                &h,
                "time",
                &[n, hl],
                HISTORY_BLOCK,
                "s",
                "sample times over the kept window, per job",
            )?;
            for (o, u) in l.observables.iter().zip(&l.units) {
                create_nan_chunked(
                    &h,
                    &o.name,
                    &[n, hl],
                    HISTORY_BLOCK,
                    u,
                    &format!("{} over the kept window, per job", o.path),
                )?;
                let ds = h.dataset(&o.name)?;
                mark_bits(&ds, l.bits)?;
            }
        }
        hybrid::create_rows(&g, n, l.shape)?;
        let d = g.new_dataset::<u64>().shape(n).create("rhs_evals")?;
        str_attr(
            &d,
            "description",
            "right-hand-side evaluations of each job's analysis run (a Lyapunov run's are counted in its chaos attributes)",
        )?;
        str_attr(&d, "unit", "1")?;
        create_nan(
            &g,
            "wall_time",
            &[n],
            "s",
            "wall-clock time of each job (machine-dependent, the only dataset that is not reproducible)",
        )?;
        if !l.sections.is_empty() {
            g.create_group("sections")?;
        }
        if l.chaos.any() {
            crate::chaos::create_rows(&g, n, &l.chaos)?;
        }
        if let Some((sh, rows)) = shard {
            u64_attr(&file, "shard", sh.index as u64)?;
            u64_attr(&file, "shards", sh.count as u64)?;
            let rows: Vec<u64> = rows.iter().map(|&j| j as u64).collect();
            write_column(
                &g,
                "job",
                &rows,
                Some("1"),
                "index of each row's job in the whole sweep (shard files only)",
            )?;
        }
        Ok(())
    })()
    .map_err(&e)?;
    file.flush().map_err(&e)?;
    Ok(file)
}
