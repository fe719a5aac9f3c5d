//! Study-format paths as a user writes them from the book: a built-in system's default
//! observables, a sweep over one component of a vector field, and a `*` edit that adds a field
//! the scene leaves at its default.

use std::path::PathBuf;

use jointplay_analysis::study::analysis::Loaded;
use jointplay_analysis::study::spec::Study;

/// The bundled scenes, against which the studies' scene paths resolve.
fn scenes() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes")
}

/// An analysis study of a built-in system without `[[observables]]` observes its state names.
#[test]
fn a_builtin_system_observes_its_state_by_default() {
    let text = r#"
[study]
name = "duffing-default"
system = { kind = "duffing", gamma = 0.2, initial = [1.0, 0.0], solver = { integrator = "rk4", step = 0.05 } }

[analysis]
periods = 4
transient = 2
samples_per_period = 10
"#;
    let st = Loaded::parse(text, &scenes().join("duffing-default.toml")).unwrap();
    let names: Vec<(&str, &str)> = st
        .spec
        .observables
        .iter()
        .map(|o| (o.name.as_str(), o.path.as_str()))
        .collect();
    assert_eq!(names, [("x", "x"), ("v", "v")]);
    let r = st.run_single(&mut |_| {}).unwrap();
    assert_eq!(r.trace.strobe.len(), 2);
    assert_eq!(r.trace.strobe[0].len(), 2);
    assert_eq!(r.units, ["1", "1"]);

    // A scene has no default: the error says what to write.
    let scene = r#"
[study]
name = "no-observables"
scene = "pendulum.toml"

[analysis]
periods = 2
period = 1.0
"#;
    let err = Loaded::parse(scene, &scenes().join("s.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("s.toml: observables: name at least one observable"),
        "{err}"
    );
}

/// A sweep over one component of a vector field (gravity, an initial velocity, a point) sets
/// that component only, and the runs differ accordingly.
#[test]
fn a_sweep_addresses_a_component_of_a_vector_field() {
    let text = r#"
[study]
name = "gravity-sweep"
scene = "pendulum.toml"
set = { "solver.end_time" = 1.0, "bodies.bob.velocity" = [0.0, 0.0, 0.0] }

[analysis]
periods = 2
period = 0.5
samples_per_period = 0

[[observables]]
name = "x"
path = "bodies.bob.position.x"

[sweep]
parameter = "gravity.1"
# Along the pivot axis: the assembly projects it out, so only gravity matters.
also = ["bodies.bob.velocity.2"]
values = [-9.81, -1.62]
"#;
    let st = Loaded::parse(text, &scenes().join("gravity-sweep.toml")).unwrap();
    let earth = st.run_value(-9.81, &mut |_| {}).unwrap();
    let moon = st.run_value(-1.62, &mut |_| {}).unwrap();
    // The same pendulum swings slower in weaker gravity: after one period of 0.5 s it has
    // moved less from its release point (x = L sin 60 deg).
    let x0 = 0.866_025_403_784_438_6;
    let (e, m) = (earth.trace.strobe[0][0], moon.trace.strobe[0][0]);
    assert!(
        (x0 - m).abs() < (x0 - e).abs() && m < x0,
        "earth {e}, moon {m}"
    );

    // A component out of range names the path, the field and the length.
    let bad = text.replace("gravity.1", "gravity.3");
    let err = Loaded::parse(&bad, &scenes().join("gravity-sweep.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sweep.parameter ('gravity.3')")
            && err.contains("index 3 is out of range: 'gravity' has 3 components"),
        "{err}"
    );
}

/// `set` with `*` adds a field that the base scene leaves at its default, under every element
/// where the parent table exists; a field the schema does not know is still an error.
#[test]
fn a_wildcard_set_adds_a_defaulted_field_and_refuses_an_unknown_one() {
    let study = |key: &str| {
        format!(
            r#"
[study]
name = "floor"
scene = "slider-crank-clearance.toml"
set = {{ "joints.*.clearance.normal.{key}" = 1e-4 }}

[[cases]]
label = "low-floor"
"#
        )
    };
    let st = Study::parse(&study("onset_velocity_floor"), &scenes().join("floor.toml")).unwrap();
    let text = &st.cases[0].scene.text;
    assert_eq!(
        text.matches("onset_velocity_floor = 0.0001").count(),
        1,
        "{text}"
    );

    let err = Study::parse(&study("onset_velocity_flor"), &scenes().join("floor.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("case 'low-floor' of")
            && err.contains("floor.toml")
            && err.contains("unknown field `onset_velocity_flor`"),
        "{err}"
    );
}

/// A sweep path with a typo makes a key the scene's law does not have: the error names the
/// scene, the edit, the field and the keys there are, without the line and excerpt of the
/// edited tree written out again (they are not the user's file's).
#[test]
fn a_misspelt_sweep_path_is_named_without_the_edited_texts_lines() {
    let text = r#"
[study]
name = "typo"
scene = "variants/lugre-stick-slip-forced.toml"
[analysis]
periods = 2
transient = 1
[[observables]]
name = "x"
path = "bodies.block.position.x"
[sweep]
parameter = "joints.floor.clearance.friction.bristle_stifness"
values = [1.0, 2.0]
"#;
    let e = Loaded::parse(text, &scenes().join("typo.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("lugre-stick-slip-forced.toml")
            && e.contains("bristle_stifness = 1.0 in")
            && e.contains("joints[0].clearance.friction.bristle_stifness: unknown field")
            && e.contains("`bristle_stiffness`"),
        "{e}"
    );
    assert!(!e.contains("line ") && !e.contains(" | "), "{e}");
}
