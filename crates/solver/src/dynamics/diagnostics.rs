//! Diagnostics evaluated on the equations, not needed to advance them: the owner of a constraint
//! row, the dense Jacobian G and its rank and redundancy analysis, the drift |Phi| and |Phi'|, the
//! mechanical energy, joint reactions `-G_j^T lambda_j`, actuator forces and drive coordinates.

use nalgebra::{DMatrix, Vector3};

use super::kinematics::point_state;
use crate::error::{Error, Result};
use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::Workspace;

impl Model {
    /// Which joint or drive owns constraint row `i`, for messages.
    pub fn row_owner(&self, i: usize) -> String {
        if let Some(j) = self.joints.iter().find(|j| j.rows.contains(&i)) {
            format!(
                "joint '{}' (row {} of its {})",
                j.name,
                i - j.rows.start,
                j.rows.len()
            )
        } else if let Some(d) = self.drives.iter().find(|d| d.row == i) {
            format!("drive '{}'", d.name)
        } else {
            format!("row {i}")
        }
    }

    /// Dense constraint Jacobian (rows x 6 nb) at (t, y), for rank analysis.
    pub fn jacobian(&self, t: f64, y: &[f64]) -> DMatrix<f64> {
        let mut ws = Workspace::new(self);
        self.kinematics(y, &mut ws);
        self.constraints(t, &mut ws);
        let nb = self.nb();
        let mut g = DMatrix::zeros(self.n_rows, 6 * nb);
        for (i, r) in ws.rows.iter().enumerate() {
            for (b, j) in [(r.a, &r.ja), (r.b, &r.jb)] {
                if b != GROUND {
                    for c in 0..6 {
                        g[(i, 6 * b + c)] += j[c];
                    }
                }
            }
        }
        g
    }

    /// Rank and redundancy analysis of the constraint Jacobian at (t, y). Refused (naming the
    /// file) when the Jacobian is not finite or its singular values do not converge: nalgebra's
    /// SVD iterates without end on a NaN.
    pub fn structure(&self, t: f64, y: &[f64]) -> Result<Structure> {
        let g = self.jacobian(t, y);
        let fail = |message: &str| Error::Assembly {
            file: self.file.clone(),
            time: t,
            message: format!("rank analysis of the constraint Jacobian: {message}"),
        };
        let rank_of = |m: DMatrix<f64>| -> Result<usize> {
            if m.nrows() == 0 || m.ncols() == 0 {
                return Ok(0);
            }
            if m.iter().any(|v| !v.is_finite()) {
                return Err(fail(
                    "it is not finite (a coordinate or a length of the scene too large?)",
                ));
            }
            // The rank is that of the matrix scaled to entries of at most 1, whose squares
            // cannot overflow.
            let scale = m.amax();
            if scale == 0.0 {
                return Ok(0);
            }
            let sv = (m / scale)
                .try_svd_unordered(false, false, f64::EPSILON, 10_000)
                .ok_or_else(|| fail("its singular values did not converge"))?
                .singular_values;
            let smax = sv.iter().cloned().fold(0.0, f64::max);
            Ok(sv.iter().filter(|s| **s > 1e-9 * smax.max(1e-300)).count())
        };
        let n_coords = 6 * self.nb();
        let joint_rank = rank_of(g.rows(0, self.joint_rows).into_owned())?;
        let rank = rank_of(g)?;
        Ok(Structure {
            n_coords,
            joint_rows: self.joint_rows,
            drive_rows: self.n_rows - self.joint_rows,
            joint_rank,
            rank,
            dof: n_coords - joint_rank,
            redundant_joint_rows: self.joint_rows - joint_rank,
            redundant_drives: (self.n_rows - self.joint_rows) - (rank - joint_rank),
            remaining_dof: n_coords - rank,
        })
    }

    /// Constraint drift |Phi| (2-norm over rows, m and rad) and velocity drift |Phi'| at (t, y).
    pub fn drift(&self, t: f64, y: &[f64], ws: &mut Workspace) -> (f64, f64) {
        if self.n_rows == 0 {
            return (0.0, 0.0);
        }
        self.kinematics(y, ws);
        self.constraints(t, ws);
        let n = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        (n(&ws.phi), n(&ws.phi_dot))
    }

