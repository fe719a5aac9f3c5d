//! The figures of a comparison study, every case overlaid (see [`super`]).

use std::path::{Path, PathBuf};

use crate::Result;
use crate::figures::plot::{PNG_AND_SVG, circle, mm, write};
use crate::figures::plot::{Panel, Series};
use crate::storage::run::{Channel, Recording};
use crate::storage::study_read::norm;
use crate::study::comparison::Comparison;
use crate::study::spec::ReportSpec;

/// The global plane (two axis indices, 0 = X) in which a spherical joint's orbit is drawn: the
/// first two report axes; with one report axis, that axis and the first other one, in index
/// order (report axis "y" draws the X-Y plane), so that an axis is never drawn against itself.
pub fn orbit_plane(axes: &[(usize, &str)]) -> (usize, usize) {
    match axes {
        [] => (0, 1),
        [(a, _)] => {
            let other = (0..3).find(|i| i != a).unwrap_or(0);
            (other.min(*a), other.max(*a))
        }
        [(a, _), (b, _), ..] => (*a, *b),
    }
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
        let panels = motion_panels(body, &axes, runs);
        files.extend(write(
            out,
            &format!("{name}-motion"),
            &panels,
            axes.len(),
            &PNG_AND_SVG,
        )?);
    }
    let mut force_panels = Vec::new();
    let mut orbit_panels = Vec::new();
    for j in &spec.joints {
        force_panels.extend(force_panel(j, runs));
        orbit_panels.extend(journal_orbits(j, &axes, runs));
    }
    files.extend(write(
        out,
        &format!("{name}-forces"),
        &force_panels,
        force_panels.len().min(3),
        &PNG_AND_SVG,
    )?);
    files.extend(write(
        out,
        &format!("{name}-orbits"),
        &orbit_panels,
        orbit_panels.len().min(4),
        &PNG_AND_SVG,
    )?);
    Ok(files)
}

