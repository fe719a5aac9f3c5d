//! Validation of the constrained solver against closed-form results, on the bundled scenes.

mod common;

use std::path::PathBuf;

use jointplay_solver::dynamics::Workspace;
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::Method;
use jointplay_solver::ode::dopri5::DOPRI5;
use jointplay_solver::ode::rk4::RK4;
use jointplay_solver::scene::{SceneFile, SceneSpec};
use nalgebra::{Matrix3, Vector3};

fn scene(name: &str) -> (Model, State) {
    scene_edited(name, &[])
}

/// A bundled scene with each text `from` replaced by `to`.
fn scene_edited(name: &str, edits: &[(&str, &str)]) -> (Model, State) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/scenes")
        .join(name);
    let mut text = std::fs::read_to_string(&path).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{name} has no '{from}'");
        text = text.replace(from, to);
    }
    let spec = SceneSpec::parse(&text, &path).unwrap();
    let file = SceneFile { path, text, spec };
    let (model, mut state) = Model::compile(&file).unwrap();
    model.assemble(&mut state).unwrap();
    (model, state)
}

/// Complete elliptic integral of the first kind K(k) by the arithmetic-geometric mean.
fn ellip_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..40 {
        let (an, bn) = (0.5 * (a + b), (a * b).sqrt());
        a = an;
        b = bn;
    }
    std::f64::consts::PI / (2.0 * a)
}

/// Times of the upward zero crossings of `f` sampled on `t`, by cubic Hermite interpolation
/// with the derivative samples `df` (accurate to O(dt^4)).
fn crossings(t: &[f64], f: &[f64], df: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for i in 0..t.len() - 1 {
        if f[i] < 0.0 && f[i + 1] >= 0.0 {
            let h = t[i + 1] - t[i];
            let p = |s: f64| {
                let (h00, h10, h01, h11) = (
                    2.0 * s.powi(3) - 3.0 * s * s + 1.0,
                    s.powi(3) - 2.0 * s * s + s,
                    -2.0 * s.powi(3) + 3.0 * s * s,
                    s.powi(3) - s * s,
                );
                h00 * f[i] + h10 * h * df[i] + h01 * f[i + 1] + h11 * h * df[i + 1]
            };
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if p(mid) < 0.0 { lo = mid } else { hi = mid }
            }
            out.push(t[i] + 0.5 * (lo + hi) * h);
        }
    }
    out
}

/// Integrates a scene, sampling (t, y) every `dt`.
fn run(
    model: &Model,
    state: &mut State,
    method: Method,
    t_end: f64,
    dt: f64,
) -> Vec<(f64, Vec<f64>)> {
    let n = ((t_end - state.t) / dt).round() as usize;
    let samples: Vec<f64> = (0..=n).map(|k| state.t + k as f64 * dt).collect();
    common::run_samples(model, state, method, t_end, &samples)
}

fn tight() -> Method {
    Method::adaptive(&DOPRI5, 1e-11, 1e-12, f64::INFINITY).unwrap()
}

/// The period of the pendulum scene released from theta0, measured with the scene's integrator
/// (after `edits`), and the exact one.
fn pendulum_period(theta0: f64, edits: &[(&str, &str)]) -> (f64, f64) {
    let (mut model, mut state) = scene_edited("pendulum.toml", edits);
    let _ = &mut model;
    // Re-pose the bob at theta0 (the scene holds 60 degrees): rotate the position and orientation.
    let (l, g) = (1.0, 9.81);
    state.y[0] = l * theta0.sin();
    state.y[1] = -l * theta0.cos();
    let h = 0.5 * theta0;
    state.y[3..7].copy_from_slice(&[h.cos(), 0.0, 0.0, h.sin()]);
    model.assemble(&mut state).unwrap();
    let samples = run(&model, &mut state, model.settings.method, 10.0, 1e-3);
    let t: Vec<f64> = samples.iter().map(|s| s.0).collect();
    let x: Vec<f64> = samples.iter().map(|s| s.1[0]).collect();
    let vx: Vec<f64> = samples.iter().map(|s| s.1[7]).collect();
    let c = crossings(&t, &x, &vx);
    let measured = (c[c.len() - 1] - c[0]) / (c.len() - 1) as f64;
    let b = &model.bodies[0];
    let i_o = b.inertia[(2, 2)] + b.mass * l * l;
    let exact = 4.0 * (i_o / (b.mass * g * l)).sqrt() * ellip_k((theta0 / 2.0).sin());
    (measured, exact)
}

