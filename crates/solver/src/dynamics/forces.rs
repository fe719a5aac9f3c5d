//! Stage 3, applied forces: per body the generalised force Q_k = (f_k, n_k - w_k x J_k w_k) of
//! gravity, springs, the clearance joints' contacts ([`super::contact`]) and external loads, with
//! the gyroscopic torque, and the global inverse inertia `J_k^-1 = A_k J'_k^-1 A_k^T`.

use nalgebra::Vector3;

use super::blocks::block;
use super::kinematics::point_state;
use crate::kin::GROUND;
use crate::model::Model;
use crate::scene::LoadFrame;
use crate::workspace::Workspace;

impl Model {
    /// Applied forces and inertial (gyroscopic) torques per body into `ws.q`, and the global
    /// inverse inertias into `ws.inv_j`. Needs [`Model::kinematics`] first.
    pub fn applied_forces(&self, t: f64, ws: &mut Workspace) {
        let _ = t;
        let nb = self.nb();
        for k in 0..nb {
            let body = &self.bodies[k];
            let kn = &ws.kin[k];
            ws.inv_j[k] = kn.rot * body.inv_inertia * kn.rot.transpose();
            let wb = kn.rot.transpose() * kn.w;
            let gyro = kn.rot * wb.cross(&(body.inertia * wb));
            let f = if self.effects.gravity {
                self.gravity.unwrap_or_default() * body.mass
            } else {
                Vector3::zeros()
            };
            ws.q[k] = block(&f, &(-gyro));
        }
        if self.effects.springs {
            for s in &self.springs {
                let (pa, va) = point_state(ws, s.a, &s.sa);
                let (pb, vb) = point_state(ws, s.b, &s.sb);
                let d = pb - pa;
                let l = d.norm();
                if l < 1e-12 {
                    continue; // direction undefined; a spring of zero length carries no force
                }
                let e = d / l;
                let ld = e.dot(&(vb - va));
                let fmag = s.stiffness * (l - s.free_length) + s.damping * ld;
                add_force(ws, s.a, &(e * fmag), &pa);
                add_force(ws, s.b, &(-e * fmag), &pb);
            }
        }
        if self.effects.clearance {
            self.contact_forces(ws);
        }
        if self.effects.loads {
            for l in &self.loads {
                let rot = ws.kin[l.body].rot;
                let (f, n) = match l.frame {
                    LoadFrame::Global => (l.force, l.torque),
                    LoadFrame::Body => (rot * l.force, rot * l.torque),
                };
                let p = ws.kin[l.body].r + rot * l.s;
                add_force(ws, l.body, &f, &p);
                let q = &mut ws.q[l.body];
                q[3] += n.x;
                q[4] += n.y;
                q[5] += n.z;
            }
        }
    }
}

/// Adds the force `f` applied at the global point `p` of body `b` (and its moment about the
/// centre of mass) to `ws.q`.
fn add_force(ws: &mut Workspace, b: usize, f: &Vector3<f64>, p: &Vector3<f64>) {
    if b == GROUND {
        return;
    }
    let n = (p - ws.kin[b].r).cross(f);
    let q = &mut ws.q[b];
    for c in 0..3 {
        q[c] += f[c];
        q[3 + c] += n[c];
    }
}
