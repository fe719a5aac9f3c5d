//! Validation of the clearance joints against analytic results: Hertz statics and impact
//! duration, the restitution each damped law produces, energy conservation, ballistic flight
//! inside the gap, and convergence to the ideal joint as the clearance closes.

mod common;

use std::path::Path;

use jointplay_solver::contact::{Damping, hunt_crossley_restitution, point_contact_stiffness};
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::Method;
use jointplay_solver::ode::dopri5::DOPRI5;
use jointplay_solver::scene::{SceneFile, SceneSpec};

/// A 1 kg ball (radius 15 mm) in a socket fixed to the ground, clearance `c`, with the given
/// normal-law and friction TOML, optional gravity, initial velocity `v`.
fn ball_scene(c: f64, normal: &str, gravity: Option<[f64; 3]>, v: [f64; 3]) -> SceneFile {
    let g = gravity
        .map(|g| format!("gravity = [{}, {}, {}]\n", g[0], g[1], g[2]))
        .unwrap_or_default();
    let text = format!(
        r#"
name = "ball"
{g}
[ground]
points = {{ O = [0.0, 0.0, 0.0] }}

[[bodies]]
name = "ball"
mass = 1.0
inertia = {{ ixx = 9.0e-5, iyy = 9.0e-5, izz = 9.0e-5 }}
velocity = [{}, {}, {}]
points = {{ C = [0.0, 0.0, 0.0] }}

[[joints]]
name = "socket"
kind = "spherical"
body_a = "ground"
body_b = "ball"
point_a = "O"
point_b = "C"
clearance = {{ ball_radius = 0.015, radial_clearance = {c}, normal = {normal}, start = "free" }}

[solver]
end_time = 1.0
"#,
        v[0], v[1], v[2]
    );
    parsed("ball.toml", text)
}

/// A scene parsed from generated text, named as if read from `name`.
fn parsed(name: &str, text: String) -> SceneFile {
    let path = Path::new(name);
    SceneFile {
        path: path.to_path_buf(),
        spec: SceneSpec::parse(&text, path).unwrap(),
        text,
    }
}

fn compile(f: &SceneFile) -> (Model, State) {
    let (m, mut s) = Model::compile(f).unwrap();
    m.assemble(&mut s).unwrap();
    (m, s)
}

use common::run_samples as run;

fn tight(max_step: f64) -> Method {
    Method::adaptive(&DOPRI5, 1e-11, 1e-14, max_step).unwrap()
}

const E: f64 = 207e9;
const NU: f64 = 0.3;
const C: f64 = 3e-4;

fn k_ball() -> f64 {
    point_contact_stiffness(0.015, 0.015 + C, E, NU, E, NU)
}

#[test]
fn ball_resting_in_socket_settles_at_the_hertz_penetration() {
    let f = ball_scene(
        C,
        r#"{ law = "lankarani_nikravesh", youngs_modulus = 207e9, poisson_ratio = 0.3, restitution = 0.9 }"#,
        Some([0.0, -9.81, 0.0]),
        [0.0; 3],
    );
    let (m, mut s) = compile(&f);
    // Falls 0.3 mm, bounces (c_e = 0.9) for ~0.15 s, then settles in continuous contact.
    let out = run(&m, &mut s, tight(1e-3), 0.6, &[0.6]);
    let y = &out[0].1;
    let delta = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]).sqrt() - C;
    let exact = (9.81 / k_ball()).powf(2.0 / 3.0);
    // Static balance K delta^1.5 = m g; measured 2e-11 relative (positions integrated to
    // ~1e-14 m absolute); the bound is 1e-8.
    assert!(
        ((delta - exact) / exact).abs() < 1e-8,
        "delta {delta:e} m vs (mg/K)^(2/3) = {exact:e} m"
    );
    assert!(y[1] < 0.0 && y[0].abs() < 1e-12 && y[2].abs() < 1e-12);
}

