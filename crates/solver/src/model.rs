//! Compilation of a [`SceneSpec`] into an immutable [`Model`] and its initial [`State`].
//!
//! Validation happens here, before anything runs: unknown and duplicate names, non-finite
//! numbers, non-positive masses, inertia tensors that are not positive definite or violate the
//! triangle inequality of principal moments, zero-length axes, joints between a body and itself.
//! Each error names the file and the field path (`joints[3].axis_a`).
//!
//! Ideal joints compile to constraint primitives (Haug, *Computer-Aided Kinematics and Dynamics of
//! Mechanical Systems*, 1989, ch. 3; Nikravesh, *Computer-Aided Analysis of Mechanical Systems*,
//! 1988, ch. 4):
//!
//! | joint | rows | primitives |
//! |---|---|---|
//! | spherical | 3 | point coincidence |
//! | revolute | 5 | point coincidence + 2 perpendicularity (axis_b normal to u_a, w_a) |
//! | universal | 4 | point coincidence + axis_a perpendicular to axis_b |
//! | cylindrical | 4 | 2 perpendicularity + 2 distance (d normal to u_a, w_a) |
//! | prismatic | 5 | cylindrical + rotation lock w_a . u_b = 0 |
//! | planar | 3 | 2 perpendicularity + d . axis_a = 0 |
//! | fixed | 6 | point coincidence + 2 perpendicularity + rotation lock |
//!
//! where (u_a, w_a, axis_a) is an orthonormal joint frame on body a, u_b the reference direction on
//! body b and d = P_b - P_a. A drive adds one row: d . axis_a - s(t) = 0 (translation) or
//! theta - s(t) = 0 with theta = atan2(u_b . w_a, u_b . u_a) (rotation).
//!
//! The model records which effects the scene calls for ([`Effects`]); the right-hand side skips every
//! stage whose effect is absent. The compiler's passes are in `crate::compile`.

use std::path::PathBuf;

use nalgebra::{Matrix3, Vector3};

use crate::clearance::Clearance;
use crate::ode::Method;
use crate::profile::Profile;
use crate::scene::*;

// Re-exported: they are used with these paths across the workspace.
pub use crate::kin::{GROUND, any_normal};

/// A rigid body, with vectors relative to its centre of mass in body axes.
#[derive(Debug, Clone)]
pub struct Body {
    pub name: String,
    /// kg.
    pub mass: f64,
    /// Inertia about the centre of mass, body axes (kg m^2).
    pub inertia: Matrix3<f64>,
    pub inv_inertia: Matrix3<f64>,
    /// Centre of mass in the body frame (m): converts declared points to COM-relative vectors.
    pub com: Vector3<f64>,
    /// The shapes the scene draws the body with (`[[bodies.visual]]`); none: it is drawn from
    /// its joint points. No part of the dynamics.
    pub visuals: Vec<Visual>,
}

/// A shape that draws a body, placed relative to its centre of mass in body axes.
#[derive(Debug, Clone, PartialEq)]
pub struct Visual {
    pub shape: Shape,
    /// The shape's centre (its origin, for a mesh), COM-relative body axes (m).
    pub centre: Vector3<f64>,
    /// The shape's axes in body axes (a cylinder's axis is the shape's z).
    pub rotation: nalgebra::UnitQuaternion<f64>,
    /// sRGB colour; `None`: the body's colour in the drawing.
    pub color: Option<[u8; 3]>,
}

/// The kinds of [`Visual`] shape (m).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Edge lengths along the shape's axes.
    Box {
        size: Vector3<f64>,
    },
    Cylinder {
        radius: f64,
        length: f64,
    },
    Sphere {
        radius: f64,
    },
    /// An OBJ or STL file (the path as the scene wrote it, resolved against the scene's folder),
    /// its coordinates times `scale` in m.
    Mesh {
        file: PathBuf,
        scale: f64,
    },
}

