//! The constrained Newton-Euler equations and everything evaluated on them.
//!
//! For body k with mass m_k, global inertia J_k = A_k J'_k A_k^T, centre-of-mass velocity v_k and
//! angular velocity w_k (global):
//!
//! ```text
//!   m_k a_k = f_k - (G^T lambda)_k,          J_k alpha_k = n_k - w_k x J_k w_k - (G^T lambda)_k
//!   G a = gamma - 2 alpha_B Phi' - beta_B^2 Phi                      (Baumgarte, 1972)
//! ```
//!
//! where G is the constraint Jacobian with respect to the velocities (6 columns per body),
//! gamma = -(dG/dt) v + s''(t) the velocity-quadratic terms, and alpha_B, beta_B the Baumgarte
//! parameters. With the block-diagonal mass matrix the multipliers follow from the reduced system
//! `S lambda = G M^-1 Q - rhs` with `S = G M^-1 G^T`, and then `a = M^-1 (Q - G^T lambda)`; when
//! constraints are redundant S is singular and lambda is its minimum-norm solution `S^+ b`.
//!
//! Every row acts on at most two bodies, so `S_ij = sum_k G_i^k M_k^-1 G_j^k^T` over the bodies k
//! (the ground aside) that rows i and j share, and S_ij = 0 when they share none. That pattern is
//! fixed by the scene ([`Coupling`](crate::coupling::Coupling), built when the model is compiled). Each evaluation gathers
//! the blocks G_i^k and M_k^-1 G_i^k^T body by body, writes every stored entry of S from its one or
//! two terms (three products instead of six for rows that constrain rotation only), and factors S
//! in place with [`SparsePsd`](crate::linalg::SparsePsd), in an elimination order computed once
//! from the pattern (for the legs of a parallel mechanism, leg rows before platform rows, without
//! fill). The cost grows with the rows per body rather than with the cube of the rows. The dense
//! solve by [`PsdSolver`] remains as the reference ([`Model::accelerations_dense`]) and as the
//! fallback for the rare evaluation where a small pivot is not clearly a redundant direction.
//!
//! The rotation is carried by Euler parameters
//! with `q' = 1/2 (0, w) (x) q`, free of the singularities of Euler angles; the rotation matrix is
//! built from q/|q|, so the slow drift of |q| under integration never distorts the body.

use std::ops::Range;

use nalgebra::{DMatrix, Matrix3, Quaternion, UnitQuaternion, Vector3};

use crate::clearance::ContactEval;
use crate::error::{Error, Result};
use crate::guard::{StepGuard, Warning};
use crate::kin::{GROUND, Kin};
use crate::linalg::PsdSolver;
use crate::model::{Model, Prim, State};
use crate::ode::OdeSystem;
use crate::profile::SinCos;
use crate::scene::LoadFrame;
use crate::state::HybridState;
use crate::workspace::minv_block;
pub use crate::workspace::{Row, Workspace};

/// Relative pivot tolerance of the reduced-matrix factorisation: pivots below it count as
/// redundant constraint directions.
pub const RANK_TOL: f64 = 1e-10;

#[inline]
fn v3(s: &[f64]) -> Vector3<f64> {
    Vector3::new(s[0], s[1], s[2])
}

#[inline]
fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
}

/// [`dot6`] of blocks one of which has a zero translational half: the rotational halves only
/// (equal to [`dot6`] up to the sign of a zero result, since the skipped products are zeros).
#[inline]
fn dot3w(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
}