#[test]
fn pendulum_large_amplitude_period_matches_the_elliptic_integral() {
    // The scene's integrator is DOPRI5 at rtol 1e-11, atol 1e-12.
    let (measured, exact) = pendulum_period(std::f64::consts::FRAC_PI_3, &[]);
    // Tolerance 1e-6 relative: the integration error at rtol 1e-11 and the O(dt^4) crossing
    // interpolation are both below 1e-9 s; the margin covers the Baumgarte-corrected drift.
    assert!(
        ((measured - exact) / exact).abs() < 1e-6,
        "measured {measured}, exact {exact}"
    );
}

#[test]
fn pendulum_small_amplitude_period_is_two_pi_sqrt_l_over_g() {
    let (measured, exact) = pendulum_period(0.01, &[]);
    let b = scene("pendulum.toml").0.bodies[0].clone();
    let small =
        2.0 * std::f64::consts::PI * ((b.inertia[(2, 2)] + b.mass) / (b.mass * 9.81)).sqrt();
    // At 0.01 rad the finite-amplitude correction is theta0^2/16 = 6.25e-6 relative.
    assert!(
        ((measured - small) / small).abs() < 1e-5,
        "measured {measured}, 2 pi sqrt(L/g) {small}"
    );
    assert!(
        ((measured - exact) / exact).abs() < 1e-7,
        "measured {measured}, exact {exact}"
    );
}

/// The scene keys `integrator = "dop853"`, `"rosenbrock23"` and `"bs3"` on a constrained
/// mechanism: the 60-degree pendulum's period against the elliptic integral. Measured relative
/// errors: 4e-13 for DOP853 at rtol 1e-10, 1.1e-6 for the order-2 Rosenbrock23 at rtol 1e-7,
/// 1.9e-9 for the order-3 BS3 at rtol 1e-9. The bounds (1e-9, 1e-5, 2e-8) sit one to two
/// decades above the tolerance's reach, about ten times the error for the low orders.
#[test]
fn pendulum_period_with_dop853_rosenbrock23_and_bs3() {
    for (integrator, rtol, bound) in [
        ("dop853", "1e-10", 1e-9),
        ("rosenbrock23", "1e-7", 1e-5),
        ("bs3", "1e-9", 2e-8),
    ] {
        let set = format!("integrator = \"{integrator}\"");
        let tol = format!("rtol = {rtol}");
        let edits = [
            ("integrator = \"dopri5\"", set.as_str()),
            ("rtol = 1e-11", &tol),
        ];
        assert_eq!(
            scene_edited("pendulum.toml", &edits)
                .0
                .settings
                .method
                .family(),
            integrator
        );
        let (measured, exact) = pendulum_period(std::f64::consts::FRAC_PI_3, &edits);
        let rel = ((measured - exact) / exact).abs();
        assert!(
            rel < bound,
            "{integrator}: measured {measured}, exact {exact}"
        );
    }
}

