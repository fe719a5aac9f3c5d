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
//! stage whose effect is absent.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, SymmetricEigen, UnitQuaternion, Vector3};

use crate::clearance::{Clearance, Geometry};
use crate::contact::{
    Damping, Elastic, FrictionLaw, NormalLaw, hunt_crossley_restitution, point_contact_stiffness,
};
use crate::error::{Error, Result};
use crate::ode::Method;
use crate::profile::{Profile, Spline};
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
            _ => 1,
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
                "clearance contact: {} joints, {} contact points{}{}",
                m.clearances.len(),
                m.n_contacts,
                if self.axial_contact {
                    ", axial contact"
                } else {
                    ""
                },
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
}

/// The mutable state: time and y = [r_0, q_0, r_1, q_1, ..., v_0, w_0, v_1, w_1, ...] with r the
/// centre-of-mass position (m), q the Euler parameters (w, x, y, z) of body-to-global rotation,
/// v the centre-of-mass velocity (m/s) and w the angular velocity (rad/s), all global.
#[derive(Debug, Clone)]
pub struct State {
    pub t: f64,
    pub y: Vec<f64>,
}

struct Ctx<'a> {
    file: &'a Path,
    warnings: std::cell::RefCell<Vec<String>>,
}

impl Ctx<'_> {
    fn warn(&self, field: impl std::fmt::Display, message: impl std::fmt::Display) {
        self.warnings
            .borrow_mut()
            .push(format!("{}: {field}: {message}", self.file.display()));
    }

    fn err(&self, field: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Invalid {
            file: self.file.to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

/// Walks the raw TOML tree and rejects NaN and infinities, naming the field path.
fn check_finite(v: &toml::Value, path: &str, cx: &Ctx) -> Result<()> {
    match v {
        toml::Value::Float(f) if !f.is_finite() => {
            Err(cx.err(path, format!("must be a finite number, got {f}")))
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                check_finite(x, &format!("{path}[{i}]"), cx)?;
            }
            Ok(())
        }
        toml::Value::Table(t) => {
            for (k, x) in t {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                check_finite(x, &p, cx)?;
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

fn orientation(o: &OrientationSpec, field: &str, cx: &Ctx) -> Result<UnitQuaternion<f64>> {
    let groups = [
        o.axis.is_some() || o.angle.is_some(),
        o.quaternion.is_some(),
        o.x.is_some() || o.y.is_some(),
    ];
    match groups.iter().filter(|g| **g).count() {
        0 => return Ok(UnitQuaternion::identity()),
        1 => {}
        _ => {
            return Err(cx.err(
                field,
                "give exactly one of axis + angle, quaternion, or x + y",
            ));
        }
    }
    if groups[0] {
        let (Some(axis), Some(angle)) = (o.axis, o.angle) else {
            return Err(cx.err(field, "axis and angle go together"));
        };
        let a = v3(axis);
        if a.norm() < 1e-12 {
            return Err(cx.err(format!("{field}.axis"), "zero-length axis"));
        }
        Ok(UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(a),
            angle,
        ))
    } else if let Some(q) = o.quaternion {
        let q = nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]);
        if q.norm() < 1e-12 {
            return Err(cx.err(format!("{field}.quaternion"), "zero quaternion"));
        }
        Ok(UnitQuaternion::from_quaternion(q))
    } else {
        let (Some(x), Some(y)) = (o.x, o.y) else {
            return Err(cx.err(field, "x and y go together"));
        };
        let x = v3(x);
        let y = v3(y);
        if x.norm() < 1e-12 {
            return Err(cx.err(format!("{field}.x"), "zero-length axis"));
        }
        let x = x.normalize();
        let yp = y - x * x.dot(&y);
        if yp.norm() < 1e-9 * y.norm().max(1e-300) || y.norm() < 1e-12 {
            return Err(cx.err(format!("{field}.y"), "zero or parallel to x"));
        }
        let y = yp.normalize();
        let z = x.cross(&y);
        let m = Matrix3::from_columns(&[x, y, z]);
        Ok(UnitQuaternion::from_matrix(&m))
    }
}

fn inertia(i: &InertiaSpec, field: &str, cx: &Ctx) -> Result<Matrix3<f64>> {
    let m = Matrix3::new(
        i.ixx, i.ixy, i.ixz, //
        i.ixy, i.iyy, i.iyz, //
        i.ixz, i.iyz, i.izz,
    );
    let eig = SymmetricEigen::new(m).eigenvalues;
    let mut p = [eig[0], eig[1], eig[2]];
    p.sort_by(f64::total_cmp);
    if p[0] <= 0.0 {
        return Err(cx.err(
            field,
            format!(
                "inertia tensor is not positive definite (principal moments {:.6e}, {:.6e}, {:.6e} kg m^2)",
                p[0], p[1], p[2]
            ),
        ));
    }
    if p[0] + p[1] < p[2] * (1.0 - 1e-9) {
        return Err(cx.err(
            field,
            format!(
                "principal moments {:.6e} + {:.6e} < {:.6e} kg m^2 violate the triangle inequality (no physical body has them)",
                p[0], p[1], p[2]
            ),
        ));
    }
    Ok(m)
}

/// Named points and axes of one body (or the ground), in its frame.
struct Frames<'a> {
    points: &'a BTreeMap<String, [f64; 3]>,
    axes: &'a BTreeMap<String, [f64; 3]>,
    /// COM offset to subtract from points (zero for ground).
    com: Vector3<f64>,
    /// Initial orientation (identity for ground).
    rot: UnitQuaternion<f64>,
    /// Initial COM position (zero for ground).
    pos: Vector3<f64>,
    label: String,
}

impl Frames<'_> {
    /// COM-relative body-axes vector of a point reference.
    fn point(&self, r: &VecRef, field: &str, cx: &Ctx) -> Result<Vector3<f64>> {
        let p = match r {
            VecRef::Coords(c) => v3(*c),
            VecRef::Name(n) => v3(*self.points.get(n).ok_or_else(|| {
                cx.err(
                    field,
                    format!(
                        "unknown point '{n}' on {} (declared: {})",
                        self.label,
                        list(self.points.keys())
                    ),
                )
            })?),
        };
        Ok(p - self.com)
    }

    /// Unit body-axes vector of an axis reference.
    fn axis(&self, r: &VecRef, field: &str, cx: &Ctx) -> Result<Vector3<f64>> {
        let a = match r {
            VecRef::Coords(c) => v3(*c),
            VecRef::Name(n) => v3(*self.axes.get(n).ok_or_else(|| {
                cx.err(
                    field,
                    format!(
                        "unknown axis '{n}' on {} (declared: {})",
                        self.label,
                        list(self.axes.keys())
                    ),
                )
            })?),
        };
        if a.norm() < 1e-12 {
            return Err(cx.err(field, "zero-length axis"));
        }
        Ok(a.normalize())
    }

    fn to_global(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rot * v
    }

    fn to_local(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rot.inverse() * v
    }

    fn global_point(&self, s: &Vector3<f64>) -> Vector3<f64> {
        self.pos + self.rot * s
    }
}

