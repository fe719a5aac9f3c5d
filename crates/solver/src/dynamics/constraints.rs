//! Stage 2, constraint rows: for every primitive of the ideal joints and drives, its Jacobian
//! rows G (with respect to the velocities, 6 columns per body, at most two bodies per row),
//! Phi, Phi' and the right-hand side of `G a = gamma - 2 alpha_B Phi' - beta_B^2 Phi` (Baumgarte,
//! 1972), with gamma = -(dG/dt) v + s''(t) the velocity-quadratic terms and s(t) a drive's
//! prescribed coordinate.

use nalgebra::Vector3;

use super::blocks::block;
use crate::kin::GROUND;
use crate::model::{Model, Prim};
use crate::profile::SinCos;
use crate::workspace::{Row, Workspace};

impl Model {
    /// Evaluates every constraint row at time t: Jacobian rows, Phi, Phi' and the Baumgarte
    /// right-hand side. Needs [`Model::kinematics`] first.
    pub fn constraints(&self, t: f64, ws: &mut Workspace) {
        let nb = self.nb();
        let kin = &ws.kin;
        let idx = |b: usize| if b == GROUND { nb } else { b };
        let mut memo = SinCos::default();
        let mut drive_eval = |d: usize| self.drives[d].profile.eval_memo(t, &mut memo);
        for (prim, r0) in &self.prims {
            let r0 = *r0;
            match prim {
                Prim::Coincident { a, sa, b, sb } => {
                    let (ka, kb) = (&kin[idx(*a)], &kin[idx(*b)]);
                    let sag = ka.rot * sa;
                    let sbg = kb.rot * sb;
                    let phi = kb.r + sbg - ka.r - sag;
                    let phid = kb.v + kb.w.cross(&sbg) - ka.v - ka.w.cross(&sag);
                    let gam = -(kb.w.cross(&kb.w.cross(&sbg)) - ka.w.cross(&ka.w.cross(&sag)));
                    for k in 0..3 {
                        let mut e = Vector3::zeros();
                        e[k] = 1.0;
                        // d/dv_a = -e, d/dw_a = e^T [s_a]x = (s_a x e)... written via the cross
                        // product identity e . (w x s) = w . (s x e).
                        let ja = block(&(-e), &sag.cross(&e).scale(-1.0));
                        let jb = block(&e, &sbg.cross(&e));
                        ws.rows[r0 + k] = Row {
                            a: *a,
                            b: *b,
                            ja,
                            jb,
                        };
                        ws.phi[r0 + k] = phi[k];
                        ws.phi_dot[r0 + k] = phid[k];
                        ws.rhs[r0 + k] = gam[k];
                    }
                }
                Prim::Perpendicular { a, u, b, v } => {
                    let (ka, kb) = (&kin[idx(*a)], &kin[idx(*b)]);
                    let ug = ka.rot * u;
                    let vg = kb.rot * v;
                    let c = ug.cross(&vg);
                    let wu = ka.w.cross(&ug);
                    let wv = kb.w.cross(&vg);
                    ws.rows[r0] = Row {
                        a: *a,
                        b: *b,
                        ja: block(&Vector3::zeros(), &c),
                        jb: block(&Vector3::zeros(), &(-c)),
                    };
                    ws.phi[r0] = ug.dot(&vg);
                    ws.phi_dot[r0] = (ka.w - kb.w).dot(&c);
                    ws.rhs[r0] =
                        -(vg.dot(&ka.w.cross(&wu)) + ug.dot(&kb.w.cross(&wv)) + 2.0 * wu.dot(&wv));
                }
                Prim::Distance {
                    a,
                    u,
                    sa,
                    b,
                    sb,
                    drive,
                } => {
                    let (ka, kb) = (&kin[idx(*a)], &kin[idx(*b)]);
                    let ug = ka.rot * u;
                    let sag = ka.rot * sa;
                    let sbg = kb.rot * sb;
                    let d = kb.r + sbg - ka.r - sag;
                    let dd = kb.v + kb.w.cross(&sbg) - ka.v - ka.w.cross(&sag);
                    let wu = ka.w.cross(&ug);
                    let (s, sd, sdd) = drive.map_or((0.0, 0.0, 0.0), &mut drive_eval);
                    ws.rows[r0] = Row {
                        a: *a,
                        b: *b,
                        ja: block(&(-ug), &ug.cross(&(d + sag))),
                        jb: block(&ug, &sbg.cross(&ug)),
                    };
                    ws.phi[r0] = ug.dot(&d) - s;
                    ws.phi_dot[r0] = wu.dot(&d) + ug.dot(&dd) - sd;
                    ws.rhs[r0] = -(ka.w.cross(&wu).dot(&d)
                        + 2.0 * wu.dot(&dd)
                        + ug.dot(&(kb.w.cross(&kb.w.cross(&sbg)) - ka.w.cross(&ka.w.cross(&sag)))))
                        + sdd;
                }
                Prim::Angle {
                    a,
                    axis,
                    ua,
                    wa,
                    b,
                    ub,
                    drive,
                } => {
                    let (ka, kb) = (&kin[idx(*a)], &kin[idx(*b)]);
                    let ax = ka.rot * axis;
                    let ubg = kb.rot * ub;
                    let theta = ubg.dot(&(ka.rot * wa)).atan2(ubg.dot(&(ka.rot * ua)));
                    let (s, sd, sdd) = drive_eval(*drive);
                    let dw = kb.w - ka.w;
                    ws.rows[r0] = Row {
                        a: *a,
                        b: *b,
                        ja: block(&Vector3::zeros(), &(-ax)),
                        jb: block(&Vector3::zeros(), &ax),
                    };
                    // Wrapped into (-pi, pi] so that a drive turning without bound stays smooth.
                    let e = theta - s;
                    ws.phi[r0] = e
                        - (2.0 * std::f64::consts::PI) * (e / (2.0 * std::f64::consts::PI)).round();
                    ws.phi_dot[r0] = ax.dot(&dw) - sd;
                    ws.rhs[r0] = -ka.w.cross(&ax).dot(&dw) + sdd;
                }
            }
        }
        let (al, be) = (self.settings.alpha, self.settings.beta);
        for i in 0..self.n_rows {
            ws.rhs[i] -= 2.0 * al * ws.phi_dot[i] + be * be * ws.phi[i];
        }
    }
}