#[inline]
fn block(v: &Vector3<f64>, w: &Vector3<f64>) -> [f64; 6] {
    [v.x, v.y, v.z, w.x, w.y, w.z]
}

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
    }

    /// The kinematics of body `k` (not the ground) from the state vector.
    #[inline]
    fn body_kinematics(&self, y: &[f64], k: usize) -> Kin {
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

    /// Contact forces of the clearance joints into `ws.q` (kinematics must be current).
    fn contact_forces(&self, ws: &mut Workspace) {
        let nb = self.nb();
        let idx = |b: usize| if b == GROUND { nb } else { b };
        for (ci, c) in self.clearances.iter().enumerate() {
            let (kh, kj) = (ws.kin[idx(c.housing)], ws.kin[idx(c.journal)]);
            let slots = c.first..c.first + c.geometry.n_contacts();
            let out = &mut ws.contacts[slots.clone()];
            c.geometry(&kh, &kj, out);
            let r = c.forces(&kh, &kj, &ws.onset[slots], out);
            ws.resultants[ci] = r;
            for (b, f, m) in [
                (c.journal, r.force_j, r.moment_j),
                (c.housing, r.force_h, r.moment_h),
            ] {
                if b != GROUND {
                    let q = &mut ws.q[b];
                    for k in 0..3 {
                        q[k] += f[k];
                        q[3 + k] += m[k];
                    }
                }
            }
        }
    }

    /// Updates the contact-onset history after an accepted step from (t0, y0) to (t1, y1).
    ///
    /// A contact whose penetration crosses zero inside the step gets the approach velocity at
    /// the crossing, located on the cubic Hermite interpolant of delta built from delta and
    /// delta_dot at both ends (not the value at the step end). A contact that is already
    /// penetrating at the start of the run takes its current rate. A contact that has separated
    /// forgets its onset. Returns true when a new onset was stored (the right-hand side at y1
    /// then changes, since it used the provisional value delta_dot(t1)).
    pub fn update_onsets(
        &self,
        t0: f64,
        y0: &[f64],
        t1: f64,
        y1: &[f64],
        ws: &mut Workspace,
    ) -> bool {
        if !self.effects.clearance {
            return false;
        }
        let nb = self.nb();
        let idx = |b: usize| if b == GROUND { nb } else { b };
        let mut changed = false;
        self.kinematics(y0, ws);
        for c in &self.clearances {
            let slots = c.first..c.first + c.geometry.n_contacts();
            c.geometry(
                &ws.kin[idx(c.housing)],
                &ws.kin[idx(c.journal)],
                &mut ws.contacts0[slots],
            );
        }
        self.kinematics(y1, ws);
        let h = t1 - t0;
        for c in &self.clearances {
            let n = c.geometry.n_contacts();
            let slots = c.first..c.first + n;
            c.geometry(
                &ws.kin[idx(c.housing)],
                &ws.kin[idx(c.journal)],
                &mut ws.contacts[slots],
            );
            if !c.law.needs_onset() {
                continue;
            }
            for s in c.first..c.first + n {
                let (a, b) = (ws.contacts0[s], ws.contacts[s]);
                if b.delta <= 0.0 {
                    ws.onset[s] = f64::NAN;
                    continue;
                }
                if !ws.onset[s].is_nan() {
                    continue;
                }
                ws.onset[s] = if a.delta > 0.0 {
                    a.delta_dot
                } else {
                    onset_rate(a.delta, a.delta_dot, b.delta, b.delta_dot, h)
                };
                changed = true;
            }
        }
        changed
    }

    /// Penetration and its rate of every contact at `y` into `ws.contacts` (m, m/s), with
    /// `out[s] = (delta, delta_dot)` per contact slot and whether the slot keeps an onset
    /// history (its law reads the approach velocity). The tangent dynamics
    /// (`jointplay_analysis::measures::lyapunov`) differentiate the onset bookkeeping of
    /// [`Model::update_onsets`] with it.
    pub fn contact_rates(&self, y: &[f64], ws: &mut Workspace, out: &mut Vec<(f64, f64, bool)>) {
        if self.effects.clearance {
            self.contact_geometry(y, ws);
        }
        self.contact_rates_in(ws, out);
    }

    /// [`Model::contact_rates`] read from a workspace whose contact geometry is current (as
    /// [`Model::rhs`] leaves it): the same values, without evaluating the geometry again.
    pub fn contact_rates_in(&self, ws: &Workspace, out: &mut Vec<(f64, f64, bool)>) {
        out.clear();
        out.resize(self.n_contacts, (f64::NAN, f64::NAN, false));
        if !self.effects.clearance {
            return;
        }
        for c in &self.clearances {
            for s in c.first..c.first + c.geometry.n_contacts() {
                out[s] = (
                    ws.contacts[s].delta,
                    ws.contacts[s].delta_dot,
                    c.law.needs_onset(),
                );
            }
        }
    }

    /// The penetration (m) and sliding speed (m/s) of contact slot `slot` at `y`: what
    /// [`Model::contact_rates`] and [`Model::sliding_speeds`] give for it, bit for bit, from the
    /// kinematics of its joint's two bodies and that joint's geometry alone (into
    /// `ws.contacts`; `ws.kin` is left as it was, so `ws` no longer holds one state). The
    /// sliding speed only when `speed` is set (NaN otherwise).
    pub(crate) fn slot_penetration(
        &self,
        y: &[f64],
        ws: &mut Workspace,
        slot: usize,
        speed: bool,
    ) -> (f64, f64) {
        let nb = self.nb();
        let joint = self
            .clearances
            .iter()
            .find(|c| (c.first..c.first + c.geometry.n_contacts()).contains(&slot));
        let Some(c) = joint.filter(|_| self.effects.clearance) else {
            return (f64::NAN, f64::NAN);
        };
        let kin = |b: usize, ws: &Workspace| {
            if b == GROUND {
                ws.kin[nb]
            } else {
                self.body_kinematics(y, b)
            }
        };
        let (kh, kj) = (kin(c.housing, ws), kin(c.journal, ws));
        let slots = c.first..c.first + c.geometry.n_contacts();
        c.geometry(&kh, &kj, &mut ws.contacts[slots]);
        let mut v = [f64::NAN];
        if speed {
            c.sliding_speeds(&kh, &kj, &ws.contacts[slot..slot + 1], &mut v);
        }
        (ws.contacts[slot].delta, v[0])
    }

    /// The sliding speed (m/s) of every contact slot into `out`, from the kinematics and contact
    /// geometry in `ws` as [`Model::contact_rates`] leaves them.
    pub fn sliding_speeds(&self, ws: &Workspace, out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.n_contacts, f64::NAN);
        if !self.effects.clearance {
            return;
        }
        let nb = self.nb();
        let idx = |b: usize| if b == GROUND { nb } else { b };
        for c in &self.clearances {
            let slots = c.first..c.first + c.geometry.n_contacts();
            c.sliding_speeds(
                &ws.kin[idx(c.housing)],
                &ws.kin[idx(c.journal)],
                &ws.contacts[slots.clone()],
                &mut out[slots],
            );
        }
    }

    /// The kinematics at `y` and every contact's geometry (penetration, rate, normal, points)
    /// into `ws.contacts`, without forces.
    fn contact_geometry(&self, y: &[f64], ws: &mut Workspace) {
        let nb = self.nb();
        let idx = |b: usize| if b == GROUND { nb } else { b };
        self.kinematics(y, ws);
        for c in &self.clearances {
            let slots = c.first..c.first + c.geometry.n_contacts();
            c.geometry(
                &ws.kin[idx(c.housing)],
                &ws.kin[idx(c.journal)],
                &mut ws.contacts[slots],
            );
        }
    }

    /// The directions along which the contacts make the right-hand side stiff at `y`, for a step
    /// of about `h` (s) (see [`OdeSystem::stiff_directions`]). A contact counts when it
    /// penetrates at `y` or would within `h` at its current rate (`delta + h delta_dot > 0`).
    /// Its force depends stiffly on its penetration `delta(q)` (the normal law's stiffness), on
    /// its penetration rate (the damping) and, when it has friction, on the sliding velocity (a
    /// regularised law's slope); each of these is `g . nu` for a velocity-level direction `g`
    /// over the two bodies (journal `(d, r_j x d)`, housing `-(d, r_h x d)`, with `d` the normal
    /// `n` or a tangent and `r` the lever from each body's centre of mass to its contact point).
    /// So per contact: the gradient of `delta` with respect to the positions (translations `d`,
    /// Euler parameters `2 G(q) (r x d) / |q|^2`, where `q' = 1/2 G(q) w`), and the velocity
    /// directions of the normal and, with friction, of the two tangents. `pattern` lists the
    /// contact slots used. The forces' other dependences (the normal's turning, the levers) are
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
        let (n, np) = (13 * nb, 7 * nb);
        self.contact_geometry(y, ws);
        for c in &self.clearances {
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
                // The gradient of delta with respect to the positions.
                let start = dirs.len();
                dirs.resize(start + n, 0.0);
                // The sides that move (the ground's coordinates are not in the state).
                let moving = || sides.iter().filter(|side| side.0 != GROUND);
                for &(b, p, sign) in moving() {
                    let d = &mut dirs[start..start + n];
                    let k = &ws.kin[b];
                    let m = (p - k.r).cross(&ce.n) * sign;
                    let q = &y[7 * b + 3..7 * b + 7];
                    let s2 = 2.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
                    for i in 0..3 {
                        d[7 * b + i] += sign * ce.n[i];
                    }
                    d[7 * b + 3] += s2 * (-q[1] * m.x - q[2] * m.y - q[3] * m.z);
                    d[7 * b + 4] += s2 * (q[0] * m.x + q[3] * m.y - q[2] * m.z);
                    d[7 * b + 5] += s2 * (-q[3] * m.x + q[0] * m.y + q[1] * m.z);
                    d[7 * b + 6] += s2 * (q[2] * m.x - q[1] * m.y + q[0] * m.z);
                }
                // The velocity directions.
                let count = if friction { 3 } else { 1 };
                for dir in [ce.n, t1, t2].iter().take(count) {
                    let start = dirs.len();
                    dirs.resize(start + n, 0.0);
                    for &(b, p, sign) in moving() {
                        let d = &mut dirs[start..start + n];
                        let m = (p - ws.kin[b].r).cross(dir);
                        for i in 0..3 {
                            d[np + 6 * b + i] += sign * dir[i];
                            d[np + 6 * b + 3 + i] += sign * m[i];
                        }
                    }
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
        let (n, np) = (13 * nb, 7 * nb);
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
        }
    }

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

    /// The reduced system on the sparse path: S assembled entry by entry and factored by
    /// [`SparsePsd`](crate::linalg::SparsePsd); then `a -= M^-1 G^T lambda`. Returns false, with
    /// the multipliers and accelerations untouched, when the factorisation defers to the dense
    /// path.
    fn solve_sparse(&self, ws: &mut Workspace) -> bool {
        let c = &self.coupling;
        let nb = self.nb();
        for k in 0..nb {
            let (mi, inv_j) = (1.0 / self.bodies[k].mass, ws.inv_j[k]);
            let (u0, u1) = (c.inc_ptr[k], c.inc_ptr[k + 1]);
            let incs = c.inc[u0..u1].iter();
            for ((&(i, side), gj), gw) in incs.zip(&mut ws.inc_j[u0..u1]).zip(&mut ws.inc_w[u0..u1])
            {
                let r = &ws.rows[i];
                let j = if side == 0 { &r.ja } else { &r.jb };
                *gj = *j;
                let t = inv_j * Vector3::new(j[3], j[4], j[5]);
                *gw = [j[0] * mi, j[1] * mi, j[2] * mi, t.x, t.y, t.z];
            }
        }
        // S_ij = sum over the bodies k that rows i and j share of G_i^k M_k^-1 G_j^k^T.
        let s = ws.sparse.values_mut();
        let (gj, gw) = (&ws.inc_j, &ws.inc_w);
        for &[slot, u, v] in &c.first[0] {
            s[slot as usize] = dot3w(&gj[u as usize], &gw[v as usize]);
        }
        for &[slot, u, v] in &c.first[1] {
            s[slot as usize] = dot6(&gj[u as usize], &gw[v as usize]);
        }
        for &[slot, u, v] in &c.extra[0] {
            s[slot as usize] += dot3w(&gj[u as usize], &gw[v as usize]);
        }
        for &[slot, u, v] in &c.extra[1] {
            s[slot as usize] += dot6(&gj[u as usize], &gw[v as usize]);
        }
        if !ws.sparse.factor(RANK_TOL) {
            return false;
        }
        ws.rank = ws.sparse.rank();
        ws.sparse.solve(&mut ws.lambda);
        for k in 0..nb {
            // In a local copy, which the compiler keeps in registers.
            let mut acc = ws.acc[k];
            let (u0, u1) = (c.inc_ptr[k], c.inc_ptr[k + 1]);
            for (&(i, _), w) in c.inc[u0..u1].iter().zip(&ws.inc_w[u0..u1]) {
                let l = ws.lambda[i];
                for c in 0..6 {
                    acc[c] -= l * w[c];
                }
            }
            ws.acc[k] = acc;
        }
        true
    }

    /// The reduced system on the dense path: S = G M^-1 G^T row pair by row pair, factored by
    /// [`PsdSolver`]; then `a -= M^-1 G^T lambda`.
    fn solve_dense(&self, ws: &mut Workspace) {
        let nr = self.n_rows;
        ws.s.resize(nr * nr, 0.0);
        // W = M^-1 G^T, row by row.
        for i in 0..nr {
            let r = &ws.rows[i];
            ws.wrows[i] = (
                minv_block(self, ws, r.a, &r.ja),
                minv_block(self, ws, r.b, &r.jb),
            );
        }
        // S = G M^-1 G^T (only bodies shared by two rows contribute).
        for i in 0..nr {
            let ri = ws.rows[i];
            for j in i..nr {
                let rj = &ws.rows[j];
                let wj = &ws.wrows[j];
                let mut s = 0.0;
                if ri.a != GROUND {
                    if ri.a == rj.a {
                        s += dot6(&ri.ja, &wj.0);
                    }
                    if ri.a == rj.b {
                        s += dot6(&ri.ja, &wj.1);
                    }
                }
                if ri.b != GROUND {
                    if ri.b == rj.a {
                        s += dot6(&ri.jb, &wj.0);
                    }
                    if ri.b == rj.b {
                        s += dot6(&ri.jb, &wj.1);
                    }
                }
                ws.s[i * nr + j] = s;
                ws.s[j * nr + i] = s;
            }
        }
        ws.solver.factor(&ws.s, nr, RANK_TOL);
        ws.rank = ws.solver.rank();
        ws.solver.solve(&mut ws.lambda);
        for i in 0..nr {
            let l = ws.lambda[i];
            let r = &ws.rows[i];
            let (wa, wb) = &ws.wrows[i];
            if r.a != GROUND {
                for c in 0..6 {
                    ws.acc[r.a][c] -= l * wa[c];
                }
            }
            if r.b != GROUND {
                for c in 0..6 {
                    ws.acc[r.b][c] -= l * wb[c];
                }
            }
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
    }

    /// Brings the state onto the position and velocity constraints at its time: Newton iterations
    /// with minimum-norm corrections for positions, then the mass-weighted projection of the
    /// velocities, `v = v0 - M^-1 G^T S^+ (G v0 - s')`.
    pub fn assemble(&self, state: &mut State) -> Result<AssemblyReport> {
        let nb = self.nb();
        let np = 7 * nb;
        let nr = self.n_rows;
        let mut report = AssemblyReport::default();
        if nr == 0 {
            return Ok(report);
        }
        let mut ws = Workspace::new(self);
        let mut solver = PsdSolver::new();
        let mut s = vec![0.0; nr * nr];
        let tol = 1e-12;
        let t = state.t;
        self.kinematics(&state.y, &mut ws);
        self.constraints(t, &mut ws);
        report.initial_residual = max_abs(&ws.phi);
        for it in 0..60 {
            let res = max_abs(&ws.phi);
            report.iterations = it;
            if res < tol {
                break;
            }
            // S = G G^T (unweighted), mu = S^+ phi, dx = -G^T mu.
            for i in 0..nr {
                for j in i..nr {
                    let v = row_dot(&ws.rows[i], &ws.rows[j]);
                    s[i * nr + j] = v;
                    s[j * nr + i] = v;
                }
            }
            solver.factor(&s, nr, RANK_TOL);
            let mut mu = ws.phi.clone();
            solver.solve(&mut mu);
            let mut dx = vec![[0.0; 6]; nb];
            for (i, r) in ws.rows.iter().enumerate() {
                for (b, j) in [(r.a, &r.ja), (r.b, &r.jb)] {
                    if b != GROUND {
                        for c in 0..6 {
                            dx[b][c] -= mu[i] * j[c];
                        }
                    }
                }
            }
            for (k, d) in dx.iter().enumerate() {
                for c in 0..3 {
                    state.y[7 * k + c] += d[c];
                }
                let q = &state.y[7 * k + 3..7 * k + 7];
                let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
                let dq = UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5]));
                let qn = (dq * q).into_inner();
                state.y[7 * k + 3..7 * k + 7].copy_from_slice(&[qn.w, qn.i, qn.j, qn.k]);
            }
            self.kinematics(&state.y, &mut ws);
            self.constraints(t, &mut ws);
        }
        let res = max_abs(&ws.phi);
        report.final_residual = res;
        // A position so far off that the corrections overflowed leaves NaN in the state: refused
        // here, before anything (the rank analysis, a run) works on it.
        if !res.is_finite() || res >= 1e-9 || state.y[..np].iter().any(|v| !v.is_finite()) {
            let worst = ws
                .phi
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                .map(|(i, _)| i)
                .unwrap_or(0);
            return Err(Error::Assembly {
                file: self.file.clone(),
                time: t,
                message: format!(
                    "position constraints not met after {} Newton iterations: residual {:.3e} (m or rad) in {}; \
                     check that the initial poses, joint points and drive values are compatible",
                    report.iterations,
                    res,
                    self.row_owner(worst)
                ),
            });
        }
        // Velocities: mass-weighted projection.
        self.accelerations(t, &state.y, &mut ws);
        report.initial_velocity_residual = max_abs(&ws.phi_dot);
        let mut mu = ws.phi_dot.clone();
        // The acceleration evaluation left G M^-1 G^T factored.
        ws.solve_reduced(&mut mu);
        for (i, r) in ws.rows.iter().enumerate() {
            for (b, j) in [(r.a, &r.ja), (r.b, &r.jb)] {
                let w = minv_block(self, &ws, b, j);
                if b != GROUND {
                    for c in 0..6 {
                        state.y[np + 6 * b + c] -= mu[i] * w[c];
                    }
                }
            }
        }
        self.kinematics(&state.y, &mut ws);
        self.constraints(t, &mut ws);
        report.final_velocity_residual = max_abs(&ws.phi_dot);
        if state.y.iter().any(|v| !v.is_finite()) {
            return Err(Error::Assembly {
                file: self.file.clone(),
                time: t,
                message: "the velocities projected onto the constraints are not finite; check \
                          the initial velocities and the masses"
                    .into(),
            });
        }
        Ok(report)
    }

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