/// The displacement, velocity and acceleration of the report body along each report axis, a
/// panel each, every run overlaid.
fn motion_panels(body: &str, axes: &[(usize, &str)], runs: &[(&str, &Recording)]) -> Vec<Panel> {
    let mut panels = Vec::new();
    for (what, ds, unit) in [
        ("displacement", "position", "m"),
        ("velocity", "velocity", "m/s"),
        ("acceleration", "acceleration", "m/s^2"),
    ] {
        for &(a, ax) in axes {
            let series = runs
                .iter()
                .filter_map(|(label, rec)| {
                    let v = rec.channel(&format!("bodies/{body}/{ds}"))?;
                    (!v.values.is_empty()).then(|| Series {
                        label: (*label).to_string(),
                        x: rec.time.clone(),
                        y: v.column(a),
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
    panels
}

/// The force magnitude of joint `j` in every run that records it (the contact force of a joint
/// with clearance, else the reaction); None when no run does.
fn force_panel(j: &str, runs: &[(&str, &Recording)]) -> Option<Panel> {
    let mut series = Vec::new();
    for (label, rec) in runs {
        let found = match rec.channel(&format!("joints/{j}/force_on_journal")) {
            Some(c) => Some(("contact", c)),
            None => rec
                .channel(&format!("joints/{j}/reaction_force"))
                .map(|c| ("ideal, reaction", c)),
        };
        if let Some((what, forces)) = found {
            series.push(Series {
                label: format!("{label} ({what})"),
                x: rec.time.clone(),
                y: forces.vectors().iter().map(norm).collect(),
            });
        }
    }
    (!series.is_empty()).then(|| {
        Panel::new(
            format!("{j}: joint force magnitude"),
            "time t (s)",
            "force |F| (N)",
            series,
        )
    })
}

/// The orbits of joint `j`'s journal in mm (its centre, or both ends of a spatial revolute)
/// inside each run's clearance circle, every run with clearance in `j` overlaid; none when no
/// run has clearance there.
fn journal_orbits<'a>(
    j: &str,
    axes: &[(usize, &str)],
    runs: &[(&str, &'a Recording)],
) -> Vec<Panel> {
    let mut panels = Vec::new();
    // Orbits, in mm.
    let with: Vec<_> = runs
        .iter()
        .filter_map(|(label, rec)| {
            rec.clearances
                .iter()
                .find(|c| c.name == j)
                .map(|c| (*label, rec, c))
        })
        .collect();
    // A channel of joint j that every run with clearance in it has.
    let ch = |rec: &'a Recording, q: &str| -> &'a Channel {
        rec.channel(&format!("joints/{j}/{q}"))
            .unwrap_or_else(|| panic!("a clearance joint records {q}"))
    };
    let Some(cmax) = with
        .iter()
        .map(|(_, _, c)| c.radial_clearance)
        .reduce(f64::max)
    else {
        return Vec::new();
    };
    let lim = 1.25 * cmax * 1e3;
    let ends: Vec<(&str, Option<usize>)> = if with.iter().all(|(_, rec, _)| {
        rec.channel(&format!("joints/{j}/end_eccentricity"))
            .is_some_and(|c| !c.values.is_empty())
    }) {
        vec![("end at rim P", Some(0)), ("end at rim Q", Some(2))]
    } else {
        vec![("centre", None)]
    };
    if with.iter().all(|(_, _, c)| c.translational) {
        // Sliders: the offset across the guide against time, between the guide's faces.
        let mut series: Vec<Series> = with
            .iter()
            .map(|(label, rec, _)| Series {
                label: (*label).to_string(),
                x: rec.time.clone(),
                y: mm(&ch(rec, "radial_eccentricity").column(0)),
            })
            .collect();
        let t1 = with
            .iter()
            .filter_map(|(_, rec, _)| rec.time.last().copied())
            .fold(0.0, f64::max);
        let t0 = with
            .iter()
            .filter_map(|(_, rec, _)| rec.time.first().copied())
            .fold(t1, f64::min);
        let c = cmax * 1e3;
        series.push(Series {
            label: "guide faces (largest clearance)".into(),
            x: vec![t0, t1, f64::NAN, t0, t1],
            y: vec![c, c, f64::NAN, -c, -c],
        });
        panels.push(Panel {
            y_range: Some((-lim, lim)),
            ..Panel::new(
                format!("{j}: slider offset across the guide"),
                "time t (s)",
                "offset along the reference direction (mm)",
                series,
            )
        });
        return panels;
    }
    let spherical = with.iter().all(|(_, _, c)| c.spherical);
    let (p0, p1) = orbit_plane(axes);
    for (end, col) in ends {
        let mut series: Vec<Series> = with
            .iter()
            .map(|(label, rec, _)| {
                let (e, kx, ky) = match col {
                    Some(k) => (ch(rec, "end_eccentricity"), k, k + 1),
                    None if spherical => (ch(rec, "eccentricity_global"), p0, p1),
                    None => (ch(rec, "radial_eccentricity"), 0, 1),
                };
                let (x, y) = (mm(&e.column(kx)), mm(&e.column(ky)));
                Series {
                    label: (*label).to_string(),
                    x,
                    y,
                }
            })
            .collect();
        let mut radii: Vec<f64> = with.iter().map(|(_, _, c)| c.radial_clearance).collect();
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
        panels.push(Panel {
            x_range: Some((-lim, lim)),
            y_range: Some((-lim, lim)),
            equal_aspect: true,
            ..Panel::new(format!("{j}: journal {end} orbit"), xl, yl, series)
        });
    }
    panels
}

/// The figures of a comparison study, drawn here so that studies never call figures.
impl Comparison<'_> {
    /// Draws the study figures of the finished cases into `dir`: one set of every case, or one
    /// per group of `report.figures` with the finished cases it names; returns the files written.
    pub fn figures(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let recs: Vec<(&str, &Recording)> = self
            .runs
            .iter()
            .map(|(r, _)| (r.label.as_str(), &r.result.recording))
            .collect();
        let spec = &self.study.spec;
        if spec.report.figures.is_empty() {
            return study_figures(dir, &spec.study.name, &spec.report, &recs);
        }
        let mut files = Vec::new();
        for g in &spec.report.figures {
            let some: Vec<(&str, &Recording)> = g
                .cases
                .iter()
                .filter_map(|c| recs.iter().find(|(l, _)| l == c).copied())
                .collect();
            if some.is_empty() {
                continue;
            }
            let name = format!("{}-{}", spec.study.name, g.name);
            files.extend(study_figures(dir, &name, &spec.report, &some)?);
        }
        Ok(files)
    }
}

#[cfg(test)]
mod tests {
    use super::orbit_plane;

    #[test]
    fn an_orbit_plane_never_draws_an_axis_against_itself() {
        assert_eq!(orbit_plane(&[(1, "y")]), (0, 1));
        assert_eq!(orbit_plane(&[(0, "x")]), (0, 1));
        assert_eq!(orbit_plane(&[(2, "z")]), (0, 2));
        assert_eq!(orbit_plane(&[(0, "x"), (2, "z")]), (0, 2));
        assert_eq!(orbit_plane(&[(1, "y"), (2, "z"), (0, "x")]), (1, 2));
        assert_eq!(orbit_plane(&[]), (0, 1));
    }
}