fn list<'a>(it: impl Iterator<Item = &'a String>) -> String {
    let v: Vec<&str> = it.map(|s| s.as_str()).collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

fn profile(p: &ProfileSpec, field: &str, cx: &Ctx) -> Result<Profile> {
    Ok(match p {
        ProfileSpec::ConstantRate { initial, rate } => Profile::ConstantRate {
            initial: *initial,
            rate: *rate,
        },
        ProfileSpec::Harmonic {
            mean,
            amplitude,
            omega,
            phase,
        } => Profile::Harmonic {
            mean: *mean,
            amplitude: *amplitude,
            omega: *omega,
            phase: *phase,
        },
        ProfileSpec::Tabulated { time, value } => {
            if time.len() != value.len() {
                return Err(cx.err(
                    format!("{field}.value"),
                    format!("has {} entries but time has {}", value.len(), time.len()),
                ));
            }
            if time.len() < 2 {
                return Err(cx.err(format!("{field}.time"), "needs at least two points"));
            }
            if let Some(i) = time.windows(2).position(|w| w[1] <= w[0]) {
                return Err(cx.err(
                    format!("{field}.time[{}]", i + 1),
                    "times must be strictly increasing",
                ));
            }
            Profile::Spline(Spline::new(time.clone(), value.clone()))
        }
        ProfileSpec::LegLength {
            anchor,
            center,
            cos_amplitude,
            sin_amplitude,
            omega,
            offset,
        } => {
            let (a, c, u, v) = (
                v3(*anchor),
                v3(*center),
                v3(*cos_amplitude),
                v3(*sin_amplitude),
            );
            // The leg must never pass through its anchor (the length would not be smooth).
            let min_len = (0..360)
                .map(|k| {
                    let th = k as f64 * std::f64::consts::PI / 180.0;
                    (c + u * th.cos() + v * th.sin() - a).norm()
                })
                .fold(f64::INFINITY, f64::min);
            if min_len < 1e-9 {
                return Err(cx.err(field, "the path passes through the anchor"));
            }
            Profile::LegLength {
                anchor: a,
                center: c,
                cos_amp: u,
                sin_amp: v,
                omega: *omega,
                offset: *offset,
            }
        }
    })
}

fn positive(v: Option<f64>, field: String, what: &str, cx: &Ctx) -> Result<f64> {
    match v {
        None => Err(cx.err(field, format!("missing: {what}"))),
        Some(x) if x > 0.0 => Ok(x),
        Some(x) => Err(cx.err(field, format!("must be positive, got {x}"))),
    }
}

/// Geometry and laws of a clearance block; `f` is the block's field path.
fn compile_clearance(
    c: &ClearanceSpec,
    kind: JointKind,
    f: &str,
    cx: &Ctx,
) -> Result<(Geometry, NormalLaw, FrictionLaw)> {
    // A joint without play is the ideal joint; the contact laws have no meaning there (the
    // point-contact stiffness grows without bound as the clearance closes).
    if c.radial_clearance == Some(0.0) {
        return Err(cx.err(
            format!("{f}.radial_clearance"),
            "zero clearance is the ideal joint: remove the clearance block (or give a positive clearance)",
        ));
    }
    let geometry = match kind {
        JointKind::Spherical => {
            if c.model.is_some() {
                return Err(cx.err(format!("{f}.model"), "only revolute joints have a model"));
            }
            for (v, n) in [
                (c.journal_radius, "journal_radius"),
                (c.bushing_radius, "bushing_radius"),
                (c.bushing_length, "bushing_length"),
                (c.face_radius, "face_radius"),
                (c.axial_clearance, "axial_clearance"),
            ] {
                if v.is_some() {
                    return Err(cx.err(format!("{f}.{n}"), "not a field of a spherical clearance (give ball_radius and radial_clearance)"));
                }
            }
            Geometry::Spherical {
                ball_radius: positive(
                    c.ball_radius,
                    format!("{f}.ball_radius"),
                    "the ball radius (m)",
                    cx,
                )?,
                clearance: positive(
                    c.radial_clearance,
                    format!("{f}.radial_clearance"),
                    "the radial clearance (m)",
                    cx,
                )?,
            }
        }
        JointKind::Revolute => {
            if c.ball_radius.is_some() {
                return Err(cx.err(
                    format!("{f}.ball_radius"),
                    "a revolute clearance has a journal_radius",
                ));
            }
            // Any two of journal radius, bushing radius and radial clearance, each positive.
            let given = |v: Option<f64>, n: &str| {
                v.map(|x| positive(Some(x), format!("{f}.{n}"), "", cx))
                    .transpose()
            };
            let (rj, rb) = match (
                given(c.journal_radius, "journal_radius")?,
                given(c.bushing_radius, "bushing_radius")?,
                given(c.radial_clearance, "radial_clearance")?,
            ) {
                (Some(rj), Some(rb), cr) => {
                    if let Some(cr) = cr
                        && ((rb - rj) - cr).abs() > 1e-9 * rb
                    {
                        return Err(cx.err(
                            format!("{f}.radial_clearance"),
                            format!(
                                "{cr} m disagrees with bushing_radius - journal_radius = {} m",
                                rb - rj
                            ),
                        ));
                    }
                    (rj, rb)
                }
                (Some(rj), None, Some(cr)) => (rj, rj + cr),
                (None, Some(rb), Some(cr)) => {
                    if cr >= rb {
                        return Err(cx.err(
                            format!("{f}.radial_clearance"),
                            format!("{cr} m leaves no journal inside a bushing of radius {rb} m"),
                        ));
                    }
                    (rb - cr, rb)
                }
                _ => {
                    return Err(cx.err(
                        format!("{f}.radial_clearance"),
                        "missing: give two of journal_radius, bushing_radius and radial_clearance (m)",
                    ));
                }
            };
            if rb <= rj {
                return Err(cx.err(
                    format!("{f}.bushing_radius"),
                    format!("the radial clearance must be positive: bushing radius {rb} m <= journal radius {rj} m"),
                ));
            }
            match c.model.unwrap_or_default() {
                RevoluteModel::Planar => {
                    for (v, n) in [
                        (c.bushing_length, "bushing_length"),
                        (c.face_radius, "face_radius"),
                        (c.axial_clearance, "axial_clearance"),
                    ] {
                        if v.is_some() {
                            return Err(
                                cx.err(format!("{f}.{n}"), "not a field of a planar clearance")
                            );
                        }
                    }
                    Geometry::Planar {
                        journal_radius: rj,
                        bearing_radius: rb,
                    }
                }
                RevoluteModel::Spatial => {
                    let lb = positive(
                        c.bushing_length,
                        format!("{f}.bushing_length"),
                        "the bushing length (m)",
                        cx,
                    )?;
                    let journal_length = match c.axial_clearance {
                        Some(ca) => Some(
                            lb + 2.0 * positive(Some(ca), format!("{f}.axial_clearance"), "", cx)?,
                        ),
                        None => None,
                    };
                    let face_radius = match (c.face_radius, journal_length) {
                        (Some(r), _) => {
                            if r <= rb {
                                return Err(cx.err(
                                    format!("{f}.face_radius"),
                                    format!("must exceed the bushing radius {rb} m, got {r} m"),
                                ));
                            }
                            r
                        }
                        (None, Some(_)) => {
                            return Err(cx.err(format!("{f}.face_radius"), "missing: axial contact needs the bushing end-face outer radius (m)"));
                        }
                        (None, None) => rb,
                    };
                    Geometry::Revolute {
                        journal_radius: rj,
                        bushing_radius: rb,
                        bushing_length: lb,
                        face_radius,
                        journal_length,
                    }
                }
            }
        }
        k => {
            return Err(cx.err(
                f,
                format!(
                    "clearance is available for spherical and revolute joints, not {}",
                    k.name()
                ),
            ));
        }
    };

    // Normal law.
    let n = &c.normal;
    let nf = format!("{f}.normal");
    let material = |cx: &Ctx| -> Result<Option<(f64, f64)>> {
        match (n.youngs_modulus, n.poisson_ratio) {
            (None, None) => Ok(None),
            (Some(e), Some(nu)) => {
                positive(Some(e), format!("{nf}.youngs_modulus"), "", cx)?;
                if !(0.0..0.5).contains(&nu) {
                    return Err(cx.err(
                        format!("{nf}.poisson_ratio"),
                        format!("must be in [0, 0.5), got {nu}"),
                    ));
                }
                Ok(Some((e, nu)))
            }
            (Some(_), None) => Err(cx.err(
                format!("{nf}.poisson_ratio"),
                "missing: youngs_modulus needs poisson_ratio",
            )),
            (None, Some(_)) => Err(cx.err(
                format!("{nf}.youngs_modulus"),
                "missing: poisson_ratio needs youngs_modulus",
            )),
        }
    };
    let el = match n.contact {
        ContactModel::Point => {
            if n.contact_length.is_some() {
                return Err(cx.err(
                    format!("{nf}.contact_length"),
                    "only line contact has a contact length",
                ));
            }
            let exponent = match n.exponent {
                None => 1.5,
                Some(e) => positive(Some(e), format!("{nf}.exponent"), "", cx)?,
            };
            let k = match (n.stiffness, material(cx)?) {
                (Some(k), None) => positive(Some(k), format!("{nf}.stiffness"), "", cx)?,
                (None, Some((e, nu))) => {
                    let (ri, rj) = match geometry {
                        Geometry::Spherical {
                            ball_radius,
                            clearance,
                        } => (ball_radius, ball_radius + clearance),
                        Geometry::Planar {
                            journal_radius,
                            bearing_radius,
                        } => (journal_radius, bearing_radius),
                        Geometry::Revolute {
                            journal_radius,
                            bushing_radius,
                            ..
                        } => (journal_radius, bushing_radius),
                    };
                    point_contact_stiffness(ri, rj, e, nu, e, nu)
                }
                (Some(_), Some(_)) => {
                    return Err(cx.err(
                        format!("{nf}.stiffness"),
                        "give stiffness or youngs_modulus + poisson_ratio, not both",
                    ));
                }
                (None, None) => {
                    return Err(cx.err(
                        format!("{nf}.stiffness"),
                        "missing: give stiffness (N/m^n) or youngs_modulus (Pa) and poisson_ratio",
                    ));
                }
            };
            Elastic::Power { k, n: exponent }
        }
        ContactModel::Line => {
            let Geometry::Planar {
                journal_radius,
                bearing_radius,
            } = geometry
            else {
                return Err(cx.err(
                    format!("{nf}.contact"),
                    "line contact is available for planar revolute clearances (model = \"planar\")",
                ));
            };
            if n.stiffness.is_some() || n.exponent.is_some() {
                return Err(cx.err(format!("{nf}.stiffness"), "line contact derives its force from youngs_modulus and poisson_ratio; stiffness and exponent do not apply"));
            }
            let Some((e, nu)) = material(cx)? else {
                return Err(cx.err(
                    format!("{nf}.youngs_modulus"),
                    "missing: line contact needs youngs_modulus (Pa) and poisson_ratio",
                ));
            };
            let length = positive(
                n.contact_length,
                format!("{nf}.contact_length"),
                "line contact needs the contact length (m)",
                cx,
            )?;
            // Same material on both sides: 1/E* = 2 (1 - nu^2) / E.
            let e_star = e / (2.0 * (1.0 - nu * nu));
            Elastic::CylinderLine {
                c: std::f64::consts::PI * length * e_star,
                dr: bearing_radius - journal_radius,
            }
        }
    };
    let restitution = |cx: &Ctx| -> Result<f64> {
        match n.restitution {
            Some(e) if e > 0.0 && e <= 1.0 => Ok(e),
            Some(e) => Err(cx.err(
                format!("{nf}.restitution"),
                format!("must be in (0, 1], got {e}"),
            )),
            None => Err(cx.err(
                format!("{nf}.restitution"),
                "missing: this law needs the coefficient of restitution",
            )),
        }
    };
    let unused = |v: Option<f64>, name: &str, cx: &Ctx| -> Result<()> {
        if v.is_some() {
            Err(cx.err(
                format!("{nf}.{name}"),
                format!("not used by the {:?} law", n.law).to_lowercase(),
            ))
        } else {
            Ok(())
        }
    };
    let damped = |kind: Damping, cx: &Ctx| -> Result<NormalLaw> {
        unused(n.max_damping, "max_damping", cx)?;
        unused(n.full_damping_penetration, "full_damping_penetration", cx)?;
        let ce = restitution(cx)?;
        let v_floor = match n.onset_velocity_floor {
            None => 1e-3,
            Some(v) => positive(Some(v), format!("{nf}.onset_velocity_floor"), "", cx)?,
        };
        // Each law of the family restitutes a definite e(c_e) in an isolated impact; warn
        // when it misses the requested c_e by more than 0.05 and name laws that meet it.
        let got = hunt_crossley_restitution(kind.factor(ce));
        if (got - ce).abs() > 0.05 {
            let better: Vec<String> = [
                (Damping::CarvalhoMartins, "carvalho_martins"),
                (Damping::Flores, "flores"),
                (Damping::Gonthier, "gonthier"),
            ]
            .iter()
            .filter(|(k, _)| *k != kind)
            .map(|&(k, name)| (name, hunt_crossley_restitution(k.factor(ce))))
            .filter(|(_, e)| (e - ce).abs() <= 0.05)
            .map(|(name, e)| format!("law = \"{name}\" (restitutes {e:.3})"))
            .collect();
            cx.warn(
                format!("{nf}.restitution"),
                format!(
                    "the {} law is outside its range at c_e = {ce}: it was derived for c_e near 1, \
                     and an isolated impact restitutes {got:.3}, not {ce}; use {}",
                    kind.name(),
                    if better.is_empty() {
                        "a law fitted to low restitution".to_string()
                    } else {
                        better.join(" or ")
                    }
                ),
            );
        }
        Ok(NormalLaw::Hysteresis {
            el,
            kind,
            restitution: ce,
            d: kind.factor(ce),
            v_floor,
        })
    };
    let law = match n.law {
        NormalLawKind::Hertz => {
            unused(n.restitution, "restitution", cx)?;
            unused(n.max_damping, "max_damping", cx)?;
            unused(n.full_damping_penetration, "full_damping_penetration", cx)?;
            unused(n.onset_velocity_floor, "onset_velocity_floor", cx)?;
            NormalLaw::Hertz { el }
        }
        NormalLawKind::LankaraniNikravesh => damped(Damping::LankaraniNikravesh, cx)?,
        NormalLawKind::HuntCrossley => damped(Damping::HuntCrossley, cx)?,
        NormalLawKind::Flores => damped(Damping::Flores, cx)?,
        NormalLawKind::Gonthier => damped(Damping::Gonthier, cx)?,
        NormalLawKind::CarvalhoMartins => damped(Damping::CarvalhoMartins, cx)?,
        NormalLawKind::Impact => {
            unused(n.restitution, "restitution", cx)?;
            unused(n.onset_velocity_floor, "onset_velocity_floor", cx)?;
            let c_max = match n.max_damping {
                Some(c) if c >= 0.0 => c,
                Some(c) => {
                    return Err(cx.err(
                        format!("{nf}.max_damping"),
                        format!("must not be negative, got {c}"),
                    ));
                }
                None => {
                    return Err(cx.err(
                        format!("{nf}.max_damping"),
                        "missing: IMPACT needs max_damping (N s/m)",
                    ));
                }
            };
            let d_max = positive(
                n.full_damping_penetration,
                format!("{nf}.full_damping_penetration"),
                "IMPACT needs the penetration at full damping (m)",
                cx,
            )?;
            let Elastic::Power { k, n: exponent } = el else {
                return Err(cx.err(
                    format!("{nf}.contact"),
                    "IMPACT is a point-contact law (K delta^n)",
                ));
            };
            NormalLaw::Impact {
                k,
                n: exponent,
                c_max,
                d_max,
            }
        }
    };

    // Friction law.
    let ff = format!("{f}.friction");
    let mu = |m: f64, cx: &Ctx| -> Result<f64> {
        if m >= 0.0 {
            Ok(m)
        } else {
            Err(cx.err(
                format!("{ff}.coefficient"),
                format!("must not be negative, got {m}"),
            ))
        }
    };
    let friction = match &c.friction {
        FrictionSpec::None => FrictionLaw::None,
        FrictionSpec::Coulomb {
            coefficient,
            regularisation_velocity,
        } => FrictionLaw::Coulomb {
            mu: mu(*coefficient, cx)?,
            v_reg: positive(
                Some(*regularisation_velocity),
                format!("{ff}.regularisation_velocity"),
                "",
                cx,
            )?,
        },
        FrictionSpec::Ambrosio {
            coefficient,
            v0,
            v1,
        } => {
            let v0 = positive(Some(*v0), format!("{ff}.v0"), "", cx)?;
            if *v1 <= v0 {
                return Err(cx.err(
                    format!("{ff}.v1"),
                    format!("must exceed v0 = {v0} m/s, got {v1}"),
                ));
            }
            FrictionLaw::Ambrosio {
                mu: mu(*coefficient, cx)?,
                v0,
                v1: *v1,
            }
        }
        FrictionSpec::Threlfall { coefficient, v0 } => FrictionLaw::Threlfall {
            mu: mu(*coefficient, cx)?,
            v0: positive(Some(*v0), format!("{ff}.v0"), "", cx)?,
        },
    };
    Ok((geometry, law, friction))
}

impl Model {
    /// Validates and compiles a scene; returns the model and the initial state as declared
    /// (not yet assembled onto the constraints: see [`Model::assemble`]).
    pub fn compile(scene: &SceneFile) -> Result<(Model, State)> {
        let cx = Ctx {
            file: &scene.path,
            warnings: Default::default(),
        };
        // Disabled effects are removed from the scene before anything is compiled.
        let (spec, disabled) = crate::disable::apply(&scene.spec)
            .map_err(|(field, message)| cx.err(field, message))?;
        let spec = &spec;
        let raw: toml::Value = toml::from_str(&scene.text).map_err(|e| Error::Parse {
            file: scene.path.clone(),
            message: e.to_string(),
        })?;
        check_finite(&raw, "", &cx)?;

        // Bodies.
        let mut body_index: HashMap<&str, usize> = HashMap::new();
        let mut bodies = Vec::with_capacity(spec.bodies.len());
        let mut frames = Vec::with_capacity(spec.bodies.len());
        let nb = spec.bodies.len();
        let mut y = vec![0.0; 13 * nb];
        for (i, b) in spec.bodies.iter().enumerate() {
            let f = format!("bodies[{i}]");
            if b.name.is_empty() {
                return Err(cx.err(format!("{f}.name"), "empty name"));
            }
            if b.name == "ground" {
                return Err(cx.err(
                    format!("{f}.name"),
                    "'ground' is reserved for the fixed frame",
                ));
            }
            if body_index.insert(&b.name, i).is_some() {
                return Err(cx.err(
                    format!("{f}.name"),
                    format!("duplicate body name '{}'", b.name),
                ));
            }
            if b.mass <= 0.0 {
                return Err(cx.err(
                    format!("{f}.mass"),
                    format!("must be positive, got {} kg", b.mass),
                ));
            }
            let j = inertia(&b.inertia, &format!("{f}.inertia"), &cx)?;
            let rot = orientation(&b.orientation, &format!("{f}.orientation"), &cx)?;
            for (k, a) in &b.axes {
                if v3(*a).norm() < 1e-12 {
                    return Err(cx.err(format!("{f}.axes.{k}"), "zero-length axis"));
                }
            }
            let com = v3(b.com);
            let pos = v3(b.position) + rot * com;
            let q = rot.quaternion();
            y[7 * i..7 * i + 3].copy_from_slice(pos.as_slice());
            y[7 * i + 3..7 * i + 7].copy_from_slice(&[q.w, q.i, q.j, q.k]);
            let o = 7 * nb + 6 * i;
            y[o..o + 3].copy_from_slice(&b.velocity);
            y[o + 3..o + 6].copy_from_slice(&b.angular_velocity);
            bodies.push(Body {
                name: b.name.clone(),
                mass: b.mass,
                inertia: j,
                inv_inertia: j
                    .try_inverse()
                    .ok_or_else(|| cx.err(format!("{f}.inertia"), "inertia tensor is singular"))?,
                com,
            });
            frames.push(Frames {
                points: &b.points,
                axes: &b.axes,
                com,
                rot,
                pos,
                label: format!("body '{}'", b.name),
            });
        }
        for (k, a) in &spec.ground.axes {
            if v3(*a).norm() < 1e-12 {
                return Err(cx.err(format!("ground.axes.{k}"), "zero-length axis"));
            }
        }
        let ground = Frames {
            points: &spec.ground.points,
            axes: &spec.ground.axes,
            com: Vector3::zeros(),
            rot: UnitQuaternion::identity(),
            pos: Vector3::zeros(),
            label: "ground".into(),
        };
        let body_ref = |name: &str, field: String| -> Result<usize> {
            if name == "ground" {
                Ok(GROUND)
            } else {
                body_index.get(name).copied().ok_or_else(|| {
                    cx.err(
                        field,
                        format!(
                            "unknown body '{name}' (declared: ground, {})",
                            list(spec.bodies.iter().map(|b| &b.name))
                        ),
                    )
                })
            }
        };
        let frame = |i: usize| if i == GROUND { &ground } else { &frames[i] };

        // Joints.
        let mut joint_index: HashMap<&str, usize> = HashMap::new();
        let mut joints = Vec::new();
        let mut prims: Vec<(Prim, usize)> = Vec::new();
        let mut row = 0usize;
        // Per joint: (axis_a, u_a, w_a, u_b) for drives.
        let mut joint_frames = Vec::new();
        let mut clearances: Vec<Clearance> = Vec::new();
        let mut n_contacts = 0usize;
        for (i, j) in spec.joints.iter().enumerate() {
            let f = format!("joints[{i}]");
            if j.name.is_empty() {
                return Err(cx.err(format!("{f}.name"), "empty name"));
            }
            if joint_index.insert(&j.name, i).is_some() {
                return Err(cx.err(
                    format!("{f}.name"),
                    format!("duplicate joint name '{}'", j.name),
                ));
            }
            let a = body_ref(&j.body_a, format!("{f}.body_a"))?;
            let b = body_ref(&j.body_b, format!("{f}.body_b"))?;
            if a == b {
                return Err(cx.err(
                    format!("{f}.body_b"),
                    format!("joint '{}' connects '{}' to itself", j.name, j.body_a),
                ));
            }
            let (fa, fb) = (frame(a), frame(b));
            let sa = fa.point(&j.point_a, &format!("{f}.point_a"), &cx)?;
            let sb = fb.point(&j.point_b, &format!("{f}.point_b"), &cx)?;
            let (axis_a, axis_b) = if j.kind.needs_axes() {
                let ra = j.axis_a.as_ref().ok_or_else(|| {
                    cx.err(
                        format!("{f}.axis_a"),
                        format!("a {} joint needs axis_a", j.kind.name()),
                    )
                })?;
                let rb = j.axis_b.as_ref().ok_or_else(|| {
                    cx.err(
                        format!("{f}.axis_b"),
                        format!("a {} joint needs axis_b", j.kind.name()),
                    )
                })?;
                (
                    fa.axis(ra, &format!("{f}.axis_a"), &cx)?,
                    fb.axis(rb, &format!("{f}.axis_b"), &cx)?,
                )
            } else {
                if j.axis_a.is_some() || j.axis_b.is_some() {
                    return Err(cx.err(format!("{f}.axis_a"), "a spherical joint has no axes"));
                }
                (Vector3::z(), Vector3::z())
            };
            // Joint frame on a: u_a normal to axis_a, w_a = axis_a x u_a.
            let ua = match &j.reference_a {
                Some(r) => {
                    let u = fa.axis(r, &format!("{f}.reference_a"), &cx)?;
                    let p = u - axis_a * axis_a.dot(&u);
                    if p.norm() < 1e-9 {
                        return Err(cx.err(format!("{f}.reference_a"), "parallel to axis_a"));
                    }
                    p.normalize()
                }
                None => any_normal(&axis_a),
            };
            let wa = axis_a.cross(&ua);
            let ub = match &j.reference_b {
                Some(r) => {
                    let u = fb.axis(r, &format!("{f}.reference_b"), &cx)?;
                    let p = u - axis_b * axis_b.dot(&u);
                    if p.norm() < 1e-9 {
                        return Err(cx.err(format!("{f}.reference_b"), "parallel to axis_b"));
                    }
                    p.normalize()
                }
                None => {
                    let g = fb.to_local(&fa.to_global(&ua));
                    let p = g - axis_b * axis_b.dot(&g);
                    if p.norm() < 1e-6 {
                        any_normal(&axis_b)
                    } else {
                        p.normalize()
                    }
                }
            };
            let start = row;
            let mut push = |p: Prim| {
                let n = p.rows();
                prims.push((p, row));
                row += n;
            };
            let coincident = Prim::Coincident { a, sa, b, sb };
            let parallel = [
                Prim::Perpendicular {
                    a,
                    u: ua,
                    b,
                    v: axis_b,
                },
                Prim::Perpendicular {
                    a,
                    u: wa,
                    b,
                    v: axis_b,
                },
            ];
            let collinear = [
                Prim::Distance {
                    a,
                    u: ua,
                    sa,
                    b,
                    sb,
                    drive: None,
                },
                Prim::Distance {
                    a,
                    u: wa,
                    sa,
                    b,
                    sb,
                    drive: None,
                },
            ];
            let lock = Prim::Perpendicular { a, u: wa, b, v: ub };
            let mut clearance = None;
            if let Some(cs) = &j.clearance {
                let (geometry, law, friction) =
                    compile_clearance(cs, j.kind, &format!("{f}.clearance"), &cx)?;
                // The contact element replaces the joint's rows; what it leaves unconstrained
                // stays a constraint: the out-of-plane rows of a planar bearing, the axial
                // position of a spatial one without axial contact.
                match geometry {
                    Geometry::Planar { .. } => {
                        parallel.into_iter().for_each(&mut push);
                        push(Prim::Distance {
                            a,
                            u: axis_a,
                            sa,
                            b,
                            sb,
                            drive: None,
                        });
                    }
                    Geometry::Revolute {
                        journal_length: None,
                        ..
                    } => {
                        push(Prim::Distance {
                            a,
                            u: axis_a,
                            sa,
                            b,
                            sb,
                            drive: None,
                        });
                    }
                    _ => {}
                }
                clearance = Some(clearances.len());
                clearances.push(Clearance {
                    name: j.name.clone(),
                    joint: i,
                    housing: a,
                    journal: b,
                    sh: sa,
                    sj: sb,
                    axis_h: axis_a,
                    axis_j: axis_b,
                    geometry,
                    law,
                    friction,
                    first: n_contacts,
                });
                n_contacts += geometry.n_contacts();
            } else {
                match j.kind {
                    JointKind::Spherical => push(coincident),
                    JointKind::Revolute => {
                        push(coincident);
                        parallel.into_iter().for_each(&mut push);
                    }
                    JointKind::Universal => {
                        push(coincident);
                        push(Prim::Perpendicular {
                            a,
                            u: axis_a,
                            b,
                            v: axis_b,
                        });
                    }
                    JointKind::Cylindrical => {
                        parallel.into_iter().for_each(&mut push);
                        collinear.into_iter().for_each(&mut push);
                    }
                    JointKind::Prismatic => {
                        parallel.into_iter().for_each(&mut push);
                        collinear.into_iter().for_each(&mut push);
                        push(lock);
                    }
                    JointKind::Planar => {
                        parallel.into_iter().for_each(&mut push);
                        push(Prim::Distance {
                            a,
                            u: axis_a,
                            sa,
                            b,
                            sb,
                            drive: None,
                        });
                    }
                    JointKind::Fixed => {
                        push(coincident);
                        parallel.into_iter().for_each(&mut push);
                        push(lock);
                    }
                }
            }
            joint_frames.push((axis_a, ua, wa, ub, sa, sb));
            joints.push(Joint {
                name: j.name.clone(),
                kind: j.kind,
                body_a: a,
                body_b: b,
                point_a: sa,
                point_b: sb,
                rows: start..row,
                clearance,
            });
        }
        let joint_rows = row;

        // Drives.
        let mut drives = Vec::new();
        let mut names = HashSet::new();
        let mut driven = HashSet::new();
        for (i, d) in spec.drives.iter().enumerate() {
            let f = format!("drives[{i}]");
            if !names.insert(d.name.as_str()) {
                return Err(cx.err(
                    format!("{f}.name"),
                    format!("duplicate drive name '{}'", d.name),
                ));
            }
            let ji = *joint_index.get(d.joint.as_str()).ok_or_else(|| {
                cx.err(
                    format!("{f}.joint"),
                    format!(
                        "unknown joint '{}' (declared: {})",
                        d.joint,
                        list(spec.joints.iter().map(|j| &j.name))
                    ),
                )
            })?;
            let kind = joints[ji].kind;
            if joints[ji].clearance.is_some() {
                return Err(cx.err(
                    format!("{f}.joint"),
                    format!("joint '{}' has clearance: its coordinate is not prescribed by a constraint and cannot be driven", d.joint),
                ));
            }
            let coordinate = match (kind, d.coordinate) {
                (JointKind::Prismatic, None | Some(DriveCoordinate::Translation)) => {
                    DriveCoordinate::Translation
                }
                (JointKind::Revolute, None | Some(DriveCoordinate::Rotation)) => {
                    DriveCoordinate::Rotation
                }
                (JointKind::Cylindrical, Some(c)) => c,
                (JointKind::Cylindrical, None) => {
                    return Err(cx.err(
                        format!("{f}.coordinate"),
                        "a cylindrical joint needs coordinate = \"translation\" or \"rotation\"",
                    ));
                }
                (k, c) => {
                    return Err(cx.err(
                        format!("{f}.joint"),
                        format!(
                            "a {} joint has no {} coordinate to drive",
                            k.name(),
                            match c {
                                Some(DriveCoordinate::Rotation) => "rotation",
                                Some(DriveCoordinate::Translation) => "translation",
                                None => "drivable",
                            }
                        ),
                    ));
                }
            };
            if !driven.insert((ji, coordinate)) {
                return Err(cx.err(
                    format!("{f}.joint"),
                    format!("joint '{}' is already driven in that coordinate", d.joint),
                ));
            }
            let prof = profile(&d.profile, &format!("{f}.profile"), &cx)?;
            let (axis_a, ua, wa, ub, sa, sb) = joint_frames[ji];
            let (a, b) = (joints[ji].body_a, joints[ji].body_b);
            let di = drives.len();
            let p = match coordinate {
                DriveCoordinate::Translation => Prim::Distance {
                    a,
                    u: axis_a,
                    sa,
                    b,
                    sb,
                    drive: Some(di),
                },
                DriveCoordinate::Rotation => Prim::Angle {
                    a,
                    axis: axis_a,
                    ua,
                    wa,
                    b,
                    ub,
                    drive: di,
                },
            };
            prims.push((p, row));
            drives.push(Drive {
                name: d.name.clone(),
                joint: ji,
                coordinate,
                profile: prof,
                row,
            });
            row += 1;
        }
        let n_rows = row;
        // The sparse factorisation indexes its entries with 32 bits; 50 000 rows keep even a full
        // triangle (1.25e9 entries) within that, far beyond any mechanism this program is for.
        if n_rows > 50_000 {
            return Err(cx.err(
                "joints",
                format!("{n_rows} constraint rows; at most 50000 are supported"),
            ));
        }

        // Springs and loads.
        let mut springs = Vec::new();
        let mut names = HashSet::new();
        for (i, s) in spec.springs.iter().enumerate() {
            let f = format!("springs[{i}]");
            if !names.insert(s.name.as_str()) {
                return Err(cx.err(
                    format!("{f}.name"),
                    format!("duplicate spring name '{}'", s.name),
                ));
            }
            let a = body_ref(&s.body_a, format!("{f}.body_a"))?;
            let b = body_ref(&s.body_b, format!("{f}.body_b"))?;
            if a == b {
                return Err(cx.err(format!("{f}.body_b"), "a spring needs two different bodies"));
            }
            let sa = frame(a).point(&s.point_a, &format!("{f}.point_a"), &cx)?;
            let sb = frame(b).point(&s.point_b, &format!("{f}.point_b"), &cx)?;
            if s.stiffness < 0.0 {
                return Err(cx.err(format!("{f}.stiffness"), "must not be negative"));
            }
            if s.damping < 0.0 {
                return Err(cx.err(format!("{f}.damping"), "must not be negative"));
            }
            let l0 = (frame(b).global_point(&sb) - frame(a).global_point(&sa)).norm();
            let free_length = s.free_length.unwrap_or(l0);
            if free_length < 0.0 {
                return Err(cx.err(format!("{f}.free_length"), "must not be negative"));
            }
            springs.push(Spring {
                name: s.name.clone(),
                a,
                sa,
                b,
                sb,
                stiffness: s.stiffness,
                damping: s.damping,
                free_length,
            });
        }
        let mut loads = Vec::new();
        let mut names = HashSet::new();
        for (i, l) in spec.loads.iter().enumerate() {
            let f = format!("loads[{i}]");
            if !names.insert(l.name.as_str()) {
                return Err(cx.err(
                    format!("{f}.name"),
                    format!("duplicate load name '{}'", l.name),
                ));
            }
            let body = body_ref(&l.body, format!("{f}.body"))?;
            if body == GROUND {
                return Err(cx.err(format!("{f}.body"), "a load on the ground has no effect"));
            }
            let s = match &l.point {
                Some(p) => frame(body).point(p, &format!("{f}.point"), &cx)?,
                None => Vector3::zeros(),
            };
            loads.push(Load {
                name: l.name.clone(),
                body,
                s,
                force: v3(l.force),
                torque: v3(l.torque),
                frame: l.frame,
            });
        }

        // Settings.
        let sv = &spec.solver;
        // rk4 needs its step; the adaptive integrators share their settings and checks.
        let max_step = sv.max_step.unwrap_or(f64::INFINITY);
        if sv.integrator == IntegratorKind::Rk4 {
            if sv.step <= 0.0 {
                return Err(cx.err(
                    "solver.step",
                    format!("must be positive, got {} s", sv.step),
                ));
            }
        } else {
            if sv.rtol <= 0.0 {
                return Err(cx.err("solver.rtol", "must be positive"));
            }
            if sv.atol <= 0.0 {
                return Err(cx.err("solver.atol", "must be positive"));
            }
            if max_step <= 0.0 {
                return Err(cx.err("solver.max_step", "must be positive"));
            }
        }
        let method = sv.integrator.method(sv.step, sv.rtol, sv.atol, max_step);
        if sv.baumgarte_alpha < 0.0 {
            return Err(cx.err("solver.baumgarte_alpha", "must not be negative"));
        }
        if sv.baumgarte_beta < 0.0 {
            return Err(cx.err("solver.baumgarte_beta", "must not be negative"));
        }
        let mut period = None;
        for (i, d) in drives.iter().enumerate() {
            if let Some(p) = d.profile.period() {
                match period {
                    None => period = Some(p),
                    Some(q) if ((p - q) / q).abs() > 1e-9 => {
                        return Err(cx.err(
                            format!("drives[{i}].profile"),
                            format!("period {p} s differs from the other drives' period {q} s"),
                        ));
                    }
                    _ => {}
                }
            }
        }
        let end_time = match (sv.end_time, sv.periods) {
            (Some(_), Some(_)) => {
                return Err(cx.err("solver.periods", "give end_time or periods, not both"));
            }
            (Some(t), None) => t,
            (None, Some(n)) => {
                let Some(p) = period else {
                    return Err(cx.err(
                        "solver.periods",
                        "no drive has a period; give end_time instead",
                    ));
                };
                if n <= 0.0 {
                    return Err(cx.err("solver.periods", "must be positive"));
                }
                sv.start_time + n * p
            }
            (None, None) => {
                return Err(cx.err("solver.end_time", "give end_time or periods"));
            }
        };
        if end_time <= sv.start_time {
            return Err(cx.err(
                "solver.end_time",
                format!("must be after start_time = {} s", sv.start_time),
            ));
        }
        // A step so small that the run could never finish is a mistake, not a setting.
        let span = end_time - sv.start_time;
        let (step_field, step) = match method {
            Method::Dopri5 { max_step, .. }
            | Method::Dop853 { max_step, .. }
            | Method::Rosenbrock23 { max_step, .. } => ("solver.max_step", max_step),
            _ => ("solver.step", method.fixed_step().unwrap_or(f64::INFINITY)),
        };
        if span / step > 1e12 {
            return Err(cx.err(
                step_field,
                format!(
                    "{step:e} s over a span of {span} s means at least {:.3e} steps; at most 1e12 are allowed",
                    span / step
                ),
            ));
        }
        let max_penetration = match sv.max_penetration {
            None => None,
            Some(v) => Some(positive(Some(v), "solver.max_penetration".into(), "", &cx)?),
        };
        let max_drift = match sv.max_constraint_drift {
            None => 0.1,
            Some(v) => positive(Some(v), "solver.max_constraint_drift".into(), "", &cx)?,
        };
        let settings = Settings {
            method,
            alpha: sv.baumgarte_alpha,
            beta: sv.baumgarte_beta,
            start_time: sv.start_time,
            end_time,
            period,
            max_penetration,
            max_drift,
        };

        // Outputs.
        let out = &spec.output;
        let span = end_time - sv.start_time;
        let interval = out.interval.unwrap_or(span / 1000.0);
        if interval <= 0.0 {
            return Err(cx.err("output.interval", "must be positive"));
        }
        // Each sample holds O(100) numbers per body; beyond 1e8 samples the recording cannot fit
        // in memory, so refuse early instead of failing an allocation mid-run.
        let n_samples = span / interval;
        if n_samples > 1e8 {
            return Err(cx.err(
                "output.interval",
                format!("{interval} s over a span of {span} s gives {n_samples:.3e} samples; at most 1e8 are recorded"),
            ));
        }
        let pick = |sel: &Option<Vec<String>>, field: &str, all: &[&str]| -> Result<Vec<usize>> {
            match sel {
                None => Ok((0..all.len()).collect()),
                Some(v) => v
                    .iter()
                    .enumerate()
                    .map(|(k, n)| {
                        all.iter().position(|x| x == n).ok_or_else(|| {
                            cx.err(
                                format!("output.{field}[{k}]"),
                                format!("unknown name '{n}'"),
                            )
                        })
                    })
                    .collect(),
            }
        };
        let bnames: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
        let jnames: Vec<&str> = joints.iter().map(|b| b.name.as_str()).collect();
        let dnames: Vec<&str> = drives.iter().map(|b| b.name.as_str()).collect();
        let outputs = Outputs {
            interval,
            bodies: pick(&out.bodies, "bodies", &bnames)?,
            joints: pick(&out.joints, "joints", &jnames)?,
            drives: pick(&out.drives, "drives", &dnames)?,
            accelerations: out.accelerations,
            diagnostics: out.diagnostics,
            energy: out.diagnostics && out.energy,
        };

        let gravity = spec.gravity.map(v3);
        let effects = Effects {
            gravity: gravity.is_some_and(|g| g.norm() > 0.0),
            springs: !springs.is_empty(),
            loads: !loads.is_empty(),
            constraints: n_rows > 0,
            drives: !drives.is_empty(),
            clearance: !clearances.is_empty(),
            friction: clearances.iter().any(|c| !c.friction.is_none()),
            axial_contact: clearances.iter().any(|c| {
                matches!(
                    c.geometry,
                    Geometry::Revolute {
                        journal_length: Some(_),
                        ..
                    }
                )
            }),
        };
        let blocks: Vec<_> = prims.iter().map(|(p, r0)| p.row_block(*r0)).collect();
        let coupling = crate::coupling::Coupling::new(bodies.len(), &blocks, n_rows);
        let model = Model {
            name: scene.name(),
            file: scene.path.clone(),
            description: spec.description.clone(),
            bodies,
            joints,
            drives,
            springs,
            loads,
            gravity,
            prims,
            clearances,
            n_contacts,
            joint_rows,
            n_rows,
            coupling,
            effects,
            disabled,
            settings,
            outputs,
            warnings: cx.warnings.take(),
        };
        let state = State {
            t: model.settings.start_time,
            y,
        };
        Ok((model, state))
    }

    /// Number of bodies.
    pub fn nb(&self) -> usize {
        self.bodies.len()
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