/// Residuals before and after assembly.
#[derive(Debug, Clone, Copy, Default)]
pub struct AssemblyReport {
    pub iterations: usize,
    /// max |Phi| (m or rad).
    pub initial_residual: f64,
    pub final_residual: f64,
    /// max |Phi'| (m/s or rad/s).
    pub initial_velocity_residual: f64,
    pub final_velocity_residual: f64,
}

/// The largest magnitude in `v`; NaN when any entry is NaN (`f64::max` would skip it, and a
/// residual that became NaN would pass for a small one).
fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(
        0.0,
        |m: f64, x| {
            if x.is_nan() { f64::NAN } else { m.max(x.abs()) }
        },
    )
}

/// G_i . G_j over the bodies the two rows share.
fn row_dot(ri: &Row, rj: &Row) -> f64 {
    let mut s = 0.0;
    for (bi, ji) in [(ri.a, &ri.ja), (ri.b, &ri.jb)] {
        if bi == GROUND {
            continue;
        }
        for (bj, jj) in [(rj.a, &rj.ja), (rj.b, &rj.jb)] {
            if bi == bj {
                s += dot6(ji, jj);
            }
        }
    }
    s
}

fn point_state(ws: &Workspace, b: usize, s: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    if b == GROUND {
        return (*s, Vector3::zeros());
    }
    let k = &ws.kin[b];
    let sg = k.rot * s;
    (k.r + sg, k.v + k.w.cross(&sg))
}

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

