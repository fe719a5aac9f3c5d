//! The model as an [`OdeSystem`]: [`Mechanism`] holds the model, its workspace, the step-size
//! guard ([`crate::guard`]), the contact events ([`super::events`]) and the onset memory's update
//! after each accepted step ([`super::onset`]).

use std::ops::Range;

use super::events::{ContactEvents, contact_events};
use crate::clearance::ContactEval;
use crate::error::{Error, Result};
use crate::guard::{StepGuard, Warning};
use crate::model::Model;
use crate::ode::{Events, OdeSystem, Stiffness};
use crate::state::HybridState;
use crate::workspace::Workspace;

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

/// A contact state deeper than none.
fn untouched() -> ContactEval {
    ContactEval {
        delta: f64::NEG_INFINITY,
        ..Default::default()
    }
}

impl OdeSystem for Mechanism<'_> {
    fn dim(&self) -> usize {
        self.model.dim()
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
    /// The contact events, when the settings ask for some ([`Events`] below).
    fn events(&mut self) -> Option<&mut dyn Events> {
        if self.events.is_some() {
            Some(self)
        } else {
            None
        }
    }
    /// The contacts' stiff directions ([`Stiffness`] below).
    fn stiffness(&mut self) -> Option<&mut dyn Stiffness> {
        Some(self)
    }
}

impl Events for Mechanism<'_> {
    /// With `onset_events`, one event per contact slot: the gap `-delta` (m), which crosses zero
    /// downwards where the contact begins; with `end_events`, one more per slot after those:
    /// the penetration `delta` (m), which crosses zero downwards where the contact ends; with
    /// `friction_events`, two per kink of each slot's friction law after those: `v - v_k` and
    /// `v_k - v` for the sliding speed v (m/s), which cross zero downwards where the speed falls
    /// and rises through the kink v_k while the contact is penetrating (1 while it is open: the
    /// friction is off there). One of the two jumps below zero where the contact begins, so
    /// `friction_events` also ends a step at the onsets of the contacts whose law has kinks,
    /// with `onset_events` off too.
    fn count(&mut self) -> usize {
        self.events.as_ref().map_or(0, |e| {
            self.model.n_contacts * (usize::from(e.onsets) + usize::from(e.ends))
                + 2 * e.kinks.len()
        })
    }
    fn values(&mut self, _t: f64, y: &[f64], g: &mut [f64]) {
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
    fn values_at_rhs(&mut self, _t: f64, _y: &[f64], g: &mut [f64]) {
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
    fn value(&mut self, i: usize, _t: f64, y: &[f64], _g: &mut [f64]) -> f64 {
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
    fn components(&mut self, i: usize, parts: &mut Vec<Range<usize>>) {
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
    fn restarts_step(&mut self, _i: usize) -> bool {
        true
    }
}

impl Stiffness for Mechanism<'_> {
    /// The contacts' stiff directions ([`Model::stiff_directions`]); the workspace's kinematics
    /// and contact states are overwritten, which the step's own evaluations then refresh.
    fn directions(
        &mut self,
        _t: f64,
        y: &[f64],
        h: f64,
        dirs: &mut Vec<f64>,
        pattern: &mut Vec<u32>,
    ) {
        self.model
            .stiff_directions(y, h, &mut self.ws, dirs, pattern);
    }
    /// The contacts' part of the Jacobian along the directions ([`Model::contact_jacobian`]).
    fn jacobian(&mut self, t: f64, y: &[f64], basis: &[f64], image: &mut [f64]) -> bool {
        let model = self.model;
        let scratch = self
            .jacobian
            .get_or_insert_with(|| Box::new(Workspace::new(model)));
        model.contact_jacobian(t, y, basis, image, &mut self.ws, scratch);
        true
    }
}
