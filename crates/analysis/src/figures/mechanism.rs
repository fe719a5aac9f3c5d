//! The mechanism as solid parts, for `jointplay animate` (an HTML page) and its glTF file: what
//! each body looks like, in its own axes, so that a pose per sample moves it.
//!
//! A body the scene gives shapes (`[[bodies.visual]]`: box, cylinder, sphere, OBJ or STL mesh)
//! is drawn with them alone. Any other body is drawn from its joints:
//!
//! * **bars** between its joint points (the points of its joints, springs and loads): one bar for
//!   two points; a closed outline through three or more, ordered by angle about their centroid
//!   in their plane of largest spread (a platform); for a single point, a bar from it through
//!   the centre of mass to the point opposite (a leg), or a cube at the centre of mass when the
//!   point is there (a slider block);
//! * **clearance elements** sized from the scene: a revolute clearance's housing as a ring of the
//!   bearing's radius about its axis and its journal as a pin of the journal's radius (its
//!   length, or a bar's thickness for a planar joint); a spherical one's socket as a sphere of
//!   the ball's radius plus the clearance (drawn see-through) and its ball as a solid sphere; a
//!   slider as a box of its length, height (and width), between two guide plates the clearance
//!   away.
//!
//! The ground's joint points are drawn as small fixed blocks, and its clearance housings as
//! above. Sizes the scene does not give (a bar's radius) are a fraction of the mechanism's extent
//! at the first sample: \\( r = D / 150 \\) with \\( D \\) the diagonal of the box around every
//! joint point. The clearance itself (typically a few tenths of a millimetre on a mechanism of
//! a metre) is invisible at that scale: the page's insets draw each journal's orbit magnified.
//!
//! Every vector here is relative to the body's centre of mass in body axes, as the solver's
//! (the ground's are global), in m.

use std::path::Path;

use jointplay_solver::clearance::Geometry;
use jointplay_solver::model::{GROUND, Model, Shape};
use nalgebra::{UnitQuaternion, Vector3};

use crate::Result;

/// One solid part of a body's drawing, in the body's axes relative to its centre of mass (m).
#[derive(Debug, Clone, PartialEq)]
pub enum Part {
    /// A round bar from `a` to `b`.
    Bar {
        a: Vector3<f64>,
        b: Vector3<f64>,
        radius: f64,
    },
    /// A closed cylinder centred at `centre` along the unit `axis`.
    Cylinder {
        centre: Vector3<f64>,
        axis: Vector3<f64>,
        radius: f64,
        length: f64,
    },
    /// A torus: a ring of `radius` about the unit `axis` with a tube of radius `tube`.
    Ring {
        centre: Vector3<f64>,
        axis: Vector3<f64>,
        radius: f64,
        tube: f64,
    },
    Sphere {
        centre: Vector3<f64>,
        radius: f64,
    },
    /// A box of half edge lengths `half` along the unit axes `axes`.
    Cuboid {
        centre: Vector3<f64>,
        axes: [Vector3<f64>; 3],
        half: Vector3<f64>,
    },
    /// Triangles over `vertices` (counter-clockwise seen from outside).
    Mesh {
        vertices: Vec<Vector3<f64>>,
        triangles: Vec<[u32; 3]>,
    },
}

/// A part with its colour (sRGB) and opacity (1 solid, below 1 see-through).
#[derive(Debug, Clone, PartialEq)]
pub struct Solid {
    pub part: Part,
    pub color: [u8; 3],
    pub opacity: f64,
}

/// The drawing of one body.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyDrawing {
    /// The body's index in the model.
    pub body: usize,
    pub name: String,
    pub solids: Vec<Solid>,
}

/// The mechanism's drawing: its moving bodies and the ground's fixed parts (global).
#[derive(Debug, Clone, PartialEq)]
pub struct Drawing {
    pub bodies: Vec<BodyDrawing>,
    pub ground: Vec<Solid>,
    /// The bar radius the drawing uses (m): the scale of the parts the scene does not size.
    pub bar_radius: f64,
}

