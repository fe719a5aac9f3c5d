//! The figures of one run (see [`super`]).

use std::path::{Path, PathBuf};

use crate::Result;
use crate::figures::plot::{PNG_AND_SVG, circle, mm, write};
use crate::figures::plot::{Panel, Series};
use crate::storage::run::{Channel, RunResult};

/// Draws the figures of one run into `out` as PNG and SVG and returns the files written:
///
/// * `<name>-positions`: every recorded body's centre of mass against time (at most 12 bodies);
/// * `<name>-drives`: the actuator forces, when drives are recorded;
/// * `<name>-diagnostics`: the constraint drift and the change of mechanical energy, when
///   diagnostics are recorded;
/// * `<name>-<joint>-clearance`: for each clearance joint, the journal-centre orbit inside the
///   clearance circle and the normal contact force of each contact (and the magnitude of a
///   lubricated joint's film force).
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
        // Both guide faces in one series, broken between them (a non-finite point ends a line).
        let (t0, t1, cl) = (t[0], t[t.len() - 1], c.radial_clearance * 1e3);
        let faces = Series {
            label: "guide faces (clearance)".into(),
            x: vec![t0, t1, f64::NAN, t0, t1],
            y: vec![cl, cl, f64::NAN, -cl, -cl],
        };
        let orbit = if c.translational {
            let mut series = vec![Series {
                label: "slider centre, across".into(),
                x: t.clone(),
                y: mm(&orbit.column(0)),
            }];
            // A box in a channel also moves towards its side faces.
            let beside = orbit.column(1);
            if beside.iter().any(|&v| v != 0.0) {
                series.push(Series {
                    label: "slider centre, beside".into(),
                    x: t.clone(),
                    y: mm(&beside),
                });
            }
            series.push(faces);
            Panel {
                y_range: Some((-lim, lim)),
                ..Panel::new(
                    format!("{}: slider offset in the guide", c.name),
                    "time t (s)",
                    "offset from the guide's centre (mm)",
                    series,
                )
            }
        } else {
            Panel {
                x_range: Some((-lim, lim)),
                y_range: Some((-lim, lim)),
                equal_aspect: true,
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
            }
        };
        let mut series: Vec<Series> = c
            .contacts
            .iter()
            .enumerate()
            .map(|(k, n)| Series {
                label: n.clone(),
                x: t.clone(),
                y: normal.column(k),
            })
            .collect();
        // A lubricated joint's film carries the journal between contacts: its force beside them.
        let film = rec.channel(&format!("joints/{}/film_force", c.name));
        if let Some(film) = film {
            series.push(Series {
                label: "oil film".into(),
                x: t.clone(),
                y: film
                    .rows()
                    .map(|r| r.iter().map(|v| v * v).sum::<f64>().sqrt())
                    .collect(),
            });
        }
        let force = Panel::new(
            if film.is_some() {
                format!("{}: normal contact and oil-film forces", c.name)
            } else {
                format!("{}: normal contact force", c.name)
            },
            "time t (s)",
            if film.is_some() {
                "force (N)"
            } else {
                "normal force (N)"
            },
            series,
        );
        sets.push((format!("{name}-{}-clearance", c.name), vec![orbit, force]));
    }
    for (stem, panels) in sets {
        let cols = if panels.len() > 4 {
            3
        } else {
            panels.len().min(2)
        };
        files.extend(write(out, &stem, &panels, cols, &PNG_AND_SVG)?);
    }
    Ok(files)
}
