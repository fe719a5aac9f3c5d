//! The scene file: a mechanism declared in TOML, in SI units (m, kg, s, rad, N).
//!
//! [`SceneSpec`] maps the file one to one (serde, unknown fields rejected). [`SceneSpec::load`]
//! reads and parses it; [`crate::model::Model::compile`] validates it and builds the simulation
//! model. The format is documented with examples in the book (book/src/reference/scene.md).
//!
//! Conventions:
//! * every body has a body frame; `com` is the centre of mass in that frame, `inertia` is the
//!   inertia tensor about the centre of mass in body axes (kg m^2);
//! * `position` is the initial global position of the body-frame origin, `orientation` the initial
//!   rotation from body to global axes, `velocity` the initial velocity of the centre of mass and
//!   `angular_velocity` the initial angular velocity, both in global axes;
//! * named `points` and `axes` live in their body's frame (on `[ground]`, in global coordinates); a
//!   joint names them, or gives coordinates inline.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::film::FilmModel;
use crate::ode::{Integrator, Method};

pub mod units;

/// Fixed-length vectors of the scene format (`[x, y, z]`, a quaternion). TOML's deserializer
/// hands an array's elements to serde's `[f64; N]` one by one and leaves those after the Nth
/// unread, so `gravity = [0, -9.81, 0, 5]` was taken as its first three components. These read
/// the whole array and refuse any other length (the field path is added by the caller).
pub mod fixed {
    use std::collections::BTreeMap;

    use serde::de::{Deserialize, Deserializer, Error, SeqAccess, Visitor};

    /// An array of exactly N numbers.
    struct Exact<const N: usize>([f64; N]);

    impl<'de, const N: usize> Deserialize<'de> for Exact<N> {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct Numbers<const N: usize>;
            impl<'de, const N: usize> Visitor<'de> for Numbers<N> {
                type Value = Exact<N>;
                fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                    write!(f, "an array of {N} numbers")
                }
                fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Exact<N>, A::Error> {
                    let mut out = [0.0; N];
                    let mut n = 0;
                    while let Some(x) = seq.next_element::<f64>()? {
                        if let Some(slot) = out.get_mut(n) {
                            *slot = x;
                        }
                        n += 1;
                    }
                    if n != N {
                        return Err(A::Error::invalid_length(n, &self));
                    }
                    Ok(Exact(out))
                }
            }
            d.deserialize_seq(Numbers::<N>)
        }
    }

    /// `[f64; N]`, refusing an array of another length.
    pub fn array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
        Exact::<N>::deserialize(d).map(|e| e.0)
    }

    /// `Option<[f64; N]>`, refusing an array of another length.
    pub fn option<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<Option<[f64; N]>, D::Error> {
        Option::<Exact<N>>::deserialize(d).map(|o| o.map(|e| e.0))
    }

    /// Named `[f64; N]`s, refusing an array of another length.
    pub fn map<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<BTreeMap<String, [f64; N]>, D::Error> {
        let m = BTreeMap::<String, Exact<N>>::deserialize(d)?;
        Ok(m.into_iter().map(|(k, v)| (k, v.0)).collect())
    }
}

/// A whole scene file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// Scene name (defaults to the file stem); names the output file.
    #[serde(default)]
    pub name: Option<String>,
    /// Free text shown by `jointplay check`.
    #[serde(default)]
    pub description: Option<String>,
    /// Gravitational acceleration vector (m/s^2, global). Absent: no gravity.
    #[serde(default, deserialize_with = "fixed::option")]
    pub gravity: Option<[f64; 3]>,
    /// The fixed frame: named points and axes in global coordinates.
    #[serde(default)]
    pub ground: GroundSpec,
    #[serde(default)]
    pub bodies: Vec<BodySpec>,
    #[serde(default)]
    pub joints: Vec<JointSpec>,
    #[serde(default)]
    pub drives: Vec<DriveSpec>,
    #[serde(default)]
    pub springs: Vec<SpringSpec>,
    #[serde(default)]
    pub loads: Vec<LoadSpec>,
    #[serde(default)]
    pub solver: SolverSpec,
    #[serde(default)]
    pub output: OutputSpec,
    /// Effects switched off (see [`crate::disable`]): "friction", "S2.friction",
    /// "axial_contact", "gravity", ...
    #[serde(default)]
    pub disable: Vec<String>,
}

