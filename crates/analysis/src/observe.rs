//! Observables: scalar functions of the time and the state, addressed by a readable path.
//!
//! For a mechanism scene (all global axes unless said otherwise; SI units):
//!
//! | path | quantity | unit |
//! |---|---|---|
//! | `bodies.B.position.C` | centre-of-mass position | m |
//! | `bodies.B.velocity.C` | centre-of-mass velocity | m/s |
//! | `bodies.B.acceleration.C` | centre-of-mass acceleration | m/s^2 |
//! | `bodies.B.angular_velocity.C` | angular velocity | rad/s |
//! | `bodies.B.angular_acceleration.C` | angular acceleration | rad/s^2 |
//! | `joints.J.eccentricity.C` | journal centre from housing centre, housing axes | m |
//! | `joints.J.eccentricity_rate.C` | its rate in housing axes | m/s |
//! | `joints.J.eccentricity_global.C` | the same offset in global axes | m |
//! | `joints.J.eccentricity_global_rate.C` | its rate | m/s |
//! | `joints.J.penetration.K` | penetration of contact K (negative: gap) | m |
//! | `joints.J.normal_force.K` | normal force of contact K | N |
//! | `joints.J.contact_force.C` | resultant contact force on the journal | N |
//! | `joints.J.reaction.C` | reaction force of an ideal joint on its second body | N |
//! | `drives.D.force` / `drives.D.coordinate` | actuator effort, drive coordinate | N or N m / m or rad |
//!
//! `C` is `x`, `y`, `z` or `magnitude`; `K` is a contact name (`radial` for spherical and planar
//! joints; `P`, `Q` (rims), `M`, `N` (faces) for a spatial revolute). Eccentricity is defined as in
//! the clearance-joint geometry: `e = (r_j + A_j s_j) - (r_h + A_h s_h)`, its rate
//! `e' = v_j + w_j x (A_j s_j) - v_h - w_h x (A_h s_h)`, and in housing axes
//! `d/dt (A_h^T e) = A_h^T (e' - w_h x e)`.
//!
//! For a built-in system the observables are its state names (see [`crate::systems`]).

use jointplay_solver::dynamics::Workspace;
use jointplay_solver::model::Model;
use nalgebra::Vector3;

use crate::systems::{self, Builtin};

