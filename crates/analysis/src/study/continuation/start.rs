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
    let file = hdf5::File::open(&path)
        .map_err(|e| bad("file", format!("cannot open {}: {e}", path.display())))?;
    let state = match s.branch {
        None => {
            if s.point.is_some() {
                return Err(bad("point", "needs continuation.start.branch".into()));
            }
            let complete: u8 = crate::storage::h5::read_attr(&file, "complete").unwrap_or(0);
            if complete != 1 {
                return Err(bad(
                    "file",
                    format!(
                        "{} is not a finished run of the program (attribute complete = 1): its last state is where it stopped",
                        path.display()
                    ),
                ));
            }
            crate::storage::hybrid::read_state(&file).map_err(|e| {
                bad(
                    "file",
                    format!(
                        "{} has no final state ({e}); a sweep's file holds one per value: start from a run file or a branch point",
                        path.display()
                    ),
                )
            })?
        }
        Some(b) => {
            let g = file
                .group(&format!("continuation/branch_{b}"))
                .map_err(|_| {
                    bad(
                        "branch",
                        format!("{} has no /continuation/branch_{b}", path.display()),
                    )
                })?;
            let read = |name: &str| crate::storage::h5::read_rows(&g, name);
            let e = |err: hdf5::Error| bad("branch", format!("{}: {err}", path.display()));
            let params = read("parameter").map_err(e)?;
            let n = params.len() as i64;
            let i = s.point.unwrap_or(-1);
            let j = if i < 0 { n + i } else { i };
            if !(0..n).contains(&j) {
                return Err(bad(
                    "point",
                    format!("branch {b} has {n} points: {i} is not one of them"),
                ));
            }
            let j = j as usize;
            let p = params[j][0];
            if (p - spec.from).abs() > 1e-9 * (spec.to - spec.from).abs() {
                return Err(bad(
                    "point",
                    format!(
                        "the point is at parameter {p:e}, continuation.from is {:e}: set from = {p:e}",
                        spec.from
                    ),
                ));
            }
            let t: f64 = crate::storage::h5::read_attr(&g, "strobe_time").map_err(e)?;
            let y = read("state").map_err(e)?.swap_remove(j);
            let onset = read("onset")
                .ok()
                .and_then(|mut o| (o.len() > j).then(|| o.swap_remove(j)))
                .unwrap_or_default();
            let mut point = HybridState::new(t, y);
            point.onset = onset;
            point
        }
    };
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
