//! Pass 2: bodies. Checks names, masses, inertia tensors, orientations and declared axes, and
//! produces the bodies, the initial state as declared and the frames in which the later passes
//! resolve named points and axes.

use std::collections::{BTreeMap, HashMap};

use nalgebra::{Matrix3, SymmetricEigen, UnitQuaternion, Vector3};

use super::ctx::{Ctx, list, v3};
use crate::error::Result;
use crate::model::{Body, GROUND, Shape, Visual};
use crate::scene::{BodySpec, InertiaSpec, OrientationSpec, SceneSpec, VecRef, VisualSpec};

/// What the bodies pass produces.
pub(crate) struct Bodies<'s> {
    pub bodies: Vec<Body>,
    /// The initial state as declared (see [`crate::model::State`]).
    pub y: Vec<f64>,
    frames: Vec<Frames<'s>>,
    ground: Frames<'s>,
    index: HashMap<&'s str, usize>,
}

impl Bodies<'_> {
    /// The index of the body called `name` ([`GROUND`] for "ground"); `field` names the reference.
    pub fn index(&self, name: &str, field: String, cx: &Ctx) -> Result<usize> {
        if name == "ground" {
            return Ok(GROUND);
        }
        self.index.get(name).copied().ok_or_else(|| {
            cx.err(
                field,
                format!(
                    "unknown body '{name}' (declared: ground, {})",
                    list(self.bodies.iter().map(|b| &b.name))
                ),
            )
        })
    }

    /// The frame of body `i` (or of the ground).
    pub fn frame(&self, i: usize) -> &Frames<'_> {
        if i == GROUND {
            &self.ground
        } else {
            &self.frames[i]
        }
    }
}

/// Compiles `spec.bodies` and the ground's axes.
pub(crate) fn compile<'s>(spec: &'s SceneSpec, cx: &Ctx) -> Result<Bodies<'s>> {
    let nb = spec.bodies.len();
    let mut index: HashMap<&str, usize> = HashMap::new();
    let mut bodies = Vec::with_capacity(nb);
    let mut frames = Vec::with_capacity(nb);
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
        if index.insert(&b.name, i).is_some() {
            return Err(cx.err(
                format!("{f}.name"),
                format!("duplicate body name '{}'", b.name),
            ));
        }
        let (body, frame) = body(b, &f, cx)?;
        let q = frame.rot.quaternion();
        y[7 * i..7 * i + 3].copy_from_slice(frame.pos.as_slice());
        y[7 * i + 3..7 * i + 7].copy_from_slice(&[q.w, q.i, q.j, q.k]);
        let o = 7 * nb + 6 * i;
        y[o..o + 3].copy_from_slice(&b.velocity);
        y[o + 3..o + 6].copy_from_slice(&b.angular_velocity);
        bodies.push(body);
        frames.push(frame);
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
    Ok(Bodies {
        bodies,
        y,
        frames,
        ground,
        index,
    })
}

/// One body (`f` its field path) and its frame in the initial pose.
fn body<'s>(b: &'s BodySpec, f: &str, cx: &Ctx) -> Result<(Body, Frames<'s>)> {
    if b.mass <= 0.0 {
        return Err(cx.err(
            format!("{f}.mass"),
            format!("must be positive, got {} kg", b.mass),
        ));
    }
    let j = inertia(&b.inertia, &format!("{f}.inertia"), cx)?;
    let rot = orientation(&b.orientation, &format!("{f}.orientation"), cx)?;
    for (k, a) in &b.axes {
        if v3(*a).norm() < 1e-12 {
            return Err(cx.err(format!("{f}.axes.{k}"), "zero-length axis"));
        }
    }
    let com = v3(b.com);
    let pos = v3(b.position) + rot * com;
    let visuals = b
        .visual
        .iter()
        .enumerate()
        .map(|(k, v)| visual(v, &com, &format!("{f}.visual[{k}]"), cx))
        .collect::<Result<Vec<_>>>()?;
    let body = Body {
        name: b.name.clone(),
        mass: b.mass,
        inertia: j,
        inv_inertia: j
            .try_inverse()
            .ok_or_else(|| cx.err(format!("{f}.inertia"), "inertia tensor is singular"))?,
        com,
        visuals,
    };
    let frame = Frames {
        points: &b.points,
        axes: &b.axes,
        com,
        rot,
        pos,
        label: format!("body '{}'", b.name),
    };
    Ok((body, frame))
}

