//! A comparison study run end to end: its cases, its file, its table and its figures.
//!
//! [`Comparison::run`] runs every case of a [`Study`] in parallel and keeps every finished case
//! even when others fail. Then, one step at a time so that a caller can report each result as it
//! comes: [`Comparison::write`] writes `DIR/<study>.h5` with the finished cases and the failures,
//! [`Comparison::write_table`] the comparison table `DIR/<study>.md` computed from that file,
//! [`Comparison::figures`] the figures, and [`Comparison::finish`] fails when a case failed.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::progress::{Progress, Stop};
use crate::storage::run::RunResult;
use crate::storage::run_file::{Meta, StudyMeta, write_study};
use crate::study::report::{self, markdown};
use crate::study::spec::{Case, CaseRun, Study};
use crate::{Error, Result};

/// The finished and failed cases of a study.
#[derive(Debug)]
pub struct Comparison<'a> {
    pub study: &'a Study,
    /// The finished cases in the order of the study, each with its case.
    pub runs: Vec<(CaseRun, &'a Case)>,
    /// The label and the error message of every failed case.
    pub failed: Vec<(String, String)>,
    /// Wall time of the runs (s).
    pub wall: f64,
}

impl<'a> Comparison<'a> {
    /// Runs every case of `study` (see [`Study::run`], which reports through `progress`). Fails
    /// when a case does not compile or when every case failed, naming each failure.
    pub fn run(study: &'a Study, progress: &(dyn Fn(Progress) + Sync)) -> Result<Comparison<'a>> {
        Comparison::run_until(study, progress, &Stop::new())
    }

    /// [`Comparison::run`] that ends early when `stop` is requested (see [`Study::run_until`]):
    /// the cases finished before are kept, the others are failures that say they were
    /// interrupted.
    pub fn run_until(
        study: &'a Study,
        progress: &(dyn Fn(Progress) + Sync),
        stop: &Stop,
    ) -> Result<Comparison<'a>> {
        let start = Instant::now();
        let results = study.run_until(progress, stop)?;
        let mut runs = Vec::new();
        let mut failed = Vec::new();
        for (r, c) in results.into_iter().zip(&study.cases) {
            match r {
                Ok(run) => runs.push((run, c)),
                // The error names the case.
                Err(e) => failed.push((c.label.clone(), e.to_string())),
            }
        }
        if runs.is_empty() {
            return Err(Error::EveryCaseFailed {
                file: study.path.clone(),
                failures: failed.into_iter().map(|f| f.1).collect(),
            });
        }
        Ok(Comparison {
            study,
            runs,
            failed,
            wall: start.elapsed().as_secs_f64(),
        })
    }

