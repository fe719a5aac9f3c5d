//! `jointplay animate`: a run's motion as one self-contained HTML page (and, with
//! [`crate::figures::gltf`], a glTF file), read from the run's file alone.
//!
//! The page shows the mechanism in 3D, drawn as [`crate::figures::mechanism`] describes, with
//! play, pause, a time slider, a speed choice, the clock and a camera that turns about the
//! mechanism; beside it, for every recorded clearance joint, an inset with the journal centre's
//! orbit \\( (u, w) \\) (m, housing axes; a slider's offset across its guide) inside its
//! clearance circle, magnified to fill the inset, with the trail of the last drive period
//! coloured by the joint's total normal force. Everything the page needs is in it: the viewer
//! (a canvas renderer written for it, `viewer.js`) and the data, as little-endian base64 arrays
//! of 32-bit floats (positions relative to the mechanism's centre, so that 32 bits keep
//! sub-micrometre detail on a metre-sized mechanism) and 64-bit times.
//!
//! **Frames.** The page keeps `frames` evenly spaced samples (4000 by default) and, so that no
//! impact is lost between them, every sample where a clearance joint's contact opens or closes
//! (with the sample before it) and the sample of the largest normal force of every stretch of
//! contact. Between frames the page interpolates (positions linearly, Euler parameters
//! normalised linearly), so playing slower than the frames' spacing stays smooth. A 10 s run of
//! the 4-UPS/RPU sampled at 1 ms gives a page of about 2 MB.

use std::path::{Path, PathBuf};

use base64::Engine;
use jointplay_solver::clearance::Geometry;
use jointplay_solver::model::Model;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde_json::{Value, json};

use crate::Result;
use crate::figures::mechanism::{self, Drawing, Triangles};
use crate::flow::Target;
use crate::storage::export::{Column, Run, Samples, read_run};
use crate::storage::kept_states::Kept;
use crate::study::analysis::load::Loaded;

const PAGE: &str = include_str!("page.html");
const VIEWER: &str = include_str!("viewer.js");

/// What to animate and how.
#[derive(Debug, Clone)]
pub struct Options {
    /// Evenly spaced frames kept (besides the impacts' samples); at least 2.
    pub frames: usize,
    /// Simulated seconds per second of playback when the page opens; `None`: a round number
    /// near a tenth of the run's duration (the run plays in about ten seconds).
    pub speed: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            frames: 4000,
            speed: None,
        }
    }
}

/// A clearance joint's orbit over the frames.
#[derive(Debug, Clone)]
pub struct Orbit {
    pub joint: String,
    /// "spherical", "planar", "revolute" or "translational".
    pub geometry: &'static str,
    /// The radial clearance (m).
    pub clearance: f64,
    /// Per frame: u, w (m), the sum of the normal forces (N), whether any contact is closed.
    pub u: Vec<f64>,
    pub w: Vec<f64>,
    pub force: Vec<f64>,
    pub contact: Vec<bool>,
}

/// A run's motion, read and decimated: what the page and the glTF file are made of.
#[derive(Debug, Clone)]
pub struct Motion {
    pub title: String,
    pub drawing: Drawing,
    /// Frame times (s).
    pub time: Vec<f64>,
    /// Per frame, per drawn body: centre-of-mass position (m, global) and rotation.
    pub poses: Vec<Vec<(Vector3<f64>, UnitQuaternion<f64>)>>,
    pub orbits: Vec<Orbit>,
    /// The run's samples, of which `time` keeps some.
    pub samples: usize,
    /// Frames kept for contact changes and force peaks besides the evenly spaced ones.
    pub impact_frames: usize,
    /// Bodies the run does not record, left out of the drawing.
    pub missing: Vec<String>,
    /// Global unit vector drawn up: against gravity, else y.
    pub up: Vector3<f64>,
    /// The span of an inset's trail (s): the drive period when the run has one, a periodic
    /// orbit's period (k drive periods) for an orbit.
    pub period: Option<f64>,
}

