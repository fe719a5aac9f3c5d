//! What accuracy costs per step: each integrator over one 0.02 s window of the 4-UPS/RPU with
//! clearance in S2, S5 and R1 (`data/scenes/4ups-rpu-mixed.toml`), from its state at 0.15 s (the
//! contacts active). The time is per window: multiply by 50 for one simulated second. The errors
//! these settings reach are measured by `jointplay precision analyses/precision/4ups-rpu.toml`
//! (book/src/results/work-precision.md).
//!
//! `cargo bench -p jointplay-analysis --bench integrators`

use std::path::PathBuf;

use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::Model;
use jointplay_solver::ode::{Flow, Method, integrate};
use jointplay_solver::scene::SceneSpec;

fn main() {
    divan::main();
}

const SETTINGS: [&str; 11] = [
    "rk4 1e-4",
    "rk4 5e-5",
    "bs3 1e-3",
    "bs3 1e-4",
    "dopri5 1e-3",
    "dopri5 1e-6",
    "dop853 1e-6",
    "dop853 1e-8",
    "rosenbrock23 1e-3",
    "ros34pw2 1e-3",
    "ros34pw2 1e-4",
];

/// The scene, compiled and assembled, and its state after 0.15 s.
fn prepared() -> (Model, Vec<f64>) {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/4ups-rpu-mixed.toml");
    let scene = SceneSpec::load(&path).unwrap();
    let (model, mut state) = Model::compile(&scene).unwrap();
    model.assemble(&mut state).unwrap();
    let mut sys = Mechanism::new(&model);
    integrate(
        &mut sys,
        model.settings.method,
        0.0,
        &mut state.y,
        0.15,
        &[],
        |_, _, _| Flow::Continue,
    )
    .unwrap();
    (model, state.y)
}

#[divan::bench(args = SETTINGS, sample_count = 20)]
fn window(bencher: divan::Bencher, setting: &str) {
    let (mut model, y0) = prepared();
    let (family, value) = setting.split_once(' ').unwrap();
    let value: f64 = value.parse().unwrap();
    let method = Method::of_family(family, value, value * 1e-3).unwrap();
    // The step-size guard follows the model's method.
    model.settings.method = method;
    bencher.bench_local(|| {
        let mut sys = Mechanism::new(&model);
        let mut y = y0.clone();
        let stats = integrate(&mut sys, method, 0.15, &mut y, 0.17, &[], |_, _, _| {
            Flow::Continue
        })
        .unwrap();
        divan::black_box((stats, y))
    });
}
