//! One flow interface that every analysis is written against, mechanisms and built-in systems
//! alike.
//!
//! A [`Flow`] is an [`OdeSystem`] with observables ([`Observed`]) that also knows its state's
//! names and units, its drive period, its integrator, its initial hybrid state, and how to take a
//! hybrid state as the start of the next advance (the mechanism loads the contact-onset history
//! and runs its guards on it). Sections ([`crate::measures::sections::trace`]), sweeps and continuation
//! ([`crate::study::analysis`]) and work-precision ([`crate::study::precision`]) take a flow, not a mechanism or
//! a system in particular: they call [`Flow::initial_state`], [`Flow::prepare`] and
//! [`jointplay_solver::ode::advance`] and read [`Flow::warnings`].
//!
//! A parameter is set by path on the flow's source, not on the compiled flow: a study edits the
//! scene or system table by path (`joints.S2.clearance.radial_clearance`,
//! [`crate::study::analysis::load::Loaded::target_with`]) and compiles a new [`Target`], whose
//! [`Target::flow`] runs it; the model stays immutable while it runs.
//!
//! [`MechFlow`] and [`SysFlow`] are the two flows; [`AnyFlow`] holds either, so an analysis is
//! compiled once (static dispatch, no cost per right-hand-side evaluation beyond a match).

pub mod observe;
pub mod scratch;
pub mod summary;
pub mod systems;
pub mod tangent;

use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::{Events, Method, OdeSystem, Stiffness};
use jointplay_solver::state::HybridState;

use crate::Result;
use crate::flow::observe::Observable;
use crate::flow::observe::Observed;
use crate::flow::systems::{Builtin, SystemSpec};

/// What every analysis needs of a flow beyond its right-hand side and observables.
pub trait Flow: Observed {
    /// Names of the components of the continuous state.
    fn state_names(&self) -> Vec<String>;
    /// SI units of the components of the continuous state.
    fn state_units(&self) -> Vec<String>;
    /// Units of the observables, in their order.
    fn observable_units(&self) -> Vec<String>;
    /// The period the analysis strobes at (s): the drive period, or the study's own.
    fn period(&self) -> f64;
    /// The integration method and its accuracy settings.
    fn method(&self) -> Method;
    /// The start time of the flow (s).
    fn start_time(&self) -> f64;
    /// The flow's initial hybrid state at its start time, with no memory: the declared state, or
    /// `y` when given (a continuation hands over the previous value's final state); a mechanism
    /// assembles it onto its constraints.
    fn initial_state(&self, y: Option<&[f64]>) -> Result<HybridState>;
    /// Takes `state` as the start of the next advance: loads its memory (contact-onset history,
    /// guard flags) and runs the guards on it; an error when the state does not fit the flow or a
    /// guard refuses it.
    fn prepare(&mut self, state: &HybridState) -> Result<()>;
    /// Warnings found when the flow was compiled (a scene's law used outside its range), one
    /// line each.
    fn compile_warnings(&self) -> Vec<String>;
    /// Warnings raised while running (the step-size guard's), one line each.
    fn warnings(&self) -> Vec<String>;
}

/// A compiled flow with its observables: what a study, a sweep value or a work-precision study
/// runs. [`Target::flow`] gives the [`Flow`] that advances it.
pub enum Target {
    Scene {
        model: Box<Model>,
        state: State,
        obs: Vec<Observable>,
        period: f64,
    },
    System {
        sys: SystemSpec,
        obs: Vec<Observable>,
        period: f64,
    },
}

/// A mechanism as a flow: the model's right-hand side and guards ([`Mechanism`]) with the
/// observables of a study.
pub struct MechFlow<'m> {
    pub mech: Mechanism<'m>,
    pub obs: &'m [Observable],
    /// Some observable needs the accelerations (a full evaluation), not the kinematics alone.
    pub dynamics: bool,
    /// The declared initial state (assembled by [`Flow::initial_state`]).
    start: &'m State,
    period: f64,
    /// Scratch of the tangent dynamics ([`crate::flow::tangent`]), made on first use.
    pub(crate) tangent: Option<Box<crate::flow::scratch::MechTangent>>,
}