/// A constraint primitive; body indices may be [`GROUND`], whose local vectors are global.
#[derive(Debug, Clone)]
pub enum Prim {
    /// P_b - P_a = 0 (3 rows); `sa`, `sb` are COM-relative body-frame vectors.
    Coincident {
        a: usize,
        sa: Vector3<f64>,
        b: usize,
        sb: Vector3<f64>,
    },
    /// (A_a u) . (A_b v) = 0.
    Perpendicular {
        a: usize,
        u: Vector3<f64>,
        b: usize,
        v: Vector3<f64>,
    },
    /// (A_a u) . (P_b - P_a) - s(t) = 0; `drive` gives s(t), else s = 0.
    Distance {
        a: usize,
        u: Vector3<f64>,
        sa: Vector3<f64>,
        b: usize,
        sb: Vector3<f64>,
        drive: Option<usize>,
    },
    /// theta - s(t) = 0, theta = atan2(u_b . w_a, u_b . u_a), about `axis` of body a.
    Angle {
        a: usize,
        axis: Vector3<f64>,
        ua: Vector3<f64>,
        wa: Vector3<f64>,
        b: usize,
        ub: Vector3<f64>,
        drive: usize,
    },
}

impl Prim {
    /// The bodies and rows of this primitive, starting at row `first`, for the sparsity pattern.
    pub fn row_block(&self, first: usize) -> crate::coupling::RowBlock {
        let (a, b) = match *self {
            Prim::Coincident { a, b, .. }
            | Prim::Perpendicular { a, b, .. }
            | Prim::Distance { a, b, .. }
            | Prim::Angle { a, b, .. } => (a, b),
        };
        crate::coupling::RowBlock {
            a,
            b,
            first,
            n: self.rows(),
            rotation_only: matches!(self, Prim::Perpendicular { .. } | Prim::Angle { .. }),
        }
    }

    pub fn rows(&self) -> usize {
        match self {
            Prim::Coincident { .. } => 3,
            Prim::Perpendicular { .. } | Prim::Distance { .. } | Prim::Angle { .. } => 1,
        }
    }
}

/// A compiled ideal joint.
#[derive(Debug, Clone)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    pub body_a: usize,
    pub body_b: usize,
    /// Joint point on b (COM-relative, body axes), about which the reaction torque is reported.
    pub point_b: Vector3<f64>,
    /// Joint point on a (COM-relative, body axes).
    pub point_a: Vector3<f64>,
    /// First constraint row and number of rows (fewer, or none, for a joint with clearance).
    pub rows: std::ops::Range<usize>,
    /// Index into [`Model::clearances`] when the joint has clearance.
    pub clearance: Option<usize>,
}

/// A compiled drive.
#[derive(Debug, Clone)]
pub struct Drive {
    pub name: String,
    pub joint: usize,
    pub coordinate: DriveCoordinate,
    pub profile: Profile,
    /// Its constraint row.
    pub row: usize,
}

impl Drive {
    /// The period of the motion it prescribes (s), when it has one: its profile's, except that a
    /// translation at a constant rate (a conveyor) repeats nothing. A rotation at a constant rate
    /// repeats every turn.
    pub fn period(&self) -> Option<f64> {
        match (&self.profile, self.coordinate) {
            (crate::profile::Profile::ConstantRate { .. }, DriveCoordinate::Translation) => None,
            _ => self.profile.period(),
        }
    }
}

/// A compiled spring-damper.
#[derive(Debug, Clone)]
pub struct Spring {
    pub name: String,
    pub a: usize,
    pub sa: Vector3<f64>,
    pub b: usize,
    pub sb: Vector3<f64>,
    pub stiffness: f64,
    pub damping: f64,
    pub free_length: f64,
}

/// A compiled constant load.
#[derive(Debug, Clone)]
pub struct Load {
    pub name: String,
    pub body: usize,
    /// Point of application, COM-relative body axes.
    pub s: Vector3<f64>,
    pub force: Vector3<f64>,
    pub torque: Vector3<f64>,
    pub frame: LoadFrame,
}

/// The effects a model simulates, derived from the scene.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Effects {
    pub gravity: bool,
    pub springs: bool,
    pub loads: bool,
    pub constraints: bool,
    pub drives: bool,
    /// Clearance contact, friction in any clearance joint, axial contact in any revolute one.
    pub clearance: bool,
    pub friction: bool,
    pub axial_contact: bool,
    /// An oil film in any revolute clearance.
    pub lubrication: bool,
}

