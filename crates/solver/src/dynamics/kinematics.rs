//! Stage 1, kinematics: each body's position r, rotation matrix A, velocity v and angular velocity
//! w (all global) from the state vector `y = (r_k, q_k for every body; v_k, w_k for every body)`.
//! The rotation is carried by Euler parameters q (`q' = 1/2 (0, w) (x) q`); A is built from
//! q/|q| ([`rotation`]), so the slow drift of |q| under integration never distorts the body.

use nalgebra::{Matrix3, Vector3};

use super::blocks::v3;
use crate::kin::{GROUND, Kin};
use crate::model::Model;
use crate::workspace::Workspace;

/// Rotation matrix of the (not necessarily unit) quaternion (w, x, y, z).
#[inline]
pub fn rotation(q: &[f64]) -> Matrix3<f64> {
    // 2/|q|^2 scales the products; no square root or per-component division is needed.
    let s = 2.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    Matrix3::new(
        1.0 - s * (y * y + z * z),
        s * (x * y - w * z),
        s * (x * z + w * y),
        s * (x * y + w * z),
        1.0 - s * (x * x + z * z),
        s * (y * z - w * x),
        s * (x * z - w * y),
        s * (y * z + w * x),
        1.0 - s * (x * x + y * y),
    )
}

impl Model {
    /// Kinematics of body `b` (or the ground) from the last [`Model::kinematics`].
    pub fn kinematics_of(&self, b: usize, ws: &Workspace) -> Kin {
        ws.kin[if b == GROUND { self.nb() } else { b }]
    }

    /// Fills the body kinematics of the workspace from the state vector.
    pub fn kinematics(&self, y: &[f64], ws: &mut Workspace) {
        for k in 0..self.nb() {
            ws.kin[k] = self.body_kinematics(y, k);
        }
        if self.n_bristle > 0 {
            let o = self.bristle_offset();
            ws.bristle.copy_from_slice(&y[o..o + self.n_bristle]);
        }
    }

    /// The kinematics of body `k` (not the ground) from the state vector.
    #[inline]
    pub(super) fn body_kinematics(&self, y: &[f64], k: usize) -> Kin {
        let np = 7 * self.nb();
        let p = &y[7 * k..7 * k + 7];
        let v = &y[np + 6 * k..np + 6 * k + 6];
        Kin {
            r: v3(&p[0..3]),
            rot: rotation(&p[3..7]),
            v: v3(&v[0..3]),
            w: v3(&v[3..6]),
        }
    }
}

/// The position and velocity (global) of the point at `s` (body axes) of body `b` (the ground's
/// points are fixed).
pub(super) fn point_state(
    ws: &Workspace,
    b: usize,
    s: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    if b == GROUND {
        return (*s, Vector3::zeros());
    }
    let k = &ws.kin[b];
    let sg = k.rot * s;
    (k.r + sg, k.v + k.w.cross(&sg))
}
