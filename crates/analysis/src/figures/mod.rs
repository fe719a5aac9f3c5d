//! Every figure the program draws, as PNG and SVG over [`crate::figures::plot`], one file per kind of
//! figure, and the redrawing of a written file's figures.
//!
//! * [`run_figures`] (file `run.rs`) draws one run: body positions, actuator forces, constraint
//!   drift and energy, and each clearance joint's orbit and contact forces.
//! * [`study_figures`] (file `study.rs`) draws a comparison study, every case overlaid:
//!   * `<study>-motion`: the report body's centre-of-mass position, velocity and acceleration
//!     along each report axis against time;
//!   * `<study>-forces`: for each report joint, the magnitude of the contact force on the journal
//!     (cases where the joint has clearance) or of the joint reaction (cases where it is ideal);
//!   * `<study>-orbits`: for each report joint with clearance, the journal (ball) centre inside its
//!     clearance circle; spherical joints in the plane of the first two report axes (global), a
//!     spatial revolute at both journal ends (the axis at the two rim planes, bushing axes),
//!     other revolutes in the plane normal to the bushing axis.
//! * [`analysis`] draws a nonlinear-analysis file's figures from the file alone.
//! * [`precision`] draws a work-precision measurement: each error measure against wall time.
//!
//! [`redraw`] draws again, from the file alone, the figures of a work-precision or an analysis
//! file, telling which it is from the file itself. [`overlay`] puts one recorded quantity of
//! several run files in one panel.

pub mod analysis;
mod analysis_data;
pub mod animate;
pub mod gltf;
pub mod mechanism;
pub mod plot;
pub mod precision;
pub mod run;
mod study;

use std::path::{Path, PathBuf};

pub use run::run_figures;
pub use study::study_figures;

use crate::Result;
use crate::figures::plot::{Format, Panel, Series};
use crate::storage::h5::read_series;
use crate::storage::inputs::Output;
use crate::storage::precision_file::Outcome;

/// Draws every figure of a written file again, from the file alone, into `dir` in the given
/// formats, and returns the files written: those of a work-precision file ([`precision::draw`],
/// named after its study) or of an analysis file ([`analysis::render`]). Any other file is an
/// error naming it.
pub fn redraw(file: &Path, dir: &Path, formats: &[Format]) -> Result<Vec<PathBuf>> {
    redraw_with(file, dir, formats, None)
}

/// [`redraw`] with the `[[figures]]` of the TOML file `figures` in place of the study's own
/// (an analysis file's only: a work-precision file has one figure, drawn as it is).
pub fn redraw_with(
    file: &Path,
    dir: &Path,
    formats: &[Format],
    figures: Option<&Path>,
) -> Result<Vec<PathBuf>> {
    if Output::read(file).is_ok_and(|k| k == Output::Precision) {
        if let Some(f) = figures {
            return Err(crate::Error::Io {
                file: f.to_path_buf(),
                message: format!(
                    "{} is a work-precision file, whose one figure has no specification to \
                     edit: plot it without --figures",
                    file.display()
                ),
            });
        }
        let o = Outcome::read(file)?;
        return precision::draw(&o, &dir.join(&o.name), formats);
    }
    analysis::render(file, dir, formats, figures)
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
    use crate::storage::run::RunResult;
    use crate::storage::run_file::{Meta, write_run};
    use crate::study::analysis::load::Loaded;
    use crate::study::analysis::sweep::{Options, execute};
    use crate::study::run::simulate;

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
