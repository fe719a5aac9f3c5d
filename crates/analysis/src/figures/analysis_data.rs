//! An analysis file read back for its figures ([`read`]): the study parsed from the file, and
//! what [`crate::storage::analysis_read`] reads of it, each sweep value labelled for its panel.

use std::collections::BTreeMap;
use std::path::Path;

use crate::Result;
use crate::measures::indicator::Row;
pub use crate::storage::analysis_read::FIGURE_HISTORY;
use crate::storage::analysis_read::{ContData, Convergence, Recorded};
use crate::study::analysis::spec::AnalysisStudy;

/// The recorded data of one run (or one sweep job).
#[derive(Debug, Clone, Default)]
pub(super) struct Job {
    /// Panel title suffix, e.g. "gamma = 0.28".
    pub(super) label: String,
    pub(super) parameter: f64,
    pub(super) up: bool,
    pub(super) history_time: Vec<f64>,
    pub(super) history: BTreeMap<String, Vec<f64>>,
    /// Section name ("strobe" or a hyperplane) to observable to points.
    pub(super) sections: BTreeMap<String, BTreeMap<String, Vec<f64>>>,
    /// Hyperplane section name to its crossing times (s).
    pub(super) crossing_times: BTreeMap<String, Vec<f64>>,
}

pub(super) struct Data {
    pub(super) spec: AnalysisStudy,
    pub(super) name: String,
    pub(super) units: BTreeMap<String, String>,
    pub(super) sweep: Option<(String, String)>,
    pub(super) jobs: Vec<Job>,
    /// Per done sweep value: parameter, lambda_1, its standard error and the two-trajectory
    /// estimate (NaN where not computed).
    pub(super) chaos: Vec<[f64; 4]>,
    /// Each chaos indicator the sweep computed (crate::measures::registry), with its parameter
    /// and number per done value.
    pub(super) numbers: Vec<(Row, Vec<[f64; 2]>)>,
    /// A single run's running Lyapunov estimates: times, one row per time, and the
    /// two-trajectory estimate.
    pub(super) convergence: Option<Convergence>,
    /// The branches of periodic orbits, when the study followed them.
    pub(super) continuation: Option<ContData>,
    /// The integrator's relative and absolute tolerances; `None` for a fixed step.
    pub(super) tolerances: Option<(f64, f64)>,
}

/// Reads the analysis file `path` for its figures: the study, then a sweep's values or a single
/// run, then the continuation when the study followed one.
pub(super) fn read(path: &Path) -> Result<Data> {
    let opened = crate::storage::analysis_read::open(path)?;
    let spec = AnalysisStudy::parse_spec(&opened.study, path)?;
    let observables: Vec<&str> = spec.observables.iter().map(|o| o.name.as_str()).collect();
    let sections: Vec<&str> = spec.sections.iter().map(|s| s.name.as_str()).collect();
    let Recorded {
        units,
        sweep,
        jobs,
        chaos,
        numbers,
        convergence,
        continuation,
        tolerances,
    } = opened.read(&observables, &sections)?;
    let jobs = jobs
        .into_iter()
        .map(|j| Job {
            label: sweep.as_ref().map_or_else(String::new, |s| {
                value_label(&s.path, &s.unit, &s.values, j.parameter, j.up)
            }),
            parameter: j.parameter,
            up: j.up,
            history_time: j.history_time,
            history: j.history,
            sections: j.sections,
            crossing_times: j.crossing_times,
        })
        .collect();
    Ok(Data {
        spec,
        name: opened.name,
        units,
        sweep: sweep.map(|s| (s.path, s.unit)),
        jobs,
        chaos,
        numbers,
        convergence,
        continuation,
        tolerances,
    })
}

/// A sweep value's panel title suffix, e.g. "gamma = 0.28": the parameter `p` of the sweep
/// `params` in the unit its axis is drawn in, marked on the way down (not `up`).
fn value_label(pname: &str, punit: &str, params: &[f64], p: f64, up: bool) -> String {
    format!(
        "{} = {}{}",
        short(pname),
        // In the unit the parameter axis is drawn in (mm for a clearance).
        match display_scale(punit, params.iter().copied()) {
            Some((k, u)) => format!("{} {u}", crate::study::report::num(p * k)),
            None if punit.is_empty() => crate::study::report::num(p),
            None => format!("{} {punit}", crate::study::report::num(p)),
        },
        if up { "" } else { " (down)" }
    )
}

/// Last segment of a parameter path that is not a wildcard or a number.
pub(super) fn short(path: &str) -> &str {
    path.rsplit('.').next().unwrap_or(path)
}

/// Lengths recorded in metres that all stay below 0.1 m (clearances, eccentricities, offsets)
/// are drawn in millimetres, as the literature's figures draw them: the factor and the unit, or
/// None to draw the values as recorded.
pub fn display_scale(
    unit: &str,
    vals: impl IntoIterator<Item = f64>,
) -> Option<(f64, &'static str)> {
    if unit != "m" {
        return None;
    }
    let mut any = false;
    for v in vals.into_iter().filter(|v| v.is_finite()) {
        if v.abs() >= 0.1 {
            return None;
        }
        any = true;
    }
    any.then_some((1e3, "mm"))
}
