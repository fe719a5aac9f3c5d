//! Tests of the scene format: the contact laws' and the integrators' fields, and errors that name
//! the field path and clip what they echo.

use super::*;

/// A scene with one spherical clearance joint whose `normal` table is `normal`.
fn scene(normal: &str) -> Result<SceneSpec> {
    let text = format!(
        r#"
[[bodies]]
name = "ball"
mass = 1.0
inertia = {{ ixx = 1e-3, iyy = 1e-3, izz = 1e-3 }}

[[joints]]
name = "socket"
kind = "spherical"
body_a = "ground"
body_b = "ball"
point_a = [0.0, 0.0, 0.0]
point_b = [0.0, 0.0, 0.0]
clearance = {{ ball_radius = 0.01, radial_clearance = 1e-4, normal = {normal} }}
"#
    );
    SceneSpec::parse(&text, Path::new("law.toml"))
}

fn normal(normal: &str) -> NormalSpec {
    scene(normal).unwrap().joints[0]
        .clearance
        .clone()
        .unwrap()
        .normal
}

#[test]
fn each_normal_law_reads_its_own_fields() {
    let NormalSpec::Hertz(e) = normal(r#"{ law = "hertz", stiffness = 1e9, exponent = 1.2 }"#)
    else {
        panic!("not hertz")
    };
    assert_eq!((e.stiffness, e.exponent), (Some(1e9), Some(1.2)));
    assert_eq!(e.contact, ContactModel::Point);
    for (law, want) in [
        ("lankarani_nikravesh", "LankaraniNikravesh"),
        ("hunt_crossley", "HuntCrossley"),
        ("flores", "Flores"),
        ("gonthier", "Gonthier"),
        ("carvalho_martins", "CarvalhoMartins"),
    ] {
        let n = normal(&format!(
            r#"{{ law = "{law}", youngs_modulus = 2e11, poisson_ratio = 0.3, restitution = 0.9, onset_velocity_floor = 1e-6 }}"#
        ));
        assert!(format!("{n:?}").starts_with(want), "{law}: {n:?}");
        let e = n.elastic();
        assert_eq!((e.youngs_modulus, e.poisson_ratio), (Some(2e11), Some(0.3)));
    }
    let NormalSpec::Impact(i) = normal(
        r#"{ law = "impact", stiffness = 1e9, max_damping = 50.0, full_damping_penetration = 1e-5 }"#,
    ) else {
        panic!("not impact")
    };
    assert_eq!(
        (i.max_damping, i.full_damping_penetration),
        (Some(50.0), Some(1e-5))
    );
}

#[test]
fn a_field_the_law_does_not_take_is_rejected_naming_its_path() {
    for (law, field) in [
        ("hertz", "restitution"),
        ("hertz", "onset_velocity_floor"),
        ("hertz", "max_damping"),
        ("hertz", "full_damping_penetration"),
        ("lankarani_nikravesh", "max_damping"),
        ("hunt_crossley", "full_damping_penetration"),
        ("flores", "max_damping"),
        ("gonthier", "max_damping"),
        ("carvalho_martins", "full_damping_penetration"),
        ("impact", "restitution"),
        ("impact", "onset_velocity_floor"),
    ] {
        let err = scene(&format!(
            r#"{{ law = "{law}", stiffness = 1e9, {field} = 0.5 }}"#
        ))
        .unwrap_err()
        .to_string();
        assert!(
            err.starts_with(&format!(
                "law.toml: joints[0].clearance.normal.{field}: TOML parse error"
            )) && err.contains(&format!("unknown field `{field}`")),
            "{law}, {field}: {err}"
        );
    }
}

/// A scene's `[solver]` table with `integrator = name` and the given other keys.
fn solver(name: &str, keys: &str) -> Result<SolverSpec> {
    let text = format!("[solver]\nintegrator = \"{name}\"\n{keys}\nend_time = 1.0\n");
    SceneSpec::parse(&text, Path::new("solver.toml")).map(|s| s.solver)
}

/// The integrator names scenes accept, each giving its method: rk4 at its fixed step, the
/// others adaptive with the tolerances and step bound. An unknown name is rejected with the
/// list of the known ones, and the name is written back as it was read.
#[test]
fn every_scene_integrator_name_is_accepted() {
    let accepted = [
        ("rk4", "rk4, fixed step 2e-3 s"),
        ("dopri5", "dopri5, rtol 1e-7, atol 1e-9, max step 1e-1 s"),
        ("dop853", "dop853, rtol 1e-7, atol 1e-9, max step 1e-1 s"),
        (
            "rosenbrock23",
            "rosenbrock23, rtol 1e-7, atol 1e-9, max step 1e-1 s",
        ),
    ];
    for (name, described) in accepted {
        let sv = solver(
            name,
            "step = 2e-3\nrtol = 1e-7\natol = 1e-9\nmax_step = 0.1",
        )
        .unwrap();
        let method = sv
            .integrator
            .method(sv.step, sv.rtol, sv.atol, sv.max_step.unwrap());
        assert_eq!(
            (method.family(), method.describe().as_str()),
            (name, described)
        );
        let written = toml::to_string(&sv).unwrap();
        assert!(
            written.contains(&format!("integrator = \"{name}\"")),
            "{written}"
        );
    }
    assert_eq!(
        SolverSpec::default()
            .integrator
            .method(1e-3, 1e-6, 1e-9, 1.0)
            .family(),
        "rk4"
    );
    for name in ["dopri5_fixed", "rk45", "DOPRI5"] {
        let err = solver(name, "").unwrap_err().to_string();
        assert!(
            err.starts_with("solver.toml: solver.integrator: TOML parse error at line 2, column 14")
                && err.contains(&format!(
                    "unknown variant `{name}`, expected one of `rk4`, `bs3`, `dopri5`, `dop853`, `rosenbrock23`, `ros34pw2`"
                )),
            "{name}: {err}"
        );
    }
}

/// Every registered integrator is a scene integrator under its name.
#[test]
fn every_registered_integrator_parses_from_its_name() {
    for &integrator in crate::ode::INTEGRATORS {
        let sv = solver(integrator.name, "").unwrap();
        assert!(
            std::ptr::eq(sv.integrator.0, integrator),
            "{}",
            integrator.name
        );
    }
}

/// The parser's messages echoed a 10 MB value, and a 10 MB key, in full.
#[test]
fn a_huge_value_or_key_is_echoed_clipped() {
    let huge = "x".repeat(10_000_000);
    for text in [
        format!("name = 1\ndescription = \"{huge}\"\ngravity = \"{huge}\""),
        format!("{huge} = 1"),
    ] {
        let err = SceneSpec::parse(&text, Path::new("huge.toml"))
            .unwrap_err()
            .to_string();
        assert!(err.len() < 2000, "{} characters", err.len());
        assert!(
            err.starts_with("huge.toml: ") && err.contains("more characters)"),
            "{err}"
        );
    }
}

#[test]
fn a_field_the_friction_law_does_not_take_names_its_path() {
    let err = scene(
        r#"{ law = "hertz", stiffness = 1e9 }, friction = { law = "threlfall", coefficient = 0.1, v0 = 1e-3, v1 = 1.0 }"#,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.starts_with("law.toml: joints[0].clearance.friction.v1: TOML parse error")
            && err.contains("unknown field `v1`"),
        "{err}"
    );
}

/// Angles, rates and lengths given with a unit are read into SI; a unit of the wrong kind for a
/// drive's coordinate, or an unknown one, is refused naming the field.
#[test]
fn units_are_read_into_si_and_checked_against_the_drive() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/slider-crank-clearance.toml");
    let base = std::fs::read_to_string(&path).unwrap();
    let si = SceneSpec::parse(&base, &path).unwrap();
    let edited = base
        .replace("rate = 523.5987755982989", r#"rate = "5000 rpm""#)
        .replace("bushing_radius = 0.0100", r#"bushing_radius = "10 mm""#);
    let with_units = SceneSpec::parse(&edited, &path).unwrap();
    let rate = |s: &SceneSpec| match s.drives[0].profile {
        ProfileSpec::ConstantRate { rate, .. } => rate,
        _ => panic!("not a constant rate"),
    };
    let bushing = |s: &SceneSpec| {
        s.joints[2]
            .clearance
            .as_ref()
            .and_then(|c| c.bushing_radius)
            .unwrap()
    };
    // The file's rate is 5000 rpm written out to 16 digits, its radius 10 mm: equal to the
    // converted values to the last bits of the conversion's two roundings.
    assert!((rate(&with_units) / rate(&si) - 1.0).abs() < 4.0 * f64::EPSILON);
    assert!((bushing(&with_units) / bushing(&si) - 1.0).abs() < 4.0 * f64::EPSILON);

    // An angle in degrees.
    let turned = base.replace(
        "position = [0.17, 0.0, 0.0]",
        "position = [0.17, 0.0, 0.0]\norientation = { axis = [0.0, 0.0, 1.0], angle = \"90 deg\" }",
    );
    let turned = SceneSpec::parse(&turned, &path).unwrap();
    let angle = turned.bodies[2].orientation.angle.unwrap();
    assert_eq!(angle, std::f64::consts::FRAC_PI_2);

    // An angular rate on the prismatic guide, a length on the crank, an unknown unit.
    let on_guide = edited.replace(r#"joint = "crank_pivot""#, r#"joint = "guide""#);
    let err = SceneSpec::parse(&on_guide, &path).unwrap_err().to_string();
    assert!(
        err.contains("drives[0].profile.rate")
            && err.contains("'motor'")
            && err.contains("translation"),
        "{err}"
    );
    let length = base.replace("initial = 0.0,", r#"initial = "5 mm","#);
    let err = SceneSpec::parse(&length, &path).unwrap_err().to_string();
    assert!(
        err.contains("drives[0].profile.initial") && err.contains("rotation"),
        "{err}"
    );
    let unknown = base.replace("rate = 523.5987755982989", r#"rate = "5000 rev/min""#);
    let err = SceneSpec::parse(&unknown, &path).unwrap_err().to_string();
    assert!(
        err.contains("rate") && err.contains("unknown unit 'rev/min'"),
        "{err}"
    );
    let wrong = base.replace("bushing_radius = 0.0100", r#"bushing_radius = "10 deg""#);
    let err = SceneSpec::parse(&wrong, &path).unwrap_err().to_string();
    assert!(
        err.contains("bushing_radius") && err.contains("is an angle"),
        "{err}"
    );
}
