//! Time integration of first-order ODE systems `y' = f(t, y)`; knows no mechanics.
//!
//! * [`OdeSystem`]: the only thing an integrator needs: a dimension and a right-hand side, with
//!   optional bookkeeping after each step (memories, guards); event functions ([`Events`]) and
//!   stiff structure ([`Stiffness`]) are optional capabilities the system returns when it has
//!   them ([`OdeSystem::events`], [`OdeSystem::stiffness`]).
//! * [`Integrator`]: one integration scheme (stepper, error estimate, dense output) and how
//!   scenes, studies and the step loop use it. Each lives in its own submodule, whose docs give
//!   the scheme and its source, and is listed once in [`INTEGRATORS`], the registry.
//! * [`Method`]: an integrator at an [`Accuracy`]: a fixed step, or tolerances for the error
//!   control. Scenes select an integrator by its name (`integrator = "dopri5"`,
//!   [`Integrator::method`]: adaptive when the integrator has error control), studies a method
//!   by its family name and setting ([`Method::of_family`]).
//!
//! The adaptive methods share one step-size controller. The error norm is the root mean square
//! of the error estimate scaled per component by `atol + rtol * max(|y_old|, |y_new|)` (DOP853
//! combines its two estimates in that scaling as Hairer's code does); a step is accepted when the
//! norm is at most 1 and the next step follows the PI rule `h * 0.9 err^(-0.7/q) err_prev^(0.4/q)`
//! (a PI controller of Gustafsson's form; Hairer's codes use other exponents), at most 10 times larger (not larger right after a
//! rejection); a rejected step is retried with `h * 0.9 err^(-1/q)`, at most 5 times smaller.
//! Here the estimate is O(h^q), q the integrator's [`Adaptive::control_order`]: 3 for BS3, 5 for
//! DOPRI5, 8 for DOP853, 3 for Rosenbrock23. The initial step follows Hairer's HINIT with the same q.
//!
//! [`integrate`] advances from `t0` to `t_end`, and hands the observer the state at each requested
//! sample time, evaluated on the dense output: the step sequence does not depend on the sampling.
//! The last step is shortened so that `t_end` is reached exactly. A non-finite state stops the run
//! with [`crate::Error::Diverged`] naming the time.
//!
//! # Adding an integrator
//!
//! 1. A file `ode/<name>.rs` (copy `dopri5.rs` for an explicit pair, `rosenbrock23.rs` for a
//!    linearly implicit method) with the scheme's citation, a stepper implementing `Stepper`
//!    (`step` leaves the new state in `Work::y_new`, f at it in stage `fsal`, evaluated last,
//!    and, when adaptive, the error estimate in `Work::tmp`; `eval_component` is the dense
//!    output's formula for one component) and its descriptor, a
//!    `pub static` [`Integrator`]: the name scenes use, order, stage count, FSAL stage,
//!    stability function, whether it runs adaptive ([`Adaptive`]: control order, default
//!    tolerances of work-precision studies) and/or at a fixed step ([`Fixed`]: family name,
//!    default steps).
//! 2. Its `pub mod <name>;` line and one line in [`INTEGRATORS`]. Scenes, studies, the scene
//!    compiler's checks and the default work-precision runs follow from the descriptor; the
//!    registry test (`every_registered_integrator_is_complete`) checks the descriptor against
//!    the stepper.
//! 3. Tests of the scheme itself, copied from those of a similar one: the observed order at a
//!    fixed step (`dop853_fixed_step_converges_with_order_eight`), the error estimate
//!    (`rosenbrock23_error_estimate_is_of_order_three`) and the dense output
//!    (`dop853_dense_output_has_order_seven`).

use std::ops::Range;
use std::sync::OnceLock;
use std::time::Duration;

use nalgebra::{DMatrix, Dyn, LU};

use crate::error::Result;
use crate::state::HybridState;

pub mod bs3;
pub mod dop853;
pub mod dopri5;
pub mod rk4;
pub mod ros34pw2;
pub mod rosenbrock23;
mod step_loop;
#[cfg(test)]
mod tests;

pub use step_loop::{
    SampleTimes, Step, StepObserver, advance, advance_on, integrate, integrate_partial,
    integrate_steps,
};

