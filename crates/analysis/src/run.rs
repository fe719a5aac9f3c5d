//! Simulation runs with recording.
//!
//! [`simulate`] assembles the initial state, integrates from the scene's start to its end time and,
//! at every sample time (evaluated on the integrator's dense output, so exactly at
//! `t0 + k * interval`), evaluates the model once more to record accelerations, joint reactions,
//! actuator forces and the diagnostics. A non-finite recorded value stops the run with an error
//! naming the time and the quantity: nothing non-finite is ever recorded.
//!
//! A run that diverges (the guards of [`jointplay_solver::guard`], a non-finite state, a
//! non-finite recorded value) keeps every sample recorded before the failure:
//! [`RunResult::stopped`] says where and why, and the file written from it is marked incomplete.
//!
//! Every run ends with its hybrid state ([`RunResult::final_state`]: the continuous state with
//! the contact-onset history, the guard's flags and the integrator's memory), written to the run
//! file ([`crate::hybrid`]). [`resume`] continues a run from such a state to the scene's end
//! time, without assembling it again: a run of 2T and a run of T continued for T from its file
//! are the same run, bit for bit when T lies on a fixed-step method's grid.

use jointplay_solver::clearance::Geometry;
use jointplay_solver::dynamics::{AssemblyReport, Mechanism};
use jointplay_solver::guard::Warning;
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::{Flow, OdeSystem, Stats, advance};
use jointplay_solver::scene::DriveCoordinate;
use jointplay_solver::state::HybridState;

use crate::Result;

/// Time histories of one body (global axes; per sample).
#[derive(Debug, Clone, Default)]
pub struct BodyTrack {
    pub name: String,
    /// Centre-of-mass position (m).
    pub position: Vec<[f64; 3]>,
    /// Euler parameters (w, x, y, z), body to global, unit norm.
    pub orientation: Vec<[f64; 4]>,
    /// m/s.
    pub velocity: Vec<[f64; 3]>,
    /// rad/s.
    pub angular_velocity: Vec<[f64; 3]>,
    /// m/s^2 (empty when accelerations are not recorded).
    pub acceleration: Vec<[f64; 3]>,
    /// rad/s^2.
    pub angular_acceleration: Vec<[f64; 3]>,
}

/// Reaction of one ideal joint on its body b, torque about the joint point on b.
#[derive(Debug, Clone, Default)]
pub struct JointTrack {
    pub name: String,
    /// N.
    pub force: Vec<[f64; 3]>,
    /// N m.
    pub torque: Vec<[f64; 3]>,
}

/// One joint with clearance (per sample; per-contact arrays hold `contacts.len()` values per
/// sample, in the order of `contacts`).
#[derive(Debug, Clone, Default)]
pub struct ClearanceTrack {
    pub name: String,
    /// Contact names: "radial" (spherical, planar) or P, Q (rims), M, N (faces).
    pub contacts: Vec<String>,
    /// Journal centre relative to the housing centre, housing axes (m).
    pub eccentricity: Vec<[f64; 3]>,
    /// The same in global axes (m).
    pub eccentricity_global: Vec<[f64; 3]>,
    /// Eccentricity components in the plane normal to the housing axis (m), along the joint
    /// frame's u and w directions: the orbit of the journal centre.
    pub radial_eccentricity: Vec<[f64; 2]>,
    /// Spatial revolute: the journal axis at the two rim planes (P side u, w, Q side u, w) in the
    /// same axes (m): the orbits of both journal ends. Empty for other joints.
    pub end_eccentricity: Vec<[f64; 4]>,
    /// m, m/s, N, N per contact.
    pub penetration: Vec<f64>,
    pub penetration_rate: Vec<f64>,
    pub normal_force: Vec<f64>,
    pub friction_force: Vec<f64>,
    /// 1 in contact, 0 free, per contact.
    pub state: Vec<u8>,
    /// Resultant force (N) and moment about the centre of mass (N m) on journal and housing.
    pub force_journal: Vec<[f64; 3]>,
    pub moment_journal: Vec<[f64; 3]>,
    pub force_housing: Vec<[f64; 3]>,
    pub moment_housing: Vec<[f64; 3]>,
    /// The clearance (m): radial clearance for the orbit figure.
    pub radial_clearance: f64,
    /// A spherical joint: its orbit is three-dimensional (the eccentricity), not a plane one.
    pub spherical: bool,
}

/// One drive: its coordinate and actuator effort.
#[derive(Debug, Clone, Default)]
pub struct DriveTrack {
    pub name: String,
    pub rotational: bool,
    /// m or rad.
    pub coordinate: Vec<f64>,
    /// N or N m.
    pub force: Vec<f64>,
}