/// The name of a clearance geometry, for an inset's title.
fn geometry_name(g: &Geometry) -> &'static str {
    match g {
        Geometry::Spherical { .. } => "spherical",
        Geometry::Planar { .. } => "planar",
        Geometry::Revolute { .. } => "revolute",
        Geometry::Translational { .. } => "translational",
    }
}

/// The datasets a drawing needs from a run of `model`.
fn wanted(model: &Model) -> Vec<String> {
    let mut out = Vec::new();
    for b in &model.bodies {
        out.push(format!("bodies/{}/position", b.name));
        out.push(format!("bodies/{}/orientation", b.name));
    }
    for cl in &model.clearances {
        for d in ["radial_eccentricity", "normal_force", "contact_state"] {
            out.push(format!("joints/{}/{d}", cl.name));
        }
    }
    out
}

/// The indices of the samples at `time` kept as frames: `count` + 1 evenly spaced over the run,
/// and for every joint (`contact[j][i]`: any contact of joint j closed at sample i;
/// `force[j][i]` its total normal force) each sample where its contact state changes with the
/// one before it, and the sample of the largest force of each stretch of contact. Sorted, each
/// once.
pub fn frames(time: &[f64], count: usize, contact: &[Vec<bool>], force: &[Vec<f64>]) -> Vec<usize> {
    let n = time.len();
    if n <= count + 1 {
        return (0..n).collect();
    }
    let (t0, t1) = (time[0], time[n - 1]);
    let mut keep: Vec<usize> = (0..=count)
        .map(|k| {
            let t = t0 + (t1 - t0) * k as f64 / count as f64;
            let i = time.partition_point(|&s| s < t).min(n - 1);
            if i > 0 && (t - time[i - 1]) < (time[i] - t) {
                i - 1
            } else {
                i
            }
        })
        .collect();
    for (c, f) in contact.iter().zip(force) {
        let mut stretch: Option<usize> = None;
        for i in 0..n {
            if i > 0 && c[i] != c[i - 1] {
                keep.extend([i - 1, i]);
            }
            if c[i] {
                let best = stretch.get_or_insert(i);
                if f[i] > f[*best] {
                    *best = i;
                }
            } else if let Some(best) = stretch.take() {
                keep.push(best);
            }
        }
        keep.extend(stretch);
    }
    keep.sort_unstable();
    keep.dedup();
    keep
}

/// Which motion of a file to animate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pick<'a> {
    /// A run's file, or the case of a comparison study's file.
    Run { case: Option<&'a str> },
    /// An analysis study's sweep value: `periods` drive periods from the end of its run.
    Value { value: f64, periods: f64 },
    /// A periodic orbit of an analysis study's continuation: one period of it.
    Orbit { branch: usize, point: usize },
}

impl Motion {
    /// The motion `pick` chooses in `file`: read from a run's file, or run again from the state
    /// an analysis file keeps.
    pub fn pick(file: &Path, pick: Pick, options: &Options) -> Result<Motion> {
        match pick {
            Pick::Run { case } => Motion::read(file, case, options),
            Pick::Value { value, periods } => {
                let kept = crate::storage::kept_states::sweep_value(file, value)?;
                Motion::again(file, kept, Some(periods), options)
            }
            Pick::Orbit { branch, point } => {
                let kept = crate::storage::kept_states::orbit(file, branch, point)?;
                Motion::again(file, kept, None, options)
            }
        }
    }

    /// The motion of the run in `file` (or of its case `case`, for a comparison study's file).
    pub fn read(file: &Path, case: Option<&str>, options: &Options) -> Result<Motion> {
        let Run { model, samples } = read_run(file, case, wanted)?;
        let title = match case {
            Some(c) => format!(
                "{} (case {c} of {})",
                model.name,
                crate::storage::export::stem(file, None)
            ),
            None => model.name.clone(),
        };
        Motion::build(file, &model, &samples, title, options)
    }