/// Every integrator, in the order of the lists shown to users (known names, study families,
/// default work-precision runs): the registry.
pub static INTEGRATORS: &[&Integrator] = &[
    &rk4::RK4,
    &bs3::BS3,
    &dopri5::DOPRI5,
    &dop853::DOP853,
    &rosenbrock23::ROSENBROCK23,
    &ros34pw2::ROS34PW2,
];

/// A first-order system `y' = f(t, y)`.
pub trait OdeSystem {
    /// Length of the state vector.
    fn dim(&self) -> usize;
    /// Writes `f(t, y)` into `dydt` (both of length [`OdeSystem::dim`]).
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]);

    /// How many leading components of the state the adaptive error control (and the initial
    /// step estimate) measures; the rest are carried along in the same steps without steering
    /// them. The default is all of them. A state extended by its tangent vectors
    /// (`jointplay_analysis::measures::lyapunov`) sets this to the length of the physical state, so that
    /// the extended run takes exactly the steps of the plain run.
    fn error_dim(&self) -> usize {
        self.dim()
    }

    /// Called after every accepted step from `(t0, y0)` to `(t1, y1)`, before the samples inside
    /// the step are emitted, for bookkeeping of discrete history (such as the approach velocity
    /// at contact onset, located inside the step). Returns true when that history changed the
    /// right-hand side, so that the integrator evaluates `f(t1, y1)` again instead of reusing the
    /// last stage. The default keeps no history.
    fn step_accepted(&mut self, _t0: f64, _y0: &[f64], _t1: f64, _y1: &[f64]) -> bool {
        false
    }

    /// The divergence guard, called after every accepted step (after
    /// [`OdeSystem::step_accepted`]) with the new state: returns a description of a quantity that
    /// has run away (the run then stops with [`Error::Diverged`](crate::Error::Diverged) at `t`). The default checks
    /// nothing beyond the integrator's own test for a non-finite state.
    fn check_step(&mut self, _t: f64, _y: &[f64]) -> Option<String> {
        None
    }

    /// Explains a non-finite state: component `component` became non-finite in the step from
    /// `(t, y)`, the last state accepted. The default names the component.
    fn explain_non_finite(&mut self, _t: f64, _y: &[f64], component: usize) -> String {
        format!("state component {component} became non-finite")
    }

    /// Takes the system's discrete memory (contact-onset history, guard flags) from `state`
    /// before [`advance`] integrates; an error when it does not fit the system. A state without
    /// memory (empty vectors) starts the memory afresh. The default keeps none.
    fn load_memory(&mut self, _state: &HybridState) -> Result<()> {
        Ok(())
    }

    /// Writes the system's discrete memory into `state` after [`advance`] has integrated.
    fn save_memory(&self, _state: &mut HybridState) {}

    /// The system's event functions (state resets such as an impact, or points where a step
    /// must end, such as a contact onset); None (the default) for a system without them.
    fn events(&mut self) -> Option<&mut dyn Events> {
        None
    }

    /// Where the right-hand side is stiff, for the linearly implicit W-method ([`ros34pw2`]);
    /// None (the default) when the system knows no such structure: the method then differences
    /// the whole Jacobian.
    fn stiffness(&mut self) -> Option<&mut dyn Stiffness> {
        None
    }
}

/// The number of event functions of `sys` (0 without [`OdeSystem::events`]).
pub fn event_count<S: OdeSystem + ?Sized>(sys: &mut S) -> usize {
    sys.events().map_or(0, |e| e.count())
}

/// Event functions of an [`OdeSystem`]: state resets such as an impact (a Newton impact law
/// `v -> -e v` at a rigid stop), or points where a step must end (a contact onset). The state `y`
/// they read is the system's whole state.
pub trait Events {
    /// Number of event functions.
    fn count(&mut self) -> usize;

    /// Values of the event functions at `(t, y)` into `g`: event `i` fires where `g_i` crosses
    /// from positive to zero or below inside a step. The integrator locates the crossing on its
    /// dense output (bisection to round-off), ends the step there, calls [`Events::apply`] and
    /// restarts from the reset state (a fresh first stage).
    fn values(&mut self, t: f64, y: &[f64], g: &mut [f64]);