/// A model and its workspace as an [`OdeSystem`], with the guards of [`crate::guard`].
pub struct Mechanism<'m> {
    pub model: &'m Model,
    pub ws: Workspace,
    /// Warnings of the step-size guard so far.
    pub warnings: Vec<Warning>,
    guard: StepGuard,
    /// Fixed-step methods: the deepest state of each contact over the stages of the current
    /// step (a step that overshoots into a contact may leave it again before its end, where
    /// the step-size guard looks).
    deepest: Option<Vec<ContactEval>>,
    /// With `onset_events`, `end_events` or `friction_events`: the event functions' own workspace
    /// (the gaps and sliding speeds are evaluated inside a step, between the stages, and must
    /// not disturb the step's evaluation).
    events: Option<ContactEvents>,
    /// A second workspace for [`Model::contact_jacobian`], made on first use.
    jacobian: Option<Box<Workspace>>,
}

/// The contact events: which kinds are on, a workspace of their own and the contact rates and
/// sliding speeds it returns.
struct ContactEvents {
    onsets: bool,
    ends: bool,
    /// With `friction_events`: the contact slot and kink speed (m/s) of each pair of friction
    /// events.
    kinks: Vec<(usize, f64)>,
    /// Per contact slot: the components of the state its functions read (the positions and
    /// velocities of its joint's bodies).
    parts: Vec<Vec<Range<usize>>>,
    ws: Box<Workspace>,
    rates: Vec<(f64, f64, bool)>,
    speeds: Vec<f64>,
}

