//! A disabled effect is absent: the run equals, bit for bit, a scene that never declared it, and
//! nothing of it is evaluated or recorded.

mod common;

use jointplay_analysis::storage::run::{Recording, RunResult};

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

/// The values of `dataset` in `r` (it must be recorded).
fn values<'a>(r: &'a Recording, dataset: &str) -> &'a [f64] {
    &r.channel(dataset)
        .unwrap_or_else(|| panic!("{dataset} is not recorded"))
        .values
}

fn assert_identical(a: &RunResult, b: &RunResult) {
    let (ra, rb) = (&a.recording, &b.recording);
    assert_eq!(ra.time, rb.time);
    assert!(ra.members("bodies").eq(rb.members("bodies")));
    for n in ra.members("bodies") {
        for q in ["position", "velocity", "acceleration"] {
            let d = format!("bodies/{n}/{q}");
            assert_eq!(values(ra, &d), values(rb, &d), "{d}");
        }
    }
    assert_eq!(ra.clearances.len(), rb.clearances.len());
    for (x, y) in ra.clearances.iter().zip(&rb.clearances) {
        assert_eq!(x.contacts, y.contacts, "{}", x.name);
        for q in ["normal_force", "friction_force"] {
            let d = format!("joints/{}/{q}", x.name);
            assert_eq!(
                values(ra, &d),
                values(rb, &format!("joints/{}/{q}", y.name)),
                "{d}"
            );
        }
    }
    assert!(ra.members("drives").eq(rb.members("drives")));
    for n in ra.members("drives") {
        let d = format!("drives/{n}/force");
        assert_eq!(values(ra, &d), values(rb, &d), "{d}");
    }
    assert_eq!(a.stats.rhs_evals, b.stats.rhs_evals);
}

/// Friction force values of every recorded clearance joint.
fn friction(r: &Recording) -> Vec<f64> {
    r.clearances
        .iter()
        .flat_map(|c| values(r, &format!("joints/{}/friction_force", c.name)).to_vec())
        .collect()
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
    let first = format!("bodies/{}/position", d.members("bodies").next().unwrap());
    assert_ne!(values(d, &first), values(full, &first));
    // Absent means not stored: R1 keeps its two rims only, and friction is exactly zero.
    let r1 = d.clearances.iter().find(|c| c.name == "R1").unwrap();
    assert_eq!(r1.contacts, ["P", "Q"]);
    assert!(!friction(d).is_empty() && friction(d).iter().all(|&f| f == 0.0));
    let r1_full = full.clearances.iter().find(|c| c.name == "R1").unwrap();
    assert_eq!(r1_full.contacts, ["P", "Q", "M", "N"]);
    assert!(friction(full).iter().any(|&f| f > 0.0));
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
    let energy = |r: &RunResult| {
        r.recording
            .channel("diagnostics/energy")
            .map(|c| c.values.len())
    };
    assert_eq!(energy(&runs[0]), None);
    assert!(energy(&runs[1]).is_some_and(|n| n > 0));
}
