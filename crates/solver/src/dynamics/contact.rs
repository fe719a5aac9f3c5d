//! Contact state of the clearance joints: each contact slot's penetration delta, its rate
//! delta', normal and contact points from the two bodies' kinematics (the joint's geometry), the
//! contact forces and moments that the normal and friction laws give (added into Q by
//! [`super::forces`]), and the sliding speeds the friction laws and events read.

use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::Workspace;

impl Model {
    /// Contact forces of the clearance joints into `ws.q` (kinematics must be current).
    pub(super) fn contact_forces(&self, ws: &mut Workspace) {
        let nb = self.nb();
        let idx = |b: usize| if b == GROUND { nb } else { b };
        for (ci, c) in self.clearances.iter().enumerate() {
            let (kh, kj) = (ws.kin[idx(c.housing)], ws.kin[idx(c.journal)]);
            let slots = c.first..c.first + c.geometry.n_contacts();
            let out = &mut ws.contacts[slots.clone()];
            c.geometry(&kh, &kj, out);
            let bristles = c.bristle.map_or(0..0, |b| b..b + 3 * slots.len());
            let r = c.forces(
                (&kh, &kj),
                &ws.onset[slots],
                (
                    &ws.bristle[bristles.clone()],
                    &mut ws.bristle_rate[bristles],
                ),
                out,
            );
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
    pub(super) fn contact_geometry(&self, y: &[f64], ws: &mut Workspace) {
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
}