/// What event function of [`ContactEvents`] is: a slot's onset or end, or side 0 or 1 of a
/// friction kink (its index in `kinks`).
enum ContactEvent {
    Onset(usize),
    End(usize),
    Kink(usize, usize),
}

impl<'m> Mechanism<'m> {
    pub fn new(model: &'m Model) -> Self {
        let fixed = model.settings.method.fixed_step().is_some() && model.effects.clearance;
        Mechanism {
            model,
            ws: Workspace::new(model),
            warnings: Vec::new(),
            guard: StepGuard::default(),
            deepest: fixed.then(|| vec![untouched(); model.n_contacts]),
            events: contact_events(model),
            jacobian: None,
        }
    }

    /// Runs the guards on the initial state `(t, y)` (before the first step): the step-size
    /// guard's warnings go to [`Mechanism::warnings`]; a runaway quantity is returned as an error.
    pub fn check_initial(&mut self, t: f64, y: &[f64]) -> Result<()> {
        self.model.accelerations(t, y, &mut self.ws);
        if let Some(message) = self.model.runaway(&self.ws) {
            return Err(Error::Diverged { time: t, message });
        }
        let contacts = self.ws.contacts.clone();
        self.model.step_guard(
            t,
            (&contacts, &contacts),
            &mut self.ws,
            &mut self.guard,
            &mut self.warnings,
        );
        Ok(())
    }
}

/// The event function of a slot's onset at penetration `delta` (m): the gap. A slot whose
/// geometry is undefined (NaN) counts as open: its onset never fires, and its end (the negated
/// gap) fires if it was closed.
fn gap(delta: f64) -> f64 {
    if delta.is_nan() { 1.0 } else { -delta }
}

/// The two event functions of a friction kink at speed `vk` (m/s) of a slot at penetration
/// `delta` (m) and sliding speed `v` (m/s): `v - v_k` and `v_k - v` while the contact
/// penetrates, 1 while it is open (the friction is off there).
fn kink_value(delta: f64, v: f64, vk: f64) -> [f64; 2] {
    if delta > 0.0 && v.is_finite() {
        [v - vk, vk - v]
    } else {
        [1.0; 2]
    }
}

impl ContactEvents {
    /// Event function `i` of the layout onsets, ends, then two per kink, for `n` slots.
    fn event(&self, i: usize, n: usize) -> ContactEvent {
        let n_onsets = if self.onsets { n } else { 0 };
        let n_ends = if self.ends { n } else { 0 };
        if i < n_onsets {
            ContactEvent::Onset(i)
        } else if i < n_onsets + n_ends {
            ContactEvent::End(i - n_onsets)
        } else {
            let k = i - n_onsets - n_ends;
            ContactEvent::Kink(k / 2, k % 2)
        }
    }