/// Points and axes fixed in the global frame.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GroundSpec {
    #[serde(default, deserialize_with = "fixed::map")]
    pub points: BTreeMap<String, [f64; 3]>,
    #[serde(default, deserialize_with = "fixed::map")]
    pub axes: BTreeMap<String, [f64; 3]>,
}

/// A rigid body.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    pub name: String,
    /// Mass (kg), > 0.
    pub mass: f64,
    /// Inertia tensor about the centre of mass, body axes (kg m^2).
    pub inertia: InertiaSpec,
    /// Centre of mass in the body frame (m).
    #[serde(default, deserialize_with = "fixed::array")]
    pub com: [f64; 3],
    /// Initial global position of the body-frame origin (m).
    #[serde(default, deserialize_with = "fixed::array")]
    pub position: [f64; 3],
    /// Initial orientation (body to global).
    #[serde(default)]
    pub orientation: OrientationSpec,
    /// Initial velocity of the centre of mass (m/s, global).
    #[serde(default, deserialize_with = "fixed::array")]
    pub velocity: [f64; 3],
    /// Initial angular velocity (rad/s, global).
    #[serde(default, deserialize_with = "fixed::array")]
    pub angular_velocity: [f64; 3],
    /// Named points in the body frame (m).
    #[serde(default, deserialize_with = "fixed::map")]
    pub points: BTreeMap<String, [f64; 3]>,
    /// Named directions in the body frame (need not be unit length).
    #[serde(default, deserialize_with = "fixed::map")]
    pub axes: BTreeMap<String, [f64; 3]>,
    /// Shapes that draw the body in `jointplay animate` and its glTF file, in place of the
    /// bars between its joint points; they take no part in the dynamics.
    #[serde(default)]
    pub visual: Vec<VisualSpec>,
}

/// A shape that draws a body (`[[bodies.visual]]`), placed in the body frame (m).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum VisualSpec {
    /// A box of edge lengths `size` along its axes, centred at `at`.
    Box {
        #[serde(deserialize_with = "fixed::array")]
        size: [f64; 3],
        #[serde(default, deserialize_with = "fixed::array")]
        at: [f64; 3],
        /// The box's axes in the body frame (default: the body's).
        #[serde(default)]
        orientation: OrientationSpec,
        #[serde(default)]
        color: Option<String>,
    },
    /// A cylinder of `radius` and `length` along `axis`, centred at `at`.
    Cylinder {
        radius: f64,
        length: f64,
        #[serde(default, deserialize_with = "fixed::array")]
        at: [f64; 3],
        /// Default: the body frame's z.
        #[serde(default, deserialize_with = "fixed::option")]
        axis: Option<[f64; 3]>,
        #[serde(default)]
        color: Option<String>,
    },
    /// A sphere of `radius` centred at `at`.
    Sphere {
        radius: f64,
        #[serde(default, deserialize_with = "fixed::array")]
        at: [f64; 3],
        #[serde(default)]
        color: Option<String>,
    },
    /// A triangle mesh read from an OBJ or STL file (relative to the scene's folder), its
    /// coordinates times `scale` (1 when they are in m; 0.001 for mm), placed by `orientation`
    /// and then `at`.
    Mesh {
        file: String,
        #[serde(default)]
        scale: Option<f64>,
        #[serde(default, deserialize_with = "fixed::array")]
        at: [f64; 3],
        #[serde(default)]
        orientation: OrientationSpec,
        #[serde(default)]
        color: Option<String>,
    },
}