#[test]
fn torque_free_body_conserves_energy_and_momentum_and_flips() {
    let (model, mut state) = scene("free-body.toml");
    let samples = run(
        &model,
        &mut state,
        Method::adaptive(&DOPRI5, 1e-10, 1e-12, f64::INFINITY).unwrap(),
        30.0,
        0.01,
    );
    let mut ws = Workspace::new(&model);
    let jb = model.bodies[0].inertia;
    let ang_mom = |y: &[f64]| {
        let q = &y[3..7];
        let r = jointplay_solver::dynamics::rotation(q);
        let w = Vector3::new(y[10], y[11], y[12]);
        let j: Matrix3<f64> = r * jb * r.transpose();
        (j * w, r.transpose() * w)
    };
    let e0 = model.energy(&samples[0].1, &mut ws);
    let (l0, _) = ang_mom(&samples[0].1);
    let mut worst_e: f64 = 0.0;
    let mut worst_l: f64 = 0.0;
    let mut flips = 0;
    let mut last_sign = ang_mom(&samples[0].1).1.y.signum();
    for (_, y) in &samples {
        worst_e = worst_e.max(((model.energy(y, &mut ws) - e0) / e0).abs());
        let (l, wb) = ang_mom(y);
        worst_l = worst_l.max((l - l0).norm() / l0.norm());
        if wb.y.signum() != last_sign {
            flips += 1;
            last_sign = wb.y.signum();
        }
    }
    // 30 s is ~24 revolutions at rtol 1e-10: measured 5e-12 (energy) and 2e-11 (momentum); the
    // bound allows for a different step sequence on another machine.
    assert!(worst_e < 1e-9, "relative energy error {worst_e}");
    assert!(worst_l < 1e-9, "relative angular momentum error {worst_l}");
    assert!(
        flips >= 4,
        "the intermediate-axis flip did not appear ({flips} sign changes)"
    );
}

#[test]
fn slider_crank_follows_closed_form_kinematics() {
    let (model, mut state) = scene("slider-crank.toml");
    let w = 523.5987755982989;
    let (r, l) = (0.05, 0.12);
    let period = 2.0 * std::f64::consts::PI / w;
    let samples = run(
        &model,
        &mut state,
        Method::adaptive(&DOPRI5, 1e-10, 1e-12, f64::INFINITY).unwrap(),
        2.0 * period,
        period / 200.0,
    );
    let slider = 2;
    let mut ws = Workspace::new(&model);
    let (mut ep, mut ev, mut ea) = (0.0f64, 0.0f64, 0.0f64);
    for (t, y) in &samples {
        let th = w * t;
        let (s, c) = th.sin_cos();
        let root = (l * l - r * r * s * s).sqrt();
        let x = r * c + root;
        let xd = -r * w * s - r * r * w * s * c / root;
        let xdd = -r * w * w * c
            - r * r * w * w * (c * c - s * s) / root
            - r.powi(4) * w * w * s * s * c * c / root.powi(3);
        model.accelerations(*t, y, &mut ws);
        ep = ep.max((y[7 * slider] - x).abs());
        ev = ev.max((y[7 * 3 + 6 * slider] - xd).abs());
        ea = ea.max((ws.acc[slider][0] - xdd).abs());
    }
    // Peak values are 0.17 m, 31 m/s and 2.1e4 m/s^2; at rtol 1e-10 the measured errors are
    // 5e-12 m, 2e-9 m/s and 7e-7 m/s^2 (~1e-10 relative). Bounds: 1e-9 relative to the peaks.
    assert!(ep < 2e-10, "position error {ep} m");
    assert!(ev < 3e-8, "velocity error {ev} m/s");
    assert!(ea < 2e-5, "acceleration error {ea} m/s^2");
}

#[test]
fn slider_crank_has_three_redundant_rows_and_one_dof() {
    let (model, state) = scene("slider-crank.toml");
    let s = model.structure(state.t, &state.y).unwrap();
    assert_eq!(s.dof, 1);
    assert_eq!(s.redundant_joint_rows, 3);
    assert_eq!(s.redundant_drives, 0);
    assert_eq!(s.remaining_dof, 0);
}

#[test]
fn ideal_4ups_rpu_has_four_dof_and_one_redundant_drive() {
    let (model, state) = scene("4ups-rpu.toml");
    let s = model.structure(state.t, &state.y).unwrap();
    assert_eq!(s.n_coords, 66);
    assert_eq!(s.joint_rows, 62);
    assert_eq!(s.dof, 4);
    assert_eq!(s.redundant_joint_rows, 0);
    assert_eq!(s.drive_rows, 5);
    assert_eq!(s.redundant_drives, 1);
    assert_eq!(s.remaining_dof, 0);
}