/// Constraint and energy diagnostics per sample.
#[derive(Debug, Clone, Default)]
pub struct Diagnostics {
    /// 2-norm of the position constraint residuals (m and rad mixed).
    pub constraint_drift: Vec<f64>,
    /// 2-norm of the velocity constraint residuals (m/s and rad/s mixed).
    pub velocity_drift: Vec<f64>,
    /// Kinetic + gravitational + spring energy (J); empty when energy is not recorded.
    pub energy: Vec<f64>,
}

/// Everything one run recorded.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// s.
    pub time: Vec<f64>,
    pub bodies: Vec<BodyTrack>,
    pub joints: Vec<JointTrack>,
    pub drives: Vec<DriveTrack>,
    pub clearances: Vec<ClearanceTrack>,
    pub diagnostics: Option<Diagnostics>,
}

impl Recording {
    /// Keeps the first `n` samples of every series (per-contact series keep `n` times their
    /// number of contacts).
    fn truncate(&mut self, n: usize) {
        self.time.truncate(n);
        for b in &mut self.bodies {
            b.position.truncate(n);
            b.orientation.truncate(n);
            b.velocity.truncate(n);
            b.angular_velocity.truncate(n);
            b.acceleration.truncate(n);
            b.angular_acceleration.truncate(n);
        }
        for j in &mut self.joints {
            j.force.truncate(n);
            j.torque.truncate(n);
        }
        for d in &mut self.drives {
            d.coordinate.truncate(n);
            d.force.truncate(n);
        }
        for c in &mut self.clearances {
            let k = n * c.contacts.len();
            c.eccentricity.truncate(n);
            c.eccentricity_global.truncate(n);
            c.radial_eccentricity.truncate(n);
            c.end_eccentricity.truncate(n);
            c.penetration.truncate(k);
            c.penetration_rate.truncate(k);
            c.normal_force.truncate(k);
            c.friction_force.truncate(k);
            c.state.truncate(k);
            c.force_journal.truncate(n);
            c.moment_journal.truncate(n);
            c.force_housing.truncate(n);
            c.moment_housing.truncate(n);
        }
        if let Some(d) = &mut self.diagnostics {
            d.constraint_drift.truncate(n);
            d.velocity_drift.truncate(n);
            d.energy.truncate(n);
        }
    }
}

/// Where and why a run stopped before its end time.
#[derive(Debug, Clone, PartialEq)]
pub struct Stopped {
    /// Simulated time of the failure (s).
    pub time: f64,
    /// What failed (the joint or quantity, and its value).
    pub message: String,
}

impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "integration stopped at t = {} s: {}",
            self.time, self.message
        )
    }
}

impl Stopped {
    fn from_error(e: &jointplay_solver::Error, fallback_time: f64) -> Stopped {
        match e {
            jointplay_solver::Error::Diverged { time, message } => Stopped {
                time: *time,
                message: message.clone(),
            },
            other => Stopped {
                time: fallback_time,
                message: other.to_string(),
            },
        }
    }
}

/// A run, finished or stopped by a failure after the initial assembly.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// Every sample recorded (up to the failure, when the run stopped).
    pub recording: Recording,
    pub stats: Stats,
    pub assembly: AssemblyReport,
    /// The hybrid state at the end time; for a run that stopped, the last accepted state at or
    /// before the failure (with its own time, which [`RunResult::stopped`] may exceed).
    pub final_state: HybridState,
    /// Warnings of the step-size guard.
    pub warnings: Vec<Warning>,
    /// Set when the run stopped before its end time.
    pub stopped: Option<Stopped>,
}

impl RunResult {
    /// The run as a `Result`: an error when it stopped before its end time.
    pub fn finished(self) -> Result<RunResult> {
        match &self.stopped {
            None => Ok(self),
            Some(s) => Err(jointplay_solver::Error::Diverged {
                time: s.time,
                message: s.message.clone(),
            }
            .into()),
        }
    }
}

fn finite3(v: &[f64; 3], what: &str, t: f64) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(jointplay_solver::Error::Diverged {
            time: t,
            message: format!("{what} became non-finite"),
        }
        .into())
    }
}

/// Simulates `model` from `state` (assembled first) and records its outputs.
/// `progress` receives the fraction of the span done after every sample. Errors only when the
/// initial state cannot be assembled; a failure later returns what was recorded, with
/// [`RunResult::stopped`] set.
pub fn simulate(
    model: &Model,
    mut state: State,
    progress: &mut dyn FnMut(f64),
) -> Result<RunResult> {
    let assembly = model.assemble(&mut state)?;
    record(
        model,
        HybridState::new(state.t, state.y),
        assembly,
        progress,
    )
}