    /// The warnings of the finished cases, each naming its case: the scene's, then the run's.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (run, c) in &self.runs {
            for w in &run.model.warnings {
                out.push(format!("case {}: {w}", c.label));
            }
            for w in &run.result.warnings {
                out.push(format!("case {}: {}", c.label, w.message));
            }
        }
        out
    }

    /// Writes `dir/<study>.h5`: every finished case and every failure. `version` is the program
    /// version stored in the file.
    pub fn write(&self, dir: &Path, version: &str) -> Result<PathBuf> {
        let metas: Vec<(String, Meta, &RunResult)> = self
            .runs
            .iter()
            .map(|(r, c)| {
                (
                    r.label.clone(),
                    Meta::of(&r.model, &c.scene.path, &c.scene.text, version),
                    &r.result,
                )
            })
            .collect();
        let meta = StudyMeta {
            study_name: &self.study.spec.study.name,
            study_file: &self.study.path,
            study_text: &self.study.text,
            program_version: version,
        };
        write_study(dir, &meta, &metas, &self.failed)
    }

    /// What was run, one line each: the study, every finished case with its steps, RHS
    /// evaluations and wall time, and the study's wall time.
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "study        {} ({}), {} cases",
            self.study.spec.study.name,
            self.study.path.display(),
            self.study.cases.len()
        )];
        for (r, _) in &self.runs {
            let st = &r.result.stats;
            let w = st.wall.as_secs_f64();
            out.push(format!(
                "  {:<14} {} steps, {} RHS evaluations, {:.1} s ({:.0} RHS/s)",
                r.label,
                st.accepted,
                st.rhs_evals,
                w,
                st.rhs_evals as f64 / w.max(1e-9)
            ));
        }
        let threads = rayon::current_num_threads();
        out.push(format!(
            "wall time    {:.1} s for the study on {} threads",
            self.wall, threads
        ));
        if threads > 1 && self.runs.len() > 1 && self.wall > 0.0 {
            // The finished cases' summed wall time over the threads' (failed cases not counted).
            let busy: f64 = self
                .runs
                .iter()
                .map(|(r, _)| r.result.stats.wall.as_secs_f64())
                .sum();
            out.push(format!(
                "parallel     efficiency {:.0} % on {threads} threads (cases {busy:.1} s of {threads} x {:.1} s)",
                100.0 * busy / (threads as f64 * self.wall),
                self.wall
            ));
        }
        out
    }

    /// Computes the comparison table from the written study file `file` and writes it to
    /// `dir/<study>.md`; returns that path.
    pub fn write_table(&self, file: &Path, dir: &Path) -> Result<PathBuf> {
        let path = dir.join(format!("{}.md", self.study.spec.study.name));
        std::fs::write(&path, markdown(&report::compute(file)?)).map_err(|e| Error::Write {
            file: path.clone(),
            message: e.to_string(),
        })?;
        Ok(path)
    }

    /// Fails when a case failed, naming each failure (the others are written by then).
    pub fn finish(&self) -> Result<()> {
        if self.failed.is_empty() {
            return Ok(());
        }
        Err(Error::CasesFailed {
            file: self.study.path.clone(),
            cases: self.study.cases.len(),
            failures: self.failed.iter().map(|f| f.1.clone()).collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;

    fn scenes() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes")
    }

    fn study(cases: &str) -> Study {
        let text = format!(
            r#"
[study]
name = "pendulum-lengths"
scene = "pendulum.toml"
set = {{ "solver.end_time" = 0.2 }}
{cases}
"#
        );
        Study::parse(&text, &scenes().join("comparison-test.toml")).unwrap()
    }

    fn tmp(tag: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("jointplay-comparison-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn every_case_is_written_with_its_table_and_reported_in_order() {
        let st = study(
            r#"
[[cases]]
label = "base"

[[cases]]
label = "short"
set = { "solver.end_time" = 0.1 }
"#,
        );
        let seen = Mutex::new(Vec::new());
        let c = Comparison::run(&st, &|p| {
            // The fractions of a running case are not part of the order checked here.
            if !matches!(p, Progress::Fraction { .. }) {
                seen.lock().unwrap().push(format!("{p:?}"))
            }
        })
        .unwrap();
        let mut seen = seen.into_inner().unwrap();
        seen[1..].sort();
        assert_eq!(
            seen,
            [
                "Start { total: 2, pending: 2 }",
                "Done { job: 0, ok: true }",
                "Done { job: 1, ok: true }"
            ]
        );
        assert!(c.failed.is_empty());
        let labels: Vec<&str> = c.runs.iter().map(|(r, _)| r.label.as_str()).collect();
        assert_eq!(labels, ["base", "short"]);
        let lines = c.lines();
        assert!(
            lines[0].starts_with("study        pendulum-lengths ("),
            "{}",
            lines[0]
        );
        assert!(
            lines[0].ends_with("comparison-test.toml), 2 cases"),
            "{}",
            lines[0]
        );
        assert!(lines[1].starts_with("  base           "), "{}", lines[1]);
        assert!(lines[2].starts_with("  short          "), "{}", lines[2]);
        assert!(lines[3].starts_with("wall time    "), "{}", lines[3]);
        // On more than one thread the efficiency follows.
        if rayon::current_num_threads() > 1 {
            assert!(
                lines[4].starts_with("parallel     efficiency "),
                "{}",
                lines[4]
            );
            assert!(lines[4].contains(" % on ") && lines[4].contains("(cases "));
            assert_eq!(lines.len(), 5);
        } else {
            assert_eq!(lines.len(), 4);
        }

        let dir = tmp("ok");
        let file = c.write(&dir, "test").unwrap();
        assert_eq!(file, dir.join("pendulum-lengths.h5"));
        let h = hdf5::File::open(&file).unwrap();
        assert!(h.group("cases/base").is_ok() && h.group("cases/short").is_ok());
        let table = c.write_table(&file, &dir).unwrap();
        assert_eq!(table, dir.join("pendulum-lengths.md"));
        let md = std::fs::read_to_string(&table).unwrap();
        assert!(md.contains("base") && md.contains("short"), "{md}");
        c.finish().unwrap();
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn figure_groups_draw_one_set_of_figures_each_and_name_a_case_that_is_not_there() {
        let cases = r#"
[[cases]]
label = "base"

[[cases]]
label = "short"
set = { "solver.end_time" = 0.1 }

[report]
body = "bob"
joints = ["pivot"]
figures = [{ name = "both", cases = ["short", "base"] }, { name = "one", cases = ["base"] }]
"#;
        let st = study(cases);
        let c = Comparison::run(&st, &|_| {}).unwrap();
        let dir = tmp("groups");
        std::fs::create_dir_all(&dir).unwrap();
        // The pendulum has no clearance joint, so no orbit figures.
        let files = c.figures(&dir).unwrap();
        let names: Vec<String> = files
            .iter()
            .filter(|f| f.extension().is_some_and(|e| e == "png"))
            .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            [
                "pendulum-lengths-both-motion.png",
                "pendulum-lengths-both-forces.png",
                "pendulum-lengths-one-motion.png",
                "pendulum-lengths-one-forces.png"
            ]
        );
        let _ = std::fs::remove_dir_all(&dir);
        let bad = cases.replace(r#"cases = ["base"]"#, r#"cases = ["bsae"]"#);
        let text = format!("[study]\nname = \"x\"\nscene = \"pendulum.toml\"\n{bad}");
        let msg = Study::parse(&text, &scenes().join("comparison-test.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("report.figures[1].cases") && msg.contains("no case 'bsae'"),
            "{msg}"
        );
    }

    #[test]
    fn failed_cases_are_kept_in_the_file_and_named_in_the_error() {
        // RK4 with a 3 s step on a 1 m pendulum is far past its stability limit: the divergence
        // guard stops that case; the other one finishes.
        let st = study(
            r#"
[[cases]]
label = "base"

[[cases]]
label = "diverges"
set = { "solver.integrator" = "rk4", "solver.step" = 3.0, "solver.end_time" = 300.0 }
remove = ["solver.rtol", "solver.atol"]
"#,
        );
        let seen = Mutex::new(Vec::new());
        let c = Comparison::run(&st, &|p| {
            // The fractions of a running case are not part of the order checked here.
            if !matches!(p, Progress::Fraction { .. }) {
                seen.lock().unwrap().push(format!("{p:?}"))
            }
        })
        .unwrap();
        let mut seen = seen.into_inner().unwrap();
        seen[1..].sort();
        assert_eq!(
            seen,
            [
                "Start { total: 2, pending: 2 }",
                "Done { job: 0, ok: true }",
                "Done { job: 1, ok: false }"
            ]
        );
        assert_eq!(c.runs.len(), 1);
        assert_eq!(c.failed.len(), 1);
        assert_eq!(c.failed[0].0, "diverges");
        assert!(
            c.failed[0].1.contains("integration stopped at t = "),
            "{}",
            c.failed[0].1
        );
        let dir = tmp("failed");
        let file = c.write(&dir, "test").unwrap();
        let h = hdf5::File::open(&file).unwrap();
        assert!(h.group("cases/diverges").unwrap().attr("error").is_ok());
        assert!(h.dataset("cases/base/time").is_ok());
        let msg = c.finish().unwrap_err().to_string();
        assert!(
            msg.starts_with("1 of 2 cases of study ")
                && msg.contains("comparison-test.toml failed (the others are written; the file records the failures):\n  "),
            "{msg}"
        );
        assert!(msg.contains("diverges"), "{msg}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_study_whose_every_case_fails_is_an_error_naming_each_failure() {
        let st = study(
            r#"
[[cases]]
label = "diverges"
set = { "solver.integrator" = "rk4", "solver.step" = 3.0, "solver.end_time" = 300.0 }
remove = ["solver.rtol", "solver.atol"]
"#,
        );
        let msg = Comparison::run(&st, &|_| {}).unwrap_err().to_string();
        assert!(
            msg.starts_with("running study ")
                && msg.contains("comparison-test.toml: every case failed:\n  case 'diverges': "),
            "{msg}"
        );
    }
}