/// Inertia tensor components (kg m^2); products of inertia default to zero.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InertiaSpec {
    pub ixx: f64,
    pub iyy: f64,
    pub izz: f64,
    #[serde(default)]
    pub ixy: f64,
    #[serde(default)]
    pub ixz: f64,
    #[serde(default)]
    pub iyz: f64,
}

/// An orientation: exactly one of `axis` + `angle`, `quaternion` (w, x, y, z), or `x` + `y`
/// (the body's x and y axes in global coordinates; z = x cross y). Empty: identity.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OrientationSpec {
    #[serde(default, deserialize_with = "fixed::option")]
    pub axis: Option<[f64; 3]>,
    /// Rotation angle about `axis` (rad; or a string with a unit, `"30 deg"`: [`units`]).
    #[serde(default, deserialize_with = "units::option_angle")]
    pub angle: Option<f64>,
    #[serde(default, deserialize_with = "fixed::option")]
    pub quaternion: Option<[f64; 4]>,
    #[serde(default, deserialize_with = "fixed::option")]
    pub x: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "fixed::option")]
    pub y: Option<[f64; 3]>,
}

/// A point or an axis: the name of one declared on the body, or coordinates in the body frame.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(
    untagged,
    expecting = "the name of a declared point or axis, or coordinates [x, y, z]"
)]
pub enum VecRef {
    Name(String),
    #[serde(deserialize_with = "fixed::array")]
    Coords([f64; 3]),
}

/// Kinds of ideal joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    /// Points coincide (3 rows).
    Spherical,
    /// Points coincide, axes parallel (5 rows).
    Revolute,
    /// Points coincide, axis_a perpendicular to axis_b (4 rows).
    Universal,
    /// Axes parallel and collinear, no rotation about them (5 rows).
    Prismatic,
    /// Axes parallel and collinear (4 rows).
    Cylindrical,
    /// Axes parallel, point_b in the plane through point_a normal to axis_a (3 rows).
    Planar,
    /// No relative motion (6 rows).
    Fixed,
}

impl JointKind {
    /// Whether the joint needs `axis_a`/`axis_b`.
    pub fn needs_axes(self) -> bool {
        !matches!(self, JointKind::Spherical)
    }
    pub fn name(self) -> &'static str {
        match self {
            JointKind::Spherical => "spherical",
            JointKind::Revolute => "revolute",
            JointKind::Universal => "universal",
            JointKind::Prismatic => "prismatic",
            JointKind::Cylindrical => "cylindrical",
            JointKind::Planar => "planar",
            JointKind::Fixed => "fixed",
        }
    }
}

/// An ideal joint between `body_a` and `body_b` ("ground" for the fixed frame).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    pub name: String,
    pub kind: JointKind,
    pub body_a: String,
    pub body_b: String,
    /// Joint point on body a (name or body-frame coordinates).
    pub point_a: VecRef,
    /// Joint point on body b.
    pub point_b: VecRef,
    /// Joint axis on body a (all kinds but spherical).
    #[serde(default)]
    pub axis_a: Option<VecRef>,
    /// Joint axis on body b.
    #[serde(default)]
    pub axis_b: Option<VecRef>,
    /// Direction on body a, normal to axis_a, from which the joint angle is measured
    /// (default: any normal; the angle is then zero in the initial pose).
    #[serde(default)]
    pub reference_a: Option<VecRef>,
    /// Direction on body b that lies along reference_a at joint angle zero
    /// (default: reference_a as seen from body b in the initial pose).
    #[serde(default)]
    pub reference_b: Option<VecRef>,
    /// Turns a spherical, revolute or prismatic joint into a joint with clearance: the housing
    /// (socket, bushing, guide) is on body_a at point_a, the journal (ball, pin, slider) on
    /// body_b at point_b.
    #[serde(default)]
    pub clearance: Option<ClearanceSpec>,
}

/// How a revolute joint with clearance is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RevoluteModel {
    /// Journal free to translate and tilt in the bushing: radial contact at both rims, axial
    /// contact at both faces when `axial_clearance` is given.
    #[default]
    Spatial,
    /// Journal in bearing in the plane normal to axis_a (planar mechanisms): the joint keeps its
    /// three out-of-plane rows and one radial contact replaces the in-plane ones.
    Planar,
}

