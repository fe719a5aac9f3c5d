//! Helpers shared by the solver's integration tests.

use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::{Flow, Method, integrate};

/// Integrates `model` from `state` to `t_end` and returns (t, y) at the `samples` times.
pub fn run_samples(
    model: &Model,
    state: &mut State,
    method: Method,
    t_end: f64,
    samples: &[f64],
) -> Vec<(f64, Vec<f64>)> {
    let mut out = Vec::new();
    let mut sys = Mechanism::new(model);
    integrate(
        &mut sys,
        method,
        state.t,
        &mut state.y,
        t_end,
        samples,
        |_, t, y| {
            out.push((t, y.to_vec()));
            Flow::Continue
        },
    )
    .unwrap();
    state.t = t_end;
    out
}
