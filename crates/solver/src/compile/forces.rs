//! Pass 6: applied forces. Spring-dampers between two bodies and constant loads on one body.

use std::collections::HashSet;

use nalgebra::Vector3;

use super::bodies::Bodies;
use super::ctx::{Ctx, v3};
use crate::error::Result;
use crate::model::{GROUND, Load, Spring};
use crate::scene::SceneSpec;

/// Compiles `spec.springs`; the free length defaults to the initial distance of the points.
pub(crate) fn springs(spec: &SceneSpec, bodies: &Bodies, cx: &Ctx) -> Result<Vec<Spring>> {
    let mut springs = Vec::new();
    let mut names = HashSet::new();
    for (i, s) in spec.springs.iter().enumerate() {
        let f = format!("springs[{i}]");
        if !names.insert(s.name.as_str()) {
            return Err(cx.err(
                format!("{f}.name"),
                format!("duplicate spring name '{}'", s.name),
            ));
        }
        let a = bodies.index(&s.body_a, format!("{f}.body_a"), cx)?;
        let b = bodies.index(&s.body_b, format!("{f}.body_b"), cx)?;
        if a == b {
            return Err(cx.err(format!("{f}.body_b"), "a spring needs two different bodies"));
        }
        let (fa, fb) = (bodies.frame(a), bodies.frame(b));
        let sa = fa.point(&s.point_a, &format!("{f}.point_a"), cx)?;
        let sb = fb.point(&s.point_b, &format!("{f}.point_b"), cx)?;
        if s.stiffness < 0.0 {
            return Err(cx.err(format!("{f}.stiffness"), "must not be negative"));
        }
        if s.damping < 0.0 {
            return Err(cx.err(format!("{f}.damping"), "must not be negative"));
        }
        let l0 = (fb.global_point(&sb) - fa.global_point(&sa)).norm();
        let free_length = s.free_length.unwrap_or(l0);
        if free_length < 0.0 {
            return Err(cx.err(format!("{f}.free_length"), "must not be negative"));
        }
        springs.push(Spring {
            name: s.name.clone(),
            a,
            sa,
            b,
            sb,
            stiffness: s.stiffness,
            damping: s.damping,
            free_length,
        });
    }
    Ok(springs)
}

/// Compiles `spec.loads`; the point of application defaults to the centre of mass.
pub(crate) fn loads(spec: &SceneSpec, bodies: &Bodies, cx: &Ctx) -> Result<Vec<Load>> {
    let mut loads = Vec::new();
    let mut names = HashSet::new();
    for (i, l) in spec.loads.iter().enumerate() {
        let f = format!("loads[{i}]");
        if !names.insert(l.name.as_str()) {
            return Err(cx.err(
                format!("{f}.name"),
                format!("duplicate load name '{}'", l.name),
            ));
        }
        let body = bodies.index(&l.body, format!("{f}.body"), cx)?;
        if body == GROUND {
            return Err(cx.err(format!("{f}.body"), "a load on the ground has no effect"));
        }
        let s = match &l.point {
            Some(p) => bodies.frame(body).point(p, &format!("{f}.point"), cx)?,
            None => Vector3::zeros(),
        };
        loads.push(Load {
            name: l.name.clone(),
            body,
            s,
            force: v3(l.force),
            torque: v3(l.torque),
            frame: l.frame,
        });
    }
    Ok(loads)
}