/// The colours bodies are drawn in, in turn (Okabe and Ito's palette, distinct also to readers
/// with a colour-vision deficiency), and the ground's grey.
const PALETTE: [[u8; 3]; 7] = [
    [0, 114, 178],
    [230, 159, 0],
    [0, 158, 115],
    [204, 121, 167],
    [86, 180, 233],
    [213, 94, 0],
    [240, 228, 66],
];
const GROUND_COLOR: [u8; 3] = [120, 120, 120];
const HOUSING_COLOR: [u8; 3] = [90, 90, 90];

/// The drawing of `model`, its bodies at the poses `poses` (centre-of-mass position and body-to-
/// global rotation, one per body: the first sample) used only for the scale. Only the bodies in
/// `drawn` are drawn (the recorded ones). `travel[i]`, when given, is the range (m) of clearance
/// joint i's journal centre along its housing's axis over the run, which a slider's guide is
/// drawn to cover. A mesh file that cannot be read is an error naming it.
pub fn drawing(
    model: &Model,
    poses: &[(Vector3<f64>, UnitQuaternion<f64>)],
    drawn: &[usize],
    travel: &[Option<(f64, f64)>],
) -> Result<Drawing> {
    let nb = model.bodies.len();
    // Every attachment point of every body (COM-relative), the ground's global.
    let mut points: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); nb + 1];
    let slot = |b: usize| if b == GROUND { nb } else { b };
    let mut add = |b: usize, p: Vector3<f64>| {
        let list = &mut points[slot(b)];
        if !list.iter().any(|q| (q - p).norm() < 1e-9) {
            list.push(p);
        }
    };
    for j in &model.joints {
        add(j.body_a, j.point_a);
        add(j.body_b, j.point_b);
    }
    for s in &model.springs {
        add(s.a, s.sa);
        add(s.b, s.sb);
    }
    for l in &model.loads {
        add(l.body, l.s);
    }
    let global = |b: usize, p: &Vector3<f64>| match poses.get(b) {
        Some((x, q)) if b != GROUND => x + q * p,
        _ => *p,
    };
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(-f64::INFINITY),
    );
    for (b, list) in points.iter().enumerate() {
        let body = if b == nb { GROUND } else { b };
        for p in list {
            let g = global(body, p);
            lo = lo.inf(&g);
            hi = hi.sup(&g);
        }
    }
    for (x, _) in poses {
        lo = lo.inf(x);
        hi = hi.sup(x);
    }
    let diagonal = if lo.x.is_finite() {
        (hi - lo).norm()
    } else {
        0.0
    };
    let r = if diagonal > 0.0 {
        diagonal / 150.0
    } else {
        0.01
    };

    let mut bodies = Vec::new();
    for (k, &b) in drawn.iter().enumerate() {
        let body = &model.bodies[b];
        let color = PALETTE[k % PALETTE.len()];
        let solids = if body.visuals.is_empty() {
            let mut s = bars(&points[b], r, color);
            s.extend(clearance_parts(model, b, r, color, travel));
            s
        } else {
            visuals(model, b, color)?
        };
        bodies.push(BodyDrawing {
            body: b,
            name: body.name.clone(),
            solids,
        });
    }
    let mut ground: Vec<Solid> = points[nb]
        .iter()
        .map(|p| Solid {
            part: Part::Cuboid {
                centre: *p,
                axes: [Vector3::x(), Vector3::y(), Vector3::z()],
                half: Vector3::repeat(1.5 * r),
            },
            color: GROUND_COLOR,
            opacity: 1.0,
        })
        .collect();
    ground.extend(clearance_parts(model, GROUND, r, GROUND_COLOR, travel));
    Ok(Drawing {
        bodies,
        ground,
        bar_radius: r,
    })
}

/// The bars through a body's attachment points (see the module's overview).
fn bars(points: &[Vector3<f64>], r: f64, color: [u8; 3]) -> Vec<Solid> {
    let solid = |part| Solid {
        part,
        color,
        opacity: 1.0,
    };
    match points {
        [] => vec![solid(Part::Sphere {
            centre: Vector3::zeros(),
            radius: 2.0 * r,
        })],
        [p] if p.norm() < r => vec![solid(Part::Cuboid {
            centre: Vector3::zeros(),
            axes: [Vector3::x(), Vector3::y(), Vector3::z()],
            half: Vector3::repeat(3.0 * r),
        })],
        [p] => vec![solid(Part::Bar {
            a: *p,
            b: -p,
            radius: r,
        })],
        [a, b] => vec![solid(Part::Bar {
            a: *a,
            b: *b,
            radius: r,
        })],
        _ => {
            let ordered = outline(points);
            (0..ordered.len())
                .map(|i| {
                    solid(Part::Bar {
                        a: ordered[i],
                        b: ordered[(i + 1) % ordered.len()],
                        radius: r,
                    })
                })
                .collect()
        }
    }
}