/// Head-on impact of the ball on the socket wall at v0 = 0.1 m/s without gravity: returns
/// (restitution, contact duration, max penetration, worst relative energy drift).
fn impact(normal: &str) -> (f64, f64, f64, f64) {
    let v0 = 0.1;
    let f = ball_scene(C, normal, None, [v0, 0.0, 0.0]);
    let (m, mut s) = compile(&f);
    // Free flight to the wall takes c/v0 = 3 ms; contact lasts ~0.2 ms. Sample the contact
    // densely (0.1 us) so that its duration can be read from the samples.
    let samples: Vec<f64> = (0..=40000).map(|k| 2.9e-3 + k as f64 * 1e-8).collect();
    let out = run(&m, &mut s, tight(2e-6), 4.0e-3, &samples);
    let mut ws = jointplay_solver::dynamics::Workspace::new(&m);
    let e0 = 0.5 * v0 * v0;
    let mut drift: f64 = 0.0;
    let (mut t_in, mut t_out, mut dmax) = (f64::NAN, f64::NAN, 0.0f64);
    let mut prev: Option<(f64, f64)> = None;
    for (t, y) in &out {
        let d = y[0].hypot(y[1]).hypot(y[2]) - C;
        dmax = dmax.max(d);
        if let Some((tp, dp)) = prev {
            if dp <= 0.0 && d > 0.0 {
                t_in = tp + (t - tp) * (-dp) / (d - dp);
            }
            if dp > 0.0 && d <= 0.0 {
                t_out = tp + (t - tp) * dp / (dp - d);
            }
        }
        prev = Some((*t, d));
        drift = drift.max((m.energy(y, &mut ws) - e0).abs() / e0);
    }
    let v_after = s.y[7];
    (-v_after / v0, t_out - t_in, dmax, drift)
}