    /// The motion run again from a state an analysis file keeps: `periods` drive periods from a
    /// sweep value's end, or one period of a periodic orbit (`periods` None), every body and
    /// clearance joint recorded from the state on at the scene's output interval or finer (at
    /// least 2000 samples).
    fn again(file: &Path, kept: Kept, periods: Option<f64>, options: &Options) -> Result<Motion> {
        let loaded =
            Loaded::parse_kept(&kept.study, &kept.study_file, &kept.flow_text).map_err(|e| {
                crate::Error::Context {
                    what: format!("{}: its study", file.display()),
                    inner: Box::new(e),
                }
            })?;
        let target = match kept.period {
            Some(_) => loaded.continuation_target(kept.value)?,
            None => loaded.target(Some(kept.value))?,
        };
        let Target::Scene {
            mut model, period, ..
        } = target
        else {
            return Err(crate::Error::Io {
                file: file.to_path_buf(),
                message: "the study's flow is a built-in system, which has no mechanism to draw"
                    .into(),
            });
        };
        let span = match (kept.period, periods) {
            (Some(p), _) => p,
            (None, Some(k)) if k > 0.0 && k.is_finite() => k * period,
            (None, k) => {
                return Err(crate::Error::Io {
                    file: file.to_path_buf(),
                    message: format!("--periods: a positive number of drive periods, got {k:?}"),
                });
            }
        };
        // The samples from the state on, at least 2000, the span a whole number of them.
        model.settings.start_time = kept.state.t;
        model.settings.end_time = kept.state.t + span;
        let count = (span / model.outputs.interval).ceil().max(2000.0);
        model.outputs.interval = span / count;
        model.outputs.bodies = (0..model.bodies.len()).collect();
        model.outputs.joints = (0..model.joints.len()).collect();
        model.outputs.drives.clear();
        model.outputs.accelerations = false;
        model.outputs.diagnostics = false;
        model.outputs.energy = false;
        let run = crate::study::run::rerun(&model, kept.state.for_new_run())?;
        if let Some(s) = &run.stopped {
            return Err(crate::Error::Io {
                file: file.to_path_buf(),
                message: format!("the {} could not be run again: {s}", kept.label),
            });
        }
        let samples = Samples {
            time: run.recording.time.clone(),
            datasets: run
                .recording
                .channels
                .iter()
                .map(|c| Column {
                    dataset: c.dataset.clone(),
                    unit: c.unit.clone(),
                    names: c.columns.iter().map(|o| o.path.clone()).collect(),
                    values: c.values.clone(),
                })
                .collect(),
        };
        let title = format!(
            "{} ({} = {:.6e}, {})",
            loaded.spec.study.name,
            path_of(&loaded, kept.period.is_some()),
            kept.value,
            kept.label
        );
        let mut motion = Motion::build(file, &model, &samples, title, options)?;
        // An orbit's trail is the whole orbit, k drive periods.
        if kept.period.is_some() {
            motion.period = kept.period;
        }
        Ok(motion)
    }