    /// [`Events::values`] at the state `y` of the last [`OdeSystem::rhs`]: the integrator calls
    /// it at the end of every accepted step, whose last right-hand side is `f(t + h, y_new)`
    /// (every `Stepper::step` ends with it; `t` is the step's end time, which `t + h` may miss
    /// by a rounding). A system that keeps what its right-hand side computed may read the values
    /// from that instead of evaluating them afresh; they must be those of `values`, bit for bit.
    /// The default evaluates them.
    fn values_at_rhs(&mut self, t: f64, y: &[f64], g: &mut [f64]) {
        self.values(t, y, g)
    }

    /// Event function `i` alone at `(t, y)`, as [`Events::values`] gives it (bit for bit): the
    /// bisection that locates a crossing needs no other. `g` (of length [`Events::count`]) is
    /// scratch. The default evaluates them all.
    fn value(&mut self, i: usize, t: f64, y: &[f64], g: &mut [f64]) -> f64 {
        self.values(t, y, g);
        g[i]
    }

    /// The components of the state that event function `i` reads, into `parts` (replacing what
    /// it held): the bisection interpolates only these, and [`Events::value`] must give the same
    /// value whatever the others hold. Left empty (the default), the whole state.
    fn components(&mut self, _i: usize, parts: &mut Vec<Range<usize>>) {
        parts.clear();
    }

    /// Applies event `i` at `(t, y)`: resets `y` in place. An error stops the run with it (for
    /// example [`Error::Diverged`](crate::Error::Diverged) at `t` for an impact too slow to
    /// resolve: chattering). The default changes nothing.
    fn apply(&mut self, _i: usize, _t: f64, _y: &mut [f64]) -> Result<()> {
        Ok(())
    }

    /// Whether the step after event `i` starts from a fresh step-size estimate (Hairer's HINIT
    /// at the event state, kept no larger than the controller's proposal) instead of the
    /// controller's proposal alone: for an event where the dynamics change character, such as
    /// a contact onset, the step the controller grew before it is too long after it. False by
    /// default.
    fn restarts_step(&mut self, _i: usize) -> bool {
        false
    }
}

/// Where the right-hand side of an [`OdeSystem`] is stiff, for the linearly implicit W-method
/// ([`ros34pw2`]).
pub trait Stiffness {
    /// Directions of the state space along which the right-hand side may be stiff near
    /// `(t, y)`, for a step of about `h` (s): the method differences f along them only and
    /// treats the rest of the Jacobian as zero. Writes the directions (each of length
    /// [`OdeSystem::dim`], any scale, not necessarily orthogonal) one after the other into
    /// `dirs` and a list identifying where they come from into `pattern` (the method
    /// differences again when the pattern changes).
    fn directions(
        &mut self,
        t: f64,
        y: &[f64],
        h: f64,
        dirs: &mut Vec<f64>,
        pattern: &mut Vec<u32>,
    );

    /// The Jacobian df/dy at `(t, y)` along the `r` unit directions `basis` (each of length
    /// [`OdeSystem::dim`], one after the other), into `image` (the same layout), for the
    /// directions [`Stiffness::directions`] gave: `J q` or an approximation of it that keeps its
    /// stiff part, as the W-method allows. Counts as one right-hand-side evaluation. Returns
    /// false (the default) when the system has no such product: the method then differences f
    /// along each direction (r evaluations).
    fn jacobian(&mut self, _t: f64, _y: &[f64], _basis: &[f64], _image: &mut [f64]) -> bool {
        false
    }
}

/// An integration scheme and how it is used: the descriptor each integrator file defines and
/// [`INTEGRATORS`] lists. An integrator runs adaptive, at a fixed step, or both.
pub struct Integrator {
    /// The name scenes select it by (`integrator = "dopri5"`), and the family name of its
    /// adaptive method in studies.
    pub name: &'static str,
    /// Order of the propagated solution.
    pub order: u32,
    /// Its run with error control; None for a fixed-step scheme.
    pub adaptive: Option<Adaptive>,
    /// Its run at a fixed step; None for a scheme that runs only with error control.
    pub fixed: Option<Fixed>,
    /// The stability function R(z) of the propagated solution at z = h lambda = (re, im), as
    /// (re, im): one step multiplies the mode `exp(lambda t)` of a linear system by R(z).
    pub stability: fn(f64, f64) -> (f64, f64),
    /// Stage vectors in [`Work::k`].
    stages: usize,
    /// Dense-output coefficient vectors in [`Work::cont`].
    dense_len: usize,
    /// The stage holding f(t + h, y_new) after a step: the next step's first stage (FSAL).
    fsal: usize,
    /// Whether the stepper needs a Jacobian and its factorisation ([`Work::lin`]).
    jacobian: bool,
    stepper: &'static dyn Stepper,
}

