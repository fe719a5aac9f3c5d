//! Small shared types of the solver, at the bottom of its module graph: the kinematics of a body
//! ([`Kin`]), the index of the ground ([`GROUND`]) and a deterministic normal to an axis
//! ([`any_normal`]). This module imports nothing from the crate, so every other module may use it
//! without closing an import cycle.

use nalgebra::{Matrix3, Vector3};

/// Index used for the ground in body references.
pub const GROUND: usize = usize::MAX;

/// Kinematics of one body at the current state (global).
#[derive(Debug, Clone, Copy)]
pub struct Kin {
    pub r: Vector3<f64>,
    pub rot: Matrix3<f64>,
    pub v: Vector3<f64>,
    pub w: Vector3<f64>,
}

impl Default for Kin {
    fn default() -> Self {
        Kin {
            r: Vector3::zeros(),
            rot: Matrix3::identity(),
            v: Vector3::zeros(),
            w: Vector3::zeros(),
        }
    }
}

/// Any unit vector normal to `a` (unit), chosen deterministically.
pub fn any_normal(a: &Vector3<f64>) -> Vector3<f64> {
    let t = if a.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    (t - a * a.dot(&t)).normalize()
}