    /// The motion of `samples`, recorded from `model`.
    fn build(
        file: &Path,
        model: &Model,
        samples: &Samples,
        title: String,
        options: &Options,
    ) -> Result<Motion> {
        let n = samples.time.len();
        if n < 2 {
            return Err(crate::Error::Io {
                file: file.to_path_buf(),
                message: format!("the run holds {n} sample(s): nothing moves"),
            });
        }
        let column = |d: &str| samples.datasets.iter().find(|c| c.dataset == d);
        let mut drawn = Vec::new();
        let mut missing = Vec::new();
        let mut tracks = Vec::new();
        for (b, body) in model.bodies.iter().enumerate() {
            match (
                column(&format!("bodies/{}/position", body.name)),
                column(&format!("bodies/{}/orientation", body.name)),
            ) {
                (Some(p), Some(q)) if p.names.len() == 3 && q.names.len() == 4 => {
                    drawn.push(b);
                    tracks.push((&p.values, &q.values));
                }
                _ => missing.push(body.name.clone()),
            }
        }
        if drawn.is_empty() {
            return Err(crate::Error::Io {
                file: file.to_path_buf(),
                message: "the run records no body's position and orientation ([output] bodies): \
                          nothing to draw"
                    .into(),
            });
        }
        // A recorder writes no value that is not finite; a file edited by hand might.
        for (k, (p, q)) in tracks.iter().enumerate() {
            let bad = (0..n).find(|&i| {
                let q = &q[4 * i..4 * i + 4];
                !(p[3 * i..3 * i + 3].iter().chain(q).all(|x| x.is_finite())
                    && q.iter().map(|x| x * x).sum::<f64>() > 0.0)
            });
            if let Some(i) = bad {
                return Err(crate::Error::Io {
                    file: file.to_path_buf(),
                    message: format!(
                        "body '{}' at t = {} s: its position or Euler parameters are not finite, or all zero",
                        model.bodies[drawn[k]].name, samples.time[i]
                    ),
                });
            }
        }
        let pose = |i: usize| -> Vec<(Vector3<f64>, UnitQuaternion<f64>)> {
            tracks
                .iter()
                .map(|(p, q)| {
                    let x = Vector3::new(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
                    let r = UnitQuaternion::from_quaternion(Quaternion::new(
                        q[4 * i],
                        q[4 * i + 1],
                        q[4 * i + 2],
                        q[4 * i + 3],
                    ));
                    (x, r)
                })
                .collect()
        };
        // The scale of the drawing from the first sample's poses, by model body index.
        let mut first = vec![(Vector3::zeros(), UnitQuaternion::identity()); model.bodies.len()];
        for (k, p) in drawn.iter().zip(pose(0)) {
            first[*k] = p;
        }
        // Each slider's travel along its guide, for the guide's length.
        let slot = |b: usize| drawn.iter().position(|&d| d == b);
        let travel: Vec<Option<(f64, f64)>> = model
            .clearances
            .iter()
            .map(|cl| {
                if !matches!(cl.geometry, Geometry::Translational { .. }) {
                    return None;
                }
                let place =
                    |b: usize, s: &Vector3<f64>, frame: &[(Vector3<f64>, UnitQuaternion<f64>)]| {
                        if b == jointplay_solver::model::GROUND {
                            Some((*s, UnitQuaternion::identity()))
                        } else {
                            slot(b).map(|k| (frame[k].0 + frame[k].1 * s, frame[k].1))
                        }
                    };
                let mut range: Option<(f64, f64)> = None;
                for i in (0..n).step_by((n / 500).max(1)) {
                    let frame = pose(i);
                    let (Some((h, qh)), Some((j, _))) = (
                        place(cl.housing, &cl.sh, &frame),
                        place(cl.journal, &cl.sj, &frame),
                    ) else {
                        return None;
                    };
                    let along = (j - h).dot(&(qh * cl.axis_h));
                    let r = range.get_or_insert((along, along));
                    *r = (r.0.min(along), r.1.max(along));
                }
                range
            })
            .collect();
        let drawing = mechanism::drawing(model, &first, &drawn, &travel)?;

        let mut full = Vec::new();
        for cl in &model.clearances {
            let (Some(e), Some(f), Some(c)) = (
                column(&format!("joints/{}/radial_eccentricity", cl.name)),
                column(&format!("joints/{}/normal_force", cl.name)),
                column(&format!("joints/{}/contact_state", cl.name)),
            ) else {
                continue;
            };
            if e.names.len() != 2 {
                continue;
            }
            let (k, kc) = (f.names.len(), c.names.len());
            let force: Vec<f64> = (0..n)
                .map(|i| f.values[i * k..(i + 1) * k].iter().sum())
                .collect();
            let closed: Vec<bool> = (0..n)
                .map(|i| c.values[i * kc..(i + 1) * kc].iter().any(|&s| s > 0.5))
                .collect();
            full.push((cl, e, force, closed));
        }
        let contact: Vec<Vec<bool>> = full.iter().map(|f| f.3.clone()).collect();
        let forces: Vec<Vec<f64>> = full.iter().map(|f| f.2.clone()).collect();
        let count = options.frames.max(2);
        let keep = frames(&samples.time, count, &contact, &forces);
        let even = (count + 1).min(n);
        let impact_frames = keep.len().saturating_sub(even);
        let orbits = full
            .iter()
            .map(|(cl, e, force, closed)| Orbit {
                joint: cl.name.clone(),
                geometry: geometry_name(&cl.geometry),
                clearance: cl.geometry.radial_clearance(),
                u: keep.iter().map(|&i| e.values[2 * i]).collect(),
                w: keep.iter().map(|&i| e.values[2 * i + 1]).collect(),
                force: keep.iter().map(|&i| force[i]).collect(),
                contact: keep.iter().map(|&i| closed[i]).collect(),
            })
            .collect();
        let up = model
            .gravity
            .filter(|g| g.norm() > 0.0)
            .map_or(Vector3::y(), |g| -g.normalize());
        Ok(Motion {
            title,
            drawing,
            time: keep.iter().map(|&i| samples.time[i]).collect(),
            poses: keep.iter().map(|&i| pose(i)).collect(),
            orbits,
            samples: n,
            impact_frames,
            missing,
            up,
            period: model.settings.period,
        })
    }

    /// The box (global, m) round the drawing over the run (some 200 frames spread over it, and
    /// the last).
    fn extent(&self) -> (Vector3<f64>, Vector3<f64>) {
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(-f64::INFINITY),
        );
        let mut grow = |p: Vector3<f64>| {
            lo = lo.inf(&p);
            hi = hi.sup(&p);
        };
        for s in &self.drawing.ground {
            Triangles::of(&s.part)
                .vertices
                .into_iter()
                .for_each(&mut grow);
        }
        let vertices: Vec<Vec<Vector3<f64>>> = self
            .drawing
            .bodies
            .iter()
            .map(|b| {
                b.solids
                    .iter()
                    .flat_map(|s| Triangles::of(&s.part).vertices)
                    .collect()
            })
            .collect();
        let step = (self.time.len() / 200).max(1);
        for frame in self.poses.iter().step_by(step).chain(self.poses.last()) {
            for (v, (x, q)) in vertices.iter().zip(frame) {
                for p in v {
                    grow(x + q * p);
                }
            }
        }
        (lo, hi)
    }

