//! A run's motion as glTF 2.0 (Khronos, *glTF 2.0 Specification*, 2021), binary `.glb`: the
//! mechanism's parts ([`crate::figures::mechanism`]) as meshes, one node per body, and the
//! motion as one animation that moves every body's node (translation and rotation, linear
//! interpolation, time in s from the run's first frame), for Blender, three.js editors and any
//! glTF viewer.
//!
//! The document is built with the `gltf-json` crate's types; the binary container (a 12-byte
//! header, the JSON chunk and the binary chunk, each padded to 4 bytes) is written here. Lengths
//! are in m, as glTF's are. glTF's up is +y: a root node `mechanism` turns the scene's up
//! (against gravity, else y) onto it. Triangles are written unshared with their face normal, so
//! that viewers shade the parts flat, as the page does. Colours are the page's, converted from
//! sRGB to the linear values glTF's base colour takes; see-through parts (a spherical joint's
//! socket) are blended.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use nalgebra::{UnitQuaternion, Vector3};

use crate::Result;
use crate::figures::animate::{Motion, Pick, stem};
use crate::figures::mechanism::{Solid, Triangles};

/// The little-endian bytes of the floats `values`.
fn bytes(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// sRGB to linear, IEC 61966-2-1.
fn linear(c: u8) -> f32 {
    let c = f64::from(c) / 255.0;
    (if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }) as f32
}

/// The document under construction and its binary chunk.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
    materials: BTreeMap<([u8; 3], u64), json::Index<json::Material>>,
}

impl Builder {
    /// An accessor of `count` elements of `type_` over `data` (floats), with its own view.
    fn accessor(
        &mut self,
        data: Vec<u8>,
        count: usize,
        type_: json::accessor::Type,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::Accessor> {
        let view = self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64(data.len() as u64),
            byte_offset: Some(USize64(self.bin.len() as u64)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: Default::default(),
            extras: Default::default(),
        });
        self.bin.extend(data);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let (min, max) = match bounds {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64(count as u64),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::F32,
            )),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    fn material(&mut self, color: [u8; 3], opacity: f64) -> json::Index<json::Material> {
        let key = (color, opacity.to_bits());
        if let Some(m) = self.materials.get(&key) {
            return *m;
        }
        let blend = opacity < 1.0;
        let m = self.root.push(json::Material {
            alpha_mode: Valid(if blend {
                json::material::AlphaMode::Blend
            } else {
                json::material::AlphaMode::Opaque
            }),
            double_sided: blend,
            name: None,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([
                    linear(color[0]),
                    linear(color[1]),
                    linear(color[2]),
                    opacity as f32,
                ]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.7),
                ..Default::default()
            },
            ..Default::default()
        });
        self.materials.insert(key, m);
        m
    }

    /// A mesh of `solids`, one primitive each; `None` when none has a triangle.
    fn mesh(&mut self, name: &str, solids: &[Solid]) -> Option<json::Index<json::Mesh>> {
        let mut primitives = Vec::new();
        for s in solids {
            let t = Triangles::of(&s.part);
            let mut positions = Vec::with_capacity(9 * t.triangles.len());
            let mut normals = Vec::with_capacity(9 * t.triangles.len());
            let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
            for tri in &t.triangles {
                let [a, b, c] = tri.map(|i| t.vertices[i as usize]);
                let n = (b - a).cross(&(c - a));
                let n = if n.norm() > 0.0 { n.normalize() } else { n };
                for p in [a, b, c] {
                    for k in 0..3 {
                        let x = p[k] as f32;
                        lo[k] = lo[k].min(x);
                        hi[k] = hi[k].max(x);
                        positions.push(x);
                        normals.push(n[k] as f32);
                    }
                }
            }
            let count = positions.len() / 3;
            if count == 0 {
                continue;
            }
            let position = self.accessor(
                bytes(positions),
                count,
                json::accessor::Type::Vec3,
                Some((lo.to_vec(), hi.to_vec())),
                Some(json::buffer::Target::ArrayBuffer),
            );
            let normal = self.accessor(
                bytes(normals),
                count,
                json::accessor::Type::Vec3,
                None,
                Some(json::buffer::Target::ArrayBuffer),
            );
            let material = self.material(s.color, s.opacity);
            primitives.push(json::mesh::Primitive {
                attributes: BTreeMap::from([
                    (Valid(json::mesh::Semantic::Positions), position),
                    (Valid(json::mesh::Semantic::Normals), normal),
                ]),
                extensions: Default::default(),
                extras: Default::default(),
                indices: None,
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            });
        }
        if primitives.is_empty() {
            return None;
        }
        Some(self.root.push(json::Mesh {
            extensions: Default::default(),
            extras: Default::default(),
            name: Some(name.to_string()),
            primitives,
            weights: None,
        }))
    }
}

fn node(name: &str) -> json::Node {
    json::Node {
        name: Some(name.to_string()),
        ..Default::default()
    }
}

