//! The compiled summary of a scene: what `jointplay check` prints, as data.
//!
//! [`Summary::new`] assembles a compiled model at its initial state and collects what will be
//! simulated: the bodies with their mass and inertia, the joints and their constraint rows, the
//! drives and their motions, the rank and the degrees of freedom of the constraints (with the
//! redundant joint rows and drives), the assembly residuals, the effects simulated and disabled,
//! the solver, the span and the outputs. [`Summary::lines`] renders it as the aligned text lines of
//! `jointplay check`.

use std::path::{Path, PathBuf};

use jointplay_solver::dynamics::{AssemblyReport, Structure};
use jointplay_solver::model::{GROUND, Model, State};
use jointplay_solver::scene::DriveCoordinate;

use crate::Result;

/// One body: kg and kg m^2 (the inertia about the centre of mass, body axes).
#[derive(Debug, Clone, PartialEq)]
pub struct BodySummary {
    pub name: String,
    pub mass: f64,
    pub inertia_diagonal: [f64; 3],
    /// The shapes the scene draws it with (`visual`); 0: drawn from its joint points.
    pub shapes: usize,
}

/// One joint: its kind, the bodies it connects (`ground` for the ground) and its constraint rows
/// (fewer, or none, for a joint with clearance).
#[derive(Debug, Clone, PartialEq)]
pub struct JointSummary {
    pub name: String,
    pub kind: &'static str,
    pub body_a: String,
    pub body_b: String,
    pub rows: usize,
}

/// One drive: the joint and coordinate it moves, its motion, and the motion's period (s) when it
/// has one.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveSummary {
    pub name: String,
    pub joint: String,
    pub coordinate: DriveCoordinate,
    pub profile: String,
    pub period: Option<f64>,
}

/// What is recorded: the sample interval (s), how many bodies, joints and drives, and whether
/// accelerations and diagnostics are kept, and the mantissa bits the values keep in the file,
/// by quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSummary {
    pub interval: f64,
    pub bodies: usize,
    pub joints: usize,
    pub drives: usize,
    pub accelerations: bool,
    pub diagnostics: bool,
    pub significant_bits: jointplay_solver::model::Bits,
}

/// The compiled summary of a scene at its assembled initial state.
#[derive(Debug, Clone)]
pub struct Summary {
    pub name: String,
    /// The scene file as given.
    pub file: PathBuf,
    pub description: Option<String>,
    pub bodies: Vec<BodySummary>,
    pub joints: Vec<JointSummary>,
    /// Constraint rows of the joints, and of joints and drives together.
    pub joint_rows: usize,
    pub rows: usize,
    pub drives: Vec<DriveSummary>,
    /// Ranks, degrees of freedom and redundancy at the assembled initial state.
    pub structure: Structure,
    pub assembly: AssemblyReport,
    /// The clearance joints the start was assembled with closed as their ideal joints.
    pub closed_start: Option<jointplay_solver::model::ClosedStart>,
    /// Clearance contacts that penetrate at the assembled start, deepest first.
    pub penetrations: Vec<jointplay_solver::guard::StartPenetration>,
    /// The effects simulated, one line each; a line starting with four spaces continues the one
    /// before it.
    pub effects: Vec<String>,
    /// What the scene's `disable` list removed, one line each.
    pub disabled: Vec<String>,
    /// The integrator and its settings.
    pub solver: String,
    /// Baumgarte parameters (1/s).
    pub alpha: f64,
    pub beta: f64,
    /// s.
    pub start_time: f64,
    pub end_time: f64,
    /// The drives' common period (s), when they have one.
    pub period: Option<f64>,
    pub output: OutputSummary,
    /// State components beyond the bodies' coordinates: the LuGre bristle deflections.
    pub bristle_states: usize,
}

fn body_name(m: &Model, b: usize) -> String {
    if b == GROUND {
        "ground".into()
    } else {
        m.bodies[b].name.clone()
    }
}

impl Summary {
    /// Assembles `model` at `state` (the state it was compiled with; assembly moves it onto the
    /// constraints) and summarises it; `file` is the scene file as the user named it.
    pub fn new(file: &Path, model: &Model, state: &mut State) -> Result<Summary> {
        let assembly = model.assemble(state)?;
        let structure = model.structure(state.t, &state.y)?;
        let penetrations = model.penetrations(
            &state.y,
            &mut jointplay_solver::workspace::Workspace::new(model),
        );
        let s = &model.settings;
        let o = &model.outputs;
        Ok(Summary {
            name: model.name.clone(),
            file: file.to_path_buf(),
            description: model.description.clone(),
            bodies: model
                .bodies
                .iter()
                .map(|b| {
                    let d = b.inertia.diagonal();
                    BodySummary {
                        name: b.name.clone(),
                        mass: b.mass,
                        inertia_diagonal: [d.x, d.y, d.z],
                        shapes: b.visuals.len(),
                    }
                })
                .collect(),
            joints: model
                .joints
                .iter()
                .map(|j| JointSummary {
                    name: j.name.clone(),
                    kind: j.kind.name(),
                    body_a: body_name(model, j.body_a),
                    body_b: body_name(model, j.body_b),
                    rows: j.rows.len(),
                })
                .collect(),
            joint_rows: model.joint_rows,
            rows: model.n_rows,
            drives: model
                .drives
                .iter()
                .map(|d| DriveSummary {
                    name: d.name.clone(),
                    joint: model.joints[d.joint].name.clone(),
                    coordinate: d.coordinate,
                    profile: d.profile.describe(),
                    period: d.period(),
                })
                .collect(),
            structure,
            assembly,
            closed_start: model.closed_start.clone(),
            penetrations,
            effects: model.effects.describe(model),
            disabled: model.disabled.clone(),
            solver: s.method.describe(),
            alpha: s.alpha,
            beta: s.beta,
            start_time: s.start_time,
            end_time: s.end_time,
            period: s.period,
            bristle_states: model.n_bristle,
            output: OutputSummary {
                interval: o.interval,
                bodies: o.bodies.len(),
                joints: o.joints.len(),
                drives: o.drives.len(),
                accelerations: o.accelerations,
                diagnostics: o.diagnostics,
                significant_bits: o.significant_bits.clone(),
            },
        })
    }