    /// The event functions from the rates and sliding speeds last stored.
    fn values(&self, g: &mut [f64]) {
        let n = self.rates.len();
        for (i, g) in g.iter_mut().enumerate() {
            *g = self.event(i, n).value(&self.kinks, |slot, speed| {
                let v = if speed { self.speeds[slot] } else { f64::NAN };
                (self.rates[slot].0, v)
            });
        }
    }
}

impl ContactEvent {
    /// The contact slot the event belongs to (`kinks` as in [`ContactEvents`]).
    fn slot(&self, kinks: &[(usize, f64)]) -> usize {
        match *self {
            ContactEvent::Onset(slot) | ContactEvent::End(slot) => slot,
            ContactEvent::Kink(k, _) => kinks[k].0,
        }
    }

    /// The event function's value from its slot's penetration (m) and, for a kink, sliding
    /// speed (m/s), which `at(slot, speed)` returns (the speed only when `speed` is set).
    fn value(&self, kinks: &[(usize, f64)], at: impl FnOnce(usize, bool) -> (f64, f64)) -> f64 {
        let (delta, v) = at(self.slot(kinks), matches!(self, ContactEvent::Kink(..)));
        match *self {
            ContactEvent::Onset(_) => gap(delta),
            ContactEvent::End(_) => -gap(delta),
            ContactEvent::Kink(k, side) => kink_value(delta, v, kinks[k].1)[side],
        }
    }
}

/// The contact events the model's settings call for; None when there are none.
fn contact_events(model: &Model) -> Option<ContactEvents> {
    let s = &model.settings;
    if !model.effects.clearance || model.n_contacts == 0 {
        return None;
    }
    let mut kinks = Vec::new();
    if s.friction_events {
        for c in &model.clearances {
            let (speeds, n) = c.friction.kinks();
            for slot in c.first..c.first + c.geometry.n_contacts() {
                kinks.extend(speeds[..n].iter().map(|&v| (slot, v)));
            }
        }
    }
    let np = model.n_pos();
    let mut parts = vec![Vec::new(); model.n_contacts];
    for c in &model.clearances {
        let bodies = [c.housing, c.journal].into_iter().filter(|&b| b != GROUND);
        let joint: Vec<Range<usize>> = bodies
            .flat_map(|b| [7 * b..7 * b + 7, np + 6 * b..np + 6 * b + 6])
            .collect();
        for slot in c.first..c.first + c.geometry.n_contacts() {
            parts[slot] = joint.clone();
        }
    }
    (s.onset_events || s.end_events || !kinks.is_empty()).then(|| ContactEvents {
        onsets: s.onset_events,
        ends: s.end_events,
        kinks,
        parts,
        ws: Box::new(Workspace::new(model)),
        rates: Vec::new(),
        speeds: Vec::new(),
    })
}

/// A contact state deeper than none.
fn untouched() -> ContactEval {
    ContactEval {
        delta: f64::NEG_INFINITY,
        ..Default::default()
    }
}