    /// The camera the page opens with: the point looked at, the horizontal direction looked
    /// from, the elevation (rad), the distance (m) and the half field of view (rad). A planar
    /// mechanism (its drawing's extent along a global axis below 5 % of its largest) is seen
    /// square on; any other from 45 degrees round and 23 degrees up.
    fn view(&self, origin: &Vector3<f64>) -> Value {
        let (lo, hi) = self.extent();
        let size = hi - lo;
        let target = (lo + hi) * 0.5 - origin;
        let half_angle: f64 = 0.35;
        let largest = size.max();
        let up = self.up;
        let thin = (0..3)
            .min_by(|&a, &b| size[a].total_cmp(&size[b]))
            .unwrap_or(2);
        let (across, elevation) = if size[thin] < 0.05 * largest {
            let mut normal = Vector3::zeros();
            normal[thin] = 1.0;
            let flat = normal - up * normal.dot(&up);
            if flat.norm() < 0.3 {
                let (u, _) = mechanism::normals(&up);
                (u, 1.55)
            } else {
                (flat.normalize(), 0.0)
            }
        } else {
            let mut axes: Vec<Vector3<f64>> = vec![Vector3::x(), Vector3::y(), Vector3::z()];
            axes.sort_by(|a, b| a.dot(&up).abs().total_cmp(&b.dot(&up).abs()));
            let mix = axes[0] + axes[1];
            let flat = mix - up * mix.dot(&up);
            (flat.normalize(), 0.4)
        };
        // Far enough that the drawing fits the field of view (its plane, for a planar one; its
        // bounding sphere less a little, for a spatial one, whose corners are rarely all in view).
        let distance = if elevation == 0.0 {
            0.55 * largest.max(1e-6) / half_angle.tan()
        } else {
            0.45 * size.norm().max(1e-6) / half_angle.sin()
        };
        json!({
            "target": [target.x, target.y, target.z],
            "up": [up.x, up.y, up.z],
            "across": [across.x, across.y, across.z],
            "elevation": elevation,
            "distance": distance,
            "half_angle": half_angle,
        })
    }

