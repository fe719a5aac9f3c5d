//! The passes of the scene compiler behind [`crate::model::Model::compile`].
//!
//! Each pass reads one part of the (already `disable`-edited, see [`crate::disable`]) scene,
//! validates it and produces its part of the model; a later pass sees only what the earlier ones
//! produced. In order:
//!
//! 1. finite numbers ([`check_finite`]): the raw TOML tree holds no NaN, infinity or magnitude
//!    beyond [`MAX_MAGNITUDE`];
//! 2. bodies ([`bodies::compile`]): the [`Body`](crate::model::Body) list, the initial state as
//!    declared, the name index and the frames that resolve named points and axes;
//! 3. joints ([`joints::compile`]): the [`Joint`](crate::model::Joint) list, the constraint
//!    primitives and rows of the ideal joints, and each joint's frame (kept for the drives);
//! 4. clearance elements ([`clearance::compile`], called by the joints pass for a joint with a
//!    `clearance` block): the geometry, the normal and friction laws ([`laws`]), the
//!    [`Clearance`](crate::clearance::Clearance) element and the rows it leaves to the joint;
//! 5. drives ([`drives::compile`]): one [`Drive`](crate::model::Drive) and one row each, after
//!    the joint rows;
//! 6. springs and loads ([`forces::springs`], [`forces::loads`]);
//! 7. solver settings and outputs ([`settings::settings`], [`settings::outputs`]), and the
//!    [`Effects`](crate::model::Effects) the model simulates ([`settings::effects`]).
//! 8. the start ([`start::close`]): the declared state assembled with every clearance joint
//!    closed as its ideal joint (concentric, or at its `initial_eccentricity`), so that the run
//!    releases it from a consistent pose and velocity.
//!
//! The passes share two leaves, which import none of them: [`ctx`] (the context [`Ctx`](ctx::Ctx)
//! that errors and warnings go through, and small field helpers) and [`rows`] (the constraint
//! rows appended so far and a joint's frame, from which joints, clearance elements and drives
//! build their primitives); `tests/module_graph.rs` checks that the passes form no import cycle.
//!
//! Every error names the file and the field path (`joints[3].axis_a`); the first error found
//! stops the compilation.

pub(crate) mod bodies;
pub(crate) mod clearance;
pub(crate) mod ctx;
pub(crate) mod drives;
pub(crate) mod forces;
pub(crate) mod joints;
pub(crate) mod laws;
pub(crate) mod rows;
pub(crate) mod settings;
pub(crate) mod start;

use std::path::Path;

use self::ctx::{Ctx, v3};
use crate::error::{Error, Result};
use crate::model::{Effects, Model, State};
use crate::scene::SceneFile;

// The entry point lives here, not in `model`, so that `model` (the compiled types) does not
// import its own compiler.
impl Model {
    /// Validates and compiles a scene; returns the model and the initial state: as declared,
    /// or, when the scene has clearance joints, assembled with them closed as their ideal
    /// joints (pass 8). Either way not yet assembled onto the model's own constraints: see
    /// [`Model::assemble`].
    pub fn compile(scene: &SceneFile) -> Result<(Model, State)> {
        let cx = Ctx::new(&scene.path);
        // Disabled effects are removed from the scene before anything is compiled.
        let (spec, disabled) = crate::disable::apply(&scene.spec)
            .map_err(|(field, error)| cx.err(field, error.to_string()))?;
        let spec = &spec;
        check_finite(&scene.text, &scene.path, &cx)?;
        let bodies = bodies::compile(spec, &cx)?;
        let mut rows = rows::Rows::default();
        let mut joints = joints::compile(spec, &bodies, &mut rows, &cx)?;
        let joint_rows = rows.n;
        let drives = drives::compile(spec, &joints, &mut rows, &cx)?;
        let frames = std::mem::take(&mut joints.frames);
        let springs = forces::springs(spec, &bodies, &cx)?;
        let loads = forces::loads(spec, &bodies, &cx)?;
        let settings = settings::settings(&spec.solver, &drives, &cx)?;
        let outputs = settings::outputs(
            &spec.output,
            &settings,
            &bodies.bodies,
            &joints.joints,
            &drives,
            &cx,
        )?;
        let (prims, n_rows) = (rows.prims, rows.n);
        let mut y = bodies.y;
        let bodies = bodies.bodies;
        // LuGre's bristle deflections follow the bodies' coordinates in the state, 3 per
        // contact of each joint whose law has them, starting undeflected.
        let mut clearances = joints.clearances;
        let mut n_bristle = 0;
        for c in clearances.iter_mut().filter(|c| c.friction.has_bristles()) {
            c.bristle = Some(n_bristle);
            n_bristle += 3 * c.geometry.n_contacts();
        }
        y.resize(y.len() + n_bristle, 0.0);
        let blocks: Vec<_> = prims.iter().map(|(p, r0)| p.row_block(*r0)).collect();
        let coupling = crate::coupling::Coupling::new(bodies.len(), &blocks, n_rows);
        let mut model = Model {
            name: scene.name(),
            file: scene.path.clone(),
            description: spec.description.clone(),
            bodies,
            joints: joints.joints,
            drives,
            springs,
            loads,
            gravity: spec.gravity.map(v3),
            prims,
            clearances,
            n_contacts: joints.n_contacts,
            n_bristle,
            joint_rows,
            n_rows,
            coupling,
            effects: Effects::default(),
            disabled,
            settings,
            outputs,
            warnings: Vec::new(),
            closed_start: None,
        };
        model.effects = settings::effects(&model);
        let mut state = State {
            t: model.settings.start_time,
            y,
        };
        model.closed_start = start::close(&model, &frames, spec, &mut state, &cx)?;
        model.warnings = cx.into_warnings();
        Ok((model, state))
    }
}

/// The largest magnitude of a number in a scene. Far beyond any physical quantity in SI units,
/// and small enough that squares and products of a few stay finite: a body placed at 1e200 m
/// made the assembly's corrections overflow to NaN, on which the rank analysis never ended.
pub(crate) const MAX_MAGNITUDE: f64 = 1e100;

/// Pass 1: parses the scene text as a raw TOML tree and rejects NaN, infinities and magnitudes
/// beyond [`MAX_MAGNITUDE`] anywhere in it, naming the field path.
pub(crate) fn check_finite(text: &str, file: &Path, cx: &Ctx) -> Result<()> {
    let raw: toml::Value = toml::from_str(text).map_err(|e| Error::Parse {
        file: file.to_path_buf(),
        message: e.to_string(),
    })?;
    finite(&raw, "", cx)
}

fn finite(v: &toml::Value, path: &str, cx: &Ctx) -> Result<()> {
    match v {
        toml::Value::Float(f) if !f.is_finite() => {
            Err(cx.err(path, format!("must be a finite number, got {f}")))
        }
        toml::Value::Float(f) if f.abs() > MAX_MAGNITUDE => Err(cx.err(
            path,
            format!(
                "{f:e} is beyond any quantity of a mechanism in SI units (at most 1e100 in \
                 magnitude: the numerics square lengths, masses and forces)"
            ),
        )),
        toml::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                finite(x, &format!("{path}[{i}]"), cx)?;
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
                finite(x, &p, cx)?;
            }
            Ok(())
        }
        _ => Ok(()),
    }
}