impl OdeSystem for Mechanism<'_> {
    fn dim(&self) -> usize {
        13 * self.model.nb()
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) {
        self.model.rhs(t, y, &mut self.ws, dydt);
        if let Some(deepest) = self.deepest.as_mut() {
            for (d, c) in deepest.iter_mut().zip(&self.ws.contacts) {
                if c.delta > d.delta {
                    *d = *c;
                }
            }
        }
    }
    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        self.model.update_onsets(t0, y0, t1, y1, &mut self.ws)
    }
    /// With `onset_events`, one event per contact slot: the gap `-delta` (m), which crosses zero
    /// downwards where the contact begins; with `end_events`, one more per slot after those:
    /// the penetration `delta` (m), which crosses zero downwards where the contact ends; with
    /// `friction_events`, two per kink of each slot's friction law after those: `v - v_k` and
    /// `v_k - v` for the sliding speed v (m/s), which cross zero downwards where the speed falls
    /// and rises through the kink v_k while the contact is penetrating (1 while it is open: the
    /// friction is off there). One of the two jumps below zero where the contact begins, so
    /// `friction_events` also ends a step at the onsets of the contacts whose law has kinks,
    /// with `onset_events` off too.
    fn events(&self) -> usize {
        self.events.as_ref().map_or(0, |e| {
            self.model.n_contacts * (usize::from(e.onsets) + usize::from(e.ends))
                + 2 * e.kinks.len()
        })
    }
    fn event_values(&mut self, _t: f64, y: &[f64], g: &mut [f64]) {
        if let Some(e) = self.events.as_mut() {
            self.model.contact_rates(y, &mut e.ws, &mut e.rates);
            if !e.kinks.is_empty() {
                self.model.sliding_speeds(&e.ws, &mut e.speeds);
            }
            e.values(g);
        }
    }
    /// The contact geometry and kinematics [`Model::rhs`] left in the mechanism's workspace are
    /// those at `(t, y)`: the rates and sliding speeds are read from them.
    fn event_values_at_rhs(&mut self, _t: f64, _y: &[f64], g: &mut [f64]) {
        if let Some(e) = self.events.as_mut() {
            self.model.contact_rates_in(&self.ws, &mut e.rates);
            if !e.kinks.is_empty() {
                self.model.sliding_speeds(&self.ws, &mut e.speeds);
            }
            e.values(g);
        }
    }
    /// Only the contact of event `i`: its joint's two bodies and geometry
    /// (`Model::slot_penetration`).
    fn event_value(&mut self, i: usize, _t: f64, y: &[f64], _g: &mut [f64]) -> f64 {
        let Some(e) = self.events.as_mut() else {
            return f64::NAN;
        };
        let model = self.model;
        let event = e.event(i, model.n_contacts);
        event.value(&e.kinks, |slot, speed| {
            model.slot_penetration(y, &mut e.ws, slot, speed)
        })
    }
    /// The positions and velocities of the bodies of event `i`'s joint.
    fn event_components(&self, i: usize, parts: &mut Vec<Range<usize>>) {
        parts.clear();
        match self.events.as_ref() {
            Some(e) => {
                let slot = e.event(i, self.model.n_contacts).slot(&e.kinks);
                parts.extend_from_slice(&e.parts[slot]);
            }
            None => parts.push(0..self.dim()),
        }
    }
    /// An onset, an end or a friction kink changes nothing in the state (the compliant force is
    /// zero at zero penetration, the friction coefficient continuous at a kink); the step that
    /// ended at an onset or an end sets or clears the onset velocity in `step_accepted`.
    fn event_restarts_step(&self, _i: usize) -> bool {
        true
    }
    /// The workspace holds the evaluation at the accepted state (the method's last stage, with
    /// the contact geometry refreshed by `step_accepted`).
    fn check_step(&mut self, t: f64, _y: &[f64]) -> Option<String> {
        if let Some(mut deepest) = self.deepest.take() {
            // Moved out and back rather than cloned: no allocation per step.
            let starts = std::mem::take(&mut self.ws.contacts0);
            self.model.step_guard(
                t,
                (&starts, &deepest),
                &mut self.ws,
                &mut self.guard,
                &mut self.warnings,
            );
            self.ws.contacts0 = starts;
            deepest.fill(untouched());
            self.deepest = Some(deepest);
        }
        self.model.runaway(&self.ws)
    }
    fn explain_non_finite(&mut self, t: f64, y: &[f64], component: usize) -> String {
        self.model.explain_non_finite(t, y, component, &mut self.ws)
    }
    /// The contacts' stiff directions ([`Model::stiff_directions`]); the workspace's kinematics
    /// and contact states are overwritten, which the step's own evaluations then refresh.
    fn stiff_directions(
        &mut self,
        _t: f64,
        y: &[f64],
        h: f64,
        dirs: &mut Vec<f64>,
        pattern: &mut Vec<u32>,
    ) -> bool {
        self.model
            .stiff_directions(y, h, &mut self.ws, dirs, pattern);
        true
    }
    /// The contacts' part of the Jacobian along the directions ([`Model::contact_jacobian`]).
    fn stiff_jacobian(&mut self, t: f64, y: &[f64], basis: &[f64], image: &mut [f64]) -> bool {
        let model = self.model;
        let scratch = self
            .jacobian
            .get_or_insert_with(|| Box::new(Workspace::new(model)));
        model.contact_jacobian(t, y, basis, image, &mut self.ws, scratch);
        true
    }
    /// The onset history and the guard's flags; empty vectors keep the mechanism's own (fresh
    /// for a new mechanism). Vectors of another length are refused: the state belongs to
    /// another model.
    fn load_memory(&mut self, state: &HybridState) -> Result<()> {
        let m = self.model;
        let fits = |len: usize, want: usize| len == 0 || len == want;
        if state.y.len() != self.dim()
            || !fits(state.onset.len(), m.n_contacts)
            || !fits(state.warned.len(), m.clearances.len())
        {
            return Err(Error::Invalid {
                file: m.file.clone(),
                field: "state".into(),
                message: format!(
                    "a state of {} coordinates, {} contacts and {} clearance joints does not \
                     fit this model ({} coordinates, {} contacts, {} clearance joints)",
                    state.y.len(),
                    state.onset.len(),
                    state.warned.len(),
                    self.dim(),
                    m.n_contacts,
                    m.clearances.len()
                ),
            });
        }
        if !state.onset.is_empty() {
            self.ws.onset.copy_from_slice(&state.onset);
        }
        if !state.warned.is_empty() {
            self.guard.set_warned(&state.warned);
        }
        Ok(())
    }
    fn save_memory(&self, state: &mut HybridState) {
        state.onset.clone_from(&self.ws.onset);
        state.warned = self.guard.warned(self.model.clearances.len());
    }
}

/// The derivative of `onset_rate` (the approach velocity read from the cubic through the step's
/// end points) along a perturbation `(dd0, dr0, dd1, dr1)` of its data: the
/// first-order change of the approach velocity stored at an onset when the trajectory is
/// perturbed. The crossing moves with the perturbation (implicit differentiation of
/// `p(s*) = 0`), which is the saltation rule of the onset-velocity reset (Mueller, Chaos Solitons
/// Fractals 5, 1995) applied to the same Hermite interpolant that locates the onset.
#[allow(clippy::too_many_arguments)]
pub fn onset_rate_tangent(
    (d0, r0, d1, r1): (f64, f64, f64, f64),
    h: f64,
    (dd0, dr0, dd1, dr1): (f64, f64, f64, f64),
) -> f64 {
    let basis = |s: f64| {
        [
            2.0 * s * s * s - 3.0 * s * s + 1.0,
            (s * s * s - 2.0 * s * s + s) * h,
            -2.0 * s * s * s + 3.0 * s * s,
            (s * s * s - s * s) * h,
        ]
    };
    let dbasis = |s: f64| {
        [
            6.0 * s * s - 6.0 * s,
            (3.0 * s * s - 4.0 * s + 1.0) * h,
            -6.0 * s * s + 6.0 * s,
            (3.0 * s * s - 2.0 * s) * h,
        ]
    };
    let ddbasis = |s: f64| {
        [
            12.0 * s - 6.0,
            (6.0 * s - 4.0) * h,
            -12.0 * s + 6.0,
            (6.0 * s - 2.0) * h,
        ]
    };
    if !hermite_trusted(d0, r0, d1, r1, h) {
        // The derivative of the linear fallback of `onset_rate`.
        let span = d1 - d0;
        let s = if span != 0.0 { -d0 / span } else { 0.5 };
        let ds = if span != 0.0 && (0.0..=1.0).contains(&s) {
            (-dd0 * span + d0 * (dd1 - dd0)) / (span * span)
        } else {
            0.0
        };
        let s = s.clamp(0.0, 1.0);
        return dr0 + (dr1 - dr0) * s + (r1 - r0) * ds;
    }
    let dot = |b: [f64; 4], x: [f64; 4]| b.iter().zip(x).map(|(b, x)| b * x).sum::<f64>();
    let data = [d0, r0, d1, r1];
    let pert = [dd0, dr0, dd1, dr1];
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if dot(basis(mid), data) > 0.0 {
            hi = mid
        } else {
            lo = mid
        }
    }
    let s = 0.5 * (lo + hi);
    let slope = dot(dbasis(s), data);
    // p(s*, data) = 0: ds*/d(data) = -p_data / p_s; the stored rate is p_s(s*) / h.
    let ds = if slope != 0.0 {
        -dot(basis(s), pert) / slope
    } else {
        0.0
    };
    (dot(dbasis(s), pert) + dot(ddbasis(s), data) * ds) / h
}

