//! Helpers shared by the analysis crate's integration tests.

use std::path::PathBuf;

use jointplay_analysis::storage::run::RunResult;
use jointplay_analysis::study::spec::Study;

/// The bundled scenes, `data/scenes`.
pub fn scenes() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes")
}

/// Runs a study whose scene paths are relative to `data/scenes` and returns its runs in the
/// order of its cases (every case must succeed).
pub fn run_study(text: &str) -> Vec<RunResult> {
    let study = Study::parse(text, &scenes().join("test-study.toml")).unwrap();
    study
        .run(&|_| {})
        .unwrap()
        .into_iter()
        .map(|r| r.unwrap().result)
        .collect()
}
