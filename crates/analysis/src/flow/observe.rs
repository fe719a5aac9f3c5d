//! Observables: scalar functions of the time and the state, addressed by a readable path.
//!
//! For a mechanism scene (all global axes unless said otherwise; SI units):
//!
//! | path | quantity | unit |
//! |---|---|---|
//! | `bodies.B.position.C` | centre-of-mass position | m |
//! | `bodies.B.orientation.Q` | Euler parameters body to global, unit norm (`Q`: `w`, `x`, `y`, `z`) | 1 |
//! | `bodies.B.velocity.C` | centre-of-mass velocity | m/s |
//! | `bodies.B.acceleration.C` | centre-of-mass acceleration | m/s^2 |
//! | `bodies.B.angular_velocity.C` | angular velocity | rad/s |
//! | `bodies.B.angular_acceleration.C` | angular acceleration | rad/s^2 |
//! | `joints.J.eccentricity.C` | journal centre from housing centre, housing axes | m |
//! | `joints.J.eccentricity_rate.C` | its rate in housing axes | m/s |
//! | `joints.J.eccentricity_global.C` | the same offset in global axes | m |
//! | `joints.J.eccentricity_global_rate.C` | its rate | m/s |
//! | `joints.J.radial_eccentricity.U` | eccentricity along the housing's radial directions (`U`: `u`, `w`) | m |
//! | `joints.J.radial_eccentricity_rate.U` | its rate in housing axes along the same directions | m/s |
//! | `joints.J.end_eccentricity.E` | spatial revolute: the journal axis at the rim planes (`E`: `P_u`, `P_w`, `Q_u`, `Q_w`) | m |
//! | `joints.J.penetration.K` | penetration of contact K (negative: gap) | m |
//! | `joints.J.penetration_rate.K` | its rate (approach positive) | m/s |
//! | `joints.J.normal_force.K` | normal force of contact K | N |
//! | `joints.J.friction_force.K` | magnitude of the friction force of contact K | N |
//! | `joints.J.contact_state.K` | 1 while contact K is in contact, 0 while free | 1 |
//! | `joints.J.bristle.K_A` | LuGre: the bristle deflection of contact K along the housing's axis `A` (`x`, `y`, `z`) | m |
//! | `joints.J.contact_force.C` (or `force_on_journal.C`) | resultant contact force on the journal (film included) | N |
//! | `joints.J.film_force.C` | a lubricated joint's oil-film force on the journal (part of the resultant) | N |
//! | `joints.J.moment_on_journal.C` | resultant contact moment on the journal, about its centre of mass | N m |
//! | `joints.J.force_on_housing.C` / `moment_on_housing.C` | the same on the housing | N / N m |
//! | `joints.J.reaction.C` (or `reaction_force.C`) | reaction force of an ideal joint on its second body | N |
//! | `joints.J.reaction_torque.C` | its torque about the joint point on the second body | N m |
//! | `drives.D.force` / `drives.D.coordinate` | actuator effort, drive coordinate | N or N m / m or rad |
//! | `diagnostics.constraint_drift` / `velocity_drift` | 2-norm of the position / velocity constraint residuals | m, rad / m/s, rad/s |
//! | `diagnostics.energy` | kinetic + gravitational + spring + elastic contact energy | J |
//!
//! `C` is `x`, `y`, `z` or `magnitude`; `K` is a contact name (`radial` for spherical and planar
//! joints; `P`, `Q` (rims), `M`, `N` (faces) for a spatial revolute). The `diagnostics.*` paths
//! evaluate the constraints and the contact geometry again, in the workspace: a run records them
//! ([`Observable::for_run`], [`Observable::eval_run`]), a study cannot observe them.
//!
//! A run's recording ([`crate::study::run`]) is made of these observables: each dataset of a run file
//! holds the observables of one path without its component, one per column, e.g.
//! `bodies.B.position.{x,y,z}` in `/bodies/B/position`. Eccentricity is defined as in
//! the clearance-joint geometry: `e = (r_j + A_j s_j) - (r_h + A_h s_h)`, its rate
//! `e' = v_j + w_j x (A_j s_j) - v_h - w_h x (A_h s_h)`, and in housing axes
//! `d/dt (A_h^T e) = A_h^T (e' - w_h x e)`.
//!
//! For a built-in system the observables are its state names (see [`crate::flow::systems`]).

use jointplay_solver::clearance::Clearance;
use jointplay_solver::dynamics::Workspace;
use jointplay_solver::kin::Kin;
use jointplay_solver::model::Model;
use nalgebra::Vector3;

