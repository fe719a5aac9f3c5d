//! Figures of a run and of a study, as PNG and SVG, and the redrawing of a written file's figures.
//!
//! [`run_figures`] draws one run: body positions, actuator forces, constraint drift and energy,
//! and each clearance joint's orbit and contact forces. [`study_figures`] draws a comparison
//! study, every case overlaid:
//!
//! * `<study>-motion`: the report body's centre-of-mass position, velocity and acceleration along
//!   each report axis against time;
//! * `<study>-forces`: for each report joint, the magnitude of the contact force on the journal
//!   (cases where the joint has clearance) or of the joint reaction (cases where it is ideal);
//! * `<study>-orbits`: for each report joint with clearance, the journal (ball) centre inside its
//!   clearance circle; spherical joints in the plane of the first two report axes (global), a
//!   spatial revolute at both journal ends (the axis at the two rim planes, bushing axes), other
//!   revolutes in the plane normal to the bushing axis.
//!
//! [`redraw`] draws again, from the file alone, the figures of a work-precision or an analysis
//! file, telling which it is from the file itself. [`overlay`] puts one recorded quantity of
//! several run files in one panel.

use std::path::{Path, PathBuf};

use crate::Result;
use crate::h5::read_series;
use crate::inputs::Output;
use crate::nlfigures::render;
use crate::plot::{Format, Panel, Series, figure};
use crate::precision::Outcome;
use crate::report::norm;
use crate::run::{Channel, Recording, RunResult};
use crate::study::ReportSpec;

