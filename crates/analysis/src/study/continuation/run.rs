//! A continuation study end to end: its first orbit shot (from the analysis's settled state, a
//! given start, or a resumed state), its branches followed, and its files written
//! ([`run_study`], [`run_into`]).

use jointplay_solver::ode::{self, Flow as Step};
use jointplay_solver::state::HybridState;

use crate::Result;
use crate::flow::Flow;
use crate::storage::branches::*;
use crate::storage::continuation_file::{Layout, snapshot_path, write, write_snapshot};
use crate::study::continuation::branch::Report;
use crate::study::continuation::follow::*;
use crate::study::continuation::spec::*;

/// What the continuation's files record of the study `st` ([`Layout`]): its text, its
/// `[continuation]` table and its observables.
pub fn layout(st: &crate::study::analysis::load::Loaded) -> Result<Layout<'_>> {
    let spec = st.spec.continuation.as_ref().ok_or_else(|| {
        crate::study::spec::invalid(&st.path, "continuation", "no [continuation] table")
    })?;
    Ok(Layout {
        study: &st.text,
        parameter: &spec.parameter,
        unit: &spec.unit,
        from: spec.from,
        to: spec.to,
        tolerance: spec.tolerance,
        locate: spec.settings(None).locate,
        observables: st
            .spec
            .observables
            .iter()
            .map(|o| o.name.as_str())
            .collect(),
        gap_observable: spec
            .grazing
            .as_ref()
            .and_then(|g| st.spec.observable(&g.observable)),
    })
}

/// Where a continuation begins.
pub enum Begin {
    /// From the study's start after `transient` periods at `from`, or from the `start` state
    /// read before with [`Loaded::continuation_start`](crate::study::analysis::load::Loaded::continuation_start) (then `transient` periods from it, default none).
    Fresh(Option<HybridState>),
    /// Going on with an unfinished continuation read back with [`read_unfinished`](crate::storage::continuation_file::read_unfinished).
    Resume(Continuation),
}

/// Runs the study's `[continuation]` from `begin`, then its branches. `progress` gets a
/// [`Report`] after every point and stops the continuation by returning `false`.
pub fn run_study(
    st: &crate::study::analysis::load::Loaded,
    begin: Begin,
    progress: &mut dyn FnMut(&mut Report) -> bool,
) -> Result<Continuation> {
    let spec = st.spec.continuation.as_ref().ok_or_else(|| {
        crate::study::spec::invalid(&st.path, "continuation", "no [continuation] table")
    })?;
    let grazing = spec
        .grazing
        .as_ref()
        .and_then(|g| st.spec.observable(&g.observable));
    let make = |p: f64| st.continuation_target(p);
    let set = spec.settings(grazing);
    let units = st.continuation_target(spec.from)?.flow().observable_units();
    let mut forward = |r: &mut Report| {
        r.snapshot.units.clone_from(&units);
        progress(r)
    };
    let mut c = match begin {
        Begin::Resume(prior) => resume(&make, &set, prior, &mut forward)?,
        Begin::Fresh(start) => {
            let state = start_state(st, spec, start)?;
            continuation(&make, &set, &state, &mut forward)?
        }
    };
    c.units = units;
    Ok(c)
}

/// Runs the study's `[continuation]` ([`run_study`]) into its analysis file `file`: its state
/// is written after every point, marked unfinished, into the file of [`snapshot_path`]
/// ([`write_snapshot`]), so that a stop or a kill keeps what was computed, and into `file` once
/// at the end ([`write()`]), stopped or finished. `on_point` sees every [`Report`]; the
/// continuation stops early when it returns `false` or after `limit` points. The outer error is
/// one of writing the file; the inner one is a continuation that could not start, which is
/// written into the file too.
pub fn run_into(
    st: &crate::study::analysis::load::Loaded,
    file: &std::path::Path,
    begin: Begin,
    limit: Option<usize>,
    on_point: &mut dyn FnMut(&Report) -> bool,
) -> Result<std::result::Result<Continuation, crate::Error>> {
    let layout = layout(st)?;
    let _lock = crate::storage::lock::Lock::acquire(file)?;
    if matches!(begin, Begin::Fresh(_)) {
        // The state of an earlier continuation into this file is not this one's.
        crate::storage::durable::remove(&snapshot_path(file))?;
    }
    let mut points = 0usize;
    let mut write_error = None;
    let res = run_study(st, begin, &mut |r| {
        let go = on_point(r);
        if let Err(e) = write_snapshot(file, &layout, &r.snapshot) {
            write_error = Some(e);
            return false;
        }
        points += 1;
        go && limit.is_none_or(|n| points < n)
    });
    if let Some(e) = write_error {
        return Err(e);
    }
    write(file, &layout, res.as_ref())?;
    Ok(res)
}

/// The strobe point the first branch is shot from (see [`run_study`]).
fn start_state(
    st: &crate::study::analysis::load::Loaded,
    spec: &ContinuationSpec,
    start: Option<HybridState>,
) -> Result<HybridState> {
    let target = st.continuation_target(spec.from)?;
    let mut flow = target.flow();
    let t_strobe = flow.start_time() + st.spec.analysis.phase;
    let (mut state, transient) = match start {
        None => (
            flow.initial_state(None)?,
            spec.transient.unwrap_or(st.spec.analysis.transient),
        ),
        Some(s) => {
            let mut s = s.for_new_run();
            s.t = t_strobe;
            (s, spec.transient.unwrap_or(0))
        }
    };
    flow.prepare(&state)?;
    // The drive is periodic: the settled state is taken back to the first strobe time, so that
    // when the parameter changes the period (a drive frequency) the strobe phase moves by
    // `t_strobe d(omega)`, not by `transient` periods' worth of it.
    // From a fresh start (at the flow's start time) the run goes on to the strobe phase, so
    // that the state labelled with the strobe time is the state at a strobe time.
    let t = t_strobe + transient as f64 * flow.period();
    let method = flow.method();
    let (_, res) = ode::advance(
        &mut flow,
        method,
        &mut state,
        t,
        &[],
        |_, _, _| Step::Continue,
        None,
    );
    res?;
    state.t = t_strobe;
    Ok(state)
}