/// Continues a run from `state` (the final state of an earlier run of the same model, as
/// [`crate::hybrid::read_state`] reads it from its file) to the scene's end time, with its
/// contact-onset history, guard flags and integrator memory, and records the samples of the
/// scene's output grid from the state's time on. The state is not assembled again (that would
/// move it); the assembly report gives its constraint residuals instead. An error when the
/// state does not fit the model or lies at or after the end time.
pub fn resume(
    model: &Model,
    state: HybridState,
    progress: &mut dyn FnMut(f64),
) -> Result<RunResult> {
    let mut sys = Mechanism::new(model);
    sys.load_memory(&state)?;
    let t1 = model.settings.end_time;
    if !state.t.is_finite() || state.t >= t1 || !state.y.iter().all(|v| v.is_finite()) {
        return Err(jointplay_solver::Error::Invalid {
            file: model.file.clone(),
            field: "state".into(),
            message: format!(
                "cannot continue from the state at t = {} s: it must be finite and before the \
                 scene's end time {t1} s",
                state.t
            ),
        }
        .into());
    }
    model.drift(state.t, &state.y, &mut sys.ws);
    let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (p, v) = (max(&sys.ws.phi), max(&sys.ws.phi_dot));
    let assembly = AssemblyReport {
        iterations: 0,
        initial_residual: p,
        final_residual: p,
        initial_velocity_residual: v,
        final_velocity_residual: v,
    };
    record(model, state, assembly, progress)
}