/// Whether the cubic Hermite interpolant of a step's penetration can be trusted: its secant
/// slope `(d1 - d0) / h`, the mean rate over the step, must lie within the range of the end
/// rates widened by that range and by half the larger rate. A step much shorter than
/// the penetration's round-off (the steps around a located onset event can be 1e-20 s long,
/// with penetrations of 1e-17 m that are round-off) fails it: there the secant is noise.
fn hermite_trusted(d0: f64, r0: f64, d1: f64, r1: f64, h: f64) -> bool {
    let secant = (d1 - d0) / h;
    let (lo, hi) = (r0.min(r1), r0.max(r1));
    let margin = (hi - lo) + 0.5 * r0.abs().max(r1.abs());
    secant >= lo - margin && secant <= hi + margin
}

/// Approach velocity where delta crosses zero inside a step of length h, from delta and its rate
/// at both ends, on the cubic Hermite interpolant (bisection on the sign change); where that
/// interpolant is not to be trusted ([`hermite_trusted`]), the rate interpolated linearly at the
/// linear crossing.
fn onset_rate(d0: f64, r0: f64, d1: f64, r1: f64, h: f64) -> f64 {
    if !hermite_trusted(d0, r0, d1, r1, h) {
        let span = d1 - d0;
        let s = if span != 0.0 {
            (-d0 / span).clamp(0.0, 1.0)
        } else {
            0.5
        };
        return r0 + (r1 - r0) * s;
    }
    let p = |s: f64| {
        (2.0 * s * s * s - 3.0 * s * s + 1.0) * d0
            + (s * s * s - 2.0 * s * s + s) * h * r0
            + (-2.0 * s * s * s + 3.0 * s * s) * d1
            + (s * s * s - s * s) * h * r1
    };
    let dp = |s: f64| {
        (6.0 * s * s - 6.0 * s) * d0
            + (3.0 * s * s - 4.0 * s + 1.0) * h * r0
            + (-6.0 * s * s + 6.0 * s) * d1
            + (3.0 * s * s - 2.0 * s) * h * r1
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if p(mid) > 0.0 { hi = mid } else { lo = mid }
    }
    dp(0.5 * (lo + hi)) / h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step of 2.7e-20 s around a located onset, whose penetrations (1e-17 m) are round-off
    /// (measured on the clearance slider-crank with onset events): the Hermite interpolant would
    /// give 1500 m/s; the rate is the ends' 4.3858 m/s.
    #[test]
    fn onset_rate_of_a_round_off_step_is_the_rate_at_its_ends() {
        let (d0, r0, d1, r1, h) = (
            -1.1058862159352145e-17,
            4.385826513509208,
            1.6588293239028218e-17,
            4.38582651350921,
            2.710505431213761e-20,
        );
        let v = onset_rate(d0, r0, d1, r1, h);
        assert!((v - r0).abs() < 1e-12 * r0, "{v}");
        // Its tangent is the tangent of the same formula (finite differences of it).
        let pert = (1e-18, 1e-3, -2e-18, 2e-3);
        let e = 1e-3;
        let fd = (onset_rate(
            d0 + e * pert.0,
            r0 + e * pert.1,
            d1 + e * pert.2,
            r1 + e * pert.3,
            h,
        ) - onset_rate(
            d0 - e * pert.0,
            r0 - e * pert.1,
            d1 - e * pert.2,
            r1 - e * pert.3,
            h,
        )) / (2.0 * e);
        let tan = onset_rate_tangent((d0, r0, d1, r1), h, pert);
        assert!((fd - tan).abs() < 1e-8, "{fd} vs {tan}");
    }

    #[test]
    fn onset_rate_tangent_matches_finite_differences() {
        // A crossing inside the step: delta from -1e-6 m (approaching at 0.3 m/s) to 2e-6 m.
        let data = (-1e-6, 0.3, 2e-6, 0.25);
        let h = 1e-5;
        let pert = (3e-7, -0.05, 1e-7, 0.02);
        let at = |e: f64| {
            onset_rate(
                data.0 + e * pert.0,
                data.1 + e * pert.1,
                data.2 + e * pert.2,
                data.3 + e * pert.3,
                h,
            )
        };
        // Central differences with e = 1e-3: the rate is smooth in the data (a simple root of a
        // cubic), truncation O(e^2) ~ 1e-6 relative, far above the bisection's 2^-50 resolution.
        let fd = (at(1e-3) - at(-1e-3)) / 2e-3;
        let an = onset_rate_tangent(data, h, pert);
        assert!((an - fd).abs() < 1e-5 * fd.abs().max(1e-3), "{an} vs {fd}");
    }
}
