//! Pass 8: the start. A run's declared start is assembled with every clearance joint closed as
//! its ideal joint, then the joint is released: a copy of the model in which each such joint
//! has the rows of its ideal joint again (a spherical joint's coincident points, a revolute
//! joint's coincident points and parallel axes) carries the declared poses and velocities onto
//! the closed loops ([`Model::assemble`] on the copy), and the run starts from there with the
//! contact element in place.
//!
//! Without it, the assembly closes only the loops through ideal joints and leaves a clearance
//! joint wherever the declared poses put it: a coupler angle rounded in the third digit starts
//! a four-bar's journal 0.27 mm inside its bearing wall, with a contact force of half a
//! meganewton at t = 0; and velocities projected onto the ideal joints alone give the journal a
//! velocity relative to its housing that the first step turns into an impact.
//!
//! A joint's clearance block can ask for an eccentric start, `initial_eccentricity = [x, y, z]`
//! (m, housing body axes): the copy then holds the journal centre at `e` from the housing
//! centre, `P_journal = P_housing + A_housing e`, which must lie within the clearance
//! (`|e| <= c`) and, for a revolute joint, normal to the housing axis. `start = "free"` keeps
//! the joint out of the copy (the declared poses decide, as for a scene that wants its journal
//! started against the wall by its own coordinates).

use nalgebra::Vector3;

use super::ctx::Ctx;
use super::joints::ideal_rows;
use super::rows::{JointFrame, Rows};
use crate::error::{Error, Result};
use crate::model::{ClosedStart, Model, State};
use crate::scene::{JointStart, SceneSpec};

/// Assembles the declared `state` of `model` with its clearance joints closed (those not
/// `start = "free"`); `frames` are the joints' frames from pass 3. Returns what was closed, or
/// `None` when no joint is.
pub(crate) fn close(
    model: &Model,
    frames: &[JointFrame],
    spec: &SceneSpec,
    state: &mut State,
    cx: &Ctx,
) -> Result<Option<ClosedStart>> {
    let mut rows = Rows::default();
    let mut joints = model.joints.clone();
    let mut closed = Vec::new();
    let mut closed_rows = Vec::new();
    for (i, j) in model.joints.iter().enumerate() {
        let first = rows.n;
        let block = spec.joints[i].clearance.as_ref();
        match (j.clearance, block) {
            (Some(k), Some(cs)) if cs.start != Some(JointStart::Free) => {
                let f = format!("joints[{i}].clearance.initial_eccentricity");
                let e = eccentricity(cs.initial_eccentricity, model, k, &frames[i], &f, cx)?;
                let mut fr = frames[i];
                fr.sa += e;
                ideal_rows(j.kind, &fr, &mut rows);
                closed.push((j.name.clone(), e));
                closed_rows.push(first..rows.n);
                joints[i].clearance = None;
            }
            (_, Some(cs)) => {
                if cs.initial_eccentricity.is_some() {
                    return Err(cx.err(
                        format!("joints[{i}].clearance.initial_eccentricity"),
                        "an initial eccentricity needs start = \"closed\" (the default): with \
                         start = \"free\" the declared poses place the journal",
                    ));
                }
                copy_rows(model, j.rows.clone(), &mut rows);
            }
            (_, None) => copy_rows(model, j.rows.clone(), &mut rows),
        }
        joints[i].rows = first..rows.n;
    }
    if closed.is_empty() {
        return Ok(None);
    }
    let joint_rows = rows.n;
    let mut drives = model.drives.clone();
    for d in &mut drives {
        let row = rows.n;
        copy_rows(model, d.row..d.row + 1, &mut rows);
        d.row = row;
    }
    let blocks: Vec<_> = rows.prims.iter().map(|(p, r0)| p.row_block(*r0)).collect();
    let copy = Model {
        joints,
        drives,
        coupling: crate::coupling::Coupling::new(model.nb(), &blocks, rows.n),
        prims: rows.prims,
        clearances: Vec::new(),
        n_contacts: 0,
        joint_rows,
        n_rows: rows.n,
        ..model.clone()
    };
    // The start the model's own assembly gives (the loops through these joints left open): when
    // it already holds them closed, to 1e-9 (m, rad, m/s, rad/s: far below any clearance or
    // contact speed, far above rounding), it is kept as it is, so a scene that declares a closed
    // start runs bit for bit as it did before the closure existed.
    let mut open = state.clone();
    let gap = match model.assemble(&mut open) {
        Ok(_) => {
            let gap = gap(&copy, &closed_rows, &open);
            if gap.0 <= 1e-9 && gap.1 <= 1e-9 {
                return Ok(Some(ClosedStart {
                    joints: closed,
                    gap: Some(gap),
                    moved: false,
                }));
            }
            Some(gap)
        }
        Err(_) => None,
    };
    let names: Vec<&str> = closed.iter().map(|(n, _)| n.as_str()).collect();
    // A start that already closes the loops (to rounding: 1e-12, the position tolerance of the
    // assembly, in m/s or rad/s) is kept bit for bit.
    let report = copy.assemble_within(state, 1e-12).map_err(|e| match e {
        Error::Assembly {
            file,
            time,
            message,
        } => Error::Assembly {
            file,
            time,
            message: format!(
                "{message} (the start is assembled with the clearance joint(s) {} closed as \
                 ideal joints: give an `initial_eccentricity` the loops allow, or \
                 start = \"free\" in a joint's clearance block to leave it where the declared \
                 poses put it)",
                names.join(", ")
            ),
        },
        other => other,
    })?;
    debug_assert!(report.final_residual < 1e-9);
    Ok(Some(ClosedStart {
        joints: closed,
        gap,
        moved: true,
    }))
}