impl Effects {
    /// Human-readable list for `jointplay check`.
    pub fn describe(&self, m: &Model) -> Vec<String> {
        let mut v = vec!["rigid-body inertia with gyroscopic terms".to_string()];
        if self.gravity {
            let g = m.gravity.unwrap_or_default();
            v.push(format!(
                "gravity [{:.4}, {:.4}, {:.4}] m/s^2",
                g.x, g.y, g.z
            ));
        }
        if self.constraints {
            v.push(format!(
                "ideal joints: {} joints, {} constraint rows, Baumgarte alpha = {} 1/s, beta = {} 1/s",
                m.joints.len(),
                m.joint_rows,
                m.settings.alpha,
                m.settings.beta
            ));
        }
        if self.drives {
            v.push(format!(
                "prescribed joint motions: {} drives",
                m.drives.len()
            ));
        }
        if self.springs {
            v.push(format!("spring-dampers: {}", m.springs.len()));
        }
        if self.loads {
            v.push(format!("applied loads: {}", m.loads.len()));
        }
        if self.clearance {
            v.push(format!(
                "clearance contact: {} joints, {} contact points{}{}{}",
                m.clearances.len(),
                m.n_contacts,
                if self.axial_contact {
                    ", axial contact"
                } else {
                    ""
                },
                if self.lubrication { ", oil films" } else { "" },
                if self.friction {
                    ", friction"
                } else {
                    ", frictionless"
                }
            ));
            for c in &m.clearances {
                v.push(format!("    {}: {}", c.name, c.geometry.describe()));
                v.push(format!("    {}: normal law {}", c.name, c.law.describe()));
                v.push(format!("    {}: {}", c.name, c.friction.describe()));
                if let Some(film) = &c.film {
                    v.push(format!("    {}: {}", c.name, film.describe()));
                }
            }
        }
        v
    }
}

/// Integration and stabilisation settings, resolved.
#[derive(Debug, Clone)]
pub struct Settings {
    pub method: Method,
    /// Baumgarte parameters (1/s).
    pub alpha: f64,
    pub beta: f64,
    /// s.
    pub start_time: f64,
    pub end_time: f64,
    /// The drive period (s) when the drives share one.
    pub period: Option<f64>,
    /// Divergence guard: largest penetration (m) of any contact, when set in the scene; else
    /// one tenth of each joint's journal radius ([`crate::clearance::Geometry::runaway_penetration`]).
    pub max_penetration: Option<f64>,
    /// Divergence guard: largest constraint residual |Phi_i| (m or rad).
    pub max_drift: f64,
    /// Contact onsets end integrator steps ([`crate::scene::SolverSpec::onset_events`]).
    pub onset_events: bool,
    /// Contact ends end integrator steps ([`crate::scene::SolverSpec::end_events`]).
    pub end_events: bool,
    /// Friction kinks end integrator steps ([`crate::scene::SolverSpec::friction_events`]).
    pub friction_events: bool,
}

/// What to record, resolved to indices.
#[derive(Debug, Clone)]
pub struct Outputs {
    /// s.
    pub interval: f64,
    pub bodies: Vec<usize>,
    pub joints: Vec<usize>,
    pub drives: Vec<usize>,
    pub accelerations: bool,
    pub diagnostics: bool,
    /// Energy with the diagnostics.
    pub energy: bool,
    /// Mantissa bits the recorded values keep in the file, by quantity.
    pub significant_bits: Bits,
}

/// The quantities of a run file whose values `output.significant_bits` may round: the last part
/// of each dataset's name (`bodies/<name>/position`, `joints/<name>/normal_force`, ...). The
/// flags (`contact_state`), the sample times and the final state are never rounded.
pub const ROUNDED_QUANTITIES: &[&str] = &[
    "position",
    "orientation",
    "velocity",
    "angular_velocity",
    "acceleration",
    "angular_acceleration",
    "reaction_force",
    "reaction_torque",
    "eccentricity",
    "eccentricity_global",
    "radial_eccentricity",
    "radial_eccentricity_rate",
    "end_eccentricity",
    "penetration",
    "penetration_rate",
    "normal_force",
    "friction_force",
    "force_on_journal",
    "moment_on_journal",
    "force_on_housing",
    "moment_on_housing",
    "coordinate",
    "force",
    "constraint_drift",
    "velocity_drift",
    "energy",
];

