//! What a run records, as data: one [`Channel`] per dataset of the run file, whose columns are
//! observables of [`crate::flow::observe`] (`bodies.B.position.x`, `.y`, `.z` for
//! `/bodies/B/position`), declared once from the model ([`Recording::of`]); the finished or
//! stopped run ([`RunResult`], [`Stopped`]); and which datasets a run written while it goes
//! keeps in memory for its figures ([`drawn`]). The run file is written from them by
//! [`crate::storage::run_file`]; runs are made by [`crate::study::run`].

use jointplay_solver::clearance::Geometry;
use jointplay_solver::dynamics::{AssemblyReport, Workspace};
use jointplay_solver::guard::Warning;
use jointplay_solver::model::Model;
use jointplay_solver::ode::Stats;
use jointplay_solver::state::HybridState;

use crate::Result;
use crate::flow::observe::Observable;

/// One recorded dataset: the observables of one path (see [`crate::flow::observe`]), one per column,
/// evaluated at every sample.
#[derive(Debug, Clone)]
pub struct Channel {
    /// Where it is written in the run's group: the columns' observable path without the
    /// component, `/` for `.` (`bodies.B.position.x`, `.y`, `.z`: `bodies/B/position`).
    pub dataset: String,
    /// The columns' common unit.
    pub unit: String,
    pub description: String,
    pub columns: Vec<Observable>,
    /// Written as a one-dimensional dataset: one column whose path has no component.
    pub scalar: bool,
    /// Written as u8: 1 or 0.
    pub flag: bool,
    /// The quantity named when one of its values is not finite; `None`: not checked (a state
    /// component, which the integrator checks, or a quantity of it).
    pub checked: Option<String>,
    /// The values, `columns.len()` per sample, sample by sample.
    pub values: Vec<f64>,
    /// Mantissa bits its values keep in the file (`output.significant_bits` of its quantity, see
    /// [`crate::storage::bitround`]); `None`: all (and always for a flag). The values held here are never
    /// rounded.
    pub bits: Option<u32>,
    /// When its values are evaluated (and checked) in a sample: bodies, ideal joints, drives,
    /// clearance joints, diagnostics (which evaluate in the workspace again, so last).
    pub(crate) stage: u8,
}

impl Channel {
    /// Values per sample.
    pub fn width(&self) -> usize {
        self.columns.len()
    }

    /// The samples' rows.
    pub fn rows(&self) -> std::slice::ChunksExact<'_, f64> {
        self.values.chunks_exact(self.width())
    }

    /// Column `k` over the samples.
    pub fn column(&self, k: usize) -> Vec<f64> {
        self.rows().map(|r| r[k]).collect()
    }

    /// The rows of a three-column dataset (a vector in global or housing axes).
    pub fn vectors(&self) -> Vec<[f64; 3]> {
        self.rows().map(|r| [r[0], r[1], r[2]]).collect()
    }
}

/// An attribute value of a group.
#[derive(Debug, Clone, PartialEq)]
pub enum Attr {
    Str(String),
    F64(f64),
}

/// A group of the run file, written even when it holds no dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Relative to the run's group, e.g. `joints/R1`.
    pub path: String,
    pub attrs: Vec<(String, Attr)>,
}

/// A recorded joint with clearance.
#[derive(Debug, Clone, PartialEq)]
pub struct Clearance {
    pub name: String,
    /// Contact names, in column order: "radial" (spherical, planar) or P, Q (rims), M, N (faces).
    pub contacts: Vec<String>,
    /// The clearance (m): radial clearance for the orbit figure.
    pub radial_clearance: f64,
    /// A spherical joint: its orbit is three-dimensional (the eccentricity), not a plane one.
    pub spherical: bool,
    /// A slider in a guide: its offset across the guide is drawn against time, between the
    /// guide's faces, not as an orbit in a circle.
    pub translational: bool,
}

/// Everything one run recorded: the sample times and one [`Channel`] per dataset of the run file
/// (layout in book/src/reference/hdf5.md), in the order they are written.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// s.
    pub time: Vec<f64>,
    pub channels: Vec<Channel>,
    /// The groups, parents first, in the order they are written.
    pub groups: Vec<Group>,
    /// The recorded joints with clearance.
    pub clearances: Vec<Clearance>,
}