/// What an observable reads.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    System(usize),
    Body {
        b: usize,
        what: BodyQ,
        comp: usize,
    },
    Ecc {
        c: usize,
        housing: bool,
        rate: bool,
        comp: usize,
    },
    Contact {
        c: usize,
        k: usize,
        force: bool,
    },
    ContactForce {
        c: usize,
        comp: usize,
    },
    Reaction {
        j: usize,
        comp: usize,
    },
    Drive {
        d: usize,
        force: bool,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum BodyQ {
    Position,
    Velocity,
    Acceleration,
    AngularVelocity,
    AngularAcceleration,
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

fn pick(v: Vector3<f64>, comp: usize) -> f64 {
    if comp == 3 { v.norm() } else { v[comp] }
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

    /// Resolves `path` for a mechanism (grammar in the module documentation).
    pub fn for_model(m: &Model, path: &str) -> Result<Observable, String> {
        let seg: Vec<&str> = path.split('.').collect();
        let ok = |source, unit: &str| {
            Ok(Observable {
                path: path.into(),
                unit: unit.into(),
                source,
            })
        };
        match seg.as_slice() {
            ["bodies", b, what, c] => {
                let bi = m
                    .bodies
                    .iter()
                    .position(|x| x.name == *b)
                    .ok_or_else(|| format!("no body '{b}'"))?;
                let comp = component(c)?;
                let (what, unit) = match *what {
                    "position" => (BodyQ::Position, "m"),
                    "velocity" => (BodyQ::Velocity, "m/s"),
                    "acceleration" => (BodyQ::Acceleration, "m/s^2"),
                    "angular_velocity" => (BodyQ::AngularVelocity, "rad/s"),
                    "angular_acceleration" => (BodyQ::AngularAcceleration, "rad/s^2"),
                    other => {
                        return Err(format!(
                            "unknown body quantity '{other}': use position, velocity, acceleration, angular_velocity or angular_acceleration"
                        ));
                    }
                };
                ok(Source::Body { b: bi, what, comp }, unit)
            }
            ["joints", j, what, c] => {
                let ji = m
                    .joints
                    .iter()
                    .position(|x| x.name == *j)
                    .ok_or_else(|| format!("no joint '{j}'"))?;
                if *what == "reaction" {
                    if m.joints[ji].rows.is_empty() {
                        return Err(format!(
                            "joint '{j}' has clearance: use contact_force instead of reaction"
                        ));
                    }
                    return ok(
                        Source::Reaction {
                            j: ji,
                            comp: component(c)?,
                        },
                        "N",
                    );
                }
                let ci = m.joints[ji]
                    .clearance
                    .ok_or_else(|| format!("joint '{j}' has no clearance, so it has no {what}"))?;
                let ecc = |housing, rate| -> Result<Observable, String> {
                    ok(
                        Source::Ecc {
                            c: ci,
                            housing,
                            rate,
                            comp: component(c)?,
                        },
                        if rate { "m/s" } else { "m" },
                    )
                };
                match *what {
                    "eccentricity" => ecc(true, false),
                    "eccentricity_rate" => ecc(true, true),
                    "eccentricity_global" => ecc(false, false),
                    "eccentricity_global_rate" => ecc(false, true),
                    "contact_force" => ok(
                        Source::ContactForce {
                            c: ci,
                            comp: component(c)?,
                        },
                        "N",
                    ),
                    "penetration" | "normal_force" => {
                        let names = m.clearances[ci].geometry.contact_names();
                        let k = names.iter().position(|n| n == c).ok_or_else(|| {
                            format!(
                                "joint '{j}' has no contact '{c}' (it has {})",
                                names.join(", ")
                            )
                        })?;
                        let force = *what == "normal_force";
                        ok(
                            Source::Contact { c: ci, k, force },
                            if force { "N" } else { "m" },
                        )
                    }
                    other => Err(format!(
                        "unknown joint quantity '{other}': use eccentricity, eccentricity_rate, eccentricity_global, eccentricity_global_rate, penetration, normal_force, contact_force or reaction"
                    )),
                }
            }
            ["drives", d, what] => {
                let di = m
                    .drives
                    .iter()
                    .position(|x| x.name == *d)
                    .ok_or_else(|| format!("no drive '{d}'"))?;
                let rot =
                    m.drives[di].coordinate == jointplay_solver::scene::DriveCoordinate::Rotation;
                match *what {
                    "force" => ok(
                        Source::Drive { d: di, force: true },
                        if rot { "N m" } else { "N" },
                    ),
                    "coordinate" => ok(
                        Source::Drive {
                            d: di,
                            force: false,
                        },
                        if rot { "rad" } else { "m" },
                    ),
                    other => Err(format!(
                        "unknown drive quantity '{other}': use force or coordinate"
                    )),
                }
            }
            _ => Err(format!(
                "cannot read '{path}': use bodies.NAME.QUANTITY.COMPONENT, joints.NAME.QUANTITY.COMPONENT or drives.NAME.force|coordinate"
            )),
        }
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
                | Source::ContactForce { .. }
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
    /// [`Observable::needs_dynamics`], the accelerations) of state `y` at time `t`.
    pub fn eval_model(&self, m: &Model, ws: &Workspace, t: f64, y: &[f64]) -> f64 {
        let np = m.n_pos();
        match self.source {
            Source::System(_) => f64::NAN,
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
                let e = cl.eccentricity(&kh, &kj);
                let v = if rate {
                    let de =
                        kj.v + kj.w.cross(&(kj.rot * cl.sj)) - kh.v - kh.w.cross(&(kh.rot * cl.sh));
                    if housing {
                        kh.rot.transpose() * (de - kh.w.cross(&e))
                    } else {
                        de
                    }
                } else if housing {
                    kh.rot.transpose() * e
                } else {
                    e
                };
                pick(v, comp)
            }
            Source::Contact { c, k, force } => {
                let ce = &ws.contacts[m.clearances[c].first + k];
                if force { ce.fn_ } else { ce.delta }
            }
            Source::ContactForce { c, comp } => pick(ws.resultants[c].force_j, comp),
            Source::Reaction { j, comp } => pick(m.reaction(j, ws).0, comp),
            Source::Drive { d, force } => {
                if force {
                    m.actuator_force(d, ws)
                } else {
                    m.drive_coordinate(d, t, ws)
                }
            }
        }
    }
}
