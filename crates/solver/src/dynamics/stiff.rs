//! What the stiff integrators ask of the contacts: the directions along which the contact forces
//! make the right-hand side stiff (penetration gradients and the normal and tangent velocity
//! directions), and the contacts' part of the Jacobian df/dy along given directions,
//! `da = M^-1 (dQ - G^T dlambda)` with `(G M^-1 G^T) dlambda = G M^-1 dQ`.

use nalgebra::Vector3;

use super::blocks::dot6;
use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::{Workspace, minv_block};

impl Model {
    /// The directions along which the contacts make the right-hand side stiff at `y`, for a step
    /// of about `h` (s) (see
    /// [`Stiffness::directions`](crate::ode::Stiffness::directions)). A contact
    /// counts when it penetrates at `y` or would within `h` at its current rate
    /// (`delta + h delta_dot > 0`).
    /// Its force depends stiffly on its penetration `delta(q)` (the normal law's stiffness), on
    /// its penetration rate (the damping) and, when it has friction, on the sliding velocity (a
    /// regularised law's slope); each of these is `g . nu` for a velocity-level direction `g`
    /// over the two bodies (journal `(d, r_j x d)`, housing `-(d, r_h x d)`, with `d` the normal
    /// `n` or a tangent and `r` the lever from each body's centre of mass to its contact point).
    /// So per contact: the gradient of `delta` with respect to the positions (translations `d`,
    /// Euler parameters `2 G(q) (r x d) / |q|^2`, where `q' = 1/2 G(q) w`), and the velocity
    /// directions of the normal and, with friction, of the two tangents. `pattern` lists the
    /// contact slots used. A lubricated joint's oil film adds, at every state, the position
    /// gradients and velocity directions of its journal centre's offset along two directions
    /// normal to the bearing axis. The forces' other dependences (the normal's turning, the levers) are
    /// of the order of the force over the journal's radius, negligible beside these.
    pub fn stiff_directions(
        &self,
        y: &[f64],
        h: f64,
        ws: &mut Workspace,
        dirs: &mut Vec<f64>,
        pattern: &mut Vec<u32>,
    ) {
        dirs.clear();
        pattern.clear();
        if !self.effects.clearance {
            return;
        }
        let nb = self.nb();
        self.contact_geometry(y, ws);
        for (ci, c) in self.clearances.iter().enumerate() {
            let slots = c.first..c.first + c.geometry.n_contacts();
            let friction = self.effects.friction && !c.friction.is_none();
            for s in slots {
                let ce = ws.contacts[s];
                let nn = ce.n.norm_squared();
                if !(nn > 0.5 && nn < 2.0) || !(ce.delta > 0.0 || ce.delta + h * ce.delta_dot > 0.0)
                {
                    continue;
                }
                pattern.push(s as u32);
                let t1 = crate::kin::any_normal(&ce.n);
                let t2 = ce.n.cross(&t1);
                let sides = [(c.journal, ce.pj, 1.0), (c.housing, ce.ph, -1.0)];
                position_gradient(y, ws, &sides, &ce.n, dirs);
                let count = if friction { 3 } else { 1 };
                for dir in [ce.n, t1, t2].iter().take(count) {
                    velocity_direction(ws, &sides, dir, dirs);
                }
            }
            // LuGre's bristles relax at the rate sigma0 |v_t| / g(|v_t|), in and out of contact:
            // each of their components is a stiff direction of its own.
            if let Some(b) = c.bristle {
                let (n, o) = (self.dim(), self.bristle_offset() + b);
                for k in 0..3 * c.geometry.n_contacts() {
                    let start = dirs.len();
                    dirs.resize(start + n, 0.0);
                    dirs[start + o + k] = 1.0;
                }
                pattern.push(BRISTLES | ci as u32);
            }
            // An oil film acts at every eccentricity and grows stiff towards the wall: its force
            // depends on the journal centre's offset and its rate in the bearing plane.
            if c.film.is_some() {
                pattern.push(FILM | ci as u32);
                let idx = |b: usize| if b == GROUND { nb } else { b };
                let s = c.film_state(&ws.kin[idx(c.housing)], &ws.kin[idx(c.journal)]);
                let sides = [(c.journal, s.rj, 1.0), (c.housing, s.rh, -1.0)];
                let u = crate::kin::any_normal(&s.a);
                for d in [u, s.a.cross(&u)] {
                    position_gradient(y, ws, &sides, &d, dirs);
                    velocity_direction(ws, &sides, &d, dirs);
                }
            }
        }
    }