/// Declares the channels of a recording, group by group.
struct Declare<'m> {
    model: &'m Model,
    rec: Recording,
    pub(crate) stage: u8,
}

impl Declare<'_> {
    fn group(&mut self, path: String, attrs: Vec<(String, Attr)>) {
        self.rec.groups.push(Group { path, attrs });
    }

    /// A dataset of the observables `path.c` for each component `c` (`path` itself, as a
    /// one-dimensional dataset, when `comps` is empty).
    fn channel(
        &mut self,
        path: &str,
        comps: &[&str],
        description: &str,
        checked: Option<String>,
    ) -> Result<()> {
        let paths: Vec<String> = if comps.is_empty() {
            vec![path.to_string()]
        } else {
            comps.iter().map(|c| format!("{path}.{c}")).collect()
        };
        let columns = paths
            .iter()
            .map(|p| Observable::for_run(self.model, p))
            .collect::<std::result::Result<Vec<_>, _>>()
            .map_err(|message| jointplay_solver::Error::Invalid {
                file: self.model.file.clone(),
                field: "outputs".into(),
                message,
            })?;
        let unit = columns[0].unit.clone();
        debug_assert!(columns.iter().all(|o| o.unit == unit), "{path}");
        // The dataset is the path of a group member: kind, name, quantity (the name may hold dots).
        let name = &self
            .rec
            .groups
            .last()
            .map(|g| g.path.clone())
            .unwrap_or_default();
        let quantity = path.rsplit('.').next().unwrap_or(path);
        let flag = quantity == "contact_state";
        self.rec.channels.push(Channel {
            dataset: format!("{name}/{quantity}"),
            unit,
            description: description.to_string(),
            flag,
            bits: match flag {
                true => None,
                false => self.model.outputs.significant_bits.of(quantity),
            },
            scalar: comps.is_empty(),
            checked,
            values: Vec::new(),
            columns,
            stage: self.stage,
        });
        Ok(())
    }

    /// The channels of every recorded body: position, orientation, velocities and, when
    /// asked, accelerations (stage 0).
    fn bodies(&mut self) -> Result<()> {
        let model = self.model;
        let out = &model.outputs;
        self.group("bodies".into(), Vec::new());
        for &b in &out.bodies {
            let name = &model.bodies[b].name;
            let p = |q: &str| format!("bodies.{name}.{q}");
            self.group(format!("bodies/{name}"), Vec::new());
            self.channel(&p("position"), &XYZ, "centre of mass, global axes", None)?;
            self.channel(
                &p("orientation"),
                &["w", "x", "y", "z"],
                "Euler parameters (w, x, y, z) of the rotation body -> global",
                None,
            )?;
            self.channel(
                &p("velocity"),
                &XYZ,
                "centre-of-mass velocity, global axes",
                None,
            )?;
            self.channel(&p("angular_velocity"), &XYZ, "global axes", None)?;
            if out.accelerations {
                self.channel(
                    &p("acceleration"),
                    &XYZ,
                    "centre-of-mass acceleration, global axes",
                    Some(format!("acceleration of body '{name}'")),
                )?;
                self.channel(
                    &p("angular_acceleration"),
                    &XYZ,
                    "global axes",
                    Some(format!("angular acceleration of body '{name}'")),
                )?;
            }
        }
        Ok(())
    }

    /// The reaction force and torque of every recorded joint that keeps constraint rows
    /// (stage 1).
    fn joints(&mut self) -> Result<()> {
        let model = self.model;
        let out = &model.outputs;
        self.group("joints".into(), Vec::new());
        self.stage = 1;
        for &j in out
            .joints
            .iter()
            .filter(|&&j| !model.joints[j].rows.is_empty())
        {
            let name = &model.joints[j].name;
            let p = |q: &str| format!("joints.{name}.{q}");
            self.group(format!("joints/{name}"), Vec::new());
            self.channel(
                &p("reaction_force"),
                &XYZ,
                "force of the joint on its body_b, global axes",
                Some(format!("reaction force of joint '{name}'")),
            )?;
            self.channel(
                &p("reaction_torque"),
                &XYZ,
                "torque of the joint on its body_b about the joint point on body_b, global axes",
                Some(format!("reaction torque of joint '{name}'")),
            )?;
        }
        Ok(())
    }

    /// The groups and channels of every recorded joint with clearance (stage 3).
    fn clearances(&mut self) -> Result<()> {
        let model = self.model;
        let out = &model.outputs;
        self.stage = 3;
        for c in out.joints.iter().filter_map(|&j| model.joints[j].clearance) {
            self.clearance(c)?;
        }
        Ok(())
    }

    /// The group of clearance `c` (its contacts and radial clearance as attributes, added to the
    /// joint's group when it has one) and its channels: eccentricities, per-contact quantities,
    /// and the resultant contact forces and moments on journal and housing.
    fn clearance(&mut self, c: usize) -> Result<()> {
        let model = self.model;
        let cl = &model.clearances[c];
        let name = &cl.name;
        let contacts: Vec<&str> = cl.geometry.contact_names().to_vec();
        let attrs = vec![
            ("contacts".to_string(), Attr::Str(contacts.join(","))),
            (
                "radial_clearance".to_string(),
                Attr::F64(cl.geometry.radial_clearance()),
            ),
            ("radial_clearance_unit".to_string(), Attr::Str("m".into())),
        ];
        // A joint that keeps rows (a planar bearing's out-of-plane rows) has its group already.
        let path = format!("joints/{name}");
        match self.rec.groups.iter().position(|g| g.path == path) {
            Some(i) => {
                let g = self.rec.groups.remove(i);
                self.rec.groups.push(Group {
                    attrs: [g.attrs, attrs].concat(),
                    ..g
                });
            }
            None => self.group(path, attrs),
        }
        self.rec.clearances.push(Clearance {
            name: name.clone(),
            contacts: contacts.iter().map(|s| s.to_string()).collect(),
            radial_clearance: cl.geometry.radial_clearance(),
            spherical: matches!(cl.geometry, Geometry::Spherical { .. }),
            translational: matches!(cl.geometry, Geometry::Translational { .. }),
        });
        let p = |q: &str| format!("joints.{name}.{q}");
        self.channel(
            &p("eccentricity"),
            &XYZ,
            "journal centre relative to the housing centre, housing axes",
            None,
        )?;
        self.channel(
            &p("eccentricity_global"),
            &XYZ,
            "journal centre relative to the housing centre, global axes",
            None,
        )?;
        self.channel(
            &p("radial_eccentricity"),
            &["u", "w"],
            "eccentricity along the two housing directions normal to its axis (u, w): the journal-centre orbit",
            None,
        )?;
        self.channel(
            &p("radial_eccentricity_rate"),
            &["u", "w"],
            "rate of the radial eccentricity in the housing's axes (u, w): with it, the orbit's phase plane and its sections",
            None,
        )?;
        if matches!(cl.geometry, Geometry::Revolute { .. }) {
            self.channel(
                &p("end_eccentricity"),
                &["P_u", "P_w", "Q_u", "Q_w"],
                "journal axis at the rim planes s = +L_B/2 (u, w) and s = -L_B/2 (u, w): the orbits of both journal ends",
                None,
            )?;
        }
        let per = |what: &str| format!("{what}, one column per contact ({})", contacts.join(", "));
        for (q, what) in [
            ("penetration", "penetration, negative while apart"),
            ("penetration_rate", "penetration rate, approach positive"),
            ("normal_force", "normal contact force"),
            ("friction_force", "magnitude of the friction force"),
            ("contact_state", "1 in contact, 0 free"),
        ] {
            self.channel(&p(q), &contacts, &per(what), None)?;
        }
        if cl.bristle.is_some() {
            let columns: Vec<String> = contacts
                .iter()
                .flat_map(|k| ["x", "y", "z"].map(|a| format!("{k}_{a}")))
                .collect();
            let columns: Vec<&str> = columns.iter().map(|c| c.as_str()).collect();
            self.channel(
                &p("bristle"),
                &columns,
                "LuGre bristle deflection, housing axes, three columns per contact (contact_x, contact_y, contact_z)",
                None,
            )?;
        }
        for (q, what, desc) in [
            (
                "force_on_journal",
                "force",
                "resultant contact force on the journal body (body_b), global axes (an oil film's included)",
            ),
            (
                "moment_on_journal",
                "moment",
                "resultant contact moment on the journal body about its centre of mass, global axes",
            ),
            (
                "force_on_housing",
                "force",
                "resultant contact force on the housing body (body_a), global axes",
            ),
            (
                "moment_on_housing",
                "moment",
                "resultant contact moment on the housing body about its centre of mass, global axes",
            ),
        ] {
            self.channel(
                &p(q),
                &XYZ,
                desc,
                Some(format!("contact {what} of clearance joint '{name}'")),
            )?;
        }
        if cl.film.is_some() {
            self.channel(
                &p("film_force"),
                &XYZ,
                "oil-film force on the journal at its centre, global axes (part of force_on_journal)",
                Some(format!("film force of lubricated joint '{name}'")),
            )?;
        }
        Ok(())
    }

    /// The coordinate and force of every recorded drive (stage 2).
    fn drives(&mut self) -> Result<()> {
        let model = self.model;
        let out = &model.outputs;
        self.group("drives".into(), Vec::new());
        self.stage = 2;
        for &dr in &out.drives {
            let name = &model.drives[dr].name;
            let p = |q: &str| format!("drives.{name}.{q}");
            let checked = Some(format!("force of drive '{name}'"));
            self.group(format!("drives/{name}"), Vec::new());
            self.channel(&p("coordinate"), &[], "joint coordinate", checked.clone())?;
            self.channel(
                &p("force"),
                &[],
                "actuator force (torque) on body_b in the direction of increasing coordinate",
                checked,
            )?;
        }
        Ok(())
    }

    /// The constraint drifts and, when asked, the energy (stage 4), when diagnostics are
    /// recorded.
    fn diagnostics(&mut self) -> Result<()> {
        let model = self.model;
        let out = &model.outputs;
        if out.diagnostics {
            self.stage = 4;
            let checked = Some("constraint drift or energy".to_string());
            self.group("diagnostics".into(), Vec::new());
            self.channel(
                "diagnostics.constraint_drift",
                &[],
                "2-norm of the position constraint residuals",
                checked.clone(),
            )?;
            self.channel(
                "diagnostics.velocity_drift",
                &[],
                "2-norm of the velocity constraint residuals",
                checked.clone(),
            )?;
            if out.energy {
                self.channel(
                    "diagnostics.energy",
                    &[],
                    "kinetic + gravitational + spring energy",
                    checked,
                )?;
            }
        }
        Ok(())
    }
}

