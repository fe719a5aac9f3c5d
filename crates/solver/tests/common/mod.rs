//! Helpers shared by the solver's integration tests.

use std::path::Path;

use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::{Flow, Method, integrate};
use jointplay_solver::scene::{SceneFile, SceneSpec};

/// The text of the bundled scene `data/scenes/<name>`.
#[allow(dead_code)] // not every test file edits scenes
pub fn scene_text(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../data/scenes")
            .join(name),
    )
    .unwrap()
}

/// `text` with `from` replaced by `to` (which must be there).
#[allow(dead_code)] // not every test file edits scenes
pub fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "the scene no longer has {from:?}");
    text.replacen(from, to, 1)
}

/// The scene `text` (as if read from the file `name`) compiled and assembled.
#[allow(dead_code)] // not every test file compiles scenes from text
pub fn compile(name: &str, text: &str) -> jointplay_solver::error::Result<(Model, State)> {
    let path = Path::new(name);
    let file = SceneFile {
        path: path.to_path_buf(),
        spec: SceneSpec::parse(text, path)?,
        text: text.to_string(),
    };
    let (m, mut s) = Model::compile(&file)?;
    m.assemble(&mut s)?;
    Ok((m, s))
}

/// Integrates `model` from `state` to `t_end` and returns (t, y) at the `samples` times.
#[allow(dead_code)] // not every test file integrates
pub fn run_samples(
    model: &Model,
    state: &mut State,
    method: Method,
    t_end: f64,
    samples: &[f64],
) -> Vec<(f64, Vec<f64>)> {
    let mut out = Vec::new();
    let mut sys = Mechanism::new(model);
    integrate(
        &mut sys,
        method,
        state.t,
        &mut state.y,
        t_end,
        samples,
        |_, t, y| {
            out.push((t, y.to_vec()));
            Flow::Continue
        },
    )
    .unwrap();
    state.t = t_end;
    out
}