/// An integrator's run with error control.
#[derive(Debug, Clone, Copy)]
pub struct Adaptive {
    /// The exponent q of the step-size control: the local error estimate is O(h^q), so a step
    /// scaled by err^(-1/q) would meet the tolerance exactly.
    pub control_order: f64,
    /// The relative tolerances of the default work-precision runs: 10^-a to 10^-b for (a, b).
    pub default_decades: (i32, i32),
}

/// An integrator's run at a fixed step.
#[derive(Debug, Clone, Copy)]
pub struct Fixed {
    /// The family name of the fixed-step method in studies; the integrator's name when it has
    /// no error control (scenes then select this method by that name).
    pub family: &'static str,
    /// The steps of the default work-precision runs, as multiples of the flow's own step (or of
    /// 1/1000 of its period); empty when this method is left out of the default runs.
    pub default_steps: &'static [f64],
}

impl Integrator {
    /// The integrator of this name; None for a name not in [`INTEGRATORS`].
    pub fn named(name: &str) -> Option<&'static Integrator> {
        INTEGRATORS.iter().copied().find(|i| i.name == name)
    }

    /// Whether its stages solve linear systems with a Jacobian (Rosenbrock23, ROS34PW2).
    pub fn linearly_implicit(&self) -> bool {
        self.jacobian
    }

    /// The names of all integrators, in registry order.
    pub fn names() -> &'static [&'static str] {
        static NAMES: OnceLock<Vec<&'static str>> = OnceLock::new();
        NAMES.get_or_init(|| INTEGRATORS.iter().map(|i| i.name).collect())
    }

    /// The method a scene selects with this integrator: with error control (the tolerances and
    /// step bound (s)) when it has it, else at the fixed `step` (s); the other settings are
    /// ignored. The callers check the values.
    pub fn method(&'static self, step: f64, rtol: f64, atol: f64, max_step: f64) -> Method {
        let accuracy = if self.adaptive.is_some() {
            Accuracy::Adaptive {
                rtol,
                atol,
                max_step,
            }
        } else {
            Accuracy::Fixed { step }
        };
        Method {
            integrator: self,
            accuracy,
        }
    }
}

impl std::fmt::Debug for Integrator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name)
    }
}

/// The accuracy settings of a [`Method`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Accuracy {
    /// A fixed step `step` (s), no error control.
    Fixed { step: f64 },
    /// Error control: the error per component is measured against
    /// `atol + rtol * max(|y_old|, |y_new|)`; `max_step` bounds the step (s).
    Adaptive { rtol: f64, atol: f64, max_step: f64 },
}

/// Integration method: an integrator and its accuracy settings. Built only for a way the
/// integrator runs (a fixed step for an integrator with [`Integrator::fixed`], tolerances for
/// one with [`Integrator::adaptive`]).
#[derive(Clone, Copy)]
pub struct Method {
    integrator: &'static Integrator,
    accuracy: Accuracy,
}

impl PartialEq for Method {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.integrator, other.integrator) && self.accuracy == other.accuracy
    }
}

impl std::fmt::Debug for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {:?}", self.family(), self.accuracy)
    }
}

impl Method {
    /// `integrator` at the fixed step `step` (s); None when it runs only with error control.
    pub fn fixed(integrator: &'static Integrator, step: f64) -> Option<Method> {
        integrator.fixed.map(|_| Method {
            integrator,
            accuracy: Accuracy::Fixed { step },
        })
    }

