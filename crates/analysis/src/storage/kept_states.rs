//! The hybrid states an analysis file keeps, read back so that a motion can be run again from
//! them (`jointplay animate --value`, `--orbit`): the state at the end of each sweep value's run
//! (`/sweep/final_*`, a row per value), and the strobe point of each periodic orbit of a
//! continuation (`/continuation/branch_<i>/state` and `onset`, with the branch's `strobe_time`
//! and `period`).

use std::path::{Path, PathBuf};

use jointplay_solver::state::HybridState;

use crate::storage::h5::{h5err, read_attr, read_rows, read_str};
use crate::{Error, Result};

/// A kept state and where it comes from.
#[derive(Debug, Clone)]
pub struct Kept {
    /// The study text and file the analysis file was written from.
    pub study: String,
    pub study_file: PathBuf,
    /// The flow the study ran (`flow_text`: its scene after the study's edits).
    pub flow_text: String,
    /// The parameter's value at the state.
    pub value: f64,
    pub state: HybridState,
    /// A periodic orbit's period (s, k drive periods); `None` for a sweep value's end state.
    pub period: Option<f64>,
    /// What the state is, for titles ("sweep value 0.0003", "branch 0, point 4").
    pub label: String,
}

fn invalid(path: &Path, message: String) -> Error {
    Error::Io {
        file: path.to_path_buf(),
        message,
    }
}

/// Opens an analysis file, or says which command fits the file it is.
fn open(path: &Path) -> Result<(hdf5::File, String, PathBuf, String)> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    if read_str(&file, "kind").unwrap_or_default() != "analysis" {
        return Err(invalid(
            path,
            "--value and --orbit take an analysis study's file (`jointplay run ANALYSIS` writes \
             one); a run's file is animated without them, a comparison study's with --case"
                .into(),
        ));
    }
    let study = read_str(&file, "study").map_err(&e)?;
    let study_file = PathBuf::from(read_str(&file, "study_file").map_err(&e)?);
    let flow_text = read_str(&file, "flow_text").map_err(&e)?;
    Ok((file, study, study_file, flow_text))
}

/// The end state of the done sweep value nearest `value` (within 1e-9 of the values' span, or
/// an error listing the done values).
pub fn sweep_value(path: &Path, value: f64) -> Result<Kept> {
    let e = h5err(path);
    let (file, study, study_file, flow_text) = open(path)?;
    let Ok(g) = file.group("sweep") else {
        return Err(invalid(
            path,
            "the study has no sweep: animate a periodic orbit with --orbit, or run its scene"
                .into(),
        ));
    };
    let values: Vec<f64> = g
        .dataset("parameter")
        .and_then(|d| d.read_raw())
        .map_err(&e)?;
    let done: Vec<u8> = g.dataset("done").and_then(|d| d.read_raw()).map_err(&e)?;
    let span = values
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let done_values: Vec<String> = values
        .iter()
        .zip(&done)
        .filter(|(_, d)| **d == 1)
        .map(|(v, _)| format!("{v}"))
        .collect();
    let Some(j) = (0..values.len())
        .filter(|&j| done.get(j) == Some(&1) && (values[j] - value).abs() <= 1e-9 * span)
        .min_by(|&a, &b| {
            (values[a] - value)
                .abs()
                .total_cmp(&(values[b] - value).abs())
        })
    else {
        return Err(invalid(
            path,
            format!(
                "no done sweep value {value}; the done values: {}",
                if done_values.is_empty() {
                    "none".into()
                } else {
                    done_values.join(", ")
                }
            ),
        ));
    };
    let state = crate::storage::hybrid::read_row(&g, j).map_err(&e)?;
    Ok(Kept {
        study,
        study_file,
        flow_text,
        value: values[j],
        state,
        period: None,
        label: format!("sweep value {}", values[j]),
    })
}

/// The strobe point of point `point` of branch `branch` of the file's continuation.
pub fn orbit(path: &Path, branch: usize, point: usize) -> Result<Kept> {
    let e = h5err(path);
    let (file, study, study_file, flow_text) = open(path)?;
    let Ok(c) = file.group("continuation") else {
        return Err(invalid(
            path,
            "the study followed no periodic orbits (no /continuation): animate a sweep value \
             with --value"
                .into(),
        ));
    };
    let branches: usize = read_attr::<u64>(&c, "branches").map_err(&e)? as usize;
    let sizes: Vec<String> = (0..branches)
        .map(|b| {
            c.dataset(&format!("branch_{b}/parameter"))
                .map(|d| format!("branch {b}: {} points", d.size()))
                .unwrap_or_else(|_| format!("branch {b}: none"))
        })
        .collect();
    let choices = || format!("the continuation's branches: {}", sizes.join("; "));
    let Ok(g) = c.group(&format!("branch_{branch}")) else {
        return Err(invalid(path, format!("no branch {branch}; {}", choices())));
    };
    let parameter: Vec<f64> = g
        .dataset("parameter")
        .and_then(|d| d.read_raw())
        .map_err(&e)?;
    if point >= parameter.len() {
        return Err(invalid(
            path,
            format!("branch {branch} has no point {point}; {}", choices()),
        ));
    }
    let states = read_rows(&g, "state").map_err(&e)?;
    let onsets = if g.link_exists("onset") {
        read_rows(&g, "onset").map_err(&e)?
    } else {
        Vec::new()
    };
    let (Some(y), onset) = (states.get(point), onsets.get(point).cloned()) else {
        return Err(invalid(
            path,
            format!("branch {branch}: its state has no row {point} (a damaged file)"),
        ));
    };
    let t: f64 = read_attr(&g, "strobe_time").map_err(&e)?;
    let period: f64 = read_attr(&g, "period").map_err(&e)?;
    if !(t.is_finite() && period.is_finite() && period > 0.0) {
        return Err(invalid(
            path,
            format!("branch {branch}: strobe_time {t} s, period {period} s (a damaged file)"),
        ));
    }
    let mut state = HybridState::new(t, y.clone());
    state.onset = onset.unwrap_or_default();
    Ok(Kept {
        study,
        study_file,
        flow_text,
        value: parameter[point],
        state,
        period: Some(period),
        label: format!("periodic orbit, branch {branch}, point {point}"),
    })
}