/// The `.glb` bytes of `motion`.
pub fn glb(motion: &Motion) -> Result<Vec<u8>> {
    let mut b = Builder {
        root: json::Root {
            asset: json::Asset {
                generator: Some(format!("jointplay {}", env!("CARGO_PKG_VERSION"))),
                ..Default::default()
            },
            ..Default::default()
        },
        bin: Vec::new(),
        materials: BTreeMap::new(),
    };
    let mut children = Vec::new();
    if !motion.drawing.ground.is_empty() {
        let mesh = b.mesh("ground", &motion.drawing.ground);
        children.push(b.root.push(json::Node {
            mesh,
            ..node("ground")
        }));
    }
    // glTF's key times must increase strictly: frames closer than a 32-bit float resolves at
    // their time from the start (impact frames, late in a long run) are left out.
    let t0 = motion.time[0];
    let mut kept = Vec::with_capacity(motion.time.len());
    let mut times: Vec<f32> = Vec::with_capacity(motion.time.len());
    for (i, t) in motion.time.iter().enumerate() {
        let key = (t - t0) as f32;
        if times.last().is_none_or(|&last| key > last) {
            times.push(key);
            kept.push(i);
        }
    }
    let n = times.len();
    let (first, last) = (times[0], times[n - 1]);
    let input = b.accessor(
        bytes(times),
        n,
        json::accessor::Type::Scalar,
        Some((vec![first], vec![last])),
        None,
    );
    let mut channels = Vec::new();
    let mut samplers = Vec::new();
    for (k, body) in motion.drawing.bodies.iter().enumerate() {
        let mesh = b.mesh(&body.name, &body.solids);
        let (x0, q0) = motion.poses[0][k];
        let q0 = q0.quaternion();
        let index = b.root.push(json::Node {
            mesh,
            translation: Some([x0.x as f32, x0.y as f32, x0.z as f32]),
            rotation: Some(json::scene::UnitQuaternion([
                q0.i as f32,
                q0.j as f32,
                q0.k as f32,
                q0.w as f32,
            ])),
            ..node(&body.name)
        });
        children.push(index);
        let translation = b.accessor(
            bytes(kept.iter().flat_map(|&i| {
                let x = motion.poses[i][k].0;
                [x.x as f32, x.y as f32, x.z as f32]
            })),
            n,
            json::accessor::Type::Vec3,
            None,
            None,
        );
        // Successive Euler parameters kept in one hemisphere, so that linear interpolation
        // takes the short way round.
        let mut previous = q0.coords;
        let rotation = b.accessor(
            bytes(kept.iter().flat_map(|&i| {
                let mut q = motion.poses[i][k].1.quaternion().coords;
                if q.dot(&previous) < 0.0 {
                    q = -q;
                }
                previous = q;
                // nalgebra stores (i, j, k, w), glTF's order.
                [q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32]
            })),
            n,
            json::accessor::Type::Vec4,
            None,
            None,
        );
        for (output, path) in [
            (translation, json::animation::Property::Translation),
            (rotation, json::animation::Property::Rotation),
        ] {
            let sampler = json::Index::push(
                &mut samplers,
                json::animation::Sampler {
                    extensions: Default::default(),
                    extras: Default::default(),
                    input,
                    interpolation: Valid(json::animation::Interpolation::Linear),
                    output,
                },
            );
            channels.push(json::animation::Channel {
                sampler,
                target: json::animation::Target {
                    extensions: Default::default(),
                    extras: Default::default(),
                    node: index,
                    path: Valid(path),
                },
                extensions: Default::default(),
                extras: Default::default(),
            });
        }
    }
    // The scene's up onto glTF's +y.
    let turn = UnitQuaternion::rotation_between(&motion.up, &Vector3::y()).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    });
    let q = turn.quaternion();
    let top = b.root.push(json::Node {
        children: Some(children),
        rotation: Some(json::scene::UnitQuaternion([
            q.i as f32, q.j as f32, q.k as f32, q.w as f32,
        ])),
        ..node("mechanism")
    });
    let scene = b.root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some(motion.title.clone()),
        nodes: vec![top],
    });
    b.root.scene = Some(scene);
    b.root.push(json::Animation {
        extensions: Default::default(),
        extras: Default::default(),
        channels,
        name: Some("motion".into()),
        samplers,
    });
    b.root.push(json::Buffer {
        byte_length: USize64(b.bin.len() as u64),
        name: None,
        uri: None,
        extensions: Default::default(),
        extras: Default::default(),
    });
    let mut text = b.root.to_vec().map_err(|e| crate::Error::Io {
        file: PathBuf::from("(glTF)"),
        message: format!("the glTF document does not serialise: {e}"),
    })?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + b.bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((text.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(text);
    out.extend((b.bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b.bin);
    Ok(out)
}

/// Writes `motion` (what `pick` chose in `file`) as `out/<name>.glb`, whole or not at all.
pub fn write(motion: &Motion, file: &Path, pick: Pick, out: &Path) -> Result<PathBuf> {
    let bytes = glb(motion)?;
    let target = out.join(format!("{}.glb", stem(file, pick)));
    crate::storage::durable::create_dir(out)?;
    crate::storage::durable::write_new(&target, &bytes)?;
    Ok(target)
}