#[test]
fn hertz_impact_is_elastic_with_the_hertz_duration() {
    let (e, tc, dmax, drift) =
        impact(r#"{ law = "hertz", youngs_modulus = 207e9, poisson_ratio = 0.3 }"#);
    let v0 = 0.1;
    let exact_dmax = (5.0 * v0 * v0 / (4.0 * k_ball())).powf(0.4);
    // Hertz (Johnson 1985, sec. 11.4): t_c = 2.9433 delta_max / v0 (constant 2.943275 from
    // 2 (2/5) B(2/5, 1/2)); delta_max = (5 m v0^2 / (4 K))^(2/5). Measured: t_c within 6e-8
    // relative (samples 1e-8 s apart, crossings interpolated), delta_max within 2e-9.
    let exact_tc = 2.943275 * exact_dmax / v0;
    assert!(
        ((dmax - exact_dmax) / exact_dmax).abs() < 1e-7,
        "delta_max {dmax:e} vs {exact_dmax:e}"
    );
    assert!(
        ((tc - exact_tc) / exact_tc).abs() < 1e-6,
        "t_c {tc:e} vs {exact_tc:e}"
    );
    // Undamped and frictionless: restitution 1 (measured 1 - 9e-11) and energy conserved to the
    // integrator tolerance (measured 2e-9 relative, elastic contact energy included).
    assert!((e - 1.0).abs() < 1e-8, "restitution {e}");
    assert!(drift < 1e-7, "energy drift {drift:e}");
}

#[test]
fn damped_laws_restore_their_analytic_restitution() {
    let ce = 0.9;
    for (law, kind) in [
        ("lankarani_nikravesh", Damping::LankaraniNikravesh),
        ("hunt_crossley", Damping::HuntCrossley),
        ("flores", Damping::Flores),
        ("gonthier", Damping::Gonthier),
        ("carvalho_martins", Damping::CarvalhoMartins),
    ] {
        let normal = format!(
            r#"{{ law = "{law}", youngs_modulus = 207e9, poisson_ratio = 0.3, restitution = {ce}, onset_velocity_floor = 1e-6 }}"#
        );
        let (e, _, _, _) = impact(&normal);
        let exact = hunt_crossley_restitution(kind.factor(ce));
        // The relation (1 + D) = (1 - e D) exp(D (1 + e)) is exact for an isolated impact; the
        // simulated values agree to 2e-10 (integration error at rtol 1e-11 and the onset
        // velocity located inside the step); the bound is 1e-8.
        assert!(
            (e - exact).abs() < 1e-8,
            "{law}: restitution {e} vs {exact}"
        );
        if kind == Damping::LankaraniNikravesh {
            assert!((e - 0.913).abs() < 5e-4, "L-N at c_e = 0.9 restores {e}");
        }
        if kind == Damping::CarvalhoMartins {
            // Their approximation of the exact inverse is within 2e-4 of c_e.
            assert!((e - ce).abs() < 2e-4, "Carvalho-Martins restores {e}");
        }
    }
}

#[test]
fn impact_function_without_damping_is_hertz_and_with_damping_dissipates() {
    let k = k_ball();
    let (e0, tc0, _, _) = impact(&format!(
        r#"{{ law = "impact", stiffness = {k}, max_damping = 0.0, full_damping_penetration = 1e-6 }}"#
    ));
    let (eh, tch, _, _) =
        impact(r#"{ law = "hertz", youngs_modulus = 207e9, poisson_ratio = 0.3 }"#);
    assert!((e0 - eh).abs() < 1e-9 && (tc0 - tch).abs() < 1e-9);
    let mut last = 1.0;
    for c_max in [100.0, 1000.0, 10000.0] {
        let (e, _, _, _) = impact(&format!(
            r#"{{ law = "impact", stiffness = {k}, max_damping = {c_max}, full_damping_penetration = 1e-6 }}"#
        ));
        assert!(e < last && e > 0.0, "c_max {c_max}: restitution {e}");
        last = e;
    }
}

#[test]
fn motion_inside_the_gap_is_ballistic() {
    let v = [0.01, 0.02, -0.005];
    let g = [0.0, -9.81, 0.0];
    let f = ball_scene(C, r#"{ law = "hertz", stiffness = 1e10 }"#, Some(g), v);
    let (m, mut s) = compile(&f);
    // The ball leaves the centre; first contact when |r| = c, after about 5.5 ms here.
    let samples: Vec<f64> = (0..=50).map(|k| k as f64 * 1e-4).collect();
    let out = run(&m, &mut s, tight(1e-3), 5e-3, &samples);
    for (t, y) in &out {
        let r = y[0].hypot(y[1]).hypot(y[2]);
        assert!(r < C, "contact reached at t = {t}");
        for k in 0..3 {
            let exact = v[k] * t + 0.5 * g[k] * t * t;
            // Polynomial motion: DOPRI5 integrates it to rounding.
            assert!(
                (y[k] - exact).abs() < 1e-15,
                "t = {t}, axis {k}: {} vs {exact}",
                y[k]
            );
        }
    }
}

/// A pendulum (1 kg bob, 0.5 m below the pivot) hanging from a ball joint with clearance `c`
/// (None: ideal spherical joint), released from 30 degrees.
fn pendulum(c: Option<f64>) -> SceneFile {
    let clearance = c
        .map(|c| format!(
            "clearance = {{ ball_radius = 0.01, radial_clearance = {c}, normal = {{ law = \"lankarani_nikravesh\", stiffness = 1e10, restitution = 0.5 }} }}"
        ))
        .unwrap_or_default();
    let th: f64 = 30f64.to_radians();
    let text = format!(
        r#"
gravity = [0.0, -9.81, 0.0]
[ground]
points = {{ O = [0.0, 0.0, 0.0] }}
[[bodies]]
name = "bob"
mass = 1.0
inertia = {{ ixx = 1e-3, iyy = 1e-3, izz = 1e-3 }}
position = [{}, {}, 0.0]
orientation = {{ axis = [0.0, 0.0, 1.0], angle = {th} }}
points = {{ P = [0.0, 0.5, 0.0] }}
[[joints]]
name = "pivot"
kind = "spherical"
body_a = "ground"
body_b = "bob"
point_a = "O"
point_b = "P"
{clearance}
[solver]
end_time = 1.0
"#,
        0.5 * th.sin(),
        -0.5 * th.cos()
    );
    parsed("pendulum-clearance.toml", text)
}

#[test]
fn response_approaches_the_ideal_joint_as_the_clearance_closes() {
    let samples: Vec<f64> = (0..=100).map(|k| k as f64 * 0.01).collect();
    let track = |c: Option<f64>| {
        let (m, mut s) = compile(&pendulum(c));
        run(
            &m,
            &mut s,
            Method::adaptive(&DOPRI5, 1e-9, 1e-12, 1e-3).unwrap(),
            1.0,
            &samples,
        )
        .into_iter()
        .map(|(_, y)| [y[0], y[1]])
        .collect::<Vec<_>>()
    };
    let ideal = track(None);
    let mut errors = Vec::new();
    for c in [1e-3, 1e-4, 1e-5] {
        let t = track(Some(c));
        let err = t
            .iter()
            .zip(&ideal)
            .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
            .fold(0.0f64, f64::max);
        errors.push(err);
    }
    // The bob's deviation from the ideal pendulum over one second shrinks with the clearance
    // (and the contact stiffness 1e10 N/m^1.5 keeps the penetration, ~1e-7 m, below the
    // smallest clearance). Measured 1.5e-3, 1.5e-4, 1.6e-5 m: linear in c. Required: at least
    // 5x per decade of clearance, and below 3 c at the smallest.
    assert!(
        errors[1] < errors[0] / 5.0 && errors[2] < errors[1] / 5.0,
        "{errors:?}"
    );
    assert!(errors[2] < 3e-5, "{errors:?}");
}

/// A 2 kg shaft in a bushing fixed to the ground (the paper's R1 dimensions), axis along z,
/// gravity along -y; `axial` adds the axial clearance (faces M, N).
fn shaft_scene(axial: bool, friction: &str) -> SceneFile {
    let axial = if axial {
        "\nface_radius = 0.014\naxial_clearance = 3e-4"
    } else {
        ""
    };
    let text = format!(
        r#"
gravity = [0.0, -9.81, 0.0]
[ground]
points = {{ B = [0.0, 0.0, 0.0] }}
axes = {{ z = [0.0, 0.0, 1.0] }}
[[bodies]]
name = "shaft"
mass = 2.0
inertia = {{ ixx = 5e-3, iyy = 5e-3, izz = 1e-4 }}
points = {{ J = [0.0, 0.0, 0.0] }}
axes = {{ z = [0.0, 0.0, 1.0] }}
[[joints]]
name = "R1"
kind = "revolute"
body_a = "ground"
body_b = "shaft"
point_a = "B"
point_b = "J"
axis_a = "z"
axis_b = "z"
[joints.clearance]
journal_radius = 0.0097
radial_clearance = 3e-4
bushing_length = 0.18{axial}
normal = {{ law = "lankarani_nikravesh", youngs_modulus = 207e9, poisson_ratio = 0.3, restitution = 0.5 }}
friction = {friction}
start = "free"
[solver]
end_time = 1.0
"#
    );
    parsed("shaft.toml", text)
}

#[test]
fn shaft_in_bushing_settles_with_the_load_shared_by_both_rims() {
    for axial in [false, true] {
        let (m, mut s) = compile(&shaft_scene(axial, r#"{ law = "none" }"#));
        let out = run(&m, &mut s, tight(1e-3), 0.5, &[0.5]);
        let y = &out[0].1;
        let k = point_contact_stiffness(0.0097, 0.0100, E, NU, E, NU);
        // Axes parallel: line contact carried by the two rim points, 2 K delta^1.5 = m g.
        let delta = -y[1] - 3e-4;
        let exact = (2.0 * 9.81 / (2.0 * k)).powf(2.0 / 3.0);
        // Measured to ~1e-10 relative; the bound is 1e-7 (delta ~ 2.3e-7 m).
        assert!(
            ((delta - exact) / exact).abs() < 1e-7,
            "axial {axial}: delta {delta:e} vs {exact:e}"
        );
        // No axial motion, no tilt.
        assert!(
            y[2].abs() < 1e-12 && y[4].abs() < 1e-9 && y[5].abs() < 1e-9,
            "{y:?}"
        );
    }
}

#[test]
fn friction_never_exceeds_mu_times_the_normal_force_in_a_running_mechanism() {
    // A shaft spinning in its bushing under gravity: it rolls up the wall and slides, with
    // Ambrosio's friction mu = 0.1 between v0 = 1e-4 and v1 = 1e-2 m/s.
    let f = shaft_scene(
        true,
        r#"{ law = "ambrosio", coefficient = 0.1, v0 = 1e-4, v1 = 1e-2 }"#,
    );
    let f = SceneFile {
        text: f.text.replace(
            "points = { J = [0.0, 0.0, 0.0] }",
            "points = { J = [0.0, 0.0, 0.0] }\nangular_velocity = [0.0, 0.0, 50.0]",
        ),
        ..f
    };
    let f = SceneFile {
        spec: SceneSpec::parse(&f.text, &f.path).unwrap(),
        ..f
    };
    let (m, mut s) = compile(&f);
    let samples: Vec<f64> = (0..=400).map(|k| k as f64 * 5e-4).collect();
    let out = run(&m, &mut s, tight(1e-4), 0.2, &samples);
    let mut ws = jointplay_solver::dynamics::Workspace::new(&m);
    let (mut sliding, mut worst) = (0, 0.0f64);
    for (t, y) in &out {
        m.accelerations(*t, y, &mut ws);
        for c in &ws.contacts {
            if c.fn_ > 0.0 {
                let ratio = c.ft.norm() / c.fn_;
                worst = worst.max(ratio);
                if ratio > 0.05 {
                    sliding += 1;
                }
            }
        }
    }
    assert!(worst <= 0.1 * (1.0 + 1e-12), "|F_T| / F_N reached {worst}");
    assert!(
        sliding > 10,
        "the test must exercise sliding contact ({sliding} samples)"
    );
}

/// A 2 kg pin in a planar bearing (radius 10 mm, clearance 0.5 mm) with Johnson's line contact
/// over 20 mm; the pin's axis is z, gravity along -y; `normal_law` selects the damping.
fn pin_scene(law: &str, v: [f64; 3]) -> SceneFile {
    let text = format!(
        r#"
gravity = [0.0, -9.81, 0.0]
[ground]
points = {{ B = [0.0, 0.0, 0.0] }}
axes = {{ z = [0.0, 0.0, 1.0] }}
[[bodies]]
name = "pin"
mass = 2.0
inertia = {{ ixx = 1e-4, iyy = 1e-4, izz = 1e-4 }}
velocity = [{}, {}, {}]
points = {{ J = [0.0, 0.0, 0.0] }}
axes = {{ z = [0.0, 0.0, 1.0] }}
[[joints]]
name = "bearing"
kind = "revolute"
body_a = "ground"
body_b = "pin"
point_a = "B"
point_b = "J"
axis_a = "z"
axis_b = "z"
[joints.clearance]
model = "planar"
journal_radius = 0.0095
radial_clearance = 5e-4
normal = {{ law = "{law}", contact = "line", contact_length = 0.02, youngs_modulus = 207e9, poisson_ratio = 0.3{} }}
start = "free"
[solver]
end_time = 1.0
"#,
        v[0],
        v[1],
        v[2],
        if law == "hertz" {
            ""
        } else {
            ", restitution = 0.5"
        }
    );
    parsed("pin.toml", text)
}

#[test]
fn pin_in_bearing_with_line_contact_settles_at_johnsons_penetration() {
    let (m, mut s) = compile(&pin_scene("lankarani_nikravesh", [0.0; 3]));
    let out = run(&m, &mut s, tight(1e-3), 0.5, &[0.5]);
    let delta = -out[0].1[1] - 5e-4;
    // Johnson: delta = (F / (pi L E*)) (ln(4 pi L E* dR / F) - 1) with F = m g, explicit.
    let c = std::f64::consts::PI * 0.02 * 207e9 / (2.0 * (1.0 - 0.09));
    let f = 2.0 * 9.81;
    let exact = f / c * ((4.0 * c * 5e-4 / f).ln() - 1.0);
    // delta ~ 3e-8 m; the bound 1e-6 relative is ~3e-14 m, the position accuracy of the run.
    assert!(
        ((delta - exact) / exact).abs() < 1e-6,
        "delta {delta:e} vs {exact:e}"
    );
}

#[test]
fn undamped_line_contact_conserves_energy() {
    let (m, mut s) = compile(&pin_scene("hertz", [0.3, 0.0, 0.0]));
    let samples: Vec<f64> = (0..=200).map(|k| k as f64 * 1e-4).collect();
    let out = run(&m, &mut s, tight(1e-5), 0.02, &samples);
    let mut ws = jointplay_solver::dynamics::Workspace::new(&m);
    let e: Vec<f64> = out.iter().map(|(_, y)| m.energy(y, &mut ws)).collect();
    let scale = 0.5 * 2.0 * 0.09;
    let worst = e.iter().map(|x| (x - e[0]).abs()).fold(0.0, f64::max) / scale;
    // Several impacts happen in 20 ms (the pin crosses the 1 mm gap in ~3 ms); the elastic
    // energy of the contact is its closed-form integral, so kinetic + potential + contact energy
    // stays at the integration tolerance.
    let impacts = out.windows(2).filter(|w| {
        let d = |y: &[f64]| y[0].hypot(y[1]) - 5e-4;
        d(&w[0].1) <= 0.0 && d(&w[1].1) > 0.0
    });
    assert!(impacts.count() >= 2, "the run must contain impacts");
    assert!(worst < 1e-7, "relative energy drift {worst:e}");
}

/// Contact onsets as integrator events (`solver.onset_events`): the step that reaches the wall
/// ends at the onset, located on the dense output, and the next one starts there with a fresh
/// step-size estimate. On the head-on impact above at a loose tolerance (DOPRI5, rtol 1e-7,
/// no step bound) the approach velocity the law remembers is the exact 0.1 m/s (straight free
/// flight: the penetration is linear in time up to the onset) to 1e-8, and the restitution is
/// the law's analytic value to the tolerance's level. With contact ends as events too
/// (`solver.end_events`) the step that leaves the wall ends where the penetration is zero, and
/// the restitution comes closer still. In every case the onset velocity is forgotten once the
/// ball is out of contact at a step's end.
#[test]
fn contact_events_end_steps_at_the_onset_and_the_end_and_keep_the_restitution() {
    let v0 = 0.1;
    let normal = r#"{ law = "lankarani_nikravesh", youngs_modulus = 207e9, poisson_ratio = 0.3, restitution = 0.9, onset_velocity_floor = 1e-6 }"#;
    let exact = hunt_crossley_restitution(Damping::LankaraniNikravesh.factor(0.9));
    for (onsets, ends) in [(false, false), (true, false), (true, true), (false, true)] {
        let base = ball_scene(C, normal, None, [v0, 0.0, 0.0]);
        let f = parsed(
            "ball.toml",
            base.text.replace(
                "[solver]\n",
                &format!("[solver]\nonset_events = {onsets}\nend_events = {ends}\n"),
            ),
        );
        let (m, mut s) = compile(&f);
        assert_eq!(
            (m.settings.onset_events, m.settings.end_events),
            (onsets, ends)
        );
        let mut sys = jointplay_solver::dynamics::Mechanism::new(&m);
        let mut onset = f64::NAN;
        let (mut cleared, mut nearest) = (None, (f64::NAN, f64::INFINITY));
        let method = Method::adaptive(&DOPRI5, 1e-7, 1e-12, f64::INFINITY).unwrap();
        let gap = |y: &[f64]| y[0].hypot(y[1]).hypot(y[2]) - C;
        let mut on_step = |sys: &mut jointplay_solver::dynamics::Mechanism,
                           step: &jointplay_solver::ode::Step| {
            if step.t0 < 3.02e-3 && step.t1 >= 3.02e-3 {
                onset = sys.ws.onset[0];
            }
            // The first step to end out of contact, and the nearest to the surface that a step
            // starting in contact ends.
            if gap(step.y0) > 0.0 {
                if gap(step.y1) <= 0.0 && cleared.is_none() {
                    cleared = Some(sys.ws.onset[0]);
                }
                if gap(step.y1).abs() < nearest.1.abs() {
                    nearest = (step.t1, gap(step.y1));
                }
            }
            jointplay_solver::ode::Flow::Continue
        };
        let stats = jointplay_solver::ode::integrate_steps(
            &mut sys,
            method,
            0.0,
            &mut s.y,
            4.0e-3,
            &[],
            |_, _, _| jointplay_solver::ode::Flow::Continue,
            Some(&mut on_step),
        )
        .unwrap();
        let e = -s.y[7] / v0;
        // Without onset events the stages of the step that straddles the onset see the contact
        // force, and so does the interpolant the onset velocity is read from: measured 3.0e-4
        // off, restitution 8.0e-5 off. With them the straddling step is taken again up to the
        // onset; when it lands a round-off short of the surface, the next step crosses within
        // its first thousandth and stands as an ordinary step (measured: velocity 2.7e-9 off).
        // Bounds: 1e-8 and 1e-5.
        if onsets {
            assert!((onset - v0).abs() < 1e-8 * v0, "onset velocity {onset}");
        } else {
            assert!((onset - v0).abs() > 1e-5, "onset velocity {onset}");
        }
        let cleared = cleared.expect("the ball leaves the wall");
        assert!(
            cleared.is_nan(),
            "onset velocity {cleared} kept after the end"
        );
        let (t_end, gap_end) = nearest;
        // One event per kind that is on, and a few more where a retaken step lands a round-off
        // short of the surface and the next one crosses it again (measured: exactly one each).
        let n = u64::from(onsets) + u64::from(ends);
        if n == 0 {
            assert_eq!(stats.events, 0);
        } else {
            assert!(
                (n..=n + 3).contains(&stats.events),
                "{} events",
                stats.events
            );
        }
        // The step that leaves the wall: without end events it runs on into free flight (the
        // nearest a step from contact ends to the surface: measured 1.2e-8 and 2.6e-7 m at rtol
        // 1e-7); with them it is taken again up to the end and lands on the surface to the
        // position's absolute tolerance (atol 1e-12 m; measured 1.1e-12 m out, or 3e-16 m in,
        // the next step then crossing in its first thousandth): bounds 1e-11 and 1e-9 m.
        if ends {
            assert!(
                gap_end.abs() < 1e-11,
                "gap {gap_end:e} m at the end, t = {t_end} s"
            );
        } else {
            assert!(
                gap_end.abs() > 1e-9,
                "gap {gap_end:e} m at the end, t = {t_end} s"
            );
        }
        // Restitution against the law's exact value: the onset velocity's error dominates
        // without onset events (measured 8.0e-5); with onsets alone the step over the end is
        // stepped over (5.1e-6); with both, 1.3e-7. Bounds 1e-5 and 1e-6.
        match (onsets, ends) {
            (true, false) => assert!((e - exact).abs() < 1e-5, "restitution {e} vs {exact}"),
            (true, true) => assert!((e - exact).abs() < 1e-6, "restitution {e} vs {exact}"),
            _ => assert!((e - exact).abs() > 1e-5, "restitution {e} vs {exact}"),
        }
    }
}

/// The linearised normal mode of a penetrating contact ([`Model::contact_modes`]) is that of the
/// damper-spring its law gives on the ball's mass. Lankarani-Nikravesh, F = K delta^1.5 (1 +
/// 3 (1 - c_e^2) / 4 delta_dot / v_on): k = dF/d(delta) = 1.5 K delta^0.5 (1 + 3 (1 - c_e^2) / 4
/// delta_dot / v_on) and c = dF/d(delta_dot) = 3 (1 - c_e^2) / 4 K delta^1.5 / v_on; the socket is
/// the ground and the normal passes through the ball's centre, so the effective mass is the
/// ball's 1 kg and lambda = (-c +- sqrt(c^2 - 4 m k)) / (2 m). The two sides are the same
/// formulas evaluated in another order, so they agree to round-off (1e-12 leaves a margin of
/// 1e3 over it); a wrong mass or derivative changes lambda by order 1. (The lever arms and the
/// constraints' share of the effective mass are the step-size guard's, which
/// `crates/solver/src/guard.rs` shares with it.)
#[test]
fn contact_modes_are_the_laws_damper_spring_on_the_effective_mass() {
    let f = ball_scene(
        C,
        r#"{ law = "lankarani_nikravesh", youngs_modulus = 207e9, poisson_ratio = 0.3, restitution = 0.9 }"#,
        None,
        [0.0; 3],
    );
    let (m, s) = compile(&f);
    let mut ws = jointplay_solver::dynamics::Workspace::new(&m);
    let mut modes = Vec::new();
    let mut y = s.y.clone();
    let mut dydt = vec![0.0; y.len()];
    // In the gap: no mode.
    m.rhs(0.0, &y, &mut ws, &mut dydt);
    m.contact_modes(&mut ws, &mut modes);
    assert_eq!(modes, vec![None]);
    let (delta, rate, v_on, ce) = (1e-5, 0.05, 0.1, 0.9);
    y[0] = C + delta;
    y[7] = rate;
    ws.onset[0] = v_on;
    m.rhs(0.0, &y, &mut ws, &mut dydt);
    m.contact_modes(&mut ws, &mut modes);
    let a = 3.0 * (1.0 - ce * ce) / 4.0;
    let k = 1.5 * k_ball() * delta.sqrt() * (1.0 + a * rate / v_on);
    let c = a * k_ball() * delta.powf(1.5) / v_on;
    let disc = c * c - 4.0 * k;
    assert!(disc < 0.0, "an underdamped mode at this state");
    let (re, im) = (-c / 2.0, (-disc).sqrt() / 2.0);
    let Some(Some((got_re, got_im))) = modes.first().copied() else {
        panic!("no mode for the penetrating contact: {modes:?}");
    };
    assert!(
        ((got_re - re) / re).abs() < 1e-12 && ((got_im - im) / im).abs() < 1e-12,
        "mode {got_re:e} +- {got_im:e}i 1/s, expected {re:e} +- {im:e}i 1/s"
    );
}

/// Friction kinks as integrator events (`solver.friction_events`): Ambrosio's coefficient has
/// kinks at the sliding speeds v0 = 1e-4 and v1 = 1e-2 m/s. The shaft of the test above, spun at
/// 1.5 rad/s (0.0146 m/s at its surface), drops onto its bushing, slides, rolls and rocks, and
/// its sliding speed crosses both kinks while the contact is closed (16 steps across one in
/// 0.1 s, measured). With the setting each crossing ends a step, which lands on the kink
/// speed; without it steps run across the kinks.
#[test]
fn friction_events_end_steps_at_the_friction_laws_kinks() {
    let friction = r#"{ law = "ambrosio", coefficient = 0.1, v0 = 1e-4, v1 = 1e-2 }"#;
    let kinks = [1e-4, 1e-2];
    for events in [false, true] {
        let text = shaft_scene(false, friction)
            .text
            .replace(
                "points = { J = [0.0, 0.0, 0.0] }",
                "points = { J = [0.0, 0.0, 0.0] }\nangular_velocity = [0.0, 0.0, 1.5]",
            )
            .replace(
                "[solver]\n",
                &format!("[solver]\nfriction_events = {events}\n"),
            );
        let (m, mut s) = compile(&parsed("shaft.toml", text));
        assert_eq!(m.settings.friction_events, events);
        let mut sys = jointplay_solver::dynamics::Mechanism::new(&m);
        let mut ws = jointplay_solver::dynamics::Workspace::new(&m);
        let (mut rates, mut speeds) = (Vec::new(), Vec::new());
        // Steps whose ends, with the contact closed at both, lie on either side of a kink, and
        // the largest distance from the kink (relative) of the nearer end of such a step.
        let (mut across, mut worst) = (0, 0.0f64);
        let mut on_step = |_: &mut jointplay_solver::dynamics::Mechanism,
                           step: &jointplay_solver::ode::Step| {
            let mut ends = [[(0.0, 0.0); 2]; 2];
            for (e, y) in ends.iter_mut().zip([step.y0, step.y1]) {
                m.contact_rates(y, &mut ws, &mut rates);
                m.sliding_speeds(&ws, &mut speeds);
                for (slot, e) in e.iter_mut().enumerate() {
                    *e = (rates[slot].0, speeds[slot]);
                }
            }
            for slot in 0..2 {
                if ends.iter().any(|e| e[slot].0 <= 0.0) {
                    continue;
                }
                for vk in kinks {
                    let (a, b) = (ends[0][slot].1 - vk, ends[1][slot].1 - vk);
                    if a * b <= 0.0 {
                        across += 1;
                        worst = worst.max(a.abs().min(b.abs()) / vk);
                    }
                }
            }
            jointplay_solver::ode::Flow::Continue
        };
        let method = Method::adaptive(&DOPRI5, 1e-8, 1e-11, f64::INFINITY).unwrap();
        let stats = jointplay_solver::ode::integrate_steps(
            &mut sys,
            method,
            0.0,
            &mut s.y,
            0.1,
            &[],
            |_, _, _| jointplay_solver::ode::Flow::Continue,
            Some(&mut on_step),
        )
        .unwrap();
        assert!(
            across >= 10,
            "{across} steps across a kink: the test must cross kinks"
        );
        // With the events a crossing step is taken again up to the kink located on its dense
        // output and lands there to its local error (measured 1.1e-5 of the kink speed at rtol
        // 1e-8): bound 1e-4. Without them the nearer end of a crossing step is up to 7.5e-2 of
        // the kink speed away (measured): bound 1e-2.
        if events {
            assert!(
                worst < 1e-4,
                "a step ended {worst:e} of the kink speed from it"
            );
        } else {
            assert_eq!(stats.events, 0);
            assert!(
                worst > 1e-2,
                "steps ended within {worst:e} of the kink speed"
            );
        }
    }
}

/// The integrator reads the contact events' functions three ways: all of them at a state
/// ([`Events::values`]), all of them from the right-hand side just evaluated there (at
/// a step's end: `values_at_rhs`), and one at a time from its contact's joint alone, given
/// only the state components it declares (in the bisection that locates a crossing:
/// `value` and `components`). The three must agree bit for bit, or a run with events
/// would depend on which was used. Checked at 201 states of the mixed
/// 4-UPS/RPU's first 0.2 s (three clearance joints, six contact slots, the R1 housing on the
/// ground), with onsets, ends and Ambrosio's friction kinks all on: 6 + 6 + 24 functions, open
/// and closed contacts, sliding speeds on both sides of the kinks.
#[test]
fn contact_event_functions_read_one_at_a_time_or_from_the_rhs_are_the_full_evaluations() {
    use jointplay_solver::ode::OdeSystem;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/4ups-rpu-mixed.toml");
    let (mut model, mut state) = compile(&SceneSpec::load(&path).unwrap());
    model.settings.onset_events = true;
    model.settings.end_events = true;
    model.settings.friction_events = true;
    let samples: Vec<f64> = (0..=200).map(|k| k as f64 * 1e-3).collect();
    let states = run(&model, &mut state, model.settings.method, 0.2, &samples);
    let mut sys = jointplay_solver::dynamics::Mechanism::new(&model);
    let n = sys.events().unwrap().count();
    assert_eq!(
        n,
        6 + 6 + 6 * 2 * 2,
        "onsets, ends and two per kink of each slot"
    );
    let (mut full, mut at_rhs, mut scratch) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut parts = Vec::new();
    let mut dy = vec![0.0; state.y.len()];
    let (mut closed, mut kinks_between) = (0, 0);
    for (t, y) in &states {
        sys.rhs(*t, y, &mut dy);
        let events = sys.events().unwrap();
        events.values_at_rhs(*t, y, &mut at_rhs);
        events.values(*t, y, &mut full);
        let bits = |g: &[f64]| g.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&at_rhs), bits(&full), "from the rhs at t = {t} s");
        for (i, all) in full.iter().enumerate() {
            // Only the components the function declares it reads: the others are NaN.
            events.components(i, &mut parts);
            let mut only = vec![f64::NAN; y.len()];
            for part in &parts {
                only[part.clone()].copy_from_slice(&y[part.clone()]);
            }
            let one = events.value(i, *t, &only, &mut scratch);
            assert_eq!(
                one.to_bits(),
                all.to_bits(),
                "event {i} alone at t = {t} s from its components {parts:?}: {one:e}, all: {all:e}"
            );
        }
        closed += full[..6].iter().filter(|g| **g < 0.0).count();
        // Between Ambrosio's two kinks: v - v0 > 0 and v1 - v > 0.
        kinks_between += full[12..]
            .chunks_exact(4)
            .filter(|g| g[0] > 0.0 && g[3] > 0.0 && g[0] != 1.0)
            .count();
    }
    assert!(
        closed > 100,
        "{closed} closed contacts: the states must close contacts"
    );
    assert!(
        kinks_between > 0,
        "no sliding speed between the kinks: the states must cross them"
    );
}