/// Integrates `model` from the hybrid state `state` to the end time and records the outputs at
/// the sample times from `state.t` on.
fn record(
    model: &Model,
    mut state: HybridState,
    assembly: AssemblyReport,
    progress: &mut dyn FnMut(f64),
) -> Result<RunResult> {
    let mut samples = model.sample_times();
    samples.retain(|&t| t >= state.t);
    let out = &model.outputs;
    let mut rec = Recording {
        time: Vec::with_capacity(samples.len()),
        bodies: out
            .bodies
            .iter()
            .map(|&b| BodyTrack {
                name: model.bodies[b].name.clone(),
                ..Default::default()
            })
            .collect(),
        joints: out
            .joints
            .iter()
            .filter(|&&j| !model.joints[j].rows.is_empty())
            .map(|&j| JointTrack {
                name: model.joints[j].name.clone(),
                ..Default::default()
            })
            .collect(),
        drives: out
            .drives
            .iter()
            .map(|&d| DriveTrack {
                name: model.drives[d].name.clone(),
                rotational: model.drives[d].coordinate == DriveCoordinate::Rotation,
                ..Default::default()
            })
            .collect(),
        clearances: out
            .joints
            .iter()
            .filter_map(|&j| model.joints[j].clearance)
            .map(|c| {
                let cl = &model.clearances[c];
                ClearanceTrack {
                    name: cl.name.clone(),
                    contacts: cl
                        .geometry
                        .contact_names()
                        .iter()
                        .map(|s| s.to_string())
                        .collect(),
                    radial_clearance: cl.geometry.radial_clearance(),
                    spherical: matches!(cl.geometry, Geometry::Spherical { .. }),
                    ..Default::default()
                }
            })
            .collect(),
        diagnostics: out.diagnostics.then(Diagnostics::default),
    };
    let ideal_joints: Vec<usize> = out
        .joints
        .iter()
        .copied()
        .filter(|&j| !model.joints[j].rows.is_empty())
        .collect();
    let clearance_ids: Vec<usize> = out
        .joints
        .iter()
        .filter_map(|&j| model.joints[j].clearance)
        .collect();
    let np = model.n_pos();
    let (t0, t1) = (state.t, model.settings.end_time);
    let mut failure = None;
    // Outputs are evaluated with the system's own workspace, so that they see its contact history.
    let mut observe = |sys: &mut Mechanism, t: f64, y: &[f64]| -> Result<()> {
        let ws = &mut sys.ws;
        model.accelerations(t, y, ws);
        rec.time.push(t);
        for (tr, &b) in rec.bodies.iter_mut().zip(&out.bodies) {
            let p = &y[7 * b..7 * b + 7];
            let n = (p[3] * p[3] + p[4] * p[4] + p[5] * p[5] + p[6] * p[6]).sqrt();
            let v = &y[np + 6 * b..np + 6 * b + 6];
            tr.position.push([p[0], p[1], p[2]]);
            tr.orientation
                .push([p[3] / n, p[4] / n, p[5] / n, p[6] / n]);
            tr.velocity.push([v[0], v[1], v[2]]);
            tr.angular_velocity.push([v[3], v[4], v[5]]);
            if out.accelerations {
                let a = &ws.acc[b];
                let lin = [a[0], a[1], a[2]];
                let ang = [a[3], a[4], a[5]];
                finite3(&lin, &format!("acceleration of body '{}'", tr.name), t)?;
                finite3(
                    &ang,
                    &format!("angular acceleration of body '{}'", tr.name),
                    t,
                )?;
                tr.acceleration.push(lin);
                tr.angular_acceleration.push(ang);
            }
        }
        for (tr, &j) in rec.joints.iter_mut().zip(&ideal_joints) {
            let (f, n) = model.reaction(j, ws);
            let (f, n) = ([f.x, f.y, f.z], [n.x, n.y, n.z]);
            finite3(&f, &format!("reaction force of joint '{}'", tr.name), t)?;
            finite3(&n, &format!("reaction torque of joint '{}'", tr.name), t)?;
            tr.force.push(f);
            tr.torque.push(n);
        }
        for (tr, &d) in rec.drives.iter_mut().zip(&out.drives) {
            let f = model.actuator_force(d, ws);
            let c = model.drive_coordinate(d, t, ws);
            finite3(&[f, c, 0.0], &format!("force of drive '{}'", tr.name), t)?;
            tr.force.push(f);
            tr.coordinate.push(c);
        }
        // Contact data of this evaluation (read before drift and energy reuse the scratch).
        for (tr, &c) in rec.clearances.iter_mut().zip(&clearance_ids) {
            let cl = &model.clearances[c];
            let (kh, kj) = (
                model.kinematics_of(cl.housing, ws),
                model.kinematics_of(cl.journal, ws),
            );
            let e = cl.eccentricity(&kh, &kj);
            let el = kh.rot.transpose() * e;
            let (u, w) = cl.radial_axes();
            tr.eccentricity.push([el.x, el.y, el.z]);
            tr.eccentricity_global.push([e.x, e.y, e.z]);
            tr.radial_eccentricity.push([el.dot(&u), el.dot(&w)]);
            if let Some([p, q]) = cl.end_offsets(&kh, &kj) {
                tr.end_eccentricity.push([p[0], p[1], q[0], q[1]]);
            }
            for ce in &ws.contacts[cl.first..cl.first + cl.geometry.n_contacts()] {
                tr.penetration.push(ce.delta);
                tr.penetration_rate.push(ce.delta_dot);
                tr.normal_force.push(ce.fn_);
                tr.friction_force.push(ce.ft.norm());
                tr.state.push(u8::from(ce.active()));
            }
            let r = &ws.resultants[c];
            let v = |x: nalgebra::Vector3<f64>| [x.x, x.y, x.z];
            for (a, what) in [
                (&r.force_j, "force"),
                (&r.moment_j, "moment"),
                (&r.force_h, "force"),
                (&r.moment_h, "moment"),
            ] {
                finite3(
                    &v(*a),
                    &format!("contact {what} of clearance joint '{}'", tr.name),
                    t,
                )?;
            }
            tr.force_journal.push(v(r.force_j));
            tr.moment_journal.push(v(r.moment_j));
            tr.force_housing.push(v(r.force_h));
            tr.moment_housing.push(v(r.moment_h));
        }
        if let Some(diag) = rec.diagnostics.as_mut() {
            let (p, v) = model.drift(t, y, ws);
            let e = if model.outputs.energy {
                model.energy(y, ws)
            } else {
                0.0
            };
            finite3(&[p, v, e], "constraint drift or energy", t)?;
            diag.constraint_drift.push(p);
            diag.velocity_drift.push(v);
            if model.outputs.energy {
                diag.energy.push(e);
            }
        }
        progress((t - t0) / (t1 - t0));
        Ok(())
    };
    let mut sys = Mechanism::new(model);
    let checked = sys
        .load_memory(&state)
        .and_then(|()| sys.check_initial(t0, &state.y));
    let (stats, res) = match checked {
        Err(e) => (Stats::default(), Err(e)),
        Ok(()) => advance(
            &mut sys,
            model.settings.method,
            &mut state,
            t1,
            &samples,
            |sys, t, y| match observe(sys, t, y) {
                Ok(()) => Flow::Continue,
                Err(e) => {
                    failure = Some(e);
                    Flow::Stop
                }
            },
            None,
        ),
    };
    let stopped = match (failure, res) {
        (Some(e), _) => {
            // The failed sample may be partly recorded: keep only the complete ones.
            let t_fail = rec.time.last().copied().unwrap_or(t0);
            let n = rec.time.len().saturating_sub(1);
            rec.truncate(n);
            Some(match &e {
                crate::Error::Solver(se) => Stopped::from_error(se, t_fail),
                other => Stopped {
                    time: t_fail,
                    message: other.to_string(),
                },
            })
        }
        (None, Err(e)) => Some(Stopped::from_error(&e, t0)),
        (None, Ok(())) => None,
    };
    Ok(RunResult {
        recording: rec,
        stats,
        assembly,
        final_state: state,
        warnings: sys.warnings,
        stopped,
    })
}