/// One visual shape of a body whose centre of mass is at `com` (body frame); `f` its field path.
fn visual(v: &VisualSpec, com: &Vector3<f64>, f: &str, cx: &Ctx) -> Result<Visual> {
    let positive = |x: f64, name: &str| {
        if x > 0.0 {
            Ok(x)
        } else {
            Err(cx.err(
                format!("{f}.{name}"),
                format!("must be positive, got {x} m"),
            ))
        }
    };
    let color = |c: &Option<String>| -> Result<Option<[u8; 3]>> {
        let Some(c) = c else { return Ok(None) };
        let hex = c.strip_prefix('#').filter(|h| h.len() == 6 && h.is_ascii());
        let parse = |h: &str| -> Option<[u8; 3]> {
            let byte = |i: usize| u8::from_str_radix(&h[i..i + 2], 16).ok();
            Some([byte(0)?, byte(2)?, byte(4)?])
        };
        hex.and_then(parse).map(Some).ok_or_else(|| {
            cx.err(
                format!("{f}.color"),
                format!("'{c}' is not a colour of the form \"#rrggbb\""),
            )
        })
    };
    let (shape, at, rotation, c) = match v {
        VisualSpec::Box {
            size,
            at,
            orientation: o,
            color: c,
        } => {
            for (k, s) in size.iter().enumerate() {
                positive(*s, &format!("size[{k}]"))?;
            }
            let rot = orientation(o, &format!("{f}.orientation"), cx)?;
            (Shape::Box { size: v3(*size) }, at, rot, c)
        }
        VisualSpec::Cylinder {
            radius,
            length,
            at,
            axis,
            color: c,
        } => {
            let rot = match axis {
                None => UnitQuaternion::identity(),
                Some(a) if v3(*a).norm() < 1e-12 => {
                    return Err(cx.err(format!("{f}.axis"), "zero-length axis"));
                }
                Some(a) => {
                    UnitQuaternion::rotation_between(&Vector3::z(), &v3(*a)).unwrap_or_else(|| {
                        // Opposite to z: a half turn about x.
                        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
                    })
                }
            };
            let shape = Shape::Cylinder {
                radius: positive(*radius, "radius")?,
                length: positive(*length, "length")?,
            };
            (shape, at, rot, c)
        }
        VisualSpec::Sphere {
            radius,
            at,
            color: c,
        } => {
            let shape = Shape::Sphere {
                radius: positive(*radius, "radius")?,
            };
            (shape, at, UnitQuaternion::identity(), c)
        }
        VisualSpec::Mesh {
            file,
            scale,
            at,
            orientation: o,
            color: c,
        } => {
            let lower = file.to_ascii_lowercase();
            if !(lower.ends_with(".obj") || lower.ends_with(".stl")) {
                return Err(cx.err(
                    format!("{f}.file"),
                    format!("'{file}' is neither an OBJ (.obj) nor an STL (.stl) file"),
                ));
            }
            let scale = match scale {
                None => 1.0,
                Some(s) if *s > 0.0 => *s,
                Some(s) => {
                    return Err(cx.err(format!("{f}.scale"), format!("must be positive, got {s}")));
                }
            };
            let dir = cx.file().parent().unwrap_or(std::path::Path::new(""));
            let rot = orientation(o, &format!("{f}.orientation"), cx)?;
            let shape = Shape::Mesh {
                file: dir.join(file),
                scale,
            };
            (shape, at, rot, c)
        }
    };
    Ok(Visual {
        shape,
        centre: v3(*at) - com,
        rotation,
        color: color(c)?,
    })
}

/// The rotation an orientation block declares (identity when empty).
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

/// The inertia tensor, checked positive definite and physical (triangle inequality).
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
pub(crate) struct Frames<'a> {
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
    pub fn point(&self, r: &VecRef, field: &str, cx: &Ctx) -> Result<Vector3<f64>> {
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
    pub fn axis(&self, r: &VecRef, field: &str, cx: &Ctx) -> Result<Vector3<f64>> {
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

    pub fn to_global(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rot * v
    }

    pub fn to_local(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rot.inverse() * v
    }

    /// Initial global position of a COM-relative body-axes point.
    pub fn global_point(&self, s: &Vector3<f64>) -> Vector3<f64> {
        self.pos + self.rot * s
    }
}