    /// `integrator` with error control at the tolerances `rtol`, `atol` and the step bound
    /// `max_step` (s); None when it runs only at a fixed step.
    pub fn adaptive(
        integrator: &'static Integrator,
        rtol: f64,
        atol: f64,
        max_step: f64,
    ) -> Option<Method> {
        integrator.adaptive.map(|_| Method {
            integrator,
            accuracy: Accuracy::Adaptive {
                rtol,
                atol,
                max_step,
            },
        })
    }

    /// The integrator.
    pub fn integrator(&self) -> &'static Integrator {
        self.integrator
    }

    /// The accuracy settings.
    pub fn accuracy(&self) -> Accuracy {
        self.accuracy
    }

    /// The relative and absolute tolerances in a text [`Method::describe`] wrote ("dopri5, rtol
    /// 1e-9, atol 1e-11"); `None` for a fixed-step method's text.
    pub fn tolerances_in(described: &str) -> Option<(f64, f64)> {
        let after = |key: &str| -> Option<f64> {
            let rest = &described[described.find(key)? + key.len()..];
            rest.split([',', ' ']).next()?.parse().ok()
        };
        Some((after("rtol ")?, after("atol ")?))
    }

    /// Human-readable settings, e.g. "rk4, fixed step 1e-4 s".
    pub fn describe(&self) -> String {
        let name = self.integrator.name;
        match self.accuracy {
            Accuracy::Fixed { step } if self.integrator.adaptive.is_none() => {
                format!("{name}, fixed step {step:e} s")
            }
            Accuracy::Fixed { step } => format!("{name} (fixed step {step:e} s)"),
            Accuracy::Adaptive {
                rtol,
                atol,
                max_step,
            } => {
                let mut s = format!("{name}, rtol {rtol:e}, atol {atol:e}");
                if max_step.is_finite() {
                    s += &format!(", max step {max_step:e} s");
                }
                s
            }
        }
    }

    /// The family name scenes and studies use for this method ("rk4", "dopri5", ...).
    pub fn family(&self) -> &'static str {
        match self.accuracy {
            Accuracy::Fixed { .. } => self
                .integrator
                .fixed
                .map_or(self.integrator.name, |f| f.family),
            Accuracy::Adaptive { .. } => self.integrator.name,
        }
    }

    /// Every family name accepted by [`Method::of_family`], integrator by integrator in registry
    /// order (the adaptive method before the fixed-step one).
    pub fn families() -> impl Iterator<Item = &'static str> {
        INTEGRATORS.iter().flat_map(|i| {
            let adaptive = i.adaptive.map(|_| i.name);
            adaptive.into_iter().chain(i.fixed.map(|f| f.family))
        })
    }

    /// The member of family `name` at accuracy `setting`: the step (s) of a fixed-step family,
    /// the relative tolerance of an adaptive one (with absolute tolerance `atol` and no step
    /// bound). None for an unknown family.
    pub fn of_family(name: &str, setting: f64, atol: f64) -> Option<Method> {
        INTEGRATORS.iter().find_map(|&i| {
            if i.adaptive.is_some() && i.name == name {
                Method::adaptive(i, setting, atol, f64::INFINITY)
            } else if i.fixed.is_some_and(|f| f.family == name) {
                Method::fixed(i, setting)
            } else {
                None
            }
        })
    }

    /// The settings of family `name` in the default work-precision runs (see
    /// [`Method::of_family`]): fixed steps as multiples of `base_step` (s), tolerances by
    /// decades. Empty for a family left out of those runs, and for an unknown one.
    pub fn default_settings(name: &str, base_step: f64) -> Vec<f64> {
        let Some(m) = Method::of_family(name, 1.0, 1.0) else {
            return Vec::new();
        };
        match m.accuracy {
            Accuracy::Adaptive { .. } => m.integrator.adaptive.map_or(Vec::new(), |a| {
                let (first, last) = a.default_decades;
                (first..=last).map(|e| 10f64.powi(-e)).collect()
            }),
            Accuracy::Fixed { .. } => m.integrator.fixed.map_or(Vec::new(), |f| {
                f.default_steps.iter().map(|s| s * base_step).collect()
            }),
        }
    }

    /// The accuracy setting of [`Method::of_family`]: the step or the relative tolerance.
    pub fn setting(&self) -> f64 {
        match self.accuracy {
            Accuracy::Fixed { step } => step,
            Accuracy::Adaptive { rtol, .. } => rtol,
        }
    }

    /// (rtol, atol, max_step) of an adaptive method; None for fixed-step methods.
    fn tolerances(&self) -> Option<(f64, f64, f64)> {
        match self.accuracy {
            Accuracy::Fixed { .. } => None,
            Accuracy::Adaptive {
                rtol,
                atol,
                max_step,
            } => Some((rtol, atol, max_step)),
        }
    }

    /// The exponent q of the step-size control of an adaptive method.
    fn control_order(&self) -> f64 {
        self.integrator
            .adaptive
            .expect("an adaptive method's integrator has error control")
            .control_order
    }

    /// The fixed step (s) of a fixed-step method; None for adaptive methods.
    pub fn fixed_step(&self) -> Option<f64> {
        match self.accuracy {
            Accuracy::Fixed { step } => Some(step),
            Accuracy::Adaptive { .. } => None,
        }
    }

    /// |R(z)|, the modulus of the stability function ([`Integrator::stability`]) of a fixed-step
    /// method at z = h lambda (given as real and imaginary part): the factor by which one step
    /// multiplies the mode `exp(lambda t)` of a linear system. None for adaptive methods, whose
    /// error control keeps them stable.
    pub fn amplification(&self, re: f64, im: f64) -> Option<f64> {
        self.fixed_step()?;
        let (pr, pi) = (self.integrator.stability)(re, im);
        Some(pr.hypot(pi))
    }

    /// The largest fixed step (s) at which the mode with eigenvalue `lambda = (re, im)` (1/s) is
    /// stable (|R(h lambda)| <= 1), found by bisection from `h_max`; None for adaptive methods.
    pub fn stable_step(&self, re: f64, im: f64, h_max: f64) -> Option<f64> {
        let stable = |h: f64| self.amplification(h * re, h * im).map(|a| a <= 1.0 + 1e-12);
        if stable(h_max)? {
            return Some(h_max);
        }
        let (mut lo, mut hi) = (0.0, h_max);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if stable(mid)? { lo = mid } else { hi = mid }
        }
        Some(lo)
    }
}