    /// Mechanical energy (J): kinetic + gravitational + spring potential + elastic energy of the
    /// contacts. Drives and loads do work on the system and damping and friction dissipate, so
    /// it is conserved only when none of them is present.
    pub fn energy(&self, y: &[f64], ws: &mut Workspace) -> f64 {
        self.kinematics(y, ws);
        let mut e = 0.0;
        for (k, b) in self.bodies.iter().enumerate() {
            let kn = &ws.kin[k];
            let wb = kn.rot.transpose() * kn.w;
            e += 0.5 * b.mass * kn.v.norm_squared() + 0.5 * wb.dot(&(b.inertia * wb));
            if let Some(g) = self.gravity {
                e -= b.mass * g.dot(&kn.r);
            }
        }
        for s in &self.springs {
            let (pa, _) = point_state(ws, s.a, &s.sa);
            let (pb, _) = point_state(ws, s.b, &s.sb);
            let dl = (pb - pa).norm() - s.free_length;
            e += 0.5 * s.stiffness * dl * dl;
        }
        // Elastic energy stored in the contacts (the integral of the elastic force).
        let nb = self.nb();
        for c in &self.clearances {
            let idx = |b: usize| if b == GROUND { nb } else { b };
            let slots = c.first..c.first + c.geometry.n_contacts();
            let (kh, kj) = (ws.kin[idx(c.housing)], ws.kin[idx(c.journal)]);
            c.geometry(&kh, &kj, &mut ws.contacts[slots.clone()]);
            for ce in &ws.contacts[slots] {
                e += c.law.elastic_energy(ce.delta);
            }
        }
        e
    }

    /// Reaction force (N) and torque (N m) that joint `j` exerts on its body b, global axes, the
    /// torque taken about the joint point on b; from the multipliers of the last evaluation.
    pub fn reaction(&self, j: usize, ws: &Workspace) -> (Vector3<f64>, Vector3<f64>) {
        let joint = &self.joints[j];
        let nb = self.nb();
        let on = |side_b: bool| {
            let mut g = [0.0; 6];
            for i in joint.rows.clone() {
                let r = &ws.rows[i];
                let jj = if side_b { &r.jb } else { &r.ja };
                for c in 0..6 {
                    g[c] -= ws.lambda[i] * jj[c];
                }
            }
            (
                Vector3::new(g[0], g[1], g[2]),
                Vector3::new(g[3], g[4], g[5]),
            )
        };
        let kb = &ws.kin[if joint.body_b == GROUND {
            nb
        } else {
            joint.body_b
        }];
        let p = kb.r + kb.rot * joint.point_b;
        if joint.body_b != GROUND {
            let (f, n) = on(true);
            (f, n + (kb.r - p).cross(&f))
        } else {
            // Constraint wrenches of a joint are internal: equal and opposite about any point.
            let ka = &ws.kin[joint.body_a];
            let (f, n) = on(false);
            (-f, -(n + (ka.r - p).cross(&f)))
        }
    }

    /// Actuator force (N) or torque (N m) of drive `d` on body b, in the direction of increasing
    /// joint coordinate, from the last evaluation.
    pub fn actuator_force(&self, d: usize, ws: &Workspace) -> f64 {
        -ws.lambda[self.drives[d].row]
    }

    /// The current value of drive `d`'s joint coordinate (m or rad) at (t, y): s(t) + Phi.
    pub fn drive_coordinate(&self, d: usize, t: f64, ws: &Workspace) -> f64 {
        self.drives[d].profile.eval(t).0 + ws.phi[self.drives[d].row]
    }
}

/// Ranks and counts of the constraint Jacobian.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Structure {
    /// Velocity coordinates (6 per body).
    pub n_coords: usize,
    pub joint_rows: usize,
    pub drive_rows: usize,
    pub joint_rank: usize,
    pub rank: usize,
    /// Degrees of freedom of the mechanism (joints only).
    pub dof: usize,
    pub redundant_joint_rows: usize,
    /// Drives beyond what the degrees of freedom need (redundant actuation).
    pub redundant_drives: usize,
    /// Degrees of freedom left free by joints and drives together.
    pub remaining_dof: usize,
}