/// `points` ordered by angle about their centroid in the plane of their two largest principal
/// directions, for a closed outline.
fn outline(points: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let c = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let mut cov = nalgebra::Matrix3::zeros();
    for p in points {
        let d = p - c;
        cov += d * d.transpose();
    }
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let e1: Vector3<f64> = eig.eigenvectors.column(order[0]).into();
    let e2: Vector3<f64> = eig.eigenvectors.column(order[1]).into();
    let mut sorted: Vec<(f64, Vector3<f64>)> = points
        .iter()
        .map(|p| ((p - c).dot(&e2).atan2((p - c).dot(&e1)), *p))
        .collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    sorted.into_iter().map(|(_, p)| p).collect()
}

/// Two unit vectors normal to the unit `n` and to each other, `(u, n x u)`.
pub(crate) fn normals(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let u = jointplay_solver::kin::any_normal(n);
    (u, n.cross(&u))
}

/// The housing (on `b` as body_a of the clearance) and journal (on `b` as body_b) parts of
/// every clearance joint that involves body `b` (or the ground); `travel` as for [`drawing`].
fn clearance_parts(
    model: &Model,
    b: usize,
    r: f64,
    color: [u8; 3],
    travel: &[Option<(f64, f64)>],
) -> Vec<Solid> {
    let mut out = Vec::new();
    let solid = |part, color, opacity| Solid {
        part,
        color,
        opacity,
    };
    for (i, cl) in model.clearances.iter().enumerate() {
        if cl.housing == b {
            let (c, n) = (cl.sh, cl.axis_h);
            match cl.geometry {
                Geometry::Spherical {
                    ball_radius,
                    clearance,
                } => out.push(solid(
                    Part::Sphere {
                        centre: c,
                        radius: ball_radius + clearance,
                    },
                    HOUSING_COLOR,
                    0.35,
                )),
                Geometry::Planar { bearing_radius, .. } => out.push(solid(
                    Part::Ring {
                        centre: c,
                        axis: n,
                        radius: bearing_radius + 0.5 * r,
                        tube: 0.5 * r,
                    },
                    HOUSING_COLOR,
                    1.0,
                )),
                Geometry::Revolute {
                    bushing_radius,
                    bushing_length,
                    ..
                } => {
                    for s in [-0.5, 0.5] {
                        out.push(solid(
                            Part::Ring {
                                centre: c + n * (s * bushing_length),
                                axis: n,
                                radius: bushing_radius + 0.5 * r,
                                tube: 0.5 * r,
                            },
                            HOUSING_COLOR,
                            1.0,
                        ));
                    }
                }
                Geometry::Translational {
                    half_length,
                    half_height,
                    clearance,
                    half_width,
                } => {
                    let across = cl.ref_h;
                    let third = n.cross(&across);
                    let t = 0.5 * r;
                    let width = half_width.map_or(2.0 * r, |w| w + clearance);
                    // Along the axis: the slider's travel and its length beyond, else three
                    // slider lengths about the guide point.
                    let (lo, hi) = travel.get(i).copied().flatten().unwrap_or((0.0, 0.0));
                    let mid = c + n * (0.5 * (lo + hi));
                    let long = 0.5 * (hi - lo) + 1.5 * half_length;
                    for s in [-1.0, 1.0] {
                        out.push(solid(
                            Part::Cuboid {
                                centre: mid + across * (s * (half_height + clearance + t)),
                                axes: [n, across, third],
                                half: Vector3::new(long, t, width),
                            },
                            HOUSING_COLOR,
                            1.0,
                        ));
                    }
                }
            }
        }
        if cl.journal == b {
            let (c, n) = (cl.sj, cl.axis_j);
            let part = match cl.geometry {
                Geometry::Spherical { ball_radius, .. } => Part::Sphere {
                    centre: c,
                    radius: ball_radius,
                },
                Geometry::Planar { journal_radius, .. } => Part::Cylinder {
                    centre: c,
                    axis: n,
                    radius: journal_radius,
                    length: 4.0 * r,
                },
                Geometry::Revolute {
                    journal_radius,
                    bushing_length,
                    journal_length,
                    ..
                } => Part::Cylinder {
                    centre: c,
                    axis: n,
                    radius: journal_radius,
                    length: journal_length.unwrap_or(bushing_length),
                },
                Geometry::Translational {
                    half_length,
                    half_height,
                    half_width,
                    ..
                } => {
                    let across = cl.ref_j;
                    Part::Cuboid {
                        centre: c,
                        axes: [n, across, n.cross(&across)],
                        half: Vector3::new(half_length, half_height, half_width.unwrap_or(r)),
                    }
                }
            };
            out.push(solid(part, color, 1.0));
        }
    }
    out
}