    /// The page's HTML.
    pub fn page(&self, options: &Options) -> String {
        let b64 = |bytes: Vec<u8>| base64::engine::general_purpose::STANDARD.encode(bytes);
        let f32s = |v: &mut dyn Iterator<Item = f64>| -> String {
            b64(v.flat_map(|x| (x as f32).to_le_bytes()).collect())
        };
        let n = self.time.len();
        let (t0, t1) = (self.time[0], self.time[n - 1]);
        let duration = t1 - t0;
        let origin =
            self.poses[0].iter().map(|(x, _)| x).sum::<Vector3<f64>>() / self.poses[0].len() as f64;
        let speed = options.speed.unwrap_or_else(|| round_down(duration / 10.0));
        let mesh = |s: &mechanism::Solid, shift: &Vector3<f64>| {
            let t = Triangles::of(&s.part);
            json!({
                "color": s.color,
                "opacity": s.opacity,
                "vertices": f32s(&mut t.vertices.iter().flat_map(|v| {
                    let p = v - shift;
                    [p.x, p.y, p.z]
                })),
                "triangles": b64(t.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect()),
            })
        };
        let zero = Vector3::zeros();
        let bodies: Vec<Value> = self
            .drawing
            .bodies
            .iter()
            .map(|b| {
                json!({
                    "name": b.name,
                    "meshes": b.solids.iter().map(|s| mesh(s, &zero)).collect::<Vec<_>>(),
                })
            })
            .collect();
        let ground: Vec<Value> = self
            .drawing
            .ground
            .iter()
            .map(|s| mesh(s, &origin))
            .collect();
        let joints: Vec<Value> = self
            .orbits
            .iter()
            .map(|o| {
                let (outline, axes) = match o.geometry {
                    "translational" => ("band", ["w", "u"]),
                    _ => ("circle", ["u", "w"]),
                };
                json!({
                    "name": o.joint,
                    "title": format!("{} ({}, c = {} mm)", o.joint, o.geometry, sig(o.clearance * 1e3)),
                    "clearance": o.clearance,
                    "outline": outline,
                    "axes": axes,
                    "force_max": o.force.iter().copied().fold(0.0, f64::max),
                })
            })
            .collect();
        let poses = f32s(&mut self.poses.iter().flat_map(|frame| {
            frame.iter().flat_map(|(x, q)| {
                let p = x - origin;
                let q = q.quaternion();
                [p.x, p.y, p.z, q.w, q.i, q.j, q.k]
            })
        }));
        let orbits = f32s(&mut (0..n).flat_map(|k| {
            self.orbits
                .iter()
                .flat_map(move |o| [o.u[k], o.w[k], o.force[k]])
        }));
        let contact: Vec<u8> = (0..n)
            .flat_map(|k| self.orbits.iter().map(move |o| u8::from(o.contact[k])))
            .collect();
        let spacing = duration / (n - 1) as f64;
        let digits = (-(spacing.max(1e-12)).log10()).ceil().clamp(1.0, 9.0) as usize;
        let trail = self.period.unwrap_or(duration / 10.0).min(duration);
        let drawn_from = "Bodies the scene gives no shapes are drawn as bars between their joint \
                          points. Each inset shows a clearance magnified (its outline the radial \
                          clearance), the trail of the last drive period (of the whole orbit for \
                          a periodic orbit, of a tenth of the run without a drive) coloured by \
                          the normal force.";
        let missing = if self.missing.is_empty() {
            String::new()
        } else {
            format!(" Not recorded, not drawn: {}.", self.missing.join(", "))
        };
        let data = json!({
            "title": self.title,
            "note": format!("{drawn_from}{missing}"),
            "speed": speed,
            "digits": digits,
            "trail": trail,
            "view": self.view(&origin),
            "bodies": bodies,
            "ground": ground,
            "joints": joints,
            "time": b64(self.time.iter().flat_map(|t| t.to_le_bytes()).collect()),
            "poses": poses,
            "orbits": orbits,
            "contact": b64(contact),
        });
        // In a <script> element only "</" could end it early; JSON allows "<\/".
        let data = data.to_string().replace("</", "<\\/");
        PAGE.replace("@TITLE@", &escape_html(&self.title))
            .replace("@VIEWER@", VIEWER)
            .replace("@DATA@", &data)
    }
}

