//! Periodic orbits by shooting and their Floquet multipliers, against exact identities of the
//! Duffing and Newton impact oscillators.

use std::path::Path;

use jointplay_analysis::flow::{Flow, Target};
use jointplay_analysis::nonlinear::Loaded;
use jointplay_analysis::periodic::{Newton, shoot};
use jointplay_solver::ode::{Flow as Step, advance};
use jointplay_solver::state::HybridState;

fn system(system: &str) -> Target {
    let text = format!(
        "[study]\nname = \"p\"\nsystem = {{ {system} }}\n[analysis]\nperiods = 2\nsamples_per_period = 0\n"
    );
    let st = Loaded::parse(&text, Path::new("periodic-test.toml")).unwrap();
    st.target_with(&[]).unwrap()
}

fn duffing(gamma: f64) -> Target {
    system(&format!(
        "kind = \"duffing\", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = {gamma}, omega = 1.2, initial = [1.0, 0.0], solver = {{ integrator = \"dopri5\", rtol = 1e-11, atol = 1e-12 }}"
    ))
}

fn impact(forcing: f64) -> Target {
    system(&format!(
        "kind = \"impact\", damping = 0.1, stiffness = 1.0, forcing = {forcing}, omega = 1.0, stop = 1.0, restitution = 0.8, initial = [0.0, 0.0], solver = {{ rtol = 1e-11, atol = 1e-12 }}"
    ))
}

/// The strobe point after `periods` drive periods from the flow's initial state.
fn settle(target: &Target, periods: usize) -> HybridState {
    let mut flow = target.flow();
    let mut s = flow.initial_state(None).unwrap();
    flow.prepare(&s).unwrap();
    let t = s.t + periods as f64 * flow.period();
    let method = flow.method();
    let (_, r) = advance(
        &mut flow,
        method,
        &mut s,
        t,
        &[],
        |_, _, _| Step::Continue,
        None,
    );
    r.unwrap();
    s
}

const NEWTON: Newton = Newton {
    tolerance: 1e-9,
    max_iterations: 12,
};

/// Duffing x'' + 0.3 x' - x + x^3 = 0.2 cos(1.2 t) from (1, 0): the period-1 orbit it settles
/// on, found by shooting from the strobe point 3 periods in, is stable, reproduces
/// itself within the Newton tolerance, and its multipliers multiply to exp(-0.3 T) (Liouville:
/// the divergence is -0.3 everywhere). The product is the determinant of the tangent map, whose
/// only error is the integration error of the variational equations at rtol 1e-11: 1e-8
/// relative is a hundred times that.
#[test]
fn duffing_period_one_multipliers_multiply_to_exp_minus_delta_t() {
    let target = duffing(0.2);
    let start = settle(&target, 3);
    let mut flow = target.flow();
    let orbit = shoot(&mut flow, &start, 1, NEWTON).unwrap();
    assert!(orbit.residual <= 1e-9, "{}", orbit.residual);
    assert!(orbit.iterations <= 6, "{} iterations", orbit.iterations);
    assert!(orbit.stable(), "{:?}", orbit.multipliers);
    assert_eq!(orbit.multipliers.len(), 2);
    assert_eq!(orbit.spurious, 0);
    let t = 2.0 * std::f64::consts::PI / 1.2;
    let exact = (-0.3 * t).exp();
    eprintln!(
        "Duffing period 1: {} iterations, residual {:e}, multipliers {:?}, product {} (exp(-0.3 T) = {exact})",
        orbit.iterations,
        orbit.residual,
        orbit.multipliers,
        orbit.product()
    );
    assert!(
        ((orbit.product() - exact) / exact).abs() < 1e-8,
        "product {} against {exact}",
        orbit.product()
    );
    // One period from the orbit's state returns to it.
    let back = settle_from(&target, &orbit.state, 1);
    let err = back
        .y
        .iter()
        .zip(&orbit.state.y)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(err <= 1e-9, "returns within {err:e}");
}

fn settle_from(target: &Target, start: &HybridState, periods: usize) -> HybridState {
    let mut flow = target.flow();
    let mut s = start.for_new_run();
    flow.prepare(&s).unwrap();
    let t = s.t + periods as f64 * flow.period();
    let method = flow.method();
    let (_, r) = advance(
        &mut flow,
        method,
        &mut s,
        t,
        &[],
        |_, _, _| Step::Continue,
        None,
    );
    r.unwrap();
    s
}

/// The Newton impact oscillator (k = 1, c = 0.1, omega = 1, stop 1, e = 0.8) at forcing 0.2,
/// above grazing (0.1): its period-1 orbit hits the stop once per period, and the product of its
/// multipliers is e^2 exp(-c T): the saltation matrix of each impact has determinant e^2 and the
/// smooth flow between contributes exp(-c T). Integration error at rtol 1e-11 and the located
/// impact time (to round-off) keep it within 1e-7 relative.
#[test]
fn impacting_orbit_multipliers_multiply_to_e_squared_exp_minus_c_t() {
    let target = impact(0.2);
    let start = settle(&target, 8);
    let mut flow = target.flow();
    let orbit = shoot(&mut flow, &start, 1, NEWTON).unwrap();
    assert_eq!(orbit.events, 1, "one impact per period");
    assert!(orbit.stable(), "{:?}", orbit.multipliers);
    let t = 2.0 * std::f64::consts::PI;
    let exact = 0.64 * (-0.1 * t).exp();
    eprintln!(
        "impact period 1: {} iterations, residual {:e}, multipliers {:?}, product {} (e^2 exp(-c T) = {exact})",
        orbit.iterations,
        orbit.residual,
        orbit.multipliers,
        orbit.product()
    );
    assert!(
        ((orbit.product() - exact) / exact).abs() < 1e-7,
        "product {} against {exact}",
        orbit.product()
    );
}
