//! Figures of a study: every case overlaid, as PNG and SVG.
//!
//! * `<study>-motion`: the report body's centre-of-mass position, velocity and acceleration along
//!   each report axis against time;
//! * `<study>-forces`: for each report joint, the magnitude of the contact force on the journal
//!   (cases where the joint has clearance) or of the joint reaction (cases where it is ideal);
//! * `<study>-orbits`: for each report joint with clearance, the journal (ball) centre inside its
//!   clearance circle; spherical joints in the plane of the first two report axes (global), a
//!   spatial revolute at both journal ends (the axis at the two rim planes, bushing axes), other
//!   revolutes in the plane normal to the bushing axis.

use std::path::{Path, PathBuf};

use crate::Result;
use crate::plot::{Format, Panel, Series, figure};
use crate::report::norm;
use crate::run::Recording;
use crate::study::ReportSpec;

fn col3(v: &[[f64; 3]], k: usize, scale: f64) -> Vec<f64> {
    v.iter().map(|p| p[k] * scale).collect()
}

/// The clearance circle of radius `r_mm` (mm), for orbit panels drawn in mm.
pub fn circle(r_mm: f64) -> Series {
    let angles = (0..=360).map(|k| (k as f64).to_radians());
    Series {
        label: format!("clearance {r_mm:.3} mm"),
        x: angles.clone().map(|a| r_mm * a.cos()).collect(),
        y: angles.map(|a| r_mm * a.sin()).collect(),
    }
}

fn write(out: &Path, stem: &str, panels: &[Panel], cols: usize) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    if panels.is_empty() {
        return Ok(files);
    }
    for fmt in [Format::Png, Format::Svg] {
        files.push(figure(&out.join(stem), fmt, panels, cols)?);
    }
    Ok(files)
}

/// Draws the study figures into `out` and returns the files written.
pub fn study_figures(
    out: &Path,
    name: &str,
    spec: &ReportSpec,
    runs: &[(&str, &Recording)],
) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let axes = spec.axis_list();
    if let Some(body) = &spec.body {
        let mut panels = Vec::new();
        for (what, ds, unit) in [
            ("displacement", 0, "m"),
            ("velocity", 1, "m/s"),
            ("acceleration", 2, "m/s^2"),
        ] {
            for &(a, ax) in &axes {
                let series = runs
                    .iter()
                    .filter_map(|(label, rec)| {
                        let b = rec.bodies.iter().find(|b| &b.name == body)?;
                        let v = match ds {
                            0 => &b.position,
                            1 => &b.velocity,
                            _ => &b.acceleration,
                        };
                        (!v.is_empty()).then(|| Series {
                            label: (*label).to_string(),
                            x: rec.time.clone(),
                            y: col3(v, a, 1.0),
                        })
                    })
                    .collect::<Vec<_>>();
                panels.push(Panel::new(
                    format!("{body}: {what} along {}", ax.to_uppercase()),
                    "time t (s)",
                    format!("{what} {} ({unit})", ax.to_uppercase()),
                    series,
                ));
            }
        }
        files.extend(write(out, &format!("{name}-motion"), &panels, axes.len())?);
    }
    let mut force_panels = Vec::new();
    let mut orbit_panels = Vec::new();
    for j in &spec.joints {
        let mut series = Vec::new();
        for (label, rec) in runs {
            let found = match rec.clearances.iter().find(|c| &c.name == j) {
                Some(c) => Some(("contact", &c.force_journal)),
                None => rec
                    .joints
                    .iter()
                    .find(|r| &r.name == j)
                    .map(|r| ("ideal, reaction", &r.force)),
            };
            if let Some((what, forces)) = found {
                series.push(Series {
                    label: format!("{label} ({what})"),
                    x: rec.time.clone(),
                    y: forces.iter().map(norm).collect(),
                });
            }
        }
        if !series.is_empty() {
            force_panels.push(Panel::new(
                format!("{j}: joint force magnitude"),
                "time t (s)",
                "force |F| (N)",
                series,
            ));
        }
        // Orbits, in mm.
        let with: Vec<_> = runs
            .iter()
            .filter_map(|(label, rec)| {
                rec.clearances
                    .iter()
                    .find(|c| &c.name == j)
                    .map(|c| (*label, c))
            })
            .collect();
        let Some(cmax) = with
            .iter()
            .map(|(_, c)| c.radial_clearance)
            .reduce(f64::max)
        else {
            continue;
        };
        let lim = 1.25 * cmax * 1e3;
        let ends: Vec<(&str, Option<usize>)> =
            if with.iter().all(|(_, c)| !c.end_eccentricity.is_empty()) {
                vec![("end at rim P", Some(0)), ("end at rim Q", Some(2))]
            } else {
                vec![("centre", None)]
            };
        let spherical = with.iter().all(|(_, c)| c.spherical);
        let (p0, p1) = (
            axes.first().map(|a| a.0).unwrap_or(0),
            axes.get(1).map(|a| a.0).unwrap_or(1),
        );
        for (end, col) in ends {
            let mut series: Vec<Series> = with
                .iter()
                .map(|(label, c)| {
                    let (x, y) = match col {
                        Some(k) => (
                            c.end_eccentricity.iter().map(|e| e[k] * 1e3).collect(),
                            c.end_eccentricity.iter().map(|e| e[k + 1] * 1e3).collect(),
                        ),
                        None if spherical => (
                            col3(&c.eccentricity_global, p0, 1e3),
                            col3(&c.eccentricity_global, p1, 1e3),
                        ),
                        None => (
                            c.radial_eccentricity.iter().map(|e| e[0] * 1e3).collect(),
                            c.radial_eccentricity.iter().map(|e| e[1] * 1e3).collect(),
                        ),
                    };
                    Series {
                        label: (*label).to_string(),
                        x,
                        y,
                    }
                })
                .collect();
            let mut radii: Vec<f64> = with.iter().map(|(_, c)| c.radial_clearance).collect();
            radii.sort_by(f64::total_cmp);
            radii.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
            series.extend(radii.iter().map(|r| circle(r * 1e3)));
            let (xl, yl) = if spherical {
                let n = |i: usize| ["X", "Y", "Z"][i];
                (
                    format!("eccentricity along global {} (mm)", n(p0)),
                    format!("eccentricity along global {} (mm)", n(p1)),
                )
            } else {
                (
                    "eccentricity along bushing u (mm)".to_string(),
                    "eccentricity along bushing w (mm)".to_string(),
                )
            };
            orbit_panels.push(Panel {
                x_range: Some((-lim, lim)),
                y_range: Some((-lim, lim)),
                ..Panel::new(format!("{j}: journal {end} orbit"), xl, yl, series)
            });
        }
    }
    files.extend(write(
        out,
        &format!("{name}-forces"),
        &force_panels,
        force_panels.len().min(3),
    )?);
    files.extend(write(
        out,
        &format!("{name}-orbits"),
        &orbit_panels,
        orbit_panels.len().min(4),
    )?);
    Ok(files)
}