/// Clearance block of a joint (lengths in m). One struct for every geometry, because the file
/// does not name the geometry (the joint kind and `model` imply it); the scene compiler sorts it
/// into a per-geometry enum and refuses the fields of another geometry (`compile/clearance.rs`).
///
/// Its lengths (m) may be given with a unit, `radial_clearance = "0.1 mm"` ([`units`]).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ClearanceSpec {
    /// Revolute joints only: spatial (default) or planar.
    #[serde(default)]
    pub model: Option<RevoluteModel>,
    /// Spherical: ball radius.
    #[serde(default, deserialize_with = "units::option_length")]
    pub ball_radius: Option<f64>,
    /// Revolute: journal radius.
    #[serde(default, deserialize_with = "units::option_length")]
    pub journal_radius: Option<f64>,
    /// Revolute: bushing (bearing) inner radius; default journal_radius + radial_clearance.
    #[serde(default, deserialize_with = "units::option_length")]
    pub bushing_radius: Option<f64>,
    /// Radial clearance (socket radius - ball radius, or bushing - journal radius); for a
    /// prismatic joint the gap on each side between slider and guide.
    #[serde(default, deserialize_with = "units::option_length")]
    pub radial_clearance: Option<f64>,
    /// Prismatic: the slider's length along the axis and its height across it, along the
    /// joint's `reference_a` (the guide's faces are normal to that direction).
    #[serde(default, deserialize_with = "units::option_length")]
    pub slider_length: Option<f64>,
    #[serde(default, deserialize_with = "units::option_length")]
    pub slider_height: Option<f64>,
    /// Prismatic, spatial model: the slider's width along axis_a x reference_a.
    #[serde(default, deserialize_with = "units::option_length")]
    pub slider_width: Option<f64>,
    /// Spatial revolute: bushing length L_B.
    #[serde(default, deserialize_with = "units::option_length")]
    pub bushing_length: Option<f64>,
    /// Spatial revolute: outer radius of the bushing end faces R_B2.
    #[serde(default, deserialize_with = "units::option_length")]
    pub face_radius: Option<f64>,
    /// Spatial revolute: axial clearance per side, (L_J - L_B)/2. Absent: no axial contact, the
    /// axial position is held by a constraint row.
    #[serde(default, deserialize_with = "units::option_length")]
    pub axial_clearance: Option<f64>,
    pub normal: NormalSpec,
    #[serde(default)]
    pub friction: FrictionSpec,
    /// How a run starts in this joint: `closed` (default) assembles the start with the joint
    /// held as its ideal joint, the journal concentric or at `initial_eccentricity`, and then
    /// releases it; `free` leaves the journal where the declared poses put it (the loops
    /// through the joint are not closed, and the journal may start inside the wall).
    #[serde(default)]
    pub start: Option<JointStart>,
    /// The journal (ball) centre's offset from the housing (socket) centre at the start (m, in
    /// the housing body's axes; normal to the axis for a revolute joint); default concentric.
    /// Only with `start = "closed"`.
    #[serde(default)]
    pub initial_eccentricity: Option<[f64; 3]>,
    /// Revolute joints: an oil film in the clearance ([`crate::film`]), with the dry laws above
    /// for asperity contact at the wall.
    #[serde(default)]
    pub lubrication: Option<LubricationSpec>,
}

/// A clearance block's `lubrication` table ([`crate::film`]; SI units, lengths may carry a
/// unit).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LubricationSpec {
    /// The film model: `short` (Ocvirk's short bearing, the default).
    #[serde(default)]
    pub model: FilmModel,
    /// Dynamic viscosity of the oil (Pa s).
    pub viscosity: f64,
    /// Length of the bearing (m); a spatial revolute's default is its bushing length.
    #[serde(default, deserialize_with = "units::option_length")]
    pub length: Option<f64>,
    /// Eccentricity ratio above which the film force is held at its value there (default 0.95).
    #[serde(default)]
    pub eccentricity_limit: Option<f64>,
}