    /// The contacts' part of the Jacobian df/dy along the `r` directions `basis` (each of length
    /// n, one after the other), into `image` (the same layout): `J q` with the contact forces'
    /// change only. Along q = (dq, dv) the positions' rows are exact
    /// (`d r' = dv`, `d e' = 1/2 (0, dw) (x) e + 1/2 (0, w) (x) de` for Euler parameters e), and
    /// the accelerations' rows are the constrained response to the change dQ of the contact
    /// forces, `da = M^-1 (dQ - G^T dlambda)` with `(G M^-1 G^T) dlambda = G M^-1 dQ` solved with
    /// the factorisation at `y`. dQ is a forward difference of the contact forces alone (the
    /// kinematics and the clearance joints' laws, no constraint solve) with the absolute
    /// increment sqrt(eps) on a unit direction, as the tangent dynamics difference them. What this
    /// leaves out (the change of the constraint Jacobian, the Baumgarte terms, the gyroscopic and
    /// other applied forces) is smooth and slow beside the contact stiffness. Costs one
    /// evaluation of the accelerations at `y` and, per direction, one of the contact forces and
    /// one solve with the factored reduced matrix. `ws` ends with the evaluation at `y`;
    /// `scratch` is a second workspace for the differences.
    pub fn contact_jacobian(
        &self,
        t: f64,
        y: &[f64],
        basis: &[f64],
        image: &mut [f64],
        ws: &mut Workspace,
        scratch: &mut Workspace,
    ) {
        let nb = self.nb();
        let (n, np) = (self.dim(), 7 * nb);
        self.accelerations(t, y, ws);
        scratch.onset.clone_from(&ws.onset);
        let contact_q = |yy: &[f64], sc: &mut Workspace| {
            self.kinematics(yy, sc);
            for q in sc.q.iter_mut() {
                *q = [0.0; 6];
            }
            if self.effects.clearance {
                self.contact_forces(sc);
            }
        };
        contact_q(y, scratch);
        let q0 = scratch.q.clone();
        let rate0 = scratch.bristle_rate.clone();
        let bo = self.bristle_offset();
        let eps = f64::EPSILON.sqrt();
        let mut yp = y.to_vec();
        let mut u = vec![0.0; self.n_rows];
        // The rows' M^-1 G^T blocks at y, the same for every direction.
        for (wr, r) in scratch.wrows.iter_mut().zip(&ws.rows) {
            *wr = (
                minv_block(self, ws, r.a, &r.ja),
                minv_block(self, ws, r.b, &r.jb),
            );
        }
        for (dir, out) in basis.chunks_exact(n).zip(image.chunks_exact_mut(n)) {
            for i in 0..n {
                yp[i] = y[i] + eps * dir[i];
            }
            contact_q(&yp, scratch);
            // M^-1 dQ into scratch.minv_q (the inverse inertia at y).
            for b in 0..nb {
                let mut dq = [0.0; 6];
                for c in 0..6 {
                    dq[c] = (scratch.q[b][c] - q0[b][c]) / eps;
                }
                scratch.minv_q[b] = minv_block(self, ws, b, &dq);
            }
            if self.effects.constraints && self.n_rows > 0 {
                for (i, r) in ws.rows.iter().enumerate() {
                    let mut v = 0.0;
                    if r.a != GROUND {
                        v += dot6(&r.ja, &scratch.minv_q[r.a]);
                    }
                    if r.b != GROUND {
                        v += dot6(&r.jb, &scratch.minv_q[r.b]);
                    }
                    u[i] = v;
                }
                ws.solve_reduced(&mut u);
                for ((r, (wa, wb)), ui) in ws.rows.iter().zip(&scratch.wrows).zip(&u) {
                    for (b, w) in [(r.a, wa), (r.b, wb)] {
                        if b != GROUND {
                            for c in 0..6 {
                                scratch.minv_q[b][c] -= ui * w[c];
                            }
                        }
                    }
                }
            }
            for b in 0..nb {
                let (dv, e, de) = (
                    &dir[np + 6 * b..np + 6 * b + 6],
                    &y[7 * b + 3..7 * b + 7],
                    &dir[7 * b + 3..7 * b + 7],
                );
                let w = &y[np + 6 * b + 3..np + 6 * b + 6];
                out[7 * b..7 * b + 3].copy_from_slice(&dv[0..3]);
                let half_rate = |w: &[f64], e: &[f64]| {
                    [
                        0.5 * (-w[0] * e[1] - w[1] * e[2] - w[2] * e[3]),
                        0.5 * (w[0] * e[0] + w[1] * e[3] - w[2] * e[2]),
                        0.5 * (w[1] * e[0] + w[2] * e[1] - w[0] * e[3]),
                        0.5 * (w[2] * e[0] + w[0] * e[2] - w[1] * e[1]),
                    ]
                };
                let (a, c) = (half_rate(&dv[3..6], e), half_rate(w, de));
                for k in 0..4 {
                    out[7 * b + 3 + k] = a[k] + c[k];
                }
                out[np + 6 * b..np + 6 * b + 6].copy_from_slice(&scratch.minv_q[b]);
            }
            // The bristles' rates change with the sliding velocity and with their deflection.
            for (k, r0) in rate0.iter().enumerate() {
                out[bo + k] = (scratch.bristle_rate[k] - r0) / eps;
            }
        }
    }
}