/// Mantissa bits the recorded values keep in the file (`output.significant_bits`), by quantity:
/// `None` keeps every bit (as does 52).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Bits {
    /// The quantities not named in `by_quantity`.
    pub default: Option<u32>,
    /// Quantities of [`ROUNDED_QUANTITIES`] with their own count, in name order.
    pub by_quantity: Vec<(String, Option<u32>)>,
}

impl Bits {
    /// Every value rounded to `bits` (52: none).
    pub fn all(bits: u32) -> Bits {
        Bits {
            default: Some(bits).filter(|&b| b < 52),
            by_quantity: Vec::new(),
        }
    }

    /// The bits the values of `quantity` (the last part of a dataset's name) keep.
    pub fn of(&self, quantity: &str) -> Option<u32> {
        match self.by_quantity.iter().find(|(q, _)| q == quantity) {
            Some((_, b)) => *b,
            None => self.default,
        }
    }

    /// Whether any value is rounded.
    pub fn any(&self) -> bool {
        self.default.is_some() || self.by_quantity.iter().any(|(_, b)| b.is_some())
    }

    /// As `jointplay check` says it: "28 mantissa bits", "28 mantissa bits (reaction_force 52,
    /// velocity 20)" (52: every bit kept), "force 16 mantissa bits (the others every bit)";
    /// `None` when nothing is rounded.
    pub fn describe(&self) -> Option<String> {
        if !self.any() {
            return None;
        }
        let count = |b: Option<u32>| b.unwrap_or(52);
        let others: Vec<String> = self
            .by_quantity
            .iter()
            .filter(|(_, b)| *b != self.default)
            .map(|(q, b)| format!("{q} {}", count(*b)))
            .collect();
        Some(match (self.default, others.is_empty()) {
            (Some(d), true) => format!("{d} mantissa bits"),
            (Some(d), false) => format!("{d} mantissa bits ({})", others.join(", ")),
            (None, _) => format!("{} mantissa bits (the others every bit)", others.join(", ")),
        })
    }
}

/// The immutable simulation model.
#[derive(Debug, Clone)]
pub struct Model {
    pub name: String,
    pub file: PathBuf,
    pub description: Option<String>,
    pub bodies: Vec<Body>,
    pub joints: Vec<Joint>,
    pub drives: Vec<Drive>,
    pub springs: Vec<Spring>,
    pub loads: Vec<Load>,
    /// m/s^2.
    pub gravity: Option<Vector3<f64>>,
    pub prims: Vec<(Prim, usize)>,
    /// Joints with clearance, and the total number of their contact points.
    pub clearances: Vec<Clearance>,
    pub n_contacts: usize,
    /// Bristle states of the LuGre contacts (3 per contact, m, housing body axes): the last
    /// components of the state, after the bodies' 13 each.
    pub n_bristle: usize,
    /// Rows of the joints (the first `joint_rows` rows) and in total (joints then drives).
    pub joint_rows: usize,
    pub n_rows: usize,
    /// Which rows act on which body, and the sparse factorisation that follows from it.
    pub coupling: crate::coupling::Coupling,
    pub effects: Effects,
    /// What the scene's `disable` list removed, one line per entry (see [`crate::disable`]).
    pub disabled: Vec<String>,
    pub settings: Settings,
    pub outputs: Outputs,
    /// Warnings about the scene found while compiling it, each naming the file and the field
    /// (a law used outside its range, for instance). The run goes ahead.
    pub warnings: Vec<String>,
    /// The clearance joints the start was assembled with closed, when any
    /// (see `compile/start.rs`).
    pub closed_start: Option<ClosedStart>,
}