    /// The summary as the text lines `jointplay check` prints.
    pub fn lines(&self) -> Vec<String> {
        let st = &self.structure;
        let mut out = vec![format!(
            "scene        {} ({})",
            self.name,
            self.file.display()
        )];
        if let Some(d) = &self.description {
            out.push(format!("description  {d}"));
        }
        out.push(format!("bodies       {}", self.bodies.len()));
        for b in &self.bodies {
            let [x, y, z] = b.inertia_diagonal;
            let shapes = match b.shapes {
                0 => String::new(),
                1 => ", drawn with 1 shape".into(),
                n => format!(", drawn with {n} shapes"),
            };
            out.push(format!(
                "  {:<14} mass {:>9.4} kg   inertia diag [{x:.4e}, {y:.4e}, {z:.4e}] kg m^2{shapes}",
                b.name, b.mass
            ));
        }
        out.push(format!(
            "coordinates  {} (6 velocity coordinates per body; positions carry Euler parameters)",
            st.n_coords
        ));
        if self.bristle_states > 0 {
            out.push(format!(
                "bristles     {} states (LuGre deflections, 3 per contact, m), after the bodies' \
                 coordinates in the state",
                self.bristle_states
            ));
        }
        out.push(format!(
            "joints       {} ({} constraint rows)",
            self.joints.len(),
            self.joint_rows
        ));
        for j in &self.joints {
            out.push(format!(
                "  {:<14} {:<11} {} -> {}   {} rows",
                j.name, j.kind, j.body_a, j.body_b, j.rows
            ));
        }
        out.push(format!("drives       {}", self.drives.len()));
        for d in &self.drives {
            let period = d
                .period
                .map(|p| format!(", period {p:.6} s"))
                .unwrap_or_default();
            out.push(format!(
                "  {:<14} joint {} {}, {}{}",
                d.name,
                d.joint,
                match d.coordinate {
                    DriveCoordinate::Translation => "translation (m)",
                    DriveCoordinate::Rotation => "rotation (rad)",
                },
                d.profile,
                period
            ));
        }
        out.push(format!(
            "constraints  {} rows, numerical rank {} at the assembled initial state (joints: {} rows, rank {})",
            self.rows, st.rank, st.joint_rows, st.joint_rank
        ));
        out.push(format!(
            "degrees of freedom  {} ({} coordinates - joint rank {})",
            st.dof, st.n_coords, st.joint_rank
        ));
        out.push(format!("redundant joint rows  {}", st.redundant_joint_rows));
        out.push(format!(
            "redundant drives  {}{}",
            st.redundant_drives,
            if st.redundant_drives > 0 {
                format!(
                    " ({} drives for {} degrees of freedom: redundant actuation, minimum-norm actuator forces)",
                    st.drive_rows, st.dof
                )
            } else {
                String::new()
            }
        ));
        out.push(format!("free degrees of freedom  {}", st.remaining_dof));
        let a = &self.assembly;
        out.push(format!(
            "assembly     {} Newton iterations, residual {:.2e} -> {:.2e} (m, rad); velocity residual {:.2e} -> {:.2e}",
            a.iterations,
            a.initial_residual,
            a.final_residual,
            a.initial_velocity_residual,
            a.final_velocity_residual
        ));
        if let Some(c) = &self.closed_start {
            let joints: Vec<String> = c
                .joints
                .iter()
                .map(|(name, e)| {
                    if e.norm() == 0.0 {
                        format!("{name} (concentric)")
                    } else {
                        format!(
                            "{name} (eccentricity [{:.4e}, {:.4e}, {:.4e}] m)",
                            e.x, e.y, e.z
                        )
                    }
                })
                .collect();
            let gap = match c.gap {
                Some((p, v)) => format!(
                    "the start assembled without closing them was {p:.2e} (m, rad) and {v:.2e} (m/s, rad/s) from it"
                ),
                None => "the start could not be assembled without closing them".into(),
            };
            out.push(format!(
                "start        clearance joints {}: {}; {gap}",
                if c.moved {
                    "closed as ideal joints, then released"
                } else {
                    "already closed at the assembled start, kept as it is"
                },
                joints.join(", ")
            ));
        }
        for p in &self.penetrations {
            out.push(format!("start        warning: {p}"));
        }
        out.push("effects simulated".into());
        for e in &self.effects {
            if let Some(sub) = e.strip_prefix("    ") {
                out.push(format!("      {sub}"));
            } else {
                out.push(format!("  - {e}"));
            }
        }
        if !self.disabled.is_empty() {
            out.push("effects disabled (scene's disable list; not evaluated, not stored)".into());
            for d in &self.disabled {
                out.push(format!("  - {d}"));
            }
        }
        let periods = self
            .period
            .map(|p| {
                format!(
                    " ({:.4} drive periods of {p:.6} s)",
                    (self.end_time - self.start_time) / p
                )
            })
            .unwrap_or_default();
        out.push(format!(
            "solver       {}, Baumgarte alpha {} 1/s, beta {} 1/s",
            self.solver, self.alpha, self.beta
        ));
        out.push(format!(
            "span         {} s to {} s{}",
            self.start_time, self.end_time, periods
        ));
        let o = &self.output;
        out.push(format!(
            "output       every {:e} s: {} bodies, {} joints, {} drives{}{}{}",
            o.interval,
            o.bodies,
            o.joints,
            o.drives,
            if o.accelerations {
                ", accelerations"
            } else {
                ""
            },
            if o.diagnostics { ", diagnostics" } else { "" },
            match o.significant_bits.describe() {
                Some(b) => format!(", values rounded to {b}"),
                None => String::new(),
            }
        ));
        out
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use jointplay_solver::scene::SceneSpec;

    use super::*;

    fn scene(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../data/scenes")
            .join(name)
    }

    fn summary(name: &str) -> Summary {
        let path = scene(name);
        let (model, mut state) = Model::compile(&SceneSpec::load(&path).unwrap()).unwrap();
        Summary::new(&path, &model, &mut state).unwrap()
    }

    #[test]
    fn the_4ups_rpu_has_four_dof_full_rank_joints_and_one_redundant_drive() {
        let s = summary("4ups-rpu.toml");
        let st = &s.structure;
        assert_eq!(st.dof, 4);
        assert_eq!((st.joint_rows, st.joint_rank), (62, 62));
        assert_eq!(st.redundant_joint_rows, 0);
        assert_eq!(st.redundant_drives, 1);
        assert_eq!(st.remaining_dof, 0);
        assert_eq!(s.drives.len(), 5);
        assert_eq!(s.joint_rows, 62);
        assert_eq!(s.rows, 67);
        assert!(s.assembly.final_residual < 1e-9, "{:?}", s.assembly);
        let lines = s.lines();
        assert!(
            lines.contains(&"degrees of freedom  4 (66 coordinates - joint rank 62)".to_string())
        );
        assert!(lines.contains(
            &"redundant drives  1 (5 drives for 4 degrees of freedom: redundant actuation, minimum-norm actuator forces)"
                .to_string()
        ));
        assert_eq!(lines.iter().filter(|l| l.starts_with("bodies ")).count(), 1);
    }

    #[test]
    fn the_clearance_slider_crank_has_three_redundant_rows_and_lists_its_clearance_joint() {
        let s = summary("slider-crank-clearance.toml");
        let st = &s.structure;
        assert_eq!((st.n_coords, st.joint_rows, st.joint_rank), (18, 18, 15));
        assert_eq!(
            (st.dof, st.redundant_joint_rows, st.remaining_dof),
            (3, 3, 2)
        );
        let pin = s.joints.iter().find(|j| j.name == "piston_pin").unwrap();
        // The planar clearance joint keeps only its axial rows: the contact replaces the others.
        assert_eq!(
            (pin.kind, pin.body_a.as_str(), pin.body_b.as_str(), pin.rows),
            ("revolute", "slider", "rod", 3)
        );
        assert_eq!(s.joints[0].body_a, "ground");
        assert_eq!(s.drives[0].coordinate, DriveCoordinate::Rotation);
        assert!((s.drives[0].period.unwrap() - 0.012).abs() < 1e-12);
        let lines = s.lines();
        assert!(lines[0].starts_with("scene        slider-crank-clearance ("));
        assert!(
            lines[0].ends_with("slider-crank-clearance.toml)"),
            "{}",
            lines[0]
        );
        assert!(lines.contains(&"  piston_pin     revolute    slider -> rod   3 rows".to_string()));
        assert!(lines.contains(
            &"  - clearance contact: 1 joints, 1 contact points, frictionless".to_string()
        ));
        // Continuation lines of an effect are indented under it.
        assert!(
            lines
                .iter()
                .any(|l| l.starts_with("      piston_pin: planar revolute"))
        );
        assert_eq!(
            lines.last().unwrap(),
            "output       every 1e-5 s: 3 bodies, 4 joints, 1 drives, accelerations, diagnostics"
        );
    }
}
