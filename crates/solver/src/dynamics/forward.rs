//! The forward dynamics, composed from the stages as MuJoCo's `mj_forward` composes its own:
//! kinematics ([`super::kinematics`]), applied forces ([`super::forces`], contacts included),
//! `M^-1 Q` per body, constraint rows ([`super::constraints`], skipped without constraints),
//! `b = G M^-1 Q - rhs` and the reduced solve ([`super::solve`]); then the full right-hand side
//! `y' = (v, 1/2 (0, w) (x) q, a, z')` (z': the LuGre bristles' rates, [`crate::contact`]).

use nalgebra::Vector3;

use super::blocks::dot6;
use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::Workspace;

impl Model {
    /// Accelerations and multipliers at (t, y) into the workspace.
    pub fn accelerations(&self, t: f64, y: &[f64], ws: &mut Workspace) {
        self.accelerations_with(t, y, ws, false);
    }

    /// [`Model::accelerations`] with the reduced system assembled and factored densely, in
    /// O(rows^3): the reference the sparse solve is verified against.
    pub fn accelerations_dense(&self, t: f64, y: &[f64], ws: &mut Workspace) {
        self.accelerations_with(t, y, ws, true);
    }

    fn accelerations_with(&self, t: f64, y: &[f64], ws: &mut Workspace, dense: bool) {
        self.kinematics(y, ws);
        self.applied_forces(t, ws);
        let nb = self.nb();
        for k in 0..nb {
            let q = &ws.q[k];
            let m = self.bodies[k].mass;
            let tq = ws.inv_j[k] * Vector3::new(q[3], q[4], q[5]);
            ws.minv_q[k] = [q[0] / m, q[1] / m, q[2] / m, tq.x, tq.y, tq.z];
        }
        ws.acc.copy_from_slice(&ws.minv_q);
        if !self.effects.constraints {
            return;
        }
        self.constraints(t, ws);
        // b = G M^-1 Q - rhs, solved in place into the multipliers.
        for i in 0..self.n_rows {
            let r = &ws.rows[i];
            let mut b = -ws.rhs[i];
            if r.a != GROUND {
                b += dot6(&r.ja, &ws.minv_q[r.a]);
            }
            if r.b != GROUND {
                b += dot6(&r.jb, &ws.minv_q[r.b]);
            }
            ws.lambda[i] = b;
        }
        ws.dense_used = dense || !self.solve_sparse(ws);
        if ws.dense_used {
            self.solve_dense(ws);
        }
    }

    /// The full right-hand side y' = f(t, y).
    pub fn rhs(&self, t: f64, y: &[f64], ws: &mut Workspace, dy: &mut [f64]) {
        self.accelerations(t, y, ws);
        let nb = self.nb();
        let np = 7 * nb;
        for k in 0..nb {
            let vel = &y[np + 6 * k..np + 6 * k + 6];
            let q = &y[7 * k + 3..7 * k + 7];
            dy[7 * k..7 * k + 3].copy_from_slice(&vel[0..3]);
            // q' = 1/2 (0, w) (x) q, w global.
            let (w0, w1, w2) = (vel[3], vel[4], vel[5]);
            dy[7 * k + 3] = 0.5 * (-w0 * q[1] - w1 * q[2] - w2 * q[3]);
            dy[7 * k + 4] = 0.5 * (w0 * q[0] + w1 * q[3] - w2 * q[2]);
            dy[7 * k + 5] = 0.5 * (w1 * q[0] + w2 * q[1] - w0 * q[3]);
            dy[7 * k + 6] = 0.5 * (w2 * q[0] + w0 * q[2] - w1 * q[1]);
            dy[np + 6 * k..np + 6 * k + 6].copy_from_slice(&ws.acc[k]);
        }
        if self.n_bristle > 0 {
            let o = self.bristle_offset();
            dy[o..o + self.n_bristle].copy_from_slice(&ws.bristle_rate);
        }
    }
}