/// A body's declared shapes as parts.
fn visuals(model: &Model, b: usize, color: [u8; 3]) -> Result<Vec<Solid>> {
    let body = &model.bodies[b];
    let mut out = Vec::new();
    for v in &body.visuals {
        let axes = [
            v.rotation * Vector3::x(),
            v.rotation * Vector3::y(),
            v.rotation * Vector3::z(),
        ];
        let part = match &v.shape {
            Shape::Box { size } => Part::Cuboid {
                centre: v.centre,
                axes,
                half: size * 0.5,
            },
            Shape::Cylinder { radius, length } => Part::Cylinder {
                centre: v.centre,
                axis: axes[2],
                radius: *radius,
                length: *length,
            },
            Shape::Sphere { radius } => Part::Sphere {
                centre: v.centre,
                radius: *radius,
            },
            Shape::Mesh { file, scale } => {
                let Triangles {
                    vertices,
                    triangles,
                } = read_mesh(file).map_err(|message| crate::Error::Io {
                    file: file.clone(),
                    message: format!(
                        "the mesh of body '{}' ({}): {message}",
                        body.name,
                        model.file.display()
                    ),
                })?;
                Part::Mesh {
                    vertices: vertices
                        .iter()
                        .map(|p| v.centre + v.rotation * (p * *scale))
                        .collect(),
                    triangles,
                }
            }
        };
        out.push(Solid {
            part,
            color: v.color.unwrap_or(color),
            opacity: 1.0,
        });
    }
    Ok(out)
}

/// The vertices and triangles of an OBJ or STL file (by its extension), in the file's units.
pub fn read_mesh(file: &Path) -> std::result::Result<Triangles, String> {
    let obj = file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let (vertices, triangles) = if obj {
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let (models, _) = tobj::load_obj(file, &options).map_err(|e| e.to_string())?;
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for m in models {
            let first = vertices.len() as u32;
            vertices.extend(
                m.mesh
                    .positions
                    .chunks_exact(3)
                    .map(|p| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))),
            );
            triangles.extend(
                m.mesh
                    .indices
                    .chunks_exact(3)
                    .map(|t| [first + t[0], first + t[1], first + t[2]]),
            );
        }
        (vertices, triangles)
    } else {
        let mut f = std::fs::File::open(file).map_err(|e| e.to_string())?;
        let mesh = stl_io::read_stl(&mut f).map_err(|e| format!("not a readable STL file: {e}"))?;
        let vertices = mesh
            .vertices
            .iter()
            .map(|p| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
            .collect();
        let triangles = mesh
            .faces
            .iter()
            .map(|t| {
                [
                    t.vertices[0] as u32,
                    t.vertices[1] as u32,
                    t.vertices[2] as u32,
                ]
            })
            .collect();
        (vertices, triangles)
    };
    if let Some(p) = vertices.iter().find(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(format!("a vertex is not finite: {p:?}"));
    }
    let n = vertices.len() as u32;
    if triangles.iter().flatten().any(|&i| i >= n) {
        return Err("a face refers to a vertex the file does not have".into());
    }
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        (b - a).cross(&(c - a)).norm()
    };
    if !triangles.iter().any(|t| area(t) > 0.0) {
        return Err("no triangle with an area".into());
    }
    Ok(Triangles {
        vertices,
        triangles,
    })
}

/// A triangle mesh: vertices and triangles over them, counter-clockwise seen from outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Triangles {
    pub vertices: Vec<Vector3<f64>>,
    pub triangles: Vec<[u32; 3]>,
}

