//! Lubricated journal bearings through the whole solver (scene, compiler, right-hand side,
//! integrator) against the short-bearing closed forms: a loaded rotor settles where Ocvirk's
//! solution carries its weight, in a planar and in a spatial bearing; a journal without spin
//! squeezes the film in the time the squeeze-film integral gives; `disable` makes the bearing
//! dry; bad lubrication tables are refused naming their field. The scene is
//! `data/scenes/journal-bearing.toml` (20 kg rotor, 100 rad/s, L/D 0.25, c = 50 um, 0.04 Pa s).

mod common;

use common::edit;

use std::f64::consts::PI;

use jointplay_solver::model::{Model, State};

const C: f64 = 5e-5;
const MU: f64 = 0.04;
const R: f64 = 0.02;
const L: f64 = 0.01;

fn scene() -> String {
    common::scene_text("journal-bearing.toml")
}

fn compile(text: &str) -> jointplay_solver::error::Result<(Model, State)> {
    common::compile("journal-bearing.toml", text)
}

/// The rotor centre's (x, y) at the sample times (the rotor is body 0; its centre of mass is
/// the journal centre, and the bearing's centre is the origin).
fn orbit(text: &str, t_end: f64, samples: &[f64]) -> Vec<(f64, f64, f64)> {
    let (m, mut s) = compile(text).unwrap();
    let method = m.settings.method;
    common::run_samples(&m, &mut s, method, t_end, samples)
        .into_iter()
        .map(|(t, y)| (t, y[0], y[1]))
        .collect()
}

/// The eccentricity ratio at which the short bearing carries `w` (N) at spin `omega`, by
/// bisection of Hamrock's load formula (to round-off).
fn ocvirk_eps(w: f64, omega: f64) -> f64 {
    let k = MU * omega * R * L.powi(3) / (C * C);
    let load = |e: f64| {
        k / 4.0 * e / (1.0 - e * e).powi(2) * (16.0 * e * e + PI * PI * (1.0 - e * e)).sqrt()
    };
    let (mut lo, mut hi) = (0.0, 1.0 - 1e-12);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if load(mid) > w { hi = mid } else { lo = mid }
    }
    lo
}

/// The settled offset of the rotor against Ocvirk's eccentricity and attitude angle. The
/// run's half second is some 60 of the settling's time constants (the orbit's spiral decays
/// by e in about 8 ms), so what remains of the transient is far below the integrator's
/// tolerance (rtol 1e-9); 1e-7 bounds both and still sees any error of the film's
/// coefficients, which would move the equilibrium by its own relative size.
fn assert_settles_at_ocvirk(text: &str) {
    let end = orbit(text, 0.5, &[0.5]);
    let (_, x, y) = end[0];
    let eps = x.hypot(y) / C;
    let want = ocvirk_eps(20.0 * 9.81, 100.0);
    assert!(
        (eps - want).abs() <= 1e-7 * want,
        "eps {eps} against {want}"
    );
    // Load along -y, spin about +z: the journal sits below the centre, turned towards +x (the
    // sense of the spin) by the attitude angle.
    let phi = x.atan2(-y);
    let phi_want = (PI * (1.0 - want * want).sqrt() / (4.0 * want)).atan();
    assert!(
        (phi - phi_want).abs() <= 1e-7,
        "attitude {phi} against {phi_want}"
    );
}

#[test]
fn a_loaded_rotor_settles_where_the_short_bearing_carries_its_weight() {
    assert_settles_at_ocvirk(&scene());
}

#[test]
fn a_spatial_bearing_film_acts_on_the_journal_centre_the_same() {
    // The spatial model with the same length: the film acts on the journal centre's offset
    // normal to the axis; the rotor's centre of mass is the journal centre, so nothing tilts it.
    let text = edit(
        &scene(),
        "model = \"planar\"",
        "model = \"spatial\"\nbushing_length = 0.01",
    );
    let text = edit(
        &text,
        "lubrication = { model = \"short\", viscosity = 0.04, length = 0.01 }",
        "lubrication = { model = \"short\", viscosity = 0.04 }",
    );
    let (m, _) = compile(&text).unwrap();
    assert_eq!(m.clearances[0].film.unwrap().length, 0.01);
    assert_settles_at_ocvirk(&text);
}

/// The eccentricity ratio at which the half-Sommerfeld long bearing of length `l` carries `w`
/// (N) at spin `omega` with oil of viscosity `mu`, by bisection of its load (Hamrock, Schmid,
/// Jacobson, ch. 10: `W = mu omega R^3 l / c^2 6 eps sqrt(pi^2 - eps^2 (pi^2 - 4)) / ((2 +
/// eps^2)(1 - eps^2))`).
fn sommerfeld_eps(w: f64, omega: f64, mu: f64, l: f64) -> f64 {
    let k = mu * omega * R.powi(3) * l / (C * C);
    let load = |e: f64| {
        k * 6.0 * e * (PI * PI - e * e * (PI * PI - 4.0)).sqrt() / ((2.0 + e * e) * (1.0 - e * e))
    };
    let (mut lo, mut hi) = (0.0, 1.0 - 1e-12);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if load(mid) > w { hi = mid } else { lo = mid }
    }
    lo
}

