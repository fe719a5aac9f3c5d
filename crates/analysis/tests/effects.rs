//! A disabled effect is absent: the run equals, bit for bit, a scene that never declared it, and
//! nothing of it is evaluated or recorded.

mod common;

use jointplay_analysis::run::RunResult;

fn run(cases: &str) -> Vec<RunResult> {
    common::run_study(&format!(
        r#"
[study]
name = "effects"
scene = "4ups-rpu-mixed.toml"
set = {{ "solver.periods" = 0.05 }}
{cases}
"#
    ))
}

fn assert_identical(a: &RunResult, b: &RunResult) {
    let (ra, rb) = (&a.recording, &b.recording);
    assert_eq!(ra.time, rb.time);
    for (x, y) in ra.bodies.iter().zip(&rb.bodies) {
        assert_eq!(x.position, y.position, "{}", x.name);
        assert_eq!(x.velocity, y.velocity, "{}", x.name);
        assert_eq!(x.acceleration, y.acceleration, "{}", x.name);
    }
    assert_eq!(ra.clearances.len(), rb.clearances.len());
    for (x, y) in ra.clearances.iter().zip(&rb.clearances) {
        assert_eq!(x.contacts, y.contacts, "{}", x.name);
        assert_eq!(x.normal_force, y.normal_force, "{}", x.name);
        assert_eq!(x.friction_force, y.friction_force, "{}", x.name);
    }
    for (x, y) in ra.drives.iter().zip(&rb.drives) {
        assert_eq!(x.force, y.force, "{}", x.name);
    }
    assert_eq!(a.stats.rhs_evals, b.stats.rhs_evals);
}

#[test]
fn disabled_effects_equal_a_scene_that_never_declared_them() {
    // Left: the effects switched off by name. Right: the same scene written without them.
    let runs = run(r#"
[[cases]]
label = "disabled"
set = { disable = ["friction", "R1.axial_contact", "S5.contact_damping", "gravity"] }
[[cases]]
label = "never-declared"
set = { "joints.*.clearance.friction" = { law = "none" }, "joints.S5.clearance.normal.law" = "hertz" }
remove = [
  "joints.R1.clearance.axial_clearance",
  "joints.R1.clearance.face_radius",
  "joints.S5.clearance.normal.restitution",
  "gravity",
]
[[cases]]
label = "all-effects"
"#);
    assert_identical(&runs[0], &runs[1]);
    // The effects did something where they were on: the full scene differs.
    let (d, full) = (&runs[0].recording, &runs[2].recording);
    assert_ne!(d.bodies[0].position, full.bodies[0].position);
    // Absent means not stored: R1 keeps its two rims only, and friction is exactly zero.
    let r1 = d.clearances.iter().find(|c| c.name == "R1").unwrap();
    assert_eq!(r1.contacts, ["P", "Q"]);
    assert!(
        d.clearances
            .iter()
            .all(|c| c.friction_force.iter().all(|&f| f == 0.0))
    );
    let r1_full = full.clearances.iter().find(|c| c.name == "R1").unwrap();
    assert_eq!(r1_full.contacts, ["P", "Q", "M", "N"]);
    assert!(
        full.clearances
            .iter()
            .any(|c| c.friction_force.iter().any(|&f| f > 0.0))
    );
}

#[test]
fn disabling_a_joints_clearance_makes_it_ideal_and_energy_is_not_recorded() {
    let runs = run(r#"
[[cases]]
label = "disabled"
set = { disable = ["clearance", "energy"] }
[[cases]]
label = "never-declared"
remove = ["joints.S2.clearance", "joints.S5.clearance", "joints.R1.clearance"]
"#);
    assert_identical(&runs[0], &runs[1]);
    assert!(runs[0].recording.clearances.is_empty());
    let energy = |r: &RunResult| r.recording.diagnostics.as_ref().unwrap().energy.len();
    assert_eq!(energy(&runs[0]), 0);
    assert!(energy(&runs[1]) > 0);
}