/// How a clearance joint starts (see [`ClearanceSpec::start`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JointStart {
    /// Assembled as the ideal joint (concentric or at the given eccentricity), then released.
    #[default]
    Closed,
    /// Left where the declared poses put it.
    Free,
}

// The contact-law fields live next to the laws (crate::contact), so that a new law is written
// in one place; they are part of the scene format and re-exported here.
pub use crate::contact::{
    ContactModel, DampedSpec, ElasticSpec, FrictionSpec, ImpactSpec, NormalSpec,
};

/// Which joint coordinate a drive prescribes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveCoordinate {
    /// Displacement of point_b from point_a along axis_a (m): prismatic, cylindrical.
    Translation,
    /// Angle of reference_b from reference_a about axis_a (rad): revolute, cylindrical.
    Rotation,
}

/// A prescribed joint coordinate.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSpec {
    pub name: String,
    /// The driven joint.
    pub joint: String,
    /// Default: translation for prismatic, rotation for revolute; required for cylindrical.
    #[serde(default)]
    pub coordinate: Option<DriveCoordinate>,
    pub profile: ProfileSpec,
}

/// A function of time s(t) (m or rad) with its first two derivatives. Its lengths, angles and
/// rates may be given with a unit (`rate = "120 rpm"`, [`units`]).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProfileSpec {
    /// s = initial + rate t.
    ConstantRate {
        #[serde(deserialize_with = "units::coordinate")]
        initial: f64,
        #[serde(deserialize_with = "units::coordinate_rate")]
        rate: f64,
        /// Seconds over which the speed rises from rest to `rate` (0: none; see
        /// [`crate::profile`]).
        #[serde(default)]
        ramp_time: f64,
    },
    /// s = mean + amplitude sin(omega t + phase).
    Harmonic {
        #[serde(deserialize_with = "units::coordinate")]
        mean: f64,
        #[serde(deserialize_with = "units::coordinate")]
        amplitude: f64,
        /// Angular frequency (rad/s).
        #[serde(deserialize_with = "units::angular_rate")]
        omega: f64,
        #[serde(default, deserialize_with = "units::angle")]
        phase: f64,
        /// Seconds over which the drive's speed rises from rest to omega (0: none; see
        /// [`crate::profile`]).
        #[serde(default)]
        ramp_time: f64,
    },
    /// Natural cubic spline through (time, value); constant outside the table.
    Tabulated { time: Vec<f64>, value: Vec<f64> },
    /// Length of a leg from a fixed `anchor` to a point moving on the harmonic path
    /// p(t) = center + cos_amplitude cos(omega t) + sin_amplitude sin(omega t), plus `offset`:
    /// the inverse kinematics of a parallel mechanism whose platform translates on an ellipse.
    LegLength {
        #[serde(deserialize_with = "fixed::array")]
        anchor: [f64; 3],
        #[serde(deserialize_with = "fixed::array")]
        center: [f64; 3],
        #[serde(deserialize_with = "fixed::array")]
        cos_amplitude: [f64; 3],
        #[serde(deserialize_with = "fixed::array")]
        sin_amplitude: [f64; 3],
        #[serde(deserialize_with = "units::angular_rate")]
        omega: f64,
        #[serde(default, deserialize_with = "units::length")]
        offset: f64,
        /// Seconds over which the drive's speed rises from rest to omega (0: none; see
        /// [`crate::profile`]).
        #[serde(default)]
        ramp_time: f64,
    },
}

/// A linear spring-damper between two points; force = stiffness (l - free_length) + damping l'.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    pub name: String,
    pub body_a: String,
    pub point_a: VecRef,
    pub body_b: String,
    pub point_b: VecRef,
    /// N/m.
    pub stiffness: f64,
    /// N s/m.
    #[serde(default)]
    pub damping: f64,
    /// m; default: the initial distance.
    #[serde(default)]
    pub free_length: Option<f64>,
}