/// The rotor in a long bearing (L/D = 2, a thinner oil so that it sits off the centre, at
/// eps = 0.2014): it settles at the long bearing's eccentricity and attitude angle `tan phi =
/// pi sqrt(1 - eps^2) / (2 eps)`, to the bound of the short bearing's test. Its spiral decays
/// more slowly than the short bearing's (measured: the offset from the end value falls
/// elevenfold every 0.1 s, a time constant of 42 ms), so it runs for 1 s, 24 time constants:
/// the transient left is some 1e-12, far below 1e-7.
#[test]
fn a_loaded_rotor_settles_where_the_long_bearing_carries_its_weight() {
    let text = edit(
        &scene(),
        "lubrication = { model = \"short\", viscosity = 0.04, length = 0.01 }",
        "lubrication = { model = \"long\", viscosity = 0.004, length = 0.08 }",
    );
    let (m, _) = compile(&text).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let text = edit(&text, "end_time = 0.5", "end_time = 1.0");
    let end = orbit(&text, 1.0, &[1.0]);
    let (_, x, y) = end[0];
    let eps = x.hypot(y) / C;
    let want = sommerfeld_eps(20.0 * 9.81, 100.0, 0.004, 0.08);
    assert!(
        (eps - want).abs() <= 1e-7 * want,
        "eps {eps} against {want}"
    );
    let phi = x.atan2(-y);
    let phi_want = (PI * (1.0 - want * want).sqrt() / (2.0 * want)).atan();
    assert!(
        (phi - phi_want).abs() <= 1e-7,
        "attitude {phi} against {phi_want}"
    );
}