impl OdeSystem for MechFlow<'_> {
    fn dim(&self) -> usize {
        self.mech.dim()
    }
    fn rhs(&mut self, t: f64, y: &[f64], d: &mut [f64]) {
        self.mech.rhs(t, y, d)
    }
    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        self.mech.step_accepted(t0, y0, t1, y1)
    }
    fn check_step(&mut self, t: f64, y: &[f64]) -> Option<String> {
        self.mech.check_step(t, y)
    }
    fn explain_non_finite(&mut self, t: f64, y: &[f64], component: usize) -> String {
        self.mech.explain_non_finite(t, y, component)
    }
    fn load_memory(&mut self, state: &HybridState) -> jointplay_solver::Result<()> {
        self.mech.load_memory(state)
    }
    fn save_memory(&self, state: &mut HybridState) {
        self.mech.save_memory(state)
    }
    fn events(&mut self) -> Option<&mut dyn Events> {
        self.mech.events()
    }
    fn stiffness(&mut self) -> Option<&mut dyn Stiffness> {
        self.mech.stiffness()
    }
}

impl Observed for MechFlow<'_> {
    fn n_obs(&self) -> usize {
        self.obs.len()
    }
    fn observe(&mut self, t: f64, y: &[f64], out: &mut [f64]) {
        let m = self.mech.model;
        if self.dynamics {
            m.accelerations(t, y, &mut self.mech.ws);
        } else {
            m.kinematics(y, &mut self.mech.ws);
        }
        for (o, v) in self.obs.iter().zip(out) {
            *v = o.eval_model(m, &self.mech.ws, t, y);
        }
    }
    fn obs_name(&self, i: usize) -> String {
        self.obs[i].path.clone()
    }
    fn observe_only(&mut self, t: f64, y: &[f64], which: &[usize], out: &mut [f64]) {
        // A full model evaluation only when one of these observables needs it: a section on
        // positions or velocities costs the kinematics alone.
        let m = self.mech.model;
        if which.iter().any(|&i| self.obs[i].needs_dynamics()) {
            m.accelerations(t, y, &mut self.mech.ws);
        } else {
            m.kinematics(y, &mut self.mech.ws);
        }
        for &i in which {
            out[i] = self.obs[i].eval_model(m, &self.mech.ws, t, y);
        }
    }
}

/// A built-in reference system as a flow.
pub struct SysFlow<'a> {
    pub sys: Builtin,
    pub obs: &'a [Observable],
    spec: &'a SystemSpec,
    period: f64,
}

impl OdeSystem for SysFlow<'_> {
    fn dim(&self) -> usize {
        self.sys.dim()
    }
    fn rhs(&mut self, t: f64, y: &[f64], d: &mut [f64]) {
        self.sys.rhs(t, y, d)
    }
    fn events(&mut self) -> Option<&mut dyn Events> {
        self.sys.events()
    }
}

impl Observed for SysFlow<'_> {
    fn n_obs(&self) -> usize {
        self.obs.len()
    }
    fn observe(&mut self, _t: f64, y: &[f64], out: &mut [f64]) {
        for (o, v) in self.obs.iter().zip(out) {
            *v = o.eval_system(y);
        }
    }
    fn obs_name(&self, i: usize) -> String {
        self.obs[i].path.clone()
    }
}

impl<'m> MechFlow<'m> {
    /// The flow of `model` from its declared state `start`, with observables `obs`, strobed at
    /// `period`.
    pub fn new(model: &'m Model, start: &'m State, obs: &'m [Observable], period: f64) -> Self {
        MechFlow {
            mech: Mechanism::new(model),
            dynamics: obs.iter().any(|o| o.needs_dynamics()),
            obs,
            start,
            period,
            tangent: None,
        }
    }

    /// Free degrees of freedom at the declared start (what `jointplay check` prints).
    pub fn remaining_dof(&self) -> usize {
        // The start was assembled when the flow was built, which refuses a state whose rank
        // analysis cannot be done; every velocity coordinate is the bound otherwise.
        let m = self.mech.model;
        m.structure(self.start.t, &self.start.y)
            .map_or(6 * m.nb(), |s| s.remaining_dof)
    }
}