/// The largest of 1, 2 or 5 times a power of ten not above `x` (`x` > 0; 1 otherwise).
fn round_down(x: f64) -> f64 {
    if !(x > 0.0 && x.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|v| *v <= x * (1.0 + 1e-12))
        .unwrap_or(p)
}

/// `x` to three significant digits, without trailing zeros.
fn sig(x: f64) -> String {
    let s = format!(
        "{:.*}",
        (2 - x.abs().log10().floor() as i32).max(0) as usize,
        x
    );
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn escape_html(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The swept (or continued) parameter's path, for a title.
fn path_of(loaded: &Loaded, continuation: bool) -> String {
    match (&loaded.spec.continuation, &loaded.spec.sweep) {
        (Some(c), _) if continuation => c.parameter.clone(),
        (_, Some(s)) => s.parameter.clone(),
        _ => "parameter".into(),
    }
}

/// Writes the page of the motion `pick` chooses in `file` as `out/<name>.html` ([`stem`]),
/// whole or not at all, and returns its path and the motion drawn.
pub fn write_page(
    file: &Path,
    pick: Pick,
    out: &Path,
    options: &Options,
) -> Result<(PathBuf, Motion)> {
    let motion = Motion::pick(file, pick, options)?;
    let html = motion.page(options);
    let target = out.join(format!("{}.html", stem(file, pick)));
    crate::storage::durable::create_dir(out)?;
    crate::storage::durable::write_new(&target, html.as_bytes())?;
    Ok((target, motion))
}

/// The name of the outputs of a motion of `file`: the file's stem, with the case for a
/// comparison study's case, `-value-<v>` for a sweep value, `-orbit-<b>-<p>` for an orbit.
pub fn stem(file: &Path, pick: Pick) -> String {
    match pick {
        Pick::Run { case } => crate::storage::export::stem(file, case),
        Pick::Value { value, .. } => {
            format!("{}-value-{value}", crate::storage::export::stem(file, None))
        }
        Pick::Orbit { branch, point } => format!(
            "{}-orbit-{branch}-{point}",
            crate::storage::export::stem(file, None)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_keep_every_contact_change_and_each_contacts_peak() {
        let time: Vec<f64> = (0..1001).map(|i| i as f64 * 1e-3).collect();
        // One impact from sample 503 to 505 (between the evenly spaced frames 500 and 510), its
        // peak at 504; a second, of one sample, at 731 (730 is an evenly spaced frame already).
        let mut contact = vec![false; 1001];
        let mut force = vec![0.0; 1001];
        for (i, f) in [(503, 10.0), (504, 30.0), (505, 20.0), (731, 5.0)] {
            contact[i] = true;
            force[i] = f;
        }
        let keep = frames(&time, 100, &[contact], &[force]);
        for i in [0, 10, 500, 502, 503, 504, 505, 506, 730, 731, 732, 1000] {
            assert!(keep.contains(&i), "sample {i} missing from {keep:?}");
        }
        assert_eq!(keep.len(), 101 + 7, "{keep:?}");
        assert!(keep.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn a_short_run_keeps_every_sample() {
        let time = [0.0, 0.5, 1.0];
        assert_eq!(frames(&time, 10, &[], &[]), vec![0, 1, 2]);
    }

    #[test]
    fn speeds_are_round_numbers_below_a_tenth_of_the_run() {
        assert_eq!(round_down(1.0), 1.0);
        assert_eq!(round_down(0.01), 0.01);
        assert_eq!(round_down(0.3), 0.2);
        assert_eq!(round_down(7.0), 5.0);
        assert_eq!(sig(0.3), "0.3");
        assert_eq!(sig(0.25), "0.25");
        assert_eq!(sig(12.345), "12.3");
    }
}