use crate::flow::systems::{self, Builtin};

/// A flow whose observables can be evaluated at any state.
pub trait Observed: jointplay_solver::ode::OdeSystem {
    /// Number of observables.
    fn n_obs(&self) -> usize;
    /// Writes the observables at `(t, y)` into `out`.
    fn observe(&mut self, t: f64, y: &[f64], out: &mut [f64]);
    /// Name of observable `i`, for error messages.
    fn obs_name(&self, i: usize) -> String;
    /// Writes only the observables `which` (indices into `out`) at `(t, y)`: what locating a
    /// section needs after every step. The default evaluates them all.
    fn observe_only(&mut self, t: f64, y: &[f64], _which: &[usize], out: &mut [f64]) {
        self.observe(t, y, out);
    }
}

/// What an observable reads.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    System(usize),
    Body {
        b: usize,
        what: BodyQ,
        comp: usize,
    },
    /// Euler parameter `comp` (w, x, y, z) of body `b`, normalised.
    Orientation {
        b: usize,
        comp: usize,
    },
    Ecc {
        c: usize,
        housing: bool,
        rate: bool,
        comp: usize,
    },
    /// Housing-axes eccentricity (or its rate in housing axes) along the radial direction u (0)
    /// or w (1).
    Radial {
        c: usize,
        rate: bool,
        comp: usize,
    },
    /// Spatial revolute: P side u, w, Q side u, w (0..4).
    End {
        c: usize,
        comp: usize,
    },
    Contact {
        c: usize,
        k: usize,
        what: ContactQ,
    },
    Resultant {
        c: usize,
        what: ResultantQ,
        comp: usize,
    },
    /// Component `i` of the bristle states of LuGre joint `c` (its contact `i / 3`, housing
    /// axis `i % 3`).
    Bristle {
        c: usize,
        i: usize,
    },
    /// The oil film's force on the journal of lubricated joint `c`.
    Film {
        c: usize,
        comp: usize,
    },
    Reaction {
        j: usize,
        torque: bool,
        comp: usize,
    },
    Drive {
        d: usize,
        force: bool,
    },
    Diagnostic(DiagnosticQ),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum BodyQ {
    Position,
    Velocity,
    Acceleration,
    AngularVelocity,
    AngularAcceleration,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum ContactQ {
    Penetration,
    PenetrationRate,
    NormalForce,
    FrictionForce,
    State,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum ResultantQ {
    ForceOnJournal,
    MomentOnJournal,
    ForceOnHousing,
    MomentOnHousing,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum DiagnosticQ {
    ConstraintDrift,
    VelocityDrift,
    Energy,
}

/// A resolved observable.
#[derive(Debug, Clone, PartialEq)]
pub struct Observable {
    pub path: String,
    pub unit: String,
    source: Source,
}

fn component(s: &str) -> Result<usize, String> {
    match s {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        "magnitude" => Ok(3),
        _ => Err(format!("unknown component '{s}': use x, y, z or magnitude")),
    }
}

/// Index of `s` in `names`, or an error listing them.
fn named(what: &str, s: &str, names: &[&str]) -> Result<usize, String> {
    names
        .iter()
        .position(|n| *n == s)
        .ok_or_else(|| format!("unknown {what} '{s}': use {}", names.join(", ")))
}

/// The segments of a mechanism path: the kind, the name (which may contain dots: the quantity
/// and the component never do), the quantity and the component; empty when the path has none of
/// the four shapes.
fn segments(path: &str) -> Vec<&str> {
    let Some((kind, rest)) = path.split_once('.') else {
        return Vec::new();
    };
    let n = match kind {
        "bodies" | "joints" => 3,
        "drives" => 2,
        "diagnostics" => 1,
        _ => return Vec::new(),
    };
    let mut v: Vec<&str> = rest.rsplitn(n, '.').collect();
    if v.len() != n || v.iter().any(|s| s.is_empty()) {
        return Vec::new();
    }
    v.push(kind);
    v.reverse();
    v
}

fn pick(v: Vector3<f64>, comp: usize) -> f64 {
    if comp == 3 { v.norm() } else { v[comp] }
}

/// d/dt of the eccentricity e = journal centre - housing centre (global axes, m/s): the
/// difference of the two centres' velocities.
fn eccentricity_rate(cl: &Clearance, kh: &Kin, kj: &Kin) -> Vector3<f64> {
    kj.v + kj.w.cross(&(kj.rot * cl.sj)) - kh.v - kh.w.cross(&(kh.rot * cl.sh))
}

/// The eccentricity's rate seen in the housing's axes (m/s): d/dt (A_h^T e) =
/// A_h^T (de/dt - w_h x e).
fn housing_rate(cl: &Clearance, kh: &Kin, kj: &Kin) -> Vector3<f64> {
    let e = cl.eccentricity(kh, kj);
    kh.rot.transpose() * (eccentricity_rate(cl, kh, kj) - kh.w.cross(&e))
}

/// What an observable reads, and its unit.
type Resolved = Result<(Source, &'static str), String>;

/// `bodies.B.WHAT.C`: a component of body `b`'s position, orientation, velocity or acceleration.
fn body_source(m: &Model, b: &str, what: &str, c: &str) -> Resolved {
    let bi = m
        .bodies
        .iter()
        .position(|x| x.name == *b)
        .ok_or_else(|| format!("no body '{b}'"))?;
    if what == "orientation" {
        let comp = named("Euler parameter", c, &["w", "x", "y", "z"])?;
        return Ok((Source::Orientation { b: bi, comp }, "1"));
    }
    let comp = component(c)?;
    let (what, unit) = match what {
        "position" => (BodyQ::Position, "m"),
        "velocity" => (BodyQ::Velocity, "m/s"),
        "acceleration" => (BodyQ::Acceleration, "m/s^2"),
        "angular_velocity" => (BodyQ::AngularVelocity, "rad/s"),
        "angular_acceleration" => (BodyQ::AngularAcceleration, "rad/s^2"),
        other => {
            return Err(format!(
                "unknown body quantity '{other}': use position, orientation, velocity, acceleration, angular_velocity or angular_acceleration"
            ));
        }
    };
    Ok((Source::Body { b: bi, what, comp }, unit))
}

/// `joints.J.WHAT.C`: the reaction of a joint that keeps constraint rows, or a quantity of a
/// joint with clearance ([`clearance_source`]).
fn joint_source(m: &Model, j: &str, what: &str, c: &str) -> Resolved {
    let ji = m
        .joints
        .iter()
        .position(|x| x.name == *j)
        .ok_or_else(|| format!("no joint '{j}'"))?;
    if let Some(torque) = match what {
        "reaction" | "reaction_force" => Some(false),
        "reaction_torque" => Some(true),
        _ => None,
    } {
        if m.joints[ji].rows.is_empty() {
            return Err(format!(
                "joint '{j}' has clearance: use contact_force instead of {what}"
            ));
        }
        return Ok((
            Source::Reaction {
                j: ji,
                torque,
                comp: component(c)?,
            },
            if torque { "N m" } else { "N" },
        ));
    }
    let ci = m.joints[ji]
        .clearance
        .ok_or_else(|| format!("joint '{j}' has no clearance, so it has no {what}"))?;
    clearance_source(m, j, ci, what, c)
}

/// `joints.J.WHAT.C` of joint `j` with clearance `ci`: an eccentricity (housing or global axes,
/// radial, at the journal ends), a resultant contact force or moment, or a per-contact quantity.
fn clearance_source(m: &Model, j: &str, ci: usize, what: &str, c: &str) -> Resolved {
    let ecc = |housing, rate| -> Resolved {
        Ok((
            Source::Ecc {
                c: ci,
                housing,
                rate,
                comp: component(c)?,
            },
            if rate { "m/s" } else { "m" },
        ))
    };
    let resultant = |what, unit| -> Resolved {
        Ok((
            Source::Resultant {
                c: ci,
                what,
                comp: component(c)?,
            },
            unit,
        ))
    };
    let geometry = &m.clearances[ci].geometry;
    match what {
        "eccentricity" => ecc(true, false),
        "eccentricity_rate" => ecc(true, true),
        "eccentricity_global" => ecc(false, false),
        "eccentricity_global_rate" => ecc(false, true),
        "radial_eccentricity" | "radial_eccentricity_rate" => {
            let rate = what == "radial_eccentricity_rate";
            Ok((
                Source::Radial {
                    c: ci,
                    rate,
                    comp: named("radial direction", c, &["u", "w"])?,
                },
                if rate { "m/s" } else { "m" },
            ))
        }
        "end_eccentricity" => {
            if !matches!(
                geometry,
                jointplay_solver::clearance::Geometry::Revolute { .. }
            ) {
                return Err(format!(
                    "joint '{j}' is not a spatial revolute, so it has no end_eccentricity"
                ));
            }
            Ok((
                Source::End {
                    c: ci,
                    comp: named("journal end", c, &["P_u", "P_w", "Q_u", "Q_w"])?,
                },
                "m",
            ))
        }
        "contact_force" | "force_on_journal" => resultant(ResultantQ::ForceOnJournal, "N"),
        "film_force" => {
            if m.clearances[ci].film.is_none() {
                return Err(format!(
                    "joint '{j}' is not lubricated, so it has no film_force"
                ));
            }
            Ok((
                Source::Film {
                    c: ci,
                    comp: component(c)?,
                },
                "N",
            ))
        }
        "bristle" => {
            if m.clearances[ci].bristle.is_none() {
                return Err(format!(
                    "joint '{j}' has no LuGre friction, so it has no bristle"
                ));
            }
            let names = geometry.contact_names();
            let found = c.rsplit_once('_').and_then(|(k, axis)| {
                let k = names.iter().position(|n| *n == k)?;
                let a = ["x", "y", "z"].iter().position(|x| *x == axis)?;
                Some(3 * k + a)
            });
            let i = found.ok_or_else(|| {
                format!(
                    "joint '{j}' has no bristle '{c}': name a contact ({}) and a housing axis, as in {}_x",
                    names.join(", "),
                    names[0]
                )
            })?;
            Ok((Source::Bristle { c: ci, i }, "m"))
        }
        "moment_on_journal" => resultant(ResultantQ::MomentOnJournal, "N m"),
        "force_on_housing" => resultant(ResultantQ::ForceOnHousing, "N"),
        "moment_on_housing" => resultant(ResultantQ::MomentOnHousing, "N m"),
        "penetration" | "penetration_rate" | "normal_force" | "friction_force"
        | "contact_state" => {
            let names = geometry.contact_names();
            let k = names.iter().position(|n| *n == c).ok_or_else(|| {
                format!(
                    "joint '{j}' has no contact '{c}' (it has {})",
                    names.join(", ")
                )
            })?;
            let (what, unit) = match what {
                "penetration" => (ContactQ::Penetration, "m"),
                "penetration_rate" => (ContactQ::PenetrationRate, "m/s"),
                "normal_force" => (ContactQ::NormalForce, "N"),
                "friction_force" => (ContactQ::FrictionForce, "N"),
                _ => (ContactQ::State, "1"),
            };
            Ok((Source::Contact { c: ci, k, what }, unit))
        }
        other => Err(format!(
            "unknown joint quantity '{other}': use eccentricity, eccentricity_rate, eccentricity_global, eccentricity_global_rate, radial_eccentricity, radial_eccentricity_rate, end_eccentricity, penetration, penetration_rate, normal_force, friction_force, contact_state, bristle, contact_force (force_on_journal), film_force, moment_on_journal, force_on_housing, moment_on_housing, reaction (reaction_force) or reaction_torque"
        )),
    }
}

/// `drives.D.WHAT`: drive `d`'s force or coordinate.
fn drive_source(m: &Model, d: &str, what: &str) -> Resolved {
    let di = m
        .drives
        .iter()
        .position(|x| x.name == *d)
        .ok_or_else(|| format!("no drive '{d}'"))?;
    let rot = m.drives[di].coordinate == jointplay_solver::scene::DriveCoordinate::Rotation;
    match what {
        "force" => Ok((
            Source::Drive { d: di, force: true },
            if rot { "N m" } else { "N" },
        )),
        "coordinate" => Ok((
            Source::Drive {
                d: di,
                force: false,
            },
            if rot { "rad" } else { "m" },
        )),
        other => Err(format!(
            "unknown drive quantity '{other}': use force or coordinate"
        )),
    }
}

/// `diagnostics.WHAT`: a run diagnostic.
fn diagnostic_source(what: &str) -> Resolved {
    match what {
        "constraint_drift" => Ok((Source::Diagnostic(DiagnosticQ::ConstraintDrift), "m, rad")),
        "velocity_drift" => Ok((Source::Diagnostic(DiagnosticQ::VelocityDrift), "m/s, rad/s")),
        "energy" => Ok((Source::Diagnostic(DiagnosticQ::Energy), "J")),
        other => Err(format!(
            "unknown diagnostic '{other}': use constraint_drift, velocity_drift or energy"
        )),
    }
}

impl Observable {
    /// Resolves `path` for a built-in system.
    pub fn for_system(sys: &Builtin, path: &str) -> Result<Observable, String> {
        let (i, unit) = sys.observable(path).ok_or_else(|| {
            format!(
                "unknown observable '{path}' of the {} system (it has {})",
                sys.kind(),
                sys.observable_names().join(", ")
            )
        })?;
        Ok(Observable {
            path: path.into(),
            unit: unit.into(),
            source: Source::System(i),
        })
    }

    /// Resolves `path` for a mechanism observed by a study (grammar in the module
    /// documentation): every path but the run diagnostics.
    pub fn for_model(m: &Model, path: &str) -> Result<Observable, String> {
        let o = Observable::for_run(m, path)?;
        if let Source::Diagnostic(_) = o.source {
            return Err(format!(
                "'{path}' is recorded by runs only (it evaluates the constraints and the contact geometry again): a study cannot observe it"
            ));
        }
        Ok(o)
    }

    /// Resolves `path` for a mechanism's run recording: every path of the module
    /// documentation, the `diagnostics.*` ones too.
    pub fn for_run(m: &Model, path: &str) -> Result<Observable, String> {
        let seg = segments(path);
        let (source, unit) = match seg.as_slice() {
            ["bodies", b, what, c] => body_source(m, b, what, c)?,
            ["joints", j, what, c] => joint_source(m, j, what, c)?,
            ["drives", d, what] => drive_source(m, d, what)?,
            ["diagnostics", what] => diagnostic_source(what)?,
            _ => {
                return Err(format!(
                    "cannot read '{path}': use bodies.NAME.QUANTITY.COMPONENT, joints.NAME.QUANTITY.COMPONENT, drives.NAME.force|coordinate or diagnostics.QUANTITY"
                ));
            }
        };
        Ok(Observable {
            path: path.into(),
            unit: unit.into(),
            source,
        })
    }

    /// True when evaluating it needs the accelerations, contact forces or multipliers (a full
    /// evaluation of the model), not only the kinematics.
    pub fn needs_dynamics(&self) -> bool {
        matches!(
            self.source,
            Source::Body {
                what: BodyQ::Acceleration | BodyQ::AngularAcceleration,
                ..
            } | Source::Contact { .. }
                | Source::Resultant { .. }
                | Source::Reaction { .. }
                | Source::Drive { force: true, .. }
        )
    }

    /// Value for a built-in system at state `y`.
    pub fn eval_system(&self, y: &[f64]) -> f64 {
        match self.source {
            Source::System(i) => systems::observe(i, y),
            _ => f64::NAN,
        }
    }

    /// Value for a mechanism whose workspace holds the kinematics (and, if
    /// [`Observable::needs_dynamics`], the accelerations) of state `y` at time `t`. The run
    /// diagnostics, which need the workspace to evaluate in, are NaN here: see
    /// [`Observable::eval_run`].
    pub fn eval_model(&self, m: &Model, ws: &Workspace, t: f64, y: &[f64]) -> f64 {
        let np = m.n_pos();
        match self.source {
            Source::System(_) | Source::Diagnostic(_) => f64::NAN,
            Source::Body { b, what, comp } => {
                let v = match what {
                    BodyQ::Position => Vector3::new(y[7 * b], y[7 * b + 1], y[7 * b + 2]),
                    BodyQ::Velocity => Vector3::from_column_slice(&y[np + 6 * b..np + 6 * b + 3]),
                    BodyQ::AngularVelocity => {
                        Vector3::from_column_slice(&y[np + 6 * b + 3..np + 6 * b + 6])
                    }
                    BodyQ::Acceleration => Vector3::from_column_slice(&ws.acc[b][0..3]),
                    BodyQ::AngularAcceleration => Vector3::from_column_slice(&ws.acc[b][3..6]),
                };
                pick(v, comp)
            }
            Source::Orientation { b, comp } => {
                let p = &y[7 * b + 3..7 * b + 7];
                let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]).sqrt();
                p[comp] / n
            }
            Source::Ecc {
                c,
                housing,
                rate,
                comp,
            } => {
                let cl = &m.clearances[c];
                let (kh, kj) = (
                    m.kinematics_of(cl.housing, ws),
                    m.kinematics_of(cl.journal, ws),
                );
                let v = match (rate, housing) {
                    (false, false) => cl.eccentricity(&kh, &kj),
                    (false, true) => kh.rot.transpose() * cl.eccentricity(&kh, &kj),
                    (true, false) => eccentricity_rate(cl, &kh, &kj),
                    (true, true) => housing_rate(cl, &kh, &kj),
                };
                pick(v, comp)
            }
            Source::Radial { c, rate, comp } => {
                let cl = &m.clearances[c];
                let (kh, kj) = (
                    m.kinematics_of(cl.housing, ws),
                    m.kinematics_of(cl.journal, ws),
                );
                // u and w are fixed in the housing's axes, so the rate along them is the
                // housing-axes rate's component.
                let el = if rate {
                    housing_rate(cl, &kh, &kj)
                } else {
                    kh.rot.transpose() * cl.eccentricity(&kh, &kj)
                };
                let (u, w) = cl.radial_axes();
                el.dot(if comp == 0 { &u } else { &w })
            }
            Source::Film { c, comp } => {
                let cl = &m.clearances[c];
                let (kh, kj) = (
                    m.kinematics_of(cl.housing, ws),
                    m.kinematics_of(cl.journal, ws),
                );
                cl.film
                    .as_ref()
                    .map_or(f64::NAN, |f| pick(cl.film_force(f, &kh, &kj), comp))
            }
            Source::Bristle { c, i } => m.clearances[c]
                .bristle
                .map_or(f64::NAN, |b| y[m.bristle_offset() + b + i]),
            Source::End { c, comp } => {
                let cl = &m.clearances[c];
                let (kh, kj) = (
                    m.kinematics_of(cl.housing, ws),
                    m.kinematics_of(cl.journal, ws),
                );
                cl.end_offsets(&kh, &kj)
                    .map_or(f64::NAN, |ends| ends[comp / 2][comp % 2])
            }
            Source::Contact { c, k, what } => {
                let ce = &ws.contacts[m.clearances[c].first + k];
                match what {
                    ContactQ::Penetration => ce.delta,
                    ContactQ::PenetrationRate => ce.delta_dot,
                    ContactQ::NormalForce => ce.fn_,
                    ContactQ::FrictionForce => ce.ft.norm(),
                    ContactQ::State => f64::from(u8::from(ce.active())),
                }
            }
            Source::Resultant { c, what, comp } => {
                let r = &ws.resultants[c];
                let v = match what {
                    ResultantQ::ForceOnJournal => r.force_j,
                    ResultantQ::MomentOnJournal => r.moment_j,
                    ResultantQ::ForceOnHousing => r.force_h,
                    ResultantQ::MomentOnHousing => r.moment_h,
                };
                pick(v, comp)
            }
            Source::Reaction { j, torque, comp } => {
                let (f, n) = m.reaction(j, ws);
                pick(if torque { n } else { f }, comp)
            }
            Source::Drive { d, force } => {
                if force {
                    m.actuator_force(d, ws)
                } else {
                    m.drive_coordinate(d, t, ws)
                }
            }
        }
    }

    /// Value for a mechanism's run recording: [`Observable::eval_model`], and the diagnostics,
    /// which evaluate the constraints (drift) or the kinematics and contact geometry (energy)
    /// again in `ws`: evaluate them after every observable that reads the evaluation's contacts.
    pub fn eval_run(&self, m: &Model, ws: &mut Workspace, t: f64, y: &[f64]) -> f64 {
        match self.source {
            Source::Diagnostic(q) => match q {
                DiagnosticQ::ConstraintDrift => m.drift(t, y, ws).0,
                DiagnosticQ::VelocityDrift => m.drift(t, y, ws).1,
                DiagnosticQ::Energy => m.energy(y, ws),
            },
            _ => self.eval_model(m, ws, t, y),
        }
    }

    /// True for the run diagnostics, which [`Observable::eval_run`] evaluates in the workspace.
    pub fn is_diagnostic(&self) -> bool {
        matches!(self.source, Source::Diagnostic(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_splits_into_kind_name_quantity_and_component_and_a_name_may_hold_dots() {
        assert_eq!(
            segments("bodies.link.1.position.x"),
            ["bodies", "link.1", "position", "x"]
        );
        assert_eq!(
            segments("joints.R1.end_eccentricity.P_u"),
            ["joints", "R1", "end_eccentricity", "P_u"]
        );
        assert_eq!(segments("drives.m.1.force"), ["drives", "m.1", "force"]);
        assert_eq!(segments("diagnostics.energy"), ["diagnostics", "energy"]);
        for bad in [
            "bodies.position.x",
            "bodies..position.x",
            "drives.force",
            "x",
            "links.a.position.x",
        ] {
            assert!(segments(bad).is_empty(), "{bad}");
        }
    }
}

/// One observable: a dataset name and a path.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObservableSpec {
    pub name: String,
    pub path: String,
}