/// A start assembled with clearance joints closed as their ideal joints
/// (`compile/start.rs`), for `jointplay check` and the run's summary.
#[derive(Debug, Clone)]
pub struct ClosedStart {
    /// Each joint closed, with the eccentricity it starts at (m, housing body axes).
    pub joints: Vec<(String, Vector3<f64>)>,
    /// The largest |Phi| (m or rad) and |Phi'| (m/s or rad/s) of these joints' ideal rows at the
    /// start the assembly gives without them: how far that start was from closing them. `None`
    /// when that assembly failed.
    pub gap: Option<(f64, f64)>,
    /// False when that start already closed them (to 1e-9) and was kept as it is.
    pub moved: bool,
}

/// The mutable state: time and y = [r_0, q_0, r_1, q_1, ..., v_0, w_0, v_1, w_1, ..., z] with r the
/// centre-of-mass position (m), q the Euler parameters (w, x, y, z) of body-to-global rotation,
/// v the centre-of-mass velocity (m/s) and w the angular velocity (rad/s), all global, and z the
/// LuGre contacts' bristle deflections (m, housing body axes; none without LuGre friction).
#[derive(Debug, Clone)]
pub struct State {
    pub t: f64,
    pub y: Vec<f64>,
}

impl Model {
    /// Number of bodies.
    pub fn nb(&self) -> usize {
        self.bodies.len()
    }

    /// Length of the state: 13 per body, then the bristle states.
    pub fn dim(&self) -> usize {
        13 * self.bodies.len() + self.n_bristle
    }

    /// Offset of the bristle states in the state vector.
    pub fn bristle_offset(&self) -> usize {
        13 * self.bodies.len()
    }

    /// Names of the bristle states, in state order: `<joint>.<contact>.z<axis>` (m, the
    /// housing body's axes).
    pub fn bristle_names(&self) -> Vec<String> {
        let mut names = Vec::with_capacity(self.n_bristle);
        for c in self.clearances.iter().filter(|c| c.bristle.is_some()) {
            for contact in c.geometry.contact_names() {
                for axis in ["zx", "zy", "zz"] {
                    names.push(format!("{}.{contact}.{axis}", c.name));
                }
            }
        }
        names
    }

    /// Length of the position part of the state (7 per body).
    pub fn n_pos(&self) -> usize {
        7 * self.bodies.len()
    }

    /// Sample times of the recorded output: start, start + interval, ..., end (inclusive).
    pub fn sample_times(&self) -> Vec<f64> {
        let (t0, t1, dt) = (
            self.settings.start_time,
            self.settings.end_time,
            self.outputs.interval,
        );
        let n = ((t1 - t0) / dt * (1.0 + 1e-12)).floor() as usize;
        let mut v: Vec<f64> = (0..=n).map(|k| t0 + k as f64 * dt).collect();
        if t1 - v[n] > 1e-9 * dt {
            v.push(t1);
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::Bits;

    /// A quantity named keeps its own count (`None`: every bit), the others the default; a
    /// quantity given the default's count is not listed again.
    #[test]
    fn bits_by_quantity_fall_back_to_the_default() {
        let bits = Bits {
            default: Some(28),
            by_quantity: vec![
                ("position".into(), Some(28)),
                ("reaction_force".into(), None),
                ("velocity".into(), Some(20)),
            ],
        };
        let of = |q| bits.of(q);
        assert_eq!(
            (of("velocity"), of("reaction_force"), of("energy")),
            (Some(20), None, Some(28))
        );
        assert_eq!(
            bits.describe().as_deref(),
            Some("28 mantissa bits (reaction_force 52, velocity 20)")
        );
        let only = Bits {
            default: None,
            by_quantity: vec![("force".into(), Some(16))],
        };
        assert_eq!((only.of("force"), only.of("position")), (Some(16), None));
        assert_eq!(
            only.describe().as_deref(),
            Some("force 16 mantissa bits (the others every bit)")
        );
        assert_eq!(Bits::all(52).describe(), None);
        assert_eq!(
            Bits::all(30).describe().as_deref(),
            Some("30 mantissa bits")
        );
    }
}
