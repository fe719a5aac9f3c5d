//! The hybrid state of a run: everything the future of a run depends on.
//!
//! A run of a flow is not determined by its continuous state `(t, y)` alone. A contact law with
//! hysteresis damping (Lankarani-Nikravesh, Hunt-Crossley, Flores, Gonthier, Carvalho-Martins)
//! remembers the approach velocity at the onset of each contact, the step-size guard remembers
//! which joints it has warned about, and the integrator remembers its step: the grid of a fixed-step method and the
//! controller's next step and last error of an adaptive one. [`HybridState`] holds all of it, so
//! that a run stopped at T, saved (to HDF5, see the analysis crate's `hybrid` module), loaded and
//! run on is the same run as one that never stopped: bit for bit for a fixed-step method whose
//! grid contains T, and for any method that the uninterrupted run also stopped at T.
//!
//! The state is handed to [`crate::ode::advance`], which loads the system's memory from it
//! ([`crate::ode::OdeSystem::load_memory`]), integrates and stores the memory back
//! ([`crate::ode::OdeSystem::save_memory`]). Between steps the memory lives where the system
//! evaluates it (the onset history in the [`crate::workspace::Workspace`]), so that no step
//! copies it.

/// Integrator memory carried from one run to the next. Equality is bitwise (NaN, the mark of an
/// unused part, equals NaN).
#[derive(Debug, Clone)]
pub struct StepperMemory {
    /// Fixed-step methods: origin of the step grid `t_k = origin + k h` (s), and the step `h` the
    /// grid was laid with (s); NaN before the first run. A run with another step lays a new grid
    /// from its start time.
    pub grid_origin: f64,
    pub grid_step: f64,
    /// Grid points reached (k of the last one).
    pub grid_steps: u64,
    /// Adaptive methods: the step the controller proposes next (s); NaN before the first run,
    /// when the initial step is chosen by Hairer's rule.
    pub next_step: f64,
    /// Adaptive methods: the error norm of the last accepted step (the PI controller's memory).
    pub last_error: f64,
}

impl Default for StepperMemory {
    fn default() -> Self {
        StepperMemory {
            grid_origin: f64::NAN,
            grid_step: f64::NAN,
            grid_steps: 0,
            next_step: f64::NAN,
            // The controller's neutral start: err_old = 1e-4 (Hairer's codes).
            last_error: 1e-4,
        }
    }
}

/// Time, continuous state and every memory of a run. Equality is bitwise: two states are equal
/// when a run continued from either is the same run (NaN, out of contact, equals NaN).
#[derive(Debug, Clone, Default)]
pub struct HybridState {
    /// s.
    pub t: f64,
    /// The continuous state (for a mechanism: positions, Euler parameters, velocities and
    /// angular velocities of the bodies, see [`crate::model::State`]).
    pub y: Vec<f64>,
    /// Approach velocity at the onset of each contact (m/s), NaN while out of contact; one entry
    /// per contact point of the clearance joints, in the order of the model's contact slots.
    /// Empty for a flow without contacts.
    pub onset: Vec<f64>,
    /// Whether the step-size guard has warned about each clearance joint.
    pub warned: Vec<bool>,
    pub stepper: StepperMemory,
}

impl HybridState {
    /// A state at `(t, y)` with no memory: no contact has begun, no warning was given, the
    /// integrator starts afresh. A system with memory sizes `onset` and `warned` when it loads it.
    pub fn new(t: f64, y: Vec<f64>) -> Self {
        HybridState {
            t,
            y,
            onset: Vec::new(),
            warned: Vec::new(),
            stepper: StepperMemory::default(),
        }
    }

    /// The same motion (time, continuous state, contact-onset history) as the start of a new
    /// run: the integrator's memory and the guard's flags start afresh. This is how a run with
    /// another method or another parameter value takes over a state (work-precision restarts,
    /// continuation sweeps): the contacts carry on, the bookkeeping of the old run does not.
    pub fn for_new_run(&self) -> HybridState {
        HybridState {
            t: self.t,
            y: self.y.clone(),
            onset: self.onset.clone(),
            warned: Vec::new(),
            stepper: StepperMemory::default(),
        }
    }
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

impl PartialEq for StepperMemory {
    fn eq(&self, o: &Self) -> bool {
        self.grid_steps == o.grid_steps
            && same_bits(
                &[
                    self.grid_origin,
                    self.grid_step,
                    self.next_step,
                    self.last_error,
                ],
                &[o.grid_origin, o.grid_step, o.next_step, o.last_error],
            )
    }
}

impl PartialEq for HybridState {
    fn eq(&self, o: &Self) -> bool {
        same_bits(&[self.t], &[o.t])
            && same_bits(&self.y, &o.y)
            && same_bits(&self.onset, &o.onset)
            && self.warned == o.warned
            && self.stepper == o.stepper
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equality_is_bitwise() {
        let mut a = HybridState::new(1.0, vec![0.5, 0.25]);
        a.onset = vec![f64::NAN, -0.1];
        let b = a.clone();
        assert_eq!(a, b, "NaN onsets and unused NaN memory compare equal");
        let mut c = a.clone();
        c.y[1] = f64::from_bits(0.25f64.to_bits() + 1);
        assert_ne!(a, c, "one unit in the last place is another state");
        let mut d = a.clone();
        d.onset[0] = 0.0;
        assert_ne!(a, d, "a contact in progress is another state");
        let mut e = a.clone();
        e.stepper.grid_steps = 1;
        assert_ne!(a, e);
    }

    #[test]
    fn a_new_run_keeps_the_motion_and_drops_the_bookkeeping() {
        let mut a = HybridState::new(2.0, vec![1.0]);
        a.onset = vec![0.3];
        a.warned = vec![true];
        a.stepper.grid_steps = 7;
        a.stepper.next_step = 1e-3;
        let n = a.for_new_run();
        assert_eq!((n.t, &n.y, &n.onset), (a.t, &a.y, &a.onset));
        assert!(n.warned.is_empty());
        assert_eq!(n.stepper, StepperMemory::default());
    }
}