impl Triangles {
    /// Appends a grid of `rows` x `cols` quads over `point(i, j)`, `i` in 0..=rows, `j` in
    /// 0..cols wrapping round (a surface of revolution): facing outwards when `i` runs along an
    /// axis and `j` counter-clockwise about it.
    fn wrap(&mut self, rows: usize, cols: usize, point: impl Fn(usize, usize) -> Vector3<f64>) {
        let first = self.vertices.len() as u32;
        for i in 0..=rows {
            for j in 0..cols {
                self.vertices.push(point(i, j));
            }
        }
        let at = |i: usize, j: usize| first + (i * cols + j % cols) as u32;
        for i in 0..rows {
            for j in 0..cols {
                self.triangles
                    .push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
                self.triangles
                    .push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            }
        }
    }

    /// Appends a disc of `radius` at `centre` facing the unit `n`, with `cols` sides.
    fn disc(&mut self, centre: Vector3<f64>, n: Vector3<f64>, radius: f64, cols: usize) {
        let (u, w) = normals(&n);
        let first = self.vertices.len() as u32;
        self.vertices.push(centre);
        for j in 0..cols {
            let a = std::f64::consts::TAU * j as f64 / cols as f64;
            self.vertices
                .push(centre + (u * a.cos() + w * a.sin()) * radius);
        }
        for j in 0..cols as u32 {
            self.triangles
                .push([first, first + 1 + j, first + 1 + (j + 1) % cols as u32]);
        }
    }

    /// Appends a closed cylinder from `a` to `b`.
    fn cylinder(&mut self, a: Vector3<f64>, b: Vector3<f64>, radius: f64) {
        const SIDES: usize = 16;
        let d = b - a;
        let len = d.norm();
        if len == 0.0 {
            return;
        }
        let n = d / len;
        let (u, w) = normals(&n);
        self.wrap(1, SIDES, |i, j| {
            let t = std::f64::consts::TAU * j as f64 / SIDES as f64;
            let base = if i == 0 { a } else { b };
            base + (u * t.cos() + w * t.sin()) * radius
        });
        self.disc(b, n, radius, SIDES);
        self.disc(a, -n, radius, SIDES);
    }

