//! An analysis study file as data: its tables, deserialised with unknown fields refused, and
//! the values of its sweep (`sweep_jobs`). Checks that need the scene are in
//! [`crate::study::analysis::load`].

use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use toml::{Table, Value};

use crate::Result;
use crate::flow::observe::ObservableSpec;
use crate::flow::systems::SystemSpec;
use crate::measures::sections::Direction;
use crate::storage::analysis_file::Declared;
use crate::study::spec::invalid;

crate::measures::registry::with_indicator_tables! {
/// A nonlinear-analysis study file. The tables of the chaos indicators (`[zero_one]`, ...) are
/// fields too, one per indicator of `crate::measures::registry` (`asked` lists those given).
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
    /// Work-precision settings, read by `jointplay precision` (see [`crate::study::precision`]).
    #[serde(default)]
    pub precision: Option<crate::study::precision::spec::PrecisionSpec>,
    /// Lyapunov exponents of the run or of every sweep value (see [`crate::measures::chaos`]).
    #[serde(default)]
    pub lyapunov: Option<crate::measures::lyapunov::LyapunovSpec>,
    /// Periodic orbits followed in a parameter (see [`crate::study::continuation`]).
    #[serde(default)]
    pub continuation: Option<crate::study::continuation::spec::ContinuationSpec>,
}
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
    /// ... or a built-in system (see [`crate::flow::systems`]).
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
    /// [`crate::storage::bitround`]); default every bit. The sample times, strobe points, crossings and
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
    /// Section for `poincare` and `bifurcation` (default the stroboscopic one); for `time`, a
    /// hyperplane section whose crossings are marked on the history.
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

/// True when the study text is a nonlinear-analysis study (has an `[analysis]` table).
pub fn is_analysis(text: &str) -> bool {
    text.parse::<Table>()
        .map(|t| t.contains_key("study") && t.contains_key("analysis"))
        .unwrap_or(false)
}

pub(crate) const RESERVED: [&str; 12] = [
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

pub(crate) fn check_name(file: &Path, field: &str, name: &str) -> Result<()> {
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

pub(crate) fn finite(file: &Path, field: &str, v: f64) -> Result<()> {
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
impl AnalysisStudy {
    /// What this study (read from `path`) declares of its sweep file's layout: its
    /// observables, sections, swept parameter, chaos measures and history rounding.
    pub(crate) fn declared(&self, path: &Path) -> Result<Declared> {
        let spec = self;
        let sw = spec
            .sweep
            .as_ref()
            .ok_or_else(|| invalid(path, "sweep", "its study text has no [sweep]"))?;
        Ok(Declared {
            observables: spec.observables.clone(),
            sections: spec.sections.iter().map(|s| s.name.clone()).collect(),
            parameter: sw.parameter.clone(),
            unit: sw.unit.clone(),
            continuation: sw.continuation,
            chaos: crate::measures::chaos::ChaosSpec {
                lyapunov: spec.lyapunov.clone(),
                indicators: spec.asked(),
            },
            bits: spec.analysis.history_bits(),
        })
    }
}
impl AnalysisStudy {
    /// Checks `figures[i]` of the study read from `path`, whose sweep has the values `jobs`: its
    /// picked sweep values, circle and scale, its observables, and
    /// what its kind needs (x, a [continuation], a [sweep], a section of this study).
    pub(crate) fn check_figure(
        &self,
        path: &Path,
        jobs: &[(f64, i8)],
        i: usize,
        f: &FigureSpec,
    ) -> Result<()> {
        self.check_figure_values(path, jobs, i, f)?;
        if let Some(c) = f.circle {
            finite(path, &format!("figures[{i}].circle"), c)?;
        }
        if let Some(sc) = f.scale
            && !(sc.is_finite() && sc != 0.0)
        {
            return Err(invalid(
                path,
                format!("figures[{i}].scale"),
                format!("{sc}: must be a finite, non-zero factor"),
            ));
        }
        for (what, name) in [("x", f.x.as_deref()), ("y", Some(f.y.as_str()))] {
            if let Some(n) = name
                && self.observable(n).is_none()
            {
                return Err(invalid(
                    path,
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
                path,
                format!("figures[{i}].x"),
                "this kind needs x",
            ));
        }
        if f.kind == FigureKind::Branches && self.continuation.is_none() {
            return Err(invalid(
                path,
                format!("figures[{i}].kind"),
                "a branches figure needs a [continuation]",
            ));
        }
        if f.kind == FigureKind::Bifurcation && self.sweep.is_none() {
            return Err(invalid(
                path,
                format!("figures[{i}].kind"),
                "a bifurcation diagram needs a [sweep]",
            ));
        }
        if f.kind == FigureKind::Time && f.section.as_deref() == Some("strobe") {
            return Err(invalid(
                path,
                format!("figures[{i}].section"),
                "a time history marks the crossings of a hyperplane section ([[sections]]); \
                 the stroboscopic points are drawn by phase and poincare figures",
            ));
        }
        if let Some(s) = &f.section
            && !self.sections.iter().any(|p| &p.name == s)
            && s != "strobe"
        {
            return Err(invalid(
                path,
                format!("figures[{i}].section"),
                format!("no section '{s}'"),
            ));
        }
        Ok(())
    }

    /// Checks the sweep values `figures[i]` picks: each finite, in a study with a sweep, and a
    /// value of it.
    fn check_figure_values(
        &self,
        path: &Path,
        jobs: &[(f64, i8)],
        i: usize,
        f: &FigureSpec,
    ) -> Result<()> {
        for (k, &v) in f.values.iter().enumerate() {
            finite(path, &format!("figures[{i}].values[{k}]"), v)?;
            // A panel is drawn for each value the sweep has: one it lacks would be left out
            // without a word.
            if self.sweep.is_none() {
                return Err(invalid(
                    path,
                    format!("figures[{i}].values"),
                    "the study has no [sweep] whose values it could pick",
                ));
            }
            if !jobs
                .iter()
                .any(|j| (j.0 - v).abs() <= 1e-9 * v.abs().max(1e-300))
            {
                let shown: Vec<String> = jobs.iter().take(8).map(|j| j.0.to_string()).collect();
                return Err(invalid(
                    path,
                    format!("figures[{i}].values[{k}]"),
                    format!(
                        "{v} is not a value of the sweep ({}{})",
                        shown.join(", "),
                        if jobs.len() > 8 { ", ..." } else { "" }
                    ),
                ));
            }
        }
        Ok(())
    }
}