const XYZ: [&str; 3] = ["x", "y", "z"];

impl Recording {
    /// The channels of `model`'s outputs (which bodies, joints and drives, whether accelerations,
    /// diagnostics and energy), with no sample yet.
    pub fn of(model: &Model) -> Result<Recording> {
        let mut d = Declare {
            model,
            rec: Recording::default(),
            stage: 0,
        };
        d.bodies()?;
        d.joints()?;
        d.clearances()?;
        d.drives()?;
        d.diagnostics()?;
        Ok(d.rec)
    }

    /// The rows of the samples at the strobe times `t0 + phase + k period` (s), k = 0, 1, ...,
    /// for every such time up to the last sample, `t0` the first sample's time: a stroboscopic
    /// (Poincare) section of the recorded run, once per drive period. The number of strobe times
    /// is counted with a tolerance of 1e-9 periods, so that the last one, at the run's end,
    /// is kept even where rounding puts it a hair past the last sample; each is found among the
    /// samples (recorded every `interval` s, and at the end time) to 1e-6 of the interval. A
    /// strobe time that is not a sample time is an error that says which interval would make it
    /// one: the samples are values the run took, not interpolated ones.
    pub fn strobe_rows(
        &self,
        interval: f64,
        phase: f64,
        period: f64,
    ) -> std::result::Result<Vec<usize>, String> {
        if !(period.is_finite() && period > 0.0) {
            return Err(format!(
                "period: must be a positive number of seconds, not {period}"
            ));
        }
        if !(phase.is_finite() && phase >= 0.0) {
            return Err(format!(
                "phase: must be zero or a positive number of seconds, not {phase}"
            ));
        }
        let t = &self.time;
        let (Some(&t0), Some(&last)) = (t.first(), t.last()) else {
            return Ok(Vec::new());
        };
        let span = (last - t0 - phase) / period;
        if span < -1e-9 {
            return Ok(Vec::new());
        }
        let count = (span + 1e-9).floor() as usize + 1;
        let tol = 1e-6 * interval;
        let mut rows = Vec::with_capacity(count);
        for k in 0..count {
            let tk = t0 + phase + k as f64 * period;
            let grid = (((tk - t0) / interval).round().max(0.0) as usize).min(t.len() - 1);
            let row = [grid, t.len() - 1]
                .into_iter()
                .min_by(|&a, &b| (t[a] - tk).abs().total_cmp(&(t[b] - tk).abs()))
                .unwrap_or(grid);
            if (t[row] - tk).abs() > tol {
                let per = period / interval;
                return Err(format!(
                    "the strobe time {tk} s (k = {k}) is not a sample time: the run was sampled \
                     every {interval} s, {per} samples per period of {period} s{}; record with \
                     output.interval = {} s (the period over a whole number of samples) and the \
                     phase a multiple of it",
                    if phase > 0.0 {
                        format!(" and a phase of {phase} s")
                    } else {
                        String::new()
                    },
                    period / per.round().max(1.0)
                ));
            }
            rows.push(row);
        }
        Ok(rows)
    }

