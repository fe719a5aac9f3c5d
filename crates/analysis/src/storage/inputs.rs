//! What kind of file the program was given, told from its content.
//!
//! * [`Input`]: a TOML input is a scene, a comparison study (a `[study]` table), an analysis study
//!   (`[study]` and `[analysis]` tables) or a work-precision study (an analysis study with a
//!   `[precision]` table). Text that is not valid TOML counts as a scene, so that the scene reader
//!   reports the syntax error with its line and column.
//! * [`Output`]: an HDF5 file written by the program is a run, a comparison study, an analysis
//!   study or a work-precision measurement.

use std::path::Path;

use toml::Table;

use crate::storage::h5::{h5err, read_str};
use crate::{Error, Result};

/// The kind of a TOML input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// A scene ([`jointplay_solver::scene::SceneSpec`]).
    Scene,
    /// A comparison study: several cases of a scene ([`crate::study::spec`]).
    Comparison,
    /// A nonlinear-analysis study ([`crate::study::analysis`]).
    Analysis,
    /// An analysis study with a `[precision]` table ([`crate::study::precision`]); it runs as an analysis
    /// study too.
    Precision,
}

impl Input {
    /// The kind of the TOML text `text`.
    pub fn of_text(text: &str) -> Input {
        let Ok(t) = text.parse::<Table>() else {
            return Input::Scene;
        };
        match (
            t.contains_key("study"),
            t.contains_key("analysis"),
            t.contains_key("precision"),
        ) {
            (false, _, _) => Input::Scene,
            (true, false, _) => Input::Comparison,
            (true, true, false) => Input::Analysis,
            (true, true, true) => Input::Precision,
        }
    }

    /// Reads the file `path` and tells its kind; returns the kind and the text. The error names
    /// the file when it cannot be read.
    pub fn read(path: &Path) -> Result<(Input, String)> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::Read {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Ok((Input::of_text(&text), text))
    }

    /// An analysis study, with or without a `[precision]` table.
    pub fn is_analysis(self) -> bool {
        matches!(self, Input::Analysis | Input::Precision)
    }
}

/// The kind of an HDF5 file written by the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// One run of a scene (`jointplay run SCENE`).
    Run,
    /// The cases of a comparison study (`jointplay run STUDY`).
    Comparison,
    /// An analysis study (root attribute `kind = "analysis"`).
    Analysis,
    /// A work-precision measurement (root attribute `kind = "work-precision"`).
    Precision,
}

impl Output {
    /// Opens `path` and tells its kind from its root attributes; the error names the file when it
    /// cannot be opened as HDF5 or was not written by the program.
    pub fn read(path: &Path) -> Result<Output> {
        let file = hdf5::File::open(path).map_err(h5err(path))?;
        let text = |name: &str| read_str(&file, name).ok();
        match text("kind").as_deref() {
            Some("analysis") => return Ok(Output::Analysis),
            Some("work-precision") => return Ok(Output::Precision),
            _ => {}
        }
        if text("study_name").is_some() && file.group("cases").is_ok() {
            Ok(Output::Comparison)
        } else if text("scene_name").is_some() {
            Ok(Output::Run)
        } else {
            Err(Error::Io {
                file: path.to_path_buf(),
                message:
                    "not a file written by jointplay (no kind, study_name or scene_name attribute)"
                        .into(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    fn root() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    fn kind_of(rel: &str) -> Input {
        let (kind, text) = Input::read(&root().join(rel)).unwrap();
        assert!(!text.is_empty());
        kind
    }

    #[test]
    fn bundled_inputs_are_told_apart() {
        assert_eq!(kind_of("data/scenes/4ups-rpu.toml"), Input::Scene);
        assert_eq!(kind_of("data/scenes/pendulum.toml"), Input::Scene);
        assert_eq!(
            kind_of("analyses/4ups-rpu/friction.toml"),
            Input::Comparison
        );
        assert_eq!(kind_of("analyses/duffing/cascade.toml"), Input::Analysis);
        assert_eq!(kind_of("analyses/precision/duffing.toml"), Input::Precision);
        assert!(Input::Precision.is_analysis() && Input::Analysis.is_analysis());
        assert!(!Input::Comparison.is_analysis() && !Input::Scene.is_analysis());
    }

    #[test]
    fn text_that_is_not_toml_counts_as_a_scene() {
        assert_eq!(Input::of_text("[study\nname = 1"), Input::Scene);
        assert_eq!(Input::of_text("[study]\nname = \"s\""), Input::Comparison);
        assert_eq!(Input::of_text("[analysis]\nperiods = 3"), Input::Scene);
    }

    #[test]
    fn an_unreadable_input_is_named() {
        let e = Input::read(Path::new("no/such/scene.toml")).unwrap_err();
        let msg = e.to_string();
        assert!(msg.starts_with("reading no/such/scene.toml: "), "{msg}");
    }

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("jointplay-inputs-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    /// Writes an HDF5 file with the given string attributes and groups at its root.
    fn h5(name: &str, attrs: &[(&str, &str)], groups: &[&str]) -> PathBuf {
        let path = tmp(name);
        let f = hdf5::File::create(&path).unwrap();
        for (k, v) in attrs {
            crate::storage::h5::str_attr(&f, k, v).unwrap();
        }
        for g in groups {
            f.create_group(g).unwrap();
        }
        path
    }

    #[test]
    fn written_files_are_told_apart_by_their_root_attributes() {
        let cases = [
            (
                "run.h5",
                &[("scene_name", "pendulum")][..],
                &[][..],
                Output::Run,
            ),
            (
                "study.h5",
                &[("study_name", "friction")],
                &["cases"],
                Output::Comparison,
            ),
            (
                "analysis.h5",
                &[("kind", "analysis"), ("study_name", "cascade")],
                &[],
                Output::Analysis,
            ),
            (
                "precision.h5",
                &[("kind", "work-precision")],
                &[],
                Output::Precision,
            ),
        ];
        for (name, attrs, groups, kind) in cases {
            assert_eq!(
                Output::read(&h5(name, attrs, groups)).unwrap(),
                kind,
                "{name}"
            );
        }
        let other = h5("other.h5", &[("title", "x")], &[]);
        let msg = Output::read(&other).unwrap_err().to_string();
        assert!(msg.contains("other.h5") && msg.contains("not a file written by jointplay"));
        let text = tmp("scene.toml");
        std::fs::write(&text, "[scene]\n").unwrap();
        let msg = Output::read(&text).unwrap_err().to_string();
        assert!(msg.contains("scene.toml") && msg.contains("HDF5"), "{msg}");
        let _ = std::fs::remove_dir_all(text.parent().unwrap());
    }
}
