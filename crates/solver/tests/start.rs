//! The start of a scene with clearance joints (`compile/start.rs`): a joint is assembled as its
//! ideal joint, concentric or at its `initial_eccentricity`, then released; a start that already
//! closes it is kept bit for bit; `start = "free"` leaves it where the declared poses put it.
//! The mechanism is the book tutorial's four-bar (0.25 mm planar clearance in the coupler-rocker
//! pin, crank at 2400 rpm).

mod common;

use std::path::Path;

use jointplay_solver::model::{Model, State};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

const CLEARANCE: f64 = 2.5e-4;

fn tutorial() -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../book/src/tutorial/four-bar.toml"),
    )
    .unwrap()
}

/// The tutorial with its rocker turned by about 0.4 degrees: the pin end of the rocker moves
/// 0.74 mm, so the declared poses put the journal 0.49 mm inside the bearing's wall.
fn rocker_turned() -> String {
    let t = tutorial().replace(
        "orientation = { x = [-0.05, 0.12, 0.0], y = [-0.12, -0.05, 0.0] }",
        "orientation = { x = [-0.0492, 0.12, 0.0], y = [-0.12, -0.0492, 0.0] }",
    );
    assert_ne!(t, tutorial(), "the tutorial's rocker orientation moved");
    t
}

/// `text` with `line` added to the pin's clearance block.
fn with_clearance_line(text: &str, line: &str) -> String {
    let anchor = "friction = { law = \"ambrosio\"";
    assert!(text.contains(anchor), "the tutorial's friction line moved");
    text.replacen(anchor, &format!("{line}\n{anchor}"), 1)
}

fn compile(text: &str) -> jointplay_solver::error::Result<(Model, State)> {
    common::compile("four-bar.toml", text)
}

/// The position (m) and velocity (m/s) of joint point `s` (COM-relative, body axes) of body `b`.
fn point(m: &Model, y: &[f64], b: usize, s: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let np = m.n_pos();
    let r = Vector3::new(y[7 * b], y[7 * b + 1], y[7 * b + 2]);
    let q = &y[7 * b + 3..7 * b + 7];
    let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let v = Vector3::new(y[np + 6 * b], y[np + 6 * b + 1], y[np + 6 * b + 2]);
    let w = Vector3::new(y[np + 6 * b + 3], y[np + 6 * b + 4], y[np + 6 * b + 5]);
    let arm = q * s;
    (r + arm, v + w.cross(&arm))
}

/// The journal centre relative to the bearing centre at the start: offset (m) in the housing's
/// (the rocker's) axes, and relative velocity (m/s, global).
fn pin(m: &Model, s: &State) -> (Vector3<f64>, Vector3<f64>) {
    let j = m.joints.iter().find(|j| j.name == "coupler_pin").unwrap();
    let (pa, va) = point(m, &s.y, j.body_a, &j.point_a);
    let (pb, vb) = point(m, &s.y, j.body_b, &j.point_b);
    let b = j.body_a;
    let q = &s.y[7 * b + 3..7 * b + 7];
    let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    (q.inverse() * (pb - pa), vb - va)
}

#[test]
fn an_open_start_is_closed_concentric_and_released_at_rest_in_its_housing() {
    let (m, s) = compile(&rocker_turned()).unwrap();
    let (e, v) = pin(&m, &s);
    // The closed rows are met to the assembly's tolerance (1e-12 m) and the velocity projection
    // is exact to rounding of the 6 m/s link speeds.
    assert!(e.norm() < 1e-11, "offset {e}");
    assert!(v.norm() < 1e-11, "relative velocity {v}");
    let closed = m.closed_start.as_ref().unwrap();
    assert!(closed.moved && closed.joints[0].0 == "coupler_pin");
    let (gap, _) = closed.gap.unwrap();
    assert!(gap > CLEARANCE, "open start {gap} m from closed");
    let mut ws = jointplay_solver::workspace::Workspace::new(&m);
    assert!(m.penetrations(&s.y, &mut ws).is_empty());

    // Left free, the declared poses decide: the journal starts inside the wall.
    let (m, s) = compile(&with_clearance_line(&rocker_turned(), "start = \"free\"")).unwrap();
    assert!(m.closed_start.is_none());
    let (e, _) = pin(&m, &s);
    assert!(e.norm() > CLEARANCE, "offset {e}");
    let mut ws = jointplay_solver::workspace::Workspace::new(&m);
    let p = m.penetrations(&s.y, &mut ws);
    assert!(p.len() == 1 && p[0].depth > 4e-4, "{p:?}");
}

#[test]
fn an_initial_eccentricity_is_where_the_journal_starts() {
    let e0 = Vector3::new(1.2e-4, -0.9e-4, 0.0);
    let text = with_clearance_line(
        &rocker_turned(),
        &format!("initial_eccentricity = [{}, {}, 0.0]", e0.x, e0.y),
    );
    let (m, s) = compile(&text).unwrap();
    let (e, v) = pin(&m, &s);
    assert!((e - e0).norm() < 1e-11, "offset {e} against {e0}");
    // At rest in the housing: the offset turns with the rocker, v = w_rocker x (A_rocker e).
    let j = m.joints.iter().find(|j| j.name == "coupler_pin").unwrap();
    let (b, np) = (j.body_a, m.n_pos());
    let w = Vector3::new(0.0, 0.0, s.y[np + 6 * b + 5]);
    let q = &s.y[7 * b + 3..7 * b + 7];
    let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let carried = w.cross(&(q * e0));
    assert!(
        (v - carried).norm() < 1e-11,
        "relative velocity {v} against {carried}"
    );
    assert_eq!(m.closed_start.as_ref().unwrap().joints[0].1, e0);
}

#[test]
fn a_start_that_is_already_closed_is_kept_bit_for_bit() {
    // The tutorial declares the ideal linkage's poses and velocities: closing its pin changes
    // nothing, and the start equals the one the joint left free gets, to the bit.
    let (m, closed) = compile(&tutorial()).unwrap();
    let c = m.closed_start.as_ref().unwrap();
    assert!(!c.moved);
    let (_, free) = compile(&with_clearance_line(&tutorial(), "start = \"free\"")).unwrap();
    assert_eq!(closed.y, free.y);
}

#[test]
fn an_impossible_or_misplaced_eccentricity_is_refused_naming_the_field() {
    let err = |line: &str| {
        compile(&with_clearance_line(&rocker_turned(), line))
            .unwrap_err()
            .to_string()
    };
    let e = err("initial_eccentricity = [3e-4, 0.0, 0.0]");
    assert!(
        e.contains("joints[3].clearance.initial_eccentricity")
            && e.contains("exceeds the radial clearance"),
        "{e}"
    );
    let e = err("initial_eccentricity = [1e-4, 0.0, 1e-4]");
    assert!(
        e.contains("joints[3].clearance.initial_eccentricity")
            && e.contains("along the joint axis"),
        "{e}"
    );
    let e = err("start = \"free\"\ninitial_eccentricity = [1e-4, 0.0, 0.0]");
    assert!(
        e.contains("joints[3].clearance.initial_eccentricity") && e.contains("start = \"closed\""),
        "{e}"
    );
    let e = err("start = \"shut\"");
    assert!(e.contains("closed") && e.contains("free"), "{e}");
}