    /// The fewest mantissa bits any channel keeps in the file ([`Channel::bits`]), marked on the
    /// run's group; `None`: every value exact.
    pub fn significant_bits(&self) -> Option<u32> {
        self.channels.iter().filter_map(|c| c.bits).min()
    }

    /// The channel written to `dataset` (e.g. `bodies/bob/position`), if recorded.
    pub fn channel(&self, dataset: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.dataset == dataset)
    }

    /// The names of the recorded members of `kind` (`bodies`, `joints` or `drives`), in order.
    pub fn members<'a>(&'a self, kind: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.groups
            .iter()
            .filter_map(move |g| g.path.strip_prefix(kind).and_then(|p| p.strip_prefix('/')))
    }

    /// The channels in evaluation order: stage by stage, those of a stage in the order they are
    /// written.
    pub(crate) fn order(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.channels.len()).collect();
        order.sort_by_key(|&i| self.channels[i].stage);
        order
    }

    /// Evaluates every channel at one sample: in stage order, each value checked as it comes, so
    /// a non-finite value stops at the first quantity the stages reach. Values of a sample that
    /// fails may be partly pushed; [`Recording::truncate`] drops them.
    pub(crate) fn sample(
        &mut self,
        order: &[usize],
        model: &Model,
        ws: &mut Workspace,
        t: f64,
        y: &[f64],
    ) -> Result<()> {
        self.time.push(t);
        for &i in order {
            let ch = &mut self.channels[i];
            for o in &ch.columns {
                let v = o.eval_run(model, ws, t, y);
                if !v.is_finite()
                    && let Some(what) = &ch.checked
                {
                    return Err(jointplay_solver::Error::Diverged {
                        time: t,
                        message: format!("{what} became non-finite"),
                    }
                    .into());
                }
                ch.values.push(v);
            }
        }
        Ok(())
    }

    /// Evaluates the model's accelerations and multipliers at `(t, y)` in `ws` (which holds the
    /// contacts' onset history), then every channel ([`Recording::sample`]); a sample that fails
    /// is dropped whole.
    pub(crate) fn sample_at(
        &mut self,
        order: &[usize],
        model: &Model,
        ws: &mut Workspace,
        t: f64,
        y: &[f64],
    ) -> Result<()> {
        model.accelerations(t, y, ws);
        let n = self.time.len();
        let sampled = self.sample(order, model, ws, t, y);
        if sampled.is_err() {
            self.truncate(n);
        }
        sampled
    }

    /// Appends the samples of `other`, a recording of the same channels.
    pub(crate) fn extend(&mut self, other: &Recording) {
        self.time.extend_from_slice(&other.time);
        for (c, o) in self.channels.iter_mut().zip(&other.channels) {
            c.values.extend_from_slice(&o.values);
        }
    }

    /// Keeps the first `n` samples of every channel.
    pub(crate) fn truncate(&mut self, n: usize) {
        self.time.truncate(n);
        for c in &mut self.channels {
            c.values.truncate(n * c.columns.len());
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
    /// Where and why `e` stopped the run; `fallback_time` when it names no time.
    pub(crate) fn of(e: &crate::Error, fallback_time: f64) -> Stopped {
        match e {
            crate::Error::Solver(se) => Stopped::from_error(se, fallback_time),
            other => Stopped {
                time: fallback_time,
                message: other.to_string(),
            },
        }
    }

    pub(crate) fn from_error(e: &jointplay_solver::Error, fallback_time: f64) -> Stopped {
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
    /// before the failure (with its own time, which [`RunResult::stopped`] may exceed). A run
    /// written as it goes whose recorded values stopped it (a value not finite where the state
    /// is) ends with the state the integration had reached when it learnt of it, at most two
    /// blocks of samples after the one that failed: a file marked incomplete is not continued
    /// from.
    pub final_state: HybridState,
    /// Warnings of the step-size guard.
    pub warnings: Vec<Warning>,
    /// Set when the run stopped before its end time.
    pub stopped: Option<Stopped>,
}

/// The message of a run stopped on request.
pub(crate) const INTERRUPTED: &str = "interrupted on request; the samples before it are kept";

impl RunResult {
    /// True when the run was stopped on request ([`simulate_until`](crate::study::run::simulate_until)) rather than by a failure.
    pub fn interrupted(&self) -> bool {
        self.stopped
            .as_ref()
            .is_some_and(|s| s.message == INTERRUPTED)
    }

    /// The run as a `Result`: an error when it stopped before its end time
    /// ([`crate::Error::Interrupted`] when it was stopped on request).
    pub fn finished(self) -> Result<RunResult> {
        match &self.stopped {
            None => Ok(self),
            Some(s) if self.interrupted() => Err(crate::Error::Interrupted { time: Some(s.time) }),
            Some(s) => Err(jointplay_solver::Error::Diverged {
                time: s.time,
                message: s.message.clone(),
            }
            .into()),
        }
    }
}

/// True for the datasets of a run (its [`Channel::dataset`]) that [`run_figures`](crate::figures::run_figures) draws: the
/// bodies' positions, the drives' forces, the diagnostics, and each clearance joint's orbit and
/// normal forces (and a lubricated joint's film force). A run written to its file while it goes
/// keeps only these in memory.
pub fn drawn(dataset: &str) -> bool {
    let (kind, quantity) = (
        dataset.split('/').next().unwrap_or(""),
        dataset.rsplit('/').next().unwrap_or(""),
    );
    match kind {
        "bodies" => quantity == "position",
        "drives" => quantity == "force",
        "diagnostics" => true,
        "joints" => matches!(
            quantity,
            "radial_eccentricity" | "normal_force" | "film_force"
        ),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sampled(t0: f64, dt: f64, n: usize) -> Recording {
        Recording {
            time: (0..=n).map(|k| t0 + k as f64 * dt).collect(),
            ..Recording::default()
        }
    }

    #[test]
    fn the_strobe_keeps_every_period_up_to_the_last_sample_and_refuses_a_missed_time() {
        // Ten periods of 0.1 s sampled every 0.01 s: eleven strobe rows, the last one the run's
        // last sample although 0.1 * 10 and 100 * 0.01 differ in the last bits.
        let r = sampled(0.0, 0.01, 100);
        let rows = r.strobe_rows(0.01, 0.0, 0.1).unwrap();
        assert_eq!(rows, (0..=10).map(|k| 10 * k).collect::<Vec<_>>());
        // A span a hair short of a whole number of periods still reaches the last one.
        let r = sampled(0.25, 0.001, 3000);
        assert_eq!(r.strobe_rows(0.001, 0.0, 0.3 - 1e-14).unwrap().len(), 11);
        // With a phase, from t0 + phase.
        let r = sampled(0.0, 0.01, 100);
        let rows = r.strobe_rows(0.01, 0.05, 0.1).unwrap();
        assert_eq!(rows, (0..10).map(|k| 5 + 10 * k).collect::<Vec<_>>());
        // A period that is not a whole number of samples names the interval that would be.
        let e = r.strobe_rows(0.01, 0.0, 0.125).unwrap_err();
        assert!(
            e.contains("12.5 samples per period") && e.contains("output.interval = 0.0096"),
            "{e}"
        );
        assert!(
            r.strobe_rows(0.01, 0.0, 0.0)
                .unwrap_err()
                .starts_with("period:")
        );
        assert!(
            r.strobe_rows(0.01, f64::NAN, 0.1)
                .unwrap_err()
                .starts_with("phase:")
        );
    }
}