    /// The triangles of `part`.
    pub fn of(part: &Part) -> Triangles {
        use std::f64::consts::{PI, TAU};
        let mut t = Triangles::default();
        match part {
            Part::Bar { a, b, radius } => t.cylinder(*a, *b, *radius),
            Part::Cylinder {
                centre,
                axis,
                radius,
                length,
            } => t.cylinder(
                centre - axis * (0.5 * length),
                centre + axis * (0.5 * length),
                *radius,
            ),
            Part::Ring {
                centre,
                axis,
                radius,
                tube,
            } => {
                const AROUND: usize = 32;
                const TUBE: usize = 8;
                let (u, w) = normals(axis);
                // i runs round the tube (closing on itself: row TUBE repeats row 0), j round the
                // ring.
                t.wrap(TUBE, AROUND, |i, j| {
                    let phi = TAU * j as f64 / AROUND as f64;
                    let theta = TAU * i as f64 / TUBE as f64;
                    let radial = u * phi.cos() + w * phi.sin();
                    centre + radial * (radius + tube * theta.cos()) + axis * (tube * theta.sin())
                });
            }
            Part::Sphere { centre, radius } => {
                const ROWS: usize = 10;
                const COLS: usize = 20;
                t.wrap(ROWS, COLS, |i, j| {
                    let polar = PI * i as f64 / ROWS as f64;
                    let az = TAU * j as f64 / COLS as f64;
                    centre
                        + Vector3::new(polar.sin() * az.cos(), polar.sin() * az.sin(), -polar.cos())
                            * *radius
                });
            }
            Part::Cuboid { centre, axes, half } => {
                let corner = |sx: f64, sy: f64, sz: f64| {
                    centre
                        + axes[0] * (sx * half.x)
                        + axes[1] * (sy * half.y)
                        + axes[2] * (sz * half.z)
                };
                for k in 0..3 {
                    for s in [-1.0, 1.0] {
                        // The face normal to axis k on side s, its corners counter-clockwise seen
                        // from outside.
                        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
                        let mut quad = [[0.0; 3]; 4];
                        for (c, (p, q)) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                            .into_iter()
                            .enumerate()
                        {
                            quad[c][k] = s;
                            quad[c][a] = p * s;
                            quad[c][b] = q;
                        }
                        let first = t.vertices.len() as u32;
                        for q in quad {
                            t.vertices.push(corner(q[0], q[1], q[2]));
                        }
                        t.triangles.push([first, first + 1, first + 2]);
                        t.triangles.push([first, first + 2, first + 3]);
                    }
                }
            }
            Part::Mesh {
                vertices,
                triangles,
            } => {
                t.vertices = vertices.clone();
                t.triangles = triangles.clone();
            }
        }
        // Triangles of no area (at a sphere's poles, or in a mesh file) have no normal.
        let v = &t.vertices;
        t.triangles.retain(|&[a, b, c]| {
            let (a, b, c) = (v[a as usize], v[b as usize], v[c as usize]);
            (b - a).cross(&(c - a)).norm() > 0.0
        });
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_outline_goes_round_a_square_whatever_the_order_given() {
        let p = |x: f64, y: f64| Vector3::new(x, y, 0.0);
        let square = [p(1.0, 0.0), p(-1.0, 0.0), p(0.0, 1.0), p(0.0, -1.0)];
        let o = outline(&square);
        // Consecutive corners are neighbours (a quarter turn apart), never opposite.
        for i in 0..4 {
            let d = (o[i] - o[(i + 1) % 4]).norm();
            assert!((d - 2f64.sqrt()).abs() < 1e-12, "{o:?}");
        }
    }

    /// The outward-facing check: for a closed convex part, every triangle's normal (by the
    /// counter-clockwise rule) points away from the part's centre, and the divergence theorem
    /// gives its volume (pi r^2 L for a cylinder, 4/3 pi r^3 for a sphere, 8 abc for a box)
    /// within the tessellation's error.
    #[test]
    fn parts_are_closed_outward_triangle_meshes_of_their_volume() {
        use std::f64::consts::PI;
        let z = Vector3::zeros();
        let cases = [
            (
                Part::Bar {
                    a: Vector3::new(-1.0, 0.0, 0.0),
                    b: Vector3::new(1.0, 0.0, 0.0),
                    radius: 0.1,
                },
                PI * 0.01 * 2.0,
                // A 16-gon's area is 16/2 sin(2 pi/16) r^2 = 0.9745 pi r^2.
                0.03,
            ),
            (
                Part::Sphere {
                    centre: z,
                    radius: 0.5,
                },
                4.0 / 3.0 * PI * 0.125,
                0.05,
            ),
            (
                Part::Cuboid {
                    centre: z,
                    axes: [Vector3::x(), Vector3::y(), Vector3::z()],
                    half: Vector3::new(1.0, 2.0, 3.0),
                },
                48.0,
                1e-12,
            ),
            (
                Part::Ring {
                    centre: z,
                    axis: Vector3::z(),
                    radius: 1.0,
                    tube: 0.1,
                },
                2.0 * PI * PI * 0.01,
                // The tube's octagon holds 8/2 sin(2 pi/8) / pi = 0.900 of its circle, the ring's
                // 32-gon 0.994 of its length: 0.894 of the torus.
                0.11,
            ),
        ];
        for (part, volume, rel) in cases {
            let t = Triangles::of(&part);
            let mut v = 0.0;
            for tri in &t.triangles {
                let [a, b, c] = tri.map(|i| t.vertices[i as usize]);
                v += a.dot(&b.cross(&c)) / 6.0;
            }
            assert!(
                (v - volume).abs() <= rel * volume,
                "{part:?}: {v} against {volume}"
            );
        }
    }

    #[test]
    fn normals_are_orthonormal() {
        for n in [
            Vector3::x(),
            Vector3::y(),
            Vector3::new(1.0, 2.0, -3.0).normalize(),
        ] {
            let (u, w) = normals(&n);
            assert!(u.dot(&n).abs() < 1e-15 && w.dot(&n).abs() < 1e-15 && u.dot(&w).abs() < 1e-15);
            assert!((u.norm() - 1.0).abs() < 1e-15 && (w.norm() - 1.0).abs() < 1e-15);
        }
    }
}
