//! What each effect costs: the right-hand side of the 4-UPS/RPU with effects added one at a time.
//!
//! `cargo bench -p jointplay-analysis --bench effects`
//!
//! Variants, each built from `data/scenes/4ups-rpu-mixed.toml` by the study path edits:
//! ideal joints; clearance in S2; S2 + S5; + R1 radial (rims P, Q, the axial position a
//! constraint row); + R1 axial (faces M, N); + friction in all three; + an oil film in R1 (a
//! short-bearing film of 0.04 Pa s over the bushing's length); the same film as a long bearing
//! (R1's L/D is 9.3, where the long bearing is the fitting model); step 6 with LuGre friction in
//! place of the scene's (its 18 bristle states integrated with the rest). Friction stays off
//! until its step. Every variant is first integrated for 0.15 s (RK4, h = 1e-4 s; 1e-5 s for the
//! LuGre variant) so the timed
//! evaluation sees the contacts active, as they are for most of a run; the time is per
//! evaluation of the right-hand side at that state.

use std::path::PathBuf;

use jointplay_analysis::study::spec::edit;
use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::Model;
use jointplay_solver::ode::{Flow, OdeSystem, integrate};
use jointplay_solver::scene::{SceneFile, SceneSpec};
use toml::{Table, Value};

fn main() {
    divan::main();
}

const STEPS: [&str; 9] = [
    "1 ideal (0 contacts, 67 rows)",
    "2 +S2 (1 contact, 64 rows)",
    "3 +S5 (2 contacts, 61 rows)",
    "4 +R1 radial (4 contacts, 57 rows)",
    "5 +R1 axial (6 contacts, 56 rows)",
    "6 +friction (6 contacts, 56 rows)",
    "7 +R1 oil film (6 contacts, 56 rows)",
    "8 +R1 long-bearing film (6 contacts, 56 rows)",
    "9 LuGre in place of step 6's friction (6 contacts, 56 rows, 18 bristle states)",
];

/// The scene of step `k` of [`STEPS`] and its state after 0.15 s.
fn prepared(k: usize) -> (Model, f64, Vec<f64>) {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/4ups-rpu-mixed.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut t: Table = text.parse().unwrap();
    let rm = |t: &mut Table, p: &str| edit(t, p, None).unwrap();
    if k == 6 {
        edit(
            &mut t,
            "joints.R1.clearance.lubrication",
            Some(&Value::Table(toml::toml! { viscosity = 0.04 })),
        )
        .unwrap();
    }
    if k == 7 {
        edit(
            &mut t,
            "joints.R1.clearance.lubrication",
            Some(&Value::Table(toml::toml! {
                viscosity = 0.04
                model = "long"
            })),
        )
        .unwrap();
    }
    if k == 8 {
        // Bristles of 1e4 1/m relax at sigma0 |v| / g, up to 1e5 1/s at the contacts' sliding
        // speeds: beyond RK4's stability at the scene's step (it diverged at 6.7 ms), so this
        // variant is prepared with a step of 1e-5 s.
        edit(&mut t, "solver.step", Some(&Value::Float(1e-5))).unwrap();
        edit(
            &mut t,
            "joints.*.clearance.friction",
            Some(&Value::Table(toml::toml! {
                law = "lugre"
                coefficient = 0.1
                static_coefficient = 0.15
                stribeck_velocity = 1e-3
                bristle_stiffness = 1e4
                bristle_damping = 30.0
            })),
        )
        .unwrap();
    }
    if k < 5 {
        edit(
            &mut t,
            "joints.*.clearance.friction",
            Some(&Value::Table(toml::toml! { law = "none" })),
        )
        .unwrap();
    }
    if k < 4 {
        rm(&mut t, "joints.R1.clearance.axial_clearance");
        rm(&mut t, "joints.R1.clearance.face_radius");
    }
    if k < 3 {
        rm(&mut t, "joints.R1.clearance");
    }
    if k < 2 {
        rm(&mut t, "joints.S5.clearance");
    }
    if k < 1 {
        rm(&mut t, "joints.S2.clearance");
    }
    let text = toml::to_string(&t).unwrap();
    let spec = SceneSpec::parse(&text, &path).unwrap();
    let (model, mut state) = Model::compile(&SceneFile { path, text, spec }).unwrap();
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
    // The labels state the sizes; make sure they stay true.
    let label = STEPS[k];
    assert!(label.contains(&format!("{} rows", model.n_rows)), "{label}");
    assert!(
        label.contains(&format!("{} contact", model.n_contacts)),
        "{label}"
    );
    (model, 0.15, state.y)
}

fn index(step: &str) -> usize {
    STEPS.iter().position(|s| *s == step).unwrap()
}

#[divan::bench(args = STEPS, sample_count = 200)]
fn rhs(bencher: divan::Bencher, step: &str) {
    let (model, t, y) = prepared(index(step));
    let mut sys = Mechanism::new(&model);
    let mut dy = vec![0.0; y.len()];
    bencher.bench_local(|| {
        sys.rhs(t, divan::black_box(&y), &mut dy);
        divan::black_box(&dy);
    });
}

/// The applied-force stage alone (gyroscopic terms, gravity, contact and friction forces) at the
/// same states: the part of the right-hand side the contact effects add to.
#[divan::bench(args = STEPS, sample_count = 200)]
fn applied_forces(bencher: divan::Bencher, step: &str) {
    let (model, t, y) = prepared(index(step));
    let mut ws = jointplay_solver::dynamics::Workspace::new(&model);
    model.kinematics(&y, &mut ws);
    bencher.bench_local(|| {
        model.applied_forces(divan::black_box(t), &mut ws);
    });
}