/// Counters of one integration run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    /// Steps accepted.
    pub accepted: u64,
    /// Steps rejected by the error control (adaptive methods only).
    pub rejected: u64,
    /// Right-hand-side evaluations (including those that difference the Jacobian).
    pub rhs_evals: u64,
    /// Jacobians df/dy formed (Rosenbrock23: one per step start, by n + 1 forward differences).
    pub jacobians: u64,
    /// Events that ended a step (impacts; contact onsets, ends and friction kinks with
    /// `onset_events`, `end_events` and `friction_events`).
    pub events: u64,
    /// Wall-clock time spent in [`integrate`].
    pub wall: Duration,
}

impl std::ops::AddAssign for Stats {
    fn add_assign(&mut self, o: Self) {
        self.accepted += o.accepted;
        self.rejected += o.rejected;
        self.rhs_evals += o.rhs_evals;
        self.jacobians += o.jacobians;
        self.events += o.events;
        self.wall += o.wall;
    }
}

/// What the observer asks the integrator to do after a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    Continue,
    /// Stop now: the state is left at the end of the step that holds the sample, and the
    /// step's later samples are not observed.
    Stop,
    /// Stop at the end of the step that holds the sample, after its later samples and its
    /// event: every sample up to the state left is observed, and the state is one the run not
    /// stopped passes through, so that going on from it is that run (a stop on request).
    StopAfterStep,
}

/// The value at z = (re, im) of the polynomial with coefficients `coeffs` (constant first), by
/// Horner's scheme in complex arithmetic: the stability function of an explicit method given as
/// its polynomial.
fn polynomial(coeffs: &[f64], re: f64, im: f64) -> (f64, f64) {
    let (mut pr, mut pi) = (0.0, 0.0);
    for &c in coeffs.iter().rev() {
        let r = pr * re - pi * im + c;
        pi = pr * im + pi * re;
        pr = r;
    }
    (pr, pi)
}