#[test]
fn ideal_4ups_rpu_follows_trajectory_69_with_finite_consistent_actuator_forces() {
    let (model, mut state) = scene("4ups-rpu.toml");
    // The drives' period, from the scene's omega = 3.14 rad/s of trajectory (69).
    let period = model.settings.period.unwrap();
    let w = 2.0 * std::f64::consts::PI / period;
    // One full drive period at the paper's RK4 step, sampled every 5 ms.
    let samples = run(
        &model,
        &mut state,
        Method::fixed(&RK4, 1e-4).unwrap(),
        period,
        5e-3,
    );
    let plat = model
        .bodies
        .iter()
        .position(|b| b.name == "platform")
        .unwrap();
    let drive = |n: &str| model.drives.iter().position(|d| d.name == n).unwrap();
    let mut ws = Workspace::new(&model);
    let (mut path_err, mut rot_err, mut drift) = (0.0f64, 0.0f64, 0.0f64);
    let (mut sym_err, mut fmax) = (0.0f64, 0.0f64);
    let mut power = Vec::new();
    let mut energy = Vec::new();
    for (t, y) in &samples {
        let r = &y[7 * plat..7 * plat + 3];
        let target = [1.21 - 0.03 * (w * t).cos(), 0.03 * (w * t).sin(), 0.0];
        for k in 0..3 {
            path_err = path_err.max((r[k] - target[k]).abs());
        }
        let q = &y[7 * plat + 3..7 * plat + 7];
        let n = (q.iter().map(|v| v * v).sum::<f64>()).sqrt();
        rot_err = rot_err.max((q[1] / n).abs().max((q[2] / n).abs()).max((q[3] / n).abs()));
        drift = drift.max(model.drift(*t, y, &mut ws).0);
        model.accelerations(*t, y, &mut ws);
        let f: Vec<f64> = (0..5).map(|d| model.actuator_force(d, &ws)).collect();
        assert!(
            f.iter().all(|x| x.is_finite()),
            "non-finite actuator force at t = {t}"
        );
        for j in 0..model.joints.len() {
            let (rf, rt) = model.reaction(j, &ws);
            assert!(
                rf.iter().chain(rt.iter()).all(|x| x.is_finite()),
                "joint {j} at t = {t}"
            );
        }
        fmax = f.iter().fold(fmax, |m, x| m.max(x.abs()));
        // Limbs 2 and 5, 3 and 4 are mirror images about Z = 0, as are the motion and gravity:
        // the minimum-norm distribution must keep that symmetry.
        sym_err = sym_err.max((f[drive("drive2")] - f[drive("drive5")]).abs());
        sym_err = sym_err.max((f[drive("drive3")] - f[drive("drive4")]).abs());
        // Actuator power: sum f_i s_i'.
        let p: f64 = model
            .drives
            .iter()
            .enumerate()
            .map(|(d, dr)| f[d] * dr.profile.eval(*t).1)
            .sum();
        power.push(p);
        energy.push(model.energy(y, &mut ws));
    }
    // The platform centre and orientation are fixed by the drives, so RK4 at h = 1e-4 s holds
    // them to rounding-level constraint error (measured 8e-15 m, 5e-15, drift 2e-14); the
    // bounds leave three orders of magnitude for other machines and compilers.
    assert!(
        path_err < 1e-11,
        "platform off trajectory (69) by {path_err} m"
    );
    assert!(
        rot_err < 1e-11,
        "platform rotated by {rot_err} (quaternion vector part)"
    );
    assert!(drift < 1e-11, "constraint drift {drift}");
    // Measured 4e-9 N on forces up to 870 N (5e-12 relative).
    assert!(
        sym_err < 1e-9 * fmax,
        "mirror-symmetric drives differ by {sym_err} N"
    );
    // Power balance: the drives are the only source of work, so the integral of the actuator
    // power over one period equals the energy change. The trapezoid rule over a whole period of
    // a smooth periodic integrand is spectrally accurate: measured |work - dE| = 2e-9 J against
    // 73 J of absolute work exchanged; the bound is 1e-7 of that.
    let dt = 5e-3;
    let work: f64 = power.windows(2).map(|p| 0.5 * (p[0] + p[1]) * dt).sum();
    let abs_work: f64 = power.iter().map(|p| p.abs() * dt).sum();
    let de = energy[energy.len() - 1] - energy[0];
    assert!(
        (work - de).abs() < 1e-7 * abs_work,
        "work {work} J vs energy change {de} J"
    );
}