impl Flow for MechFlow<'_> {
    fn state_names(&self) -> Vec<String> {
        let m = self.mech.model;
        let mut v = Vec::with_capacity(self.dim());
        for b in &m.bodies {
            for c in ["x", "y", "z", "q0", "q1", "q2", "q3"] {
                v.push(format!("{}.{c}", b.name));
            }
        }
        for b in &m.bodies {
            for c in ["vx", "vy", "vz", "wx", "wy", "wz"] {
                v.push(format!("{}.{c}", b.name));
            }
        }
        v.extend(m.bristle_names());
        v
    }
    fn state_units(&self) -> Vec<String> {
        let nb = self.mech.model.nb();
        let pos = ["m", "m", "m", "1", "1", "1", "1"];
        let vel = ["m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s"];
        let p = pos.iter().cycle().take(7 * nb);
        let v = vel.iter().cycle().take(6 * nb);
        let z = std::iter::repeat_n(&"m", self.mech.model.n_bristle);
        p.chain(v).chain(z).map(|u| u.to_string()).collect()
    }
    fn observable_units(&self) -> Vec<String> {
        self.obs.iter().map(|o| o.unit.clone()).collect()
    }
    fn period(&self) -> f64 {
        self.period
    }
    fn method(&self) -> Method {
        self.mech.model.settings.method
    }
    fn start_time(&self) -> f64 {
        self.start.t
    }
    fn initial_state(&self, y: Option<&[f64]>) -> Result<HybridState> {
        let mut state = self.start.clone();
        if let Some(y) = y {
            state.y.copy_from_slice(y);
        }
        self.mech.model.assemble(&mut state)?;
        Ok(HybridState::new(state.t, state.y))
    }
    fn prepare(&mut self, state: &HybridState) -> Result<()> {
        self.mech.load_memory(state)?;
        self.mech.check_initial(state.t, &state.y)?;
        Ok(())
    }
    fn compile_warnings(&self) -> Vec<String> {
        self.mech.model.warnings.clone()
    }
    fn warnings(&self) -> Vec<String> {
        self.mech
            .warnings
            .iter()
            .map(|w| w.message.clone())
            .collect()
    }
}

impl<'a> SysFlow<'a> {
    /// The flow of the built-in system `spec` with observables `obs`, strobed at `period`.
    pub fn new(spec: &'a SystemSpec, obs: &'a [Observable], period: f64) -> Self {
        SysFlow {
            sys: spec.builtin,
            obs,
            spec,
            period,
        }
    }
}

impl Flow for SysFlow<'_> {
    fn state_names(&self) -> Vec<String> {
        self.sys
            .state_names()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }
    fn state_units(&self) -> Vec<String> {
        self.sys
            .state_names()
            .iter()
            .map(|s| self.sys.observable(s).map_or("1", |o| o.1).to_string())
            .collect()
    }
    fn observable_units(&self) -> Vec<String> {
        self.obs.iter().map(|o| o.unit.clone()).collect()
    }
    fn period(&self) -> f64 {
        self.period
    }
    fn method(&self) -> Method {
        self.spec.method
    }
    fn start_time(&self) -> f64 {
        self.spec.start_time
    }
    fn initial_state(&self, y: Option<&[f64]>) -> Result<HybridState> {
        let y = y.map_or_else(|| self.spec.initial.clone(), <[f64]>::to_vec);
        Ok(HybridState::new(self.spec.start_time, y))
    }
    fn prepare(&mut self, state: &HybridState) -> Result<()> {
        self.load_memory(state)?;
        Ok(())
    }
    fn compile_warnings(&self) -> Vec<String> {
        Vec::new()
    }
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
}

