//! The work-precision figure (see [`crate::study::precision`]).

use std::path::{Path, PathBuf};

use crate::figures::plot::{Format, Panel, Series, figure};
use crate::storage::precision_file::{Errors, Outcome};
use crate::{Error, Result};

/// Reads one error measure.
type Measure = fn(&Errors) -> f64;

/// The work-precision figure of `o` as `<stem>.<format>`: each error measure against wall time,
/// log-log, one line per integrator family, the floor as a horizontal line.
pub fn draw(o: &Outcome, stem: &Path, formats: &[Format]) -> Result<Vec<PathBuf>> {
    let mut families: Vec<&str> = Vec::new();
    for r in &o.runs {
        if !families.contains(&r.family.as_str()) {
            families.push(&r.family);
        }
    }
    let measures: [(&str, String, Measure); 4] = [
        (
            "Position at the strobe times",
            format!("largest error ({})", o.position_unit),
            |e| e.position,
        ),
        (
            "One period from reference states",
            format!("largest error ({})", o.position_unit),
            |e| e.restart,
        ),
        (
            "Contact force over the last period",
            "largest error / peak force".into(),
            |e| e.force,
        ),
        (
            "Contact force, periods from reference states",
            "largest error / peak force".into(),
            |e| e.restart_force,
        ),
    ];
    let mut panels = Vec::new();
    for (title, ylabel, get) in measures {
        if get(&o.floor).is_nan() && o.runs.iter().all(|r| get(&r.errors).is_nan()) {
            continue;
        }
        let mut series = Vec::new();
        let (mut xlo, mut xhi) = (f64::INFINITY, 0.0f64);
        for f in &families {
            let pts: Vec<(f64, f64)> = o
                .runs
                .iter()
                .filter(|r| r.family == *f)
                .map(|r| (r.wall, get(&r.errors)))
                .filter(|(x, y)| *x > 0.0 && *y > 0.0 && y.is_finite())
                .collect();
            for (x, _) in &pts {
                xlo = xlo.min(*x);
                xhi = xhi.max(*x);
            }
            series.push(Series {
                label: f.to_string(),
                x: pts.iter().map(|p| p.0).collect(),
                y: pts.iter().map(|p| p.1).collect(),
            });
        }
        if series.iter().all(|s| s.x.is_empty()) {
            // Nothing to draw: every run failed or has no finite, positive error here.
            continue;
        }
        let floor = get(&o.floor);
        if floor > 0.0 && xhi > 0.0 {
            series.push(Series {
                label: "reference floor".into(),
                x: vec![xlo, xhi],
                y: vec![floor, floor],
            });
        }
        panels.push(Panel {
            log_x: true,
            log_y: true,
            ..Panel::new(title, "wall time (s)", ylabel, series)
        });
    }
    if let Some(dir) = stem.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io {
            file: dir.to_path_buf(),
            message: format!("cannot create output directory: {e}"),
        })?;
    }
    let mut out = Vec::new();
    for f in formats {
        out.push(figure(stem, *f, &panels, 2)?);
    }
    Ok(out)
}