/// Maximum constraint drift in the first and last tenth of a long pendulum run with coarse RK4.
fn pendulum_drift(alpha: f64, beta: f64, t_end: f64) -> (f64, f64) {
    let (mut model, mut state) = scene("pendulum.toml");
    model.settings.alpha = alpha;
    model.settings.beta = beta;
    let samples = run(
        &model,
        &mut state,
        Method::fixed(&RK4, 1e-2).unwrap(),
        t_end,
        0.1,
    );
    let mut ws = Workspace::new(&model);
    let d: Vec<f64> = samples
        .iter()
        .map(|(t, y)| model.drift(*t, y, &mut ws).0)
        .collect();
    let n = d.len() / 10;
    let max = |s: &[f64]| s.iter().fold(0.0f64, |m, x| m.max(*x));
    (max(&d[..n]), max(&d[d.len() - n..]))
}

#[test]
fn constraint_drift_stays_bounded_over_a_long_run() {
    // 1000 s is ~460 periods at a coarse step (h = 10 ms, ~200 steps per period).
    let (early, late) = pendulum_drift(5.0, 5.0, 1000.0);
    // With Baumgarte stabilisation the drift settles at the level of the per-step error
    // (measured 4.1e-8 in both the first and the last tenth): it must not grow.
    assert!(late < 1e-6, "drift {late} at the end");
    assert!(
        late < 3.0 * early.max(1e-12),
        "drift grew from {early} to {late}"
    );
    // Without stabilisation the same run drifts to 1.8e-2: the stabilisation is doing the work.
    let (_, late_free) = pendulum_drift(0.0, 0.0, 1000.0);
    assert!(
        late_free > 10.0 * late,
        "unstabilised drift {late_free} vs stabilised {late}"
    );
}

#[test]
fn rk4_on_the_pendulum_mechanism_converges_with_order_four() {
    let at = |method: Method| {
        let (model, mut state) = scene("pendulum.toml");
        let s = run(&model, &mut state, method, 2.0, 2.0);
        s.last().unwrap().1[..2].to_vec()
    };
    let reference = at(tight());
    let err = |h: f64| {
        let y = at(Method::fixed(&RK4, h).unwrap());
        ((y[0] - reference[0]).powi(2) + (y[1] - reference[1]).powi(2)).sqrt()
    };
    let (e1, e2) = (err(0.02), err(0.01));
    let p = (e1 / e2).log2();
    // Asymptotic regime at h = 10-20 ms (errors 1e-7..1e-8, far above the reference's 1e-11).
    assert!(
        (p - 4.0).abs() < 0.3,
        "observed order {p} (errors {e1:e}, {e2:e})"
    );
}

/// Long run, not part of the default suite (about a minute): `cargo test -- --ignored`.
#[test]
#[ignore]
fn ideal_4ups_rpu_drift_stays_bounded_over_ten_periods() {
    let (model, mut state) = scene("4ups-rpu.toml");
    let period = model.settings.period.unwrap();
    let samples = run(
        &model,
        &mut state,
        Method::fixed(&RK4, 1e-4).unwrap(),
        10.0 * period,
        0.05,
    );
    let mut ws = Workspace::new(&model);
    let d: Vec<f64> = samples
        .iter()
        .map(|(t, y)| model.drift(*t, y, &mut ws).0)
        .collect();
    let worst = d.iter().fold(0.0f64, |m, x| m.max(*x));
    // One period holds the drift at 2e-14; ten periods must stay at rounding level too.
    assert!(worst < 1e-11, "constraint drift reached {worst}");
}