/// Frame in which a load's vectors are given.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LoadFrame {
    #[default]
    Global,
    Body,
}

/// A constant applied force (at a point) and torque on a body.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    pub name: String,
    pub body: String,
    /// Point of application (default: centre of mass).
    #[serde(default)]
    pub point: Option<VecRef>,
    /// N.
    #[serde(default, deserialize_with = "fixed::array")]
    pub force: [f64; 3],
    /// N m.
    #[serde(default, deserialize_with = "fixed::array")]
    pub torque: [f64; 3],
    #[serde(default)]
    pub frame: LoadFrame,
}

/// The integrator a scene selects by its name (`integrator = "dopri5"`): one of
/// [`crate::ode::INTEGRATORS`], rk4 by default. An unknown name is rejected with the list of the
/// known ones, as for any enumerated value.
#[derive(Debug, Clone, Copy)]
pub struct IntegratorKind(pub &'static Integrator);

impl Default for IntegratorKind {
    fn default() -> Self {
        IntegratorKind(&crate::ode::rk4::RK4)
    }
}

impl PartialEq for IntegratorKind {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.0, other.0)
    }
}

impl Eq for IntegratorKind {}

impl IntegratorKind {
    /// The method of this kind ([`Integrator::method`]): the tolerances and step bound (s) for
    /// an integrator with error control, else `step` (s) (the other settings are ignored). The
    /// callers check the values.
    pub fn method(self, step: f64, rtol: f64, atol: f64, max_step: f64) -> Method {
        self.0.method(step, rtol, atol, max_step)
    }
}

impl Serialize for IntegratorKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let index = Integrator::names()
            .iter()
            .position(|n| *n == self.0.name)
            .unwrap_or_default();
        s.serialize_unit_variant("IntegratorKind", index as u32, self.0.name)
    }
}

impl<'de> Deserialize<'de> for IntegratorKind {
    /// Read as an enumeration of the integrators' names, so that errors read as those of any
    /// other enumerated value.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Names;
        impl<'de> serde::de::Visitor<'de> for Names {
            type Value = IntegratorKind;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an integrator name")
            }
            fn visit_enum<A: serde::de::EnumAccess<'de>>(
                self,
                data: A,
            ) -> std::result::Result<IntegratorKind, A::Error> {
                use serde::de::{Error as _, VariantAccess as _};
                let (name, variant): (String, _) = data.variant()?;
                let Some(integrator) = Integrator::named(&name) else {
                    return Err(A::Error::unknown_variant(&name, Integrator::names()));
                };
                variant.unit_variant()?;
                Ok(IntegratorKind(integrator))
            }
        }
        d.deserialize_enum("IntegratorKind", Integrator::names(), Names)
    }
}