/// The largest |Phi| and |Phi'| (m or rad, m/s or rad/s) of the rows `rows` of `copy` at `state`.
fn gap(copy: &Model, rows: &[std::ops::Range<usize>], state: &State) -> (f64, f64) {
    let mut ws = crate::workspace::Workspace::new(copy);
    copy.kinematics(&state.y, &mut ws);
    copy.constraints(state.t, &mut ws);
    let max = |v: &[f64]| {
        rows.iter()
            .flat_map(|r| v[r.clone()].iter())
            .fold(0.0f64, |m, x| m.max(x.abs()))
    };
    (max(&ws.phi), max(&ws.phi_dot))
}

/// The rows of `model` in `range` (whole primitives), appended to `rows`. The primitives are
/// in row order, so the range's are found by bisection rather than by a scan per joint.
fn copy_rows(model: &Model, range: std::ops::Range<usize>, rows: &mut Rows) {
    let first = model.prims.partition_point(|(_, r0)| *r0 < range.start);
    for (p, _) in model.prims[first..]
        .iter()
        .take_while(|(_, r0)| *r0 < range.end)
    {
        rows.push(p.clone());
    }
}

/// The eccentricity `given` for clearance element `k` of `model` (m, housing axes), checked
/// against the clearance and, for a revolute joint, the housing axis; zero when not given.
fn eccentricity(
    given: Option<[f64; 3]>,
    model: &Model,
    k: usize,
    fr: &JointFrame,
    field: &str,
    cx: &Ctx,
) -> Result<Vector3<f64>> {
    let Some(e) = given else {
        return Ok(Vector3::zeros());
    };
    let e = Vector3::from(e);
    let element = &model.clearances[k];
    let c = element.geometry.radial_clearance();
    if element.geometry.has_axis() {
        // Along the axis the ideal revolute joint holds the journal centred (and the prismatic
        // joint leaves the slider free); an axial offset would be silently dropped, so it is
        // refused. 1e-9 of the clearance is rounding.
        let along = e.dot(&fr.axis_a);
        if along.abs() > 1e-9 * c {
            return Err(cx.err(
                field,
                format!(
                    "has a component of {along:.4e} m along the joint axis; the eccentricity of a \
                     revolute or prismatic joint is normal to its axis (axis_a in the housing's axes: [{}, {}, {}])",
                    fr.axis_a.x, fr.axis_a.y, fr.axis_a.z
                ),
            ));
        }
    }
    if matches!(
        element.geometry,
        crate::clearance::Geometry::Translational {
            half_width: None,
            ..
        }
    ) {
        // A planar slider moves in the plane of its axis and reference direction; an offset
        // out of that plane contradicts the rows that hold it there.
        let out = e.dot(&fr.wa);
        if out.abs() > 1e-9 * c {
            return Err(cx.err(
                field,
                format!(
                    "has a component of {out:.4e} m out of the slider's plane; the offset of a \
                     prismatic clearance lies along reference_a (in the housing's axes: [{}, {}, {}])",
                    fr.ua.x, fr.ua.y, fr.ua.z
                ),
            ));
        }
    }
    // A box slider may sit against its floor and a wall at once: its offset is bounded in
    // each direction across the axis, not in length.
    let reach = match element.geometry {
        crate::clearance::Geometry::Translational {
            half_width: Some(_),
            ..
        } => e.dot(&fr.ua).abs().max(e.dot(&fr.wa).abs()),
        _ => e.norm(),
    };
    if reach > c {
        return Err(cx.err(
            field,
            format!(
                "|e| = {reach:.4e} m exceeds the radial clearance {c:.4e} m: the journal would \
                 start inside the wall"
            ),
        ));
    }
    Ok(e)
}