/// Component `i` of the cubic Hermite interpolant on [t, t + h] through (y0, f0) and (y1, f1) at
/// t + theta h: the dense output of the schemes whose own order it matches (RK4, BS3).
#[inline]
fn hermite(y0: &[f64], y1: &[f64], f0: &[f64], f1: &[f64], h: f64, theta: f64, i: usize) -> f64 {
    let dy = y1[i] - y0[i];
    (1.0 - theta) * y0[i]
        + theta * y1[i]
        + theta
            * (theta - 1.0)
            * ((1.0 - 2.0 * theta) * dy + (theta - 1.0) * h * f0[i] + theta * h * f1[i])
}

/// Scratch memory of one integrator, allocated once per run.
struct Work {
    /// Stage vectors (their number and meaning depend on the scheme); `k[0]` is f(t, y).
    k: Vec<Vec<f64>>,
    tmp: Vec<f64>,
    y_new: Vec<f64>,
    /// Dense-output coefficients of the last step (5 vectors for DOPRI5; none for the schemes
    /// that interpolate from their stages directly).
    cont: Vec<Vec<f64>>,
    /// Jacobian and factorisation of a linearly implicit scheme.
    lin: Option<LinearWork>,
    /// Leading components the error norm measures ([`OdeSystem::error_dim`]).
    n_err: usize,
}

impl Work {
    fn new(n: usize, n_err: usize, integrator: &Integrator) -> Self {
        let v = |count: usize| vec![vec![0.0; n]; count];
        Work {
            n_err: n_err.min(n),
            k: v(integrator.stages),
            tmp: vec![0.0; n],
            y_new: vec![0.0; n],
            cont: v(integrator.dense_len),
            lin: integrator.jacobian.then(|| LinearWork {
                dense: DenseJacobian {
                    jac: DMatrix::zeros(n, n),
                    lu: None,
                    spare: Some(DMatrix::zeros(n, n)),
                },
                dfdt: vec![0.0; n],
                low: Default::default(),
            }),
        }
    }
}

/// Linear algebra of a linearly implicit (Rosenbrock) step.
struct LinearWork {
    /// The full Jacobian and its factorisation.
    dense: DenseJacobian,
    /// df/dt at the step start (a forward difference).
    dfdt: Vec<f64>,
    /// The low-rank Jacobian of ROS34PW2.
    low: ros34pw2::LowRank,
}

/// A full Jacobian and the factorisation of `I - c J`.
struct DenseJacobian {
    /// df/dy at the step start (forward differences).
    jac: DMatrix<f64>,
    /// LU factors of `I - c J` of the last attempt; their storage is reused for the next one.
    lu: Option<LU<f64, Dyn, Dyn>>,
    /// Storage for the matrix before the first factorisation.
    spare: Option<DMatrix<f64>>,
}

impl DenseJacobian {
    /// df/dy at `(t, y)` by forward differences into `jac`, with f0 = f(t, y): column j is
    /// `(f(t, y + del e_j) - f0) / del`, del ~ sqrt(eps) |y_j| (at least sqrt(eps) 1e-5) rounded
    /// so that `y_j + del` is exact. `tmp` and `scratch` are vectors of the state's length; n
    /// evaluations.
    fn difference_jacobian(
        &mut self,
        sys: &mut dyn OdeSystem,
        (t, y, f0): (f64, &[f64], &[f64]),
        tmp: &mut [f64],
        scratch: &mut [f64],
    ) {
        let n = y.len();
        let sqrt_eps = f64::EPSILON.sqrt();
        tmp.copy_from_slice(y);
        for j in 0..n {
            let yj = y[j];
            let del = (yj + sqrt_eps * yj.abs().max(1e-5)) - yj;
            tmp[j] = yj + del;
            sys.rhs(t, tmp, scratch);
            tmp[j] = yj;
            for i in 0..n {
                self.jac[(i, j)] = (scratch[i] - f0[i]) / del;
            }
        }
    }

    /// Factorises `I - c J` in the storage of the last factorisation (`LU::l_unpack` hands the
    /// matrix back without reallocating it) into `lu`, and returns it; None when it is singular.
    fn factor(&mut self, c: f64) -> Option<&LU<f64, Dyn, Dyn>> {
        let n = self.jac.nrows();
        let mut m = match self.lu.take() {
            Some(lu) => lu.l_unpack(),
            None => self.spare.take().unwrap_or_else(|| DMatrix::zeros(n, n)),
        };
        for j in 0..n {
            for i in 0..n {
                m[(i, j)] = if i == j { 1.0 } else { 0.0 } - c * self.jac[(i, j)];
            }
        }
        let lu = LU::new(m);
        let ok = lu.is_invertible();
        let lu = self.lu.insert(lu);
        ok.then_some(&*lu)
    }
}

