//! The `[continuation] start` state read from a file (a finished run's final state, or a point
//! of a branch of an earlier continuation) and checked against the flow: its size, its time on
//! the strobe phase, its place on the constraint manifold. Errors name the field.

use jointplay_solver::state::HybridState;

use crate::Result;
use crate::flow::Flow;
use crate::study::continuation::spec::{ContinuationSpec, START_OFF_MANIFOLD, StartSpec};

/// The start state `s` of the continuation `spec` of the study file `study`, for `flow` (the
/// flow at `continuation.from`) whose first strobe time is `t_strobe`.
pub(crate) fn read_start(
    study: &std::path::Path,
    spec: &ContinuationSpec,
    s: &StartSpec,
    flow: &mut crate::flow::AnyFlow,
    t_strobe: f64,
) -> Result<HybridState> {
    let bad = |f: &str, m: String| {
        crate::study::spec::invalid(study, format!("continuation.start.{f}"), m)
    };
    let path = study
        .parent()
        .unwrap_or(std::path::Path::new(""))
        .join(&s.file);
    if s.branch.is_none() && s.point.is_some() {
        return Err(bad("point", "needs continuation.start.branch".into()));
    }
    let (state, parameter) =
        crate::storage::continuation_file::read_start(&path, s.branch, s.point)
            .map_err(|(field, m)| bad(field, m))?;
    if let Some(p) = parameter
        && (p - spec.from).abs() > 1e-9 * (spec.to - spec.from).abs()
    {
        return Err(bad(
            "point",
            format!(
                "the point is at parameter {p:e}, continuation.from is {:e}: set from = {p:e}",
                spec.from
            ),
        ));
    }
    use crate::flow::tangent::Tangent;
    let dim = jointplay_solver::ode::OdeSystem::dim(flow);
    if state.y.len() != dim {
        return Err(bad(
            "file",
            format!(
                "the state in {} has {} components, the flow at continuation.from {dim}: a state of another scene",
                path.display(),
                state.y.len()
            ),
        ));
    }
    let period = flow.period();
    let n = (state.t - t_strobe) / period;
    if !state.t.is_finite() || (n - n.round()).abs() > 1e-6 {
        return Err(bad(
            "file",
            format!(
                "the state is at t = {} s, not at a strobe time {t_strobe} + n {period} s (analysis.phase and the drive's period): shooting needs a state at the strobe phase",
                state.t
            ),
        ));
    }
    if state.y.iter().any(|v| !v.is_finite()) {
        return Err(bad("file", "the state has a non-finite component".into()));
    }
    let off = flow.off_manifold(state.t, &state.y);
    if off.iter().zip(START_OFF_MANIFOLD).any(|(r, lim)| *r > lim) {
        return Err(bad(
            "file",
            format!(
                "the state is off the constraint manifold (position residual {:.2e} m, velocity residual {:.2e} m/s, Euler-parameter norm off by {:.2e}; at most 1e-6 each): a state of another scene or parameter",
                off[0], off[1], off[2]
            ),
        ));
    }
    Ok(state)
}