/// Either flow, for analyses compiled once for both.
pub enum AnyFlow<'a> {
    /// Boxed: a mechanism's flow carries its workspace, a system's a few numbers.
    Mechanism(Box<MechFlow<'a>>),
    System(SysFlow<'a>),
}

/// Forwards a method to the flow inside an [`AnyFlow`].
macro_rules! either {
    ($self:expr, $f:ident => $e:expr) => {
        match $self {
            AnyFlow::Mechanism($f) => $e,
            AnyFlow::System($f) => $e,
        }
    };
}
pub(crate) use either;

impl OdeSystem for AnyFlow<'_> {
    fn dim(&self) -> usize {
        either!(self, f => f.dim())
    }
    fn rhs(&mut self, t: f64, y: &[f64], d: &mut [f64]) {
        either!(self, f => f.rhs(t, y, d))
    }
    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        either!(self, f => f.step_accepted(t0, y0, t1, y1))
    }
    fn check_step(&mut self, t: f64, y: &[f64]) -> Option<String> {
        either!(self, f => f.check_step(t, y))
    }
    fn explain_non_finite(&mut self, t: f64, y: &[f64], component: usize) -> String {
        either!(self, f => f.explain_non_finite(t, y, component))
    }
    fn load_memory(&mut self, state: &HybridState) -> jointplay_solver::Result<()> {
        either!(self, f => f.load_memory(state))
    }
    fn save_memory(&self, state: &mut HybridState) {
        either!(self, f => f.save_memory(state))
    }
    fn events(&mut self) -> Option<&mut dyn Events> {
        either!(self, f => f.events())
    }
    fn stiffness(&mut self) -> Option<&mut dyn Stiffness> {
        either!(self, f => f.stiffness())
    }
}

impl Observed for AnyFlow<'_> {
    fn n_obs(&self) -> usize {
        either!(self, f => f.n_obs())
    }
    fn observe(&mut self, t: f64, y: &[f64], out: &mut [f64]) {
        either!(self, f => f.observe(t, y, out))
    }
    fn obs_name(&self, i: usize) -> String {
        either!(self, f => f.obs_name(i))
    }
    fn observe_only(&mut self, t: f64, y: &[f64], which: &[usize], out: &mut [f64]) {
        either!(self, f => f.observe_only(t, y, which, out))
    }
}

impl Flow for AnyFlow<'_> {
    fn state_names(&self) -> Vec<String> {
        either!(self, f => f.state_names())
    }
    fn state_units(&self) -> Vec<String> {
        either!(self, f => f.state_units())
    }
    fn observable_units(&self) -> Vec<String> {
        either!(self, f => f.observable_units())
    }
    fn period(&self) -> f64 {
        either!(self, f => f.period())
    }
    fn method(&self) -> Method {
        either!(self, f => f.method())
    }
    fn start_time(&self) -> f64 {
        either!(self, f => f.start_time())
    }
    fn initial_state(&self, y: Option<&[f64]>) -> Result<HybridState> {
        either!(self, f => f.initial_state(y))
    }
    fn prepare(&mut self, state: &HybridState) -> Result<()> {
        either!(self, f => f.prepare(state))
    }
    fn compile_warnings(&self) -> Vec<String> {
        either!(self, f => f.compile_warnings())
    }
    fn warnings(&self) -> Vec<String> {
        either!(self, f => f.warnings())
    }
}

impl Target {
    /// The flow that runs this target.
    pub fn flow(&self) -> AnyFlow<'_> {
        match self {
            Target::Scene {
                model,
                state,
                obs,
                period,
            } => AnyFlow::Mechanism(Box::new(MechFlow::new(model, state, obs, *period))),
            Target::System { sys, obs, period } => AnyFlow::System(SysFlow::new(sys, obs, *period)),
        }
    }

    /// Runs the target with `method` from now on (work-precision compares methods on one flow).
    pub fn set_method(&mut self, method: Method) {
        match self {
            Target::Scene { model, .. } => model.settings.method = method,
            Target::System { sys, .. } => sys.method = method,
        }
    }

    /// The method the target runs with (without building its flow).
    pub fn method(&self) -> Method {
        match self {
            Target::Scene { model, .. } => model.settings.method,
            Target::System { sys, .. } => sys.method,
        }
    }

    /// The observables of the target.
    pub fn observables(&self) -> &[Observable] {
        match self {
            Target::Scene { obs, .. } | Target::System { obs, .. } => obs,
        }
    }
}