/// Solves `lu x = b` in place (the Rosenbrock methods' stages).
fn lu_solve(lu: &LU<f64, Dyn, Dyn>, b: &mut [f64]) {
    let n = b.len();
    lu.solve_mut(&mut nalgebra::DVectorViewMut::from_slice(b, n));
}

/// The stepper of an [`Integrator`]: its stages, error estimate and dense output.
trait Stepper: Sync {
    /// One step of size `h` from (t, y) with f(t, y) in `w.k[0]`: the new state in `w.y_new`,
    /// f(t + h, y_new) in the integrator's FSAL stage (the last right-hand side evaluated, so a
    /// system's own scratch memory holds the evaluation at the new state), and for an adaptive
    /// scheme what its error norm needs (by default the error estimate in `w.tmp`). Counts its
    /// evaluations in `stats`. `retry` is true when the previous attempt from the same (t, y)
    /// was rejected.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &self,
        sys: &mut dyn OdeSystem,
        t: f64,
        y: &[f64],
        h: f64,
        w: &mut Work,
        stats: &mut Stats,
        retry: bool,
    ) -> Result<()>;

    /// The scaled error norm of the step just taken (adaptive schemes): by default the root mean
    /// square of the estimate in `w.tmp` scaled by `atol + rtol * max(|y_old|, |y_new|)`.
    fn error_norm(&self, w: &Work, y: &[f64], _h: f64, rtol: f64, atol: f64) -> f64 {
        let n = w.n_err;
        error_norm(&w.tmp[..n], &y[..n], &w.y_new[..n], rtol, atol)
    }

    /// Prepares the continuous extension of the step just taken from (t, y); nothing by default
    /// (a scheme that interpolates from its stages directly).
    fn dense(
        &self,
        _sys: &mut dyn OdeSystem,
        _t: f64,
        _y: &[f64],
        _h: f64,
        _w: &mut Work,
        _stats: &mut Stats,
    ) {
    }

    /// Component `i` of the state at t + theta h on the continuous extension of the step from
    /// y0: the scheme's one formula, which [`Stepper::eval`] and [`Stepper::eval_parts`] apply.
    fn eval_component(&self, y0: &[f64], w: &Work, h: f64, theta: f64, i: usize) -> f64;

    /// The state at t + theta h on the continuous extension of the step from y0.
    fn eval(&self, y0: &[f64], w: &Work, h: f64, theta: f64, out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.eval_component(y0, w, h, theta, i);
        }
    }

    /// [`Stepper::eval`] on the components in `parts` only, with the same values bit for bit
    /// (the same formula per component); the other components of `out` are left as they are.
    fn eval_parts(
        &self,
        y0: &[f64],
        w: &Work,
        h: f64,
        theta: f64,
        out: &mut [f64],
        parts: &[Range<usize>],
    ) {
        for part in parts {
            for i in part.clone() {
                out[i] = self.eval_component(y0, w, h, theta, i);
            }
        }
    }
}

/// `out = y + c k`, over slices cut to the length of `out` first: the loop then runs without
/// bounds checks and vectorised (the steppers' loops over their stage vectors themselves reloaded
/// the vectors' addresses for every component).
fn axpy(out: &mut [f64], y: &[f64], c: f64, k: &[f64]) {
    let n = out.len();
    for ((o, &yi), &ki) in out.iter_mut().zip(&y[..n]).zip(&k[..n]) {
        *o = yi + c * ki;
    }
}

fn error_norm(err: &[f64], y0: &[f64], y1: &[f64], rtol: f64, atol: f64) -> f64 {
    let mut s = 0.0;
    for i in 0..err.len() {
        let sc = atol + rtol * y0[i].abs().max(y1[i].abs());
        let r = err[i] / sc;
        s += r * r;
    }
    (s / err.len().max(1) as f64).sqrt()
}