/// Solver settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    #[serde(default)]
    pub integrator: IntegratorKind,
    /// Fixed step for rk4 (s).
    #[serde(default = "default_step")]
    pub step: f64,
    /// Relative and absolute tolerances of the adaptive integrators (bs3, dopri5, dop853,
    /// rosenbrock23, ros34pw2).
    #[serde(default = "default_rtol")]
    pub rtol: f64,
    #[serde(default = "default_atol")]
    pub atol: f64,
    /// Largest step of the adaptive integrators (s); default unlimited.
    #[serde(default)]
    pub max_step: Option<f64>,
    /// Baumgarte stabilisation Phi'' + 2 alpha Phi' + beta^2 Phi = 0 (1/s).
    #[serde(default = "default_baumgarte")]
    pub baumgarte_alpha: f64,
    #[serde(default = "default_baumgarte")]
    pub baumgarte_beta: f64,
    /// Start time (s).
    #[serde(default)]
    pub start_time: f64,
    /// End time (s); or give `periods` of the drive.
    #[serde(default)]
    pub end_time: Option<f64>,
    /// Number of drive periods to simulate (needs a periodic drive).
    #[serde(default)]
    pub periods: Option<f64>,
    /// Divergence guard: the largest penetration (m) any contact may reach before the run stops
    /// as diverged; default one tenth of the joint's journal (ball) radius.
    #[serde(default)]
    pub max_penetration: Option<f64>,
    /// Divergence guard: the largest constraint residual |Phi_i| (m or rad) before the run stops
    /// as diverged; default 0.1.
    #[serde(default)]
    pub max_constraint_drift: Option<f64>,
    /// Contact onsets as integrator events: a step in which a contact begins ends at the onset,
    /// located on the dense output, and the next starts there with a fresh first stage and a
    /// fresh step-size estimate, instead of stepping over the kink of the contact force. Off by
    /// default (the results of earlier versions are reproduced bit for bit).
    #[serde(default)]
    pub onset_events: bool,
    /// Contact ends as integrator events: a step in which a contact ends (its penetration falls
    /// back to zero) ends there, located and restarted as an onset is; the force, smooth while
    /// the contact is closed, loses its smoothness where it ends as where it begins. Off by
    /// default (the results of earlier versions are reproduced bit for bit).
    #[serde(default)]
    pub end_events: bool,
    /// Friction kinks as integrator events: a step in which a penetrating contact's sliding speed
    /// crosses a speed where its friction law's coefficient has a kink (Ambrosio's v0 and v1,
    /// the regularised Coulomb's v_reg) ends there, located and restarted as an onset is; so
    /// does a step in which such a contact begins, with `onset_events` off too. Independent of
    /// the other two settings. Off by default (the results of earlier versions are reproduced
    /// bit for bit).
    #[serde(default)]
    pub friction_events: bool,
}

fn default_step() -> f64 {
    1e-4
}
fn default_rtol() -> f64 {
    1e-8
}
fn default_atol() -> f64 {
    1e-10
}
fn default_baumgarte() -> f64 {
    5.0
}

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec {
            integrator: IntegratorKind::default(),
            step: default_step(),
            rtol: default_rtol(),
            atol: default_atol(),
            max_step: None,
            baumgarte_alpha: default_baumgarte(),
            baumgarte_beta: default_baumgarte(),
            start_time: 0.0,
            end_time: None,
            periods: None,
            max_penetration: None,
            max_constraint_drift: None,
            onset_events: false,
            end_events: false,
            friction_events: false,
        }
    }
}

/// What to record.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Sampling interval (s); default: 1/1000 of the simulated span.
    #[serde(default)]
    pub interval: Option<f64>,
    /// Bodies to record (default: all).
    #[serde(default)]
    pub bodies: Option<Vec<String>>,
    /// Joints whose reactions are recorded (default: all).
    #[serde(default)]
    pub joints: Option<Vec<String>>,
    /// Drives whose coordinate and actuator force are recorded (default: all).
    #[serde(default)]
    pub drives: Option<Vec<String>>,
    /// Record accelerations (default true).
    #[serde(default = "yes")]
    pub accelerations: bool,
    /// Record constraint drift, velocity drift and energy (default true).
    #[serde(default = "yes")]
    pub diagnostics: bool,
    /// Record the mechanical energy with the diagnostics (default true).
    #[serde(default = "yes")]
    pub energy: bool,
    /// Mantissa bits each recorded value keeps in the file (1 to 52), for every value or by
    /// quantity; a value is rounded to the nearest double with that many, a relative error of
    /// at most 2^-(bits+1). Default: every bit, the values exactly as computed. Sample times,
    /// flags and the final state are never rounded.
    #[serde(default)]
    pub significant_bits: Option<SignificantBits>,
}

/// `output.significant_bits`: one bit count for every recorded value (`significant_bits = 28`),
/// or counts by quantity, the last part of a dataset's name in the run file, with `default` for
/// the quantities not named (`significant_bits = { default = 28, reaction_force = 16 }`; the
/// names are [`crate::model::ROUNDED_QUANTITIES`]). The counts are checked when the scene is
/// compiled, so that a count out of range is named with its field.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum SignificantBits {
    All(i64),
    ByQuantity(BTreeMap<String, i64>),
}

