//! Pass 3: joints. Resolves each joint's bodies, points, axes and reference directions into a
//! [`JointFrame`](super::rows::JointFrame), and produces the joints with the constraint
//! primitives of their rows (Haug, *Computer-Aided Kinematics and Dynamics of Mechanical
//! Systems*, 1989, ch. 3; Nikravesh, *Computer-Aided Analysis of Mechanical Systems*, 1988,
//! ch. 4; the table of rows is in [`crate::model`]). A joint with a `clearance` block becomes a
//! contact element (pass 4, [`super::clearance`]) and keeps only the rows the element leaves
//! unconstrained.

use std::collections::HashMap;

use nalgebra::Vector3;

use super::bodies::{Bodies, Frames};
use super::clearance;
use super::ctx::Ctx;
use super::rows::{JointFrame, Rows};
use crate::clearance::Clearance;
use crate::error::Result;
use crate::model::{Joint, Prim, any_normal};
use crate::scene::{JointKind, JointSpec, SceneSpec, VecRef};

/// What the joints pass produces.
pub(crate) struct Joints<'s> {
    pub joints: Vec<Joint>,
    /// The frame of each joint, for the drives.
    pub frames: Vec<JointFrame>,
    pub index: HashMap<&'s str, usize>,
    pub clearances: Vec<Clearance>,
    /// Contact points of all clearance elements.
    pub n_contacts: usize,
}

/// Compiles `spec.joints` on the bodies of pass 2, appending the joints' rows to `rows`.
pub(crate) fn compile<'s>(
    spec: &'s SceneSpec,
    bodies: &Bodies,
    rows: &mut Rows,
    cx: &Ctx,
) -> Result<Joints<'s>> {
    let mut out = Joints {
        joints: Vec::new(),
        frames: Vec::new(),
        index: HashMap::new(),
        clearances: Vec::new(),
        n_contacts: 0,
    };
    for (i, j) in spec.joints.iter().enumerate() {
        let f = format!("joints[{i}]");
        if j.name.is_empty() {
            return Err(cx.err(format!("{f}.name"), "empty name"));
        }
        if out.index.insert(&j.name, i).is_some() {
            return Err(cx.err(
                format!("{f}.name"),
                format!("duplicate joint name '{}'", j.name),
            ));
        }
        let fr = joint_frame(j, &f, bodies, cx)?;
        let start = rows.n;
        let clearance = match &j.clearance {
            Some(cs) => {
                let element = clearance::compile(cs, j, i, &fr, out.n_contacts, &f, cx)?;
                clearance::remaining_rows(&element.geometry, &fr, rows);
                out.n_contacts += element.geometry.n_contacts();
                out.clearances.push(element);
                Some(out.clearances.len() - 1)
            }
            None => {
                ideal_rows(j.kind, &fr, rows);
                None
            }
        };
        out.frames.push(fr);
        out.joints.push(Joint {
            name: j.name.clone(),
            kind: j.kind,
            body_a: fr.a,
            body_b: fr.b,
            point_a: fr.sa,
            point_b: fr.sb,
            rows: start..rows.n,
            clearance,
        });
    }
    Ok(out)
}

/// The rows of an ideal joint of kind `kind`.
pub(crate) fn ideal_rows(kind: JointKind, fr: &JointFrame, rows: &mut Rows) {
    let mut push = |p| rows.push(p);
    match kind {
        JointKind::Spherical => push(fr.coincident()),
        JointKind::Revolute => {
            push(fr.coincident());
            fr.parallel().into_iter().for_each(&mut push);
        }
        JointKind::Universal => {
            push(fr.coincident());
            push(Prim::Perpendicular {
                a: fr.a,
                u: fr.axis_a,
                b: fr.b,
                v: fr.axis_b,
            });
        }
        JointKind::Cylindrical => {
            fr.parallel().into_iter().for_each(&mut push);
            fr.collinear().into_iter().for_each(&mut push);
        }
        JointKind::Prismatic => {
            fr.parallel().into_iter().for_each(&mut push);
            fr.collinear().into_iter().for_each(&mut push);
            push(fr.lock());
        }
        JointKind::Planar => {
            fr.parallel().into_iter().for_each(&mut push);
            push(fr.along_axis(None));
        }
        JointKind::Fixed => {
            push(fr.coincident());
            fr.parallel().into_iter().for_each(&mut push);
            push(fr.lock());
        }
    }
}

/// Resolves joint `j` (field path `f`): its bodies, points, axes and joint frame.
fn joint_frame(j: &JointSpec, f: &str, bodies: &Bodies, cx: &Ctx) -> Result<JointFrame> {
    let a = bodies.index(&j.body_a, format!("{f}.body_a"), cx)?;
    let b = bodies.index(&j.body_b, format!("{f}.body_b"), cx)?;
    if a == b {
        return Err(cx.err(
            format!("{f}.body_b"),
            format!("joint '{}' connects '{}' to itself", j.name, j.body_a),
        ));
    }
    let (fa, fb) = (bodies.frame(a), bodies.frame(b));
    let sa = fa.point(&j.point_a, &format!("{f}.point_a"), cx)?;
    let sb = fb.point(&j.point_b, &format!("{f}.point_b"), cx)?;
    let (axis_a, axis_b) = if j.kind.needs_axes() {
        let needed = |r: &Option<VecRef>, side: &str| {
            r.clone().ok_or_else(|| {
                cx.err(
                    format!("{f}.axis_{side}"),
                    format!("a {} joint needs axis_{side}", j.kind.name()),
                )
            })
        };
        let (ra, rb) = (needed(&j.axis_a, "a")?, needed(&j.axis_b, "b")?);
        (
            fa.axis(&ra, &format!("{f}.axis_a"), cx)?,
            fb.axis(&rb, &format!("{f}.axis_b"), cx)?,
        )
    } else {
        if j.axis_a.is_some() || j.axis_b.is_some() {
            return Err(cx.err(format!("{f}.axis_a"), "a spherical joint has no axes"));
        }
        (Vector3::z(), Vector3::z())
    };
    // Joint frame on a: u_a normal to axis_a, w_a = axis_a x u_a.
    let ua = match &j.reference_a {
        Some(r) => reference(r, fa, &axis_a, &format!("{f}.reference_a"), "axis_a", cx)?,
        None => any_normal(&axis_a),
    };
    let wa = axis_a.cross(&ua);
    let ub = match &j.reference_b {
        Some(r) => reference(r, fb, &axis_b, &format!("{f}.reference_b"), "axis_b", cx)?,
        None => {
            let g = fb.to_local(&fa.to_global(&ua));
            let p = g - axis_b * axis_b.dot(&g);
            if p.norm() < 1e-6 {
                any_normal(&axis_b)
            } else {
                p.normalize()
            }
        }
    };
    Ok(JointFrame {
        a,
        b,
        sa,
        sb,
        axis_a,
        axis_b,
        ua,
        wa,
        ub,
    })
}

/// A declared reference direction, made normal to `axis` (called `axis_name` in the error).
fn reference(
    r: &VecRef,
    frame: &Frames,
    axis: &Vector3<f64>,
    field: &str,
    axis_name: &str,
    cx: &Ctx,
) -> Result<Vector3<f64>> {
    let u = frame.axis(r, field, cx)?;
    let p = u - axis * axis.dot(&u);
    if p.norm() < 1e-9 {
        return Err(cx.err(field, format!("parallel to {axis_name}")));
    }
    Ok(p.normalize())
}