/// I_cc over the pressure zone of a journal squeezed straight into the film without spin, the
/// half circle (pi/2, 3pi/2) around the thinnest point, by Simpson's rule on 4000 panels
/// (the integrand is smooth there; the error is far below 1e-12 relative for eps <= 0.9).
fn squeeze_icc(eps: f64) -> f64 {
    let m = 4000;
    let h = PI / m as f64;
    (0..=m)
        .map(|i| {
            let th = 0.5 * PI + i as f64 * h;
            let w = if i == 0 || i == m {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * th.cos().powi(2) / (1.0 + eps * th.cos()).powi(3)
        })
        .sum::<f64>()
        * h
        / 3.0
}

#[test]
fn a_journal_without_spin_squeezes_the_film_in_the_squeeze_film_time() {
    // Without spin and with the load along one line, the film's force is the pure squeeze
    // W = mu R L^3 / c^2 eps' I_cc(eps), so the journal goes from eps_1 to eps_2 in
    // t = mu R L^3 / (c^2 W) int I_cc d eps. That neglects the journal's inertia: a 0.02 kg
    // journal under 196.2 N (g = 9810 m/s^2) against the film's damping of at least
    // pi mu R L^3 / (2 c^3) = 1e4 N s/m has a time constant m / D <= 2 us, beside approach
    // times of milliseconds, so 1e-3 bounds the inertial lag and the sampling (1 us).
    let text = edit(&scene(), "mass = 20.0", "mass = 0.02");
    let text = edit(
        &text,
        "gravity = [0.0, -9.81, 0.0]",
        "gravity = [0.0, -9810.0, 0.0]",
    );
    let text = edit(&text, "angular_velocity = [0.0, 0.0, 100.0]", "");
    // eps = 0.9 is reached after about 55 ms.
    let text = edit(&text, "end_time = 0.5", "end_time = 0.06");
    let samples: Vec<f64> = (0..=60_000).map(|k| k as f64 * 1e-6).collect();
    let run = orbit(&text, 0.06, &samples);
    let when = |eps: f64| {
        let k = run
            .iter()
            .position(|&(_, x, y)| x.hypot(y) >= eps * C)
            .unwrap();
        let (t0, x0, y0) = run[k - 1];
        let (t1, x1, y1) = run[k];
        let (e0, e1) = (x0.hypot(y0) / C, x1.hypot(y1) / C);
        t0 + (t1 - t0) * (eps - e0) / (e1 - e0)
    };
    // The whole approach runs straight down.
    assert!(
        run.iter().all(|&(_, x, _)| x.abs() <= 1e-12),
        "the journal left the load line"
    );
    let w = 0.02 * 9810.0;
    for (e1, e2) in [(0.3, 0.6), (0.6, 0.8), (0.8, 0.9)] {
        // Simpson in eps on 200 panels of a smooth integrand.
        let n = 200;
        let h = (e2 - e1) / n as f64;
        let integral = (0..=n)
            .map(|i| {
                let wgt = if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                wgt * squeeze_icc(e1 + i as f64 * h)
            })
            .sum::<f64>()
            * h
            / 3.0;
        let want = MU * R * L.powi(3) / (C * C * w) * integral;
        let got = when(e2) - when(e1);
        assert!(
            (got - want).abs() <= 1e-3 * want,
            "{e1} -> {e2}: {got} s against {want} s"
        );
    }
}

#[test]
fn disabling_the_film_leaves_the_dry_bearing() {
    let with = edit(
        &scene(),
        "end_time = 0.5",
        "end_time = 0.02\ndisable = [\"bearing.lubrication\"]",
    );
    // `disable` is a top-level key: move it before the first table.
    let with = edit(&with, "\ndisable = [\"bearing.lubrication\"]", "");
    let with = format!("disable = [\"bearing.lubrication\"]\n{with}");
    let without = edit(
        &edit(&scene(), "end_time = 0.5", "end_time = 0.02"),
        "lubrication = { model = \"short\", viscosity = 0.04, length = 0.01 }",
        "",
    );
    let samples: Vec<f64> = (1..=200).map(|k| k as f64 * 1e-4).collect();
    let (a, b) = (
        orbit(&with, 0.02, &samples),
        orbit(&without, 0.02, &samples),
    );
    assert_eq!(a, b);
    // Dry, the rotor falls onto the wall (50 um in about 3.2 ms of free fall) and bounces.
    let deepest = a.iter().map(|&(_, x, y)| x.hypot(y)).fold(0.0, f64::max);
    assert!(
        deepest > C,
        "the dry rotor did not reach the wall: {deepest}"
    );
    let (m, _) = compile(&with).unwrap();
    assert!(m.clearances[0].film.is_none() && !m.effects.lubrication);
}

#[test]
fn bad_lubrication_tables_are_refused_naming_the_field() {
    let line = "lubrication = { model = \"short\", viscosity = 0.04, length = 0.01 }";
    for (to, field, words) in [
        (
            "lubrication = { viscosity = -0.04, length = 0.01 }",
            "joints[0].clearance.lubrication.viscosity",
            "positive",
        ),
        (
            "lubrication = { viscosity = nan, length = 0.01 }",
            "joints[0].clearance.lubrication.viscosity",
            "finite",
        ),
        (
            "lubrication = { viscosity = 0.04 }",
            "joints[0].clearance.lubrication.length",
            "missing",
        ),
        (
            "lubrication = { viscosity = 0.04, length = 0.0 }",
            "joints[0].clearance.lubrication.length",
            "positive",
        ),
        (
            "lubrication = { viscosity = 0.04, length = 0.01, eccentricity_limit = 1.0 }",
            "joints[0].clearance.lubrication.eccentricity_limit",
            "between 0 and 1",
        ),
    ] {
        let err = compile(&edit(&scene(), line, to)).unwrap_err().to_string();
        assert!(err.contains(field) && err.contains(words), "{to}: {err}");
    }
    let err = compile(&edit(
        &scene(),
        line,
        "lubrication = { model = \"reynolds\", viscosity = 0.04 }",
    ))
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("short") && err.contains("long") && err.contains("finite"),
        "{err}"
    );
    let err = compile(&edit(
        &scene(),
        line,
        "lubrication = { viscosity = 0.04, length = 0.01, oil = 1 }",
    ))
    .unwrap_err()
    .to_string();
    assert!(err.contains("oil"), "{err}");
    // A ball in a socket has no journal bearing's film.
    let ball = edit(&scene(), "kind = \"revolute\"", "kind = \"spherical\"");
    let ball = edit(
        &ball,
        "model = \"planar\"\njournal_radius = 0.02",
        "ball_radius = 0.02",
    );
    let ball = edit(&ball, "axis_a = \"z\"\naxis_b = \"z\"\n", "");
    let err = compile(&ball).unwrap_err().to_string();
    assert!(
        err.contains("joints[0].clearance.lubrication") && err.contains("revolute"),
        "{err}"
    );
    // An L/D far outside the short bearing's range is run, with a warning.
    let (m, _) = compile(&edit(
        &scene(),
        line,
        "lubrication = { viscosity = 0.04, length = 0.1 }",
    ))
    .unwrap();
    assert!(
        m.warnings.iter().any(|w| w.contains("L/D = 2.50")),
        "{:?}",
        m.warnings
    );
}

#[test]
fn the_film_is_listed_by_check() {
    let (m, _) = compile(&scene()).unwrap();
    let lines = m.effects.describe(&m).join("\n");
    assert!(lines.contains("oil films"), "{lines}");
    assert!(
        lines.contains(
            "lubricated, short bearing: viscosity 0.04 Pa s, length 0.01 m (L/D = 0.250)"
        ),
        "{lines}"
    );
}