impl<'de> Deserialize<'de> for SignificantBits {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = SignificantBits;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a bit count (1 to 52) or a table of bit counts by quantity")
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Self::Value, E> {
                Ok(SignificantBits::All(v))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Self::Value, E> {
                Ok(SignificantBits::All(i64::try_from(v).unwrap_or(i64::MAX)))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                // A key given twice is refused by the TOML parser before this.
                let by = BTreeMap::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(SignificantBits::ByQuantity(by))
            }
        }
        d.deserialize_any(Visit)
    }
}

fn yes() -> bool {
    true
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            interval: None,
            bodies: None,
            joints: None,
            drives: None,
            accelerations: true,
            diagnostics: true,
            energy: true,
            significant_bits: None,
        }
    }
}

/// A scene as read from disk, with the file it came from and its text.
#[derive(Debug, Clone)]
pub struct SceneFile {
    pub path: PathBuf,
    pub text: String,
    pub spec: SceneSpec,
}

/// Deserialises TOML `text` read from `file`; a schema error names the field path
/// (`bodies[0].mass`) before the parser's own message with line, column and the offending text.
pub fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, file: &Path) -> Result<T> {
    let err = |message: String| Error::Parse {
        file: file.to_path_buf(),
        // The parser quotes the offending line and value in full.
        message: crate::error::clip_lines(message.trim_end(), 3 * crate::error::ECHO_LIMIT)
            .into_owned(),
    };
    let de = toml::Deserializer::parse(text).map_err(|e| err(e.to_string()))?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let mut path = e.path().to_string();
        // Inside an internally tagged enum (a contact law, a profile) the path stops at the
        // table; an unknown field is named as in any other table.
        if let Some(field) = unknown_field(e.inner().message())
            && !matches!(e.path().iter().next_back(),
                Some(serde_path_to_error::Segment::Map { key }) if key == field)
        {
            path = if path.is_empty() || path == "." {
                field.to_string()
            } else {
                format!("{path}.{field}")
            };
        }
        // A key of the file (an unknown field) is echoed input too.
        let path = crate::error::clip(&path);
        let inner = e.into_inner().to_string();
        if path.is_empty() || path == "." {
            err(inner)
        } else {
            err(format!("{path}: {inner}"))
        }
    })
}

/// The field serde's "unknown field `x`, expected ..." message names.
fn unknown_field(message: &str) -> Option<&str> {
    let rest = message.strip_prefix("unknown field `")?;
    rest.split_once('`').map(|(field, _)| field)
}

impl SceneSpec {
    /// Parses scene text; `file` names the source in errors.
    pub fn parse(text: &str, file: &Path) -> Result<SceneSpec> {
        let spec: SceneSpec = parse_toml(text, file)?;
        // A unit of the wrong kind for a drive's coordinate (read again from the text: the
        // values are in SI by now). The text parsed once, so it parses again.
        if spec.drives.is_empty() {
            return Ok(spec);
        }
        let doc: toml::Table = parse_toml(text, file)?;
        units::check_drives(&doc, &spec).map_err(|(field, message)| Error::Parse {
            file: file.to_path_buf(),
            message: format!("{field}: {message}"),
        })?;
        Ok(spec)
    }

    /// Reads and parses a scene file.
    pub fn load(path: &Path) -> Result<SceneFile> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            file: path.to_path_buf(),
            source,
        })?;
        let spec = SceneSpec::parse(&text, path)?;
        Ok(SceneFile {
            path: path.to_path_buf(),
            text,
            spec,
        })
    }
}

impl SceneFile {
    /// The scene's name: its `name` field, else the file stem.
    pub fn name(&self) -> String {
        self.spec.name.clone().unwrap_or_else(|| {
            self.path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into())
        })
    }
}

#[cfg(test)]
mod tests;
