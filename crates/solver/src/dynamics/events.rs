//! The contact events, for integrators that end steps at them: per contact slot the gap
//! `-delta` (onsets) and `delta` (ends), and per kink v_k of a friction law the pair
//! `v - v_k`, `v_k - v` of the sliding speed v while the contact penetrates. They are evaluated
//! in a workspace of their own, between the stages of a step.

use std::ops::Range;

use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::Workspace;

/// The contact events: which kinds are on, a workspace of their own and the contact rates and
/// sliding speeds it returns.
pub(super) struct ContactEvents {
    pub(super) onsets: bool,
    pub(super) ends: bool,
    /// With `friction_events`: the contact slot and kink speed (m/s) of each pair of friction
    /// events.
    pub(super) kinks: Vec<(usize, f64)>,
    /// Per contact slot: the components of the state its functions read (the positions and
    /// velocities of its joint's bodies).
    pub(super) parts: Vec<Vec<Range<usize>>>,
    pub(super) ws: Box<Workspace>,
    pub(super) rates: Vec<(f64, f64, bool)>,
    pub(super) speeds: Vec<f64>,
}

/// What event function of [`ContactEvents`] is: a slot's onset or end, or side 0 or 1 of a
/// friction kink (its index in `kinks`).
pub(super) enum ContactEvent {
    Onset(usize),
    End(usize),
    Kink(usize, usize),
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
    pub(super) fn event(&self, i: usize, n: usize) -> ContactEvent {
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
    pub(super) fn values(&self, g: &mut [f64]) {
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
    pub(super) fn slot(&self, kinks: &[(usize, f64)]) -> usize {
        match *self {
            ContactEvent::Onset(slot) | ContactEvent::End(slot) => slot,
            ContactEvent::Kink(k, _) => kinks[k].0,
        }
    }

    /// The event function's value from its slot's penetration (m) and, for a kink, sliding
    /// speed (m/s), which `at(slot, speed)` returns (the speed only when `speed` is set).
    pub(super) fn value(
        &self,
        kinks: &[(usize, f64)],
        at: impl FnOnce(usize, bool) -> (f64, f64),
    ) -> f64 {
        let (delta, v) = at(self.slot(kinks), matches!(self, ContactEvent::Kink(..)));
        match *self {
            ContactEvent::Onset(_) => gap(delta),
            ContactEvent::End(_) => -gap(delta),
            ContactEvent::Kink(k, side) => kink_value(delta, v, kinks[k].1)[side],
        }
    }
}

/// The contact events the model's settings call for; None when there are none.
pub(super) fn contact_events(model: &Model) -> Option<ContactEvents> {
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