/// Metres to millimetres.
fn mm(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x * 1e3).collect()
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
pub fn study_figures<'a>(
    out: &Path,
    name: &str,
    spec: &ReportSpec,
    runs: &[(&str, &'a Recording)],
) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let axes = spec.axis_list();
    if let Some(body) = &spec.body {
        let mut panels = Vec::new();
        for (what, ds, unit) in [
            ("displacement", "position", "m"),
            ("velocity", "velocity", "m/s"),
            ("acceleration", "acceleration", "m/s^2"),
        ] {
            for &(a, ax) in &axes {
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
        files.extend(write(out, &format!("{name}-motion"), &panels, axes.len())?);
    }
    let mut force_panels = Vec::new();
    let mut orbit_panels = Vec::new();
    for j in &spec.joints {
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
            continue;
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
        let spherical = with.iter().all(|(_, _, c)| c.spherical);
        let (p0, p1) = (
            axes.first().map(|a| a.0).unwrap_or(0),
            axes.get(1).map(|a| a.0).unwrap_or(1),
        );
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

/// Draws the figures of one run into `out` as PNG and SVG and returns the files written:
///
/// * `<name>-positions`: every recorded body's centre of mass against time (at most 12 bodies);
/// * `<name>-drives`: the actuator forces, when drives are recorded;
/// * `<name>-diagnostics`: the constraint drift and the change of mechanical energy, when
///   diagnostics are recorded;
/// * `<name>-<joint>-clearance`: for each clearance joint, the journal-centre orbit inside the
///   clearance circle and the normal contact force of each contact.
pub fn run_figures(out: &Path, name: &str, run: &RunResult) -> Result<Vec<PathBuf>> {
    let rec = &run.recording;
    let t = &rec.time;
    let channel = |d: String| {
        rec.channel(&d)
            .unwrap_or_else(|| panic!("a recording has its member's {d}"))
    };
    let mut files = Vec::new();
    let mut sets: Vec<(String, Vec<Panel>)> = Vec::new();
    let body_panels: Vec<Panel> = rec
        .members("bodies")
        .take(12)
        .map(|b| {
            let position = channel(format!("bodies/{b}/position"));
            Panel {
                title: format!("{b}: centre of mass"),
                x_label: "time t (s)".into(),
                y_label: "position (m)".into(),
                series: ["x", "y", "z"]
                    .iter()
                    .enumerate()
                    .map(|(k, l)| Series {
                        label: (*l).into(),
                        x: t.clone(),
                        y: position.column(k),
                    })
                    .collect(),
                ..Panel::default()
            }
        })
        .collect();
    sets.push((format!("{name}-positions"), body_panels));
    let drives: Vec<(&str, &Channel)> = rec
        .members("drives")
        .map(|d| (d, channel(format!("drives/{d}/force"))))
        .collect();
    if !drives.is_empty() {
        sets.push((
            format!("{name}-drives"),
            vec![Panel {
                title: "Actuator forces".into(),
                x_label: "time t (s)".into(),
                y_label: if drives.iter().all(|(_, f)| f.unit == "N m") {
                    "torque (N m)"
                } else {
                    "force (N) or torque (N m)"
                }
                .into(),
                series: drives
                    .iter()
                    .map(|(d, f)| Series {
                        label: d.to_string(),
                        x: t.clone(),
                        y: f.values.clone(),
                    })
                    .collect(),
                ..Panel::default()
            }],
        ));
    }
    if let Some(drift) = rec.channel("diagnostics/constraint_drift") {
        let mut panels = vec![Panel {
            title: "Constraint drift".into(),
            x_label: "time t (s)".into(),
            y_label: "residual (m, rad; m/s, rad/s)".into(),
            series: vec![
                Series {
                    label: "position |Phi|".into(),
                    x: t.clone(),
                    y: drift.values.clone(),
                },
                Series {
                    label: "velocity |Phi'|".into(),
                    x: t.clone(),
                    y: channel("diagnostics/velocity_drift".into()).values.clone(),
                },
            ],
            log_y: true,
            ..Panel::default()
        }];
        if let Some(energy) = rec
            .channel("diagnostics/energy")
            .map(|c| &c.values)
            .filter(|e| !e.is_empty())
        {
            panels.push(Panel {
                title: format!(
                    "Mechanical energy change (E(0) = {:.6e} J)",
                    energy.first().copied().unwrap_or(0.0)
                ),
                x_label: "time t (s)".into(),
                y_label: "E - E(0) (J)".into(),
                series: vec![Series {
                    label: "energy".into(),
                    x: t.clone(),
                    y: energy.iter().map(|e| e - energy[0]).collect(),
                }],
                ..Panel::default()
            });
        }
        sets.push((format!("{name}-diagnostics"), panels));
    }
    for c in &rec.clearances {
        let lim = 1.25 * c.radial_clearance * 1e3;
        let orbit = channel(format!("joints/{}/radial_eccentricity", c.name));
        let normal = channel(format!("joints/{}/normal_force", c.name));
        let orbit = Panel {
            x_range: Some((-lim, lim)),
            y_range: Some((-lim, lim)),
            ..Panel::new(
                format!("{}: journal-centre orbit", c.name),
                "eccentricity along u (mm)",
                "eccentricity along w (mm)",
                vec![
                    Series {
                        label: "journal centre".into(),
                        x: mm(&orbit.column(0)),
                        y: mm(&orbit.column(1)),
                    },
                    circle(c.radial_clearance * 1e3),
                ],
            )
        };
        let force = Panel::new(
            format!("{}: normal contact force", c.name),
            "time t (s)",
            "normal force (N)",
            c.contacts
                .iter()
                .enumerate()
                .map(|(k, n)| Series {
                    label: n.clone(),
                    x: t.clone(),
                    y: normal.column(k),
                })
                .collect(),
        );
        sets.push((format!("{name}-{}-clearance", c.name), vec![orbit, force]));
    }
    for (stem, panels) in sets {
        if panels.is_empty() {
            continue;
        }
        let cols = if panels.len() > 4 {
            3
        } else {
            panels.len().min(2)
        };
        for fmt in [Format::Png, Format::Svg] {
            files.push(figure(&out.join(&stem), fmt, &panels, cols)?);
        }
    }
    Ok(files)
}

/// Draws every figure of a written file again, from the file alone, into `dir` in the given
/// formats, and returns the files written: those of a work-precision file
/// ([`crate::precision::Outcome::figures`], named after its study) or of an analysis file
/// ([`crate::nlfigures::render`]). Any other file is an error naming it.
pub fn redraw(file: &Path, dir: &Path, formats: &[Format]) -> Result<Vec<PathBuf>> {
    if Output::read(file).is_ok_and(|k| k == Output::Precision) {
        let o = Outcome::read(file)?;
        return o.figures(&dir.join(&o.name), formats);
    }
    render(file, dir, formats)
}

/// One panel overlaying column `component` of `dataset` (1-D datasets ignore it) from each run
/// file against time, each series labelled with its scene's name (the file name when the file
/// has none); titled `title`, or by default the dataset path and the component.
pub fn overlay(
    files: &[PathBuf],
    dataset: &str,
    component: usize,
    title: Option<String>,
) -> Result<Panel> {
    let mut series = Vec::new();
    let mut unit = String::new();
    for f in files {
        let d = read_series(f, dataset, component)?;
        unit = d.unit.clone();
        let label = if d.scene_name.is_empty() {
            f.display().to_string()
        } else {
            d.scene_name
        };
        series.push(Series {
            label,
            x: d.time,
            y: d.values,
        });
    }
    let comp = ["x", "y", "z", "w"].get(component).copied().unwrap_or("?");
    Ok(Panel::new(
        title.unwrap_or_else(|| format!("{dataset} [{comp}]")),
        "time t (s)",
        format!(
            "{} ({unit})",
            dataset
                .rsplit('/')
                .next()
                .unwrap_or(dataset)
                .replace('_', " ")
        ),
        series,
    ))
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use jointplay_solver::model::Model;
    use jointplay_solver::scene::SceneSpec;

    use super::*;
    use crate::h5::{Meta, write_run};
    use crate::nonlinear::{Loaded, Options, execute};
    use crate::run::simulate;

    fn tmp(tag: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("jointplay-figures-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Runs the bundled scene `name` for its first `span` seconds.
    fn short_run(name: &str, span: f64) -> (Model, RunResult, PathBuf, String) {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../data/scenes")
            .join(name);
        let scene = SceneSpec::load(&path).unwrap();
        let (mut model, state) = Model::compile(&scene).unwrap();
        model.settings.end_time = model.settings.start_time + span;
        let run = simulate(&model, state, &mut |_| {}).unwrap();
        (model, run, path, scene.text)
    }

    fn names(files: &[PathBuf]) -> Vec<String> {
        files
            .iter()
            .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
            .collect()
    }

    #[test]
    fn a_run_draws_positions_first_and_one_figure_per_clearance_joint() {
        let (model, run, _, _) = short_run("slider-crank-clearance.toml", 0.01);
        let dir = tmp("run");
        let files = run_figures(&dir, "sc", &run).unwrap();
        let names = names(&files);
        assert_eq!(names[..2], ["sc-positions.png", "sc-positions.svg"]);
        assert!(files.iter().all(|f| f.is_file()), "{names:?}");
        for c in &run.recording.clearances {
            for ext in ["png", "svg"] {
                let want = format!("sc-{}-clearance.{ext}", c.name);
                assert!(names.contains(&want), "{want} not in {names:?}");
            }
        }
        assert!(!model.clearances.is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn redraw_draws_an_analysis_file_and_names_any_other_file() {
        let study = r#"
[study]
name = "redraw"
system = { kind = "duffing", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = 0.2, omega = 1.2, initial = [1.0, 0.0], solver = { integrator = "rk4", step = 0.05 } }

[analysis]
periods = 4
transient = 1
samples_per_period = 20

[[observables]]
name = "x"
path = "x"

[[observables]]
name = "v"
path = "v"
"#;
        let dir = tmp("redraw");
        let st = Loaded::parse(study, &dir.join("redraw.toml")).unwrap();
        let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
        let files = redraw(&out.file, &dir, &[Format::Svg]).unwrap();
        assert!(!files.is_empty());
        assert!(
            files
                .iter()
                .all(|f| f.extension().is_some_and(|e| e == "svg") && f.is_file()),
            "{files:?}"
        );

        let (model, run, path, text) = short_run("pendulum.toml", 0.01);
        let file = write_run(&dir, &Meta::of(&model, &path, &text, "test"), &run).unwrap();
        let msg = redraw(&file, &dir, &[Format::Svg]).unwrap_err().to_string();
        assert!(
            msg.contains("pendulum.h5") && msg.contains("not a nonlinear-analysis file"),
            "{msg}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn an_overlay_has_one_series_per_file_named_by_its_scene() {
        let dir = tmp("overlay");
        let mut files = Vec::new();
        for (name, span) in [("pendulum.toml", 0.01), ("slider-crank.toml", 0.002)] {
            let (model, run, path, text) = short_run(name, span);
            files.push(write_run(&dir, &Meta::of(&model, &path, &text, "test"), &run).unwrap());
        }
        let p = overlay(&files, "time", 0, None).unwrap();
        assert_eq!(p.title, "time [x]");
        assert_eq!(p.x_label, "time t (s)");
        assert_eq!(p.y_label, "time (s)");
        let labels: Vec<&str> = p.series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(labels, ["pendulum", "slider-crank"]);
        assert!(p.series.iter().all(|s| s.x == s.y && !s.x.is_empty()));
        let p = overlay(&files[..1], "bodies/bob/position", 1, Some("bob".into())).unwrap();
        assert_eq!(
            (p.title.as_str(), p.y_label.as_str()),
            ("bob", "position (m)")
        );
        let msg = overlay(&files, "bodies/bob/position", 1, None)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("slider-crank.h5"), "{msg}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