/// The pattern entry of a clearance joint's oil film (its index in the low bits), apart from
/// the contact slots.
const FILM: u32 = 1 << 31;
/// The pattern entry of a clearance joint's bristle directions (its index in the low bits).
const BRISTLES: u32 = 1 << 30;

/// Appends the gradient of `d . (p_journal - p_housing)` with respect to the positions: `sides`
/// holds each body with the point and the sign (+1 journal, -1 housing); translations give `d`,
/// Euler parameters `2 G(q) (r x d) / |q|^2` (module docs of [`Model::stiff_directions`]).
fn position_gradient(
    y: &[f64],
    ws: &Workspace,
    sides: &[(usize, Vector3<f64>, f64); 2],
    dir: &Vector3<f64>,
    dirs: &mut Vec<f64>,
) {
    let n = ws.kin.len().saturating_sub(1) * 13 + ws.bristle.len();
    let start = dirs.len();
    dirs.resize(start + n, 0.0);
    // The sides that move (the ground's coordinates are not in the state).
    for &(b, p, sign) in sides.iter().filter(|side| side.0 != GROUND) {
        let d = &mut dirs[start..start + n];
        let k = &ws.kin[b];
        let m = (p - k.r).cross(dir) * sign;
        let q = &y[7 * b + 3..7 * b + 7];
        let s2 = 2.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        for i in 0..3 {
            d[7 * b + i] += sign * dir[i];
        }
        d[7 * b + 3] += s2 * (-q[1] * m.x - q[2] * m.y - q[3] * m.z);
        d[7 * b + 4] += s2 * (q[0] * m.x + q[3] * m.y - q[2] * m.z);
        d[7 * b + 5] += s2 * (-q[3] * m.x + q[0] * m.y + q[1] * m.z);
        d[7 * b + 6] += s2 * (q[2] * m.x - q[1] * m.y + q[0] * m.z);
    }
}

/// Appends the velocity direction of `dir . (v_journal - v_housing)` at the points of `sides`.
fn velocity_direction(
    ws: &Workspace,
    sides: &[(usize, Vector3<f64>, f64); 2],
    dir: &Vector3<f64>,
    dirs: &mut Vec<f64>,
) {
    let nb = ws.kin.len().saturating_sub(1);
    let (n, np) = (13 * nb + ws.bristle.len(), 7 * nb);
    let start = dirs.len();
    dirs.resize(start + n, 0.0);
    for &(b, p, sign) in sides.iter().filter(|side| side.0 != GROUND) {
        let d = &mut dirs[start..start + n];
        let m = (p - ws.kin[b].r).cross(dir);
        for i in 0..3 {
            d[np + 6 * b + i] += sign * dir[i];
            d[np + 6 * b + 3 + i] += sign * m[i];
        }
    }
}
