//! End-to-end tests of the `jointplay` program: what a user runs, checked on what it writes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    // The test process opens run files while other tests spawn the program;
    // HDF5 opens files without close-on-exec, so a child spawned at that
    // moment inherits the descriptor and its lock and holds it until it exits.
    // A program run that writes the same file would then fail to lock it
    // (errno 11). The tests run the program without HDF5's advisory locks.
    let mut c = Command::new(env!("CARGO_BIN_EXE_jointplay"));
    c.env("HDF5_USE_FILE_LOCKING", "FALSE");
    c
}

fn scenes() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/scenes")
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Complete elliptic integral of the first kind K(k) by the arithmetic-geometric mean.
fn ellip_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..40 {
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    std::f64::consts::PI / (2.0 * a)
}

fn read2(file: &hdf5::File, name: &str) -> Vec<[f64; 3]> {
    let a = file.dataset(name).unwrap().read_2d::<f64>().unwrap();
    a.outer_iter().map(|r| [r[0], r[1], r[2]]).collect()
}

#[test]
fn pendulum_period_from_the_hdf5_file_matches_the_elliptic_integral() {
    let dir = tempfile::tempdir().unwrap();
    let out = bin()
        .args(["run", "--no-plots", "-q"])
        .arg(scenes().join("pendulum.toml"))
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    let file = hdf5::File::open(dir.path().join("pendulum.h5")).unwrap();
    let t = file
        .dataset("time")
        .unwrap()
        .read_1d::<f64>()
        .unwrap()
        .to_vec();
    let pos = read2(&file, "bodies/bob/position");
    let vel = read2(&file, "bodies/bob/velocity");
    // Upward zero crossings of x (theta = 0), located on the cubic Hermite interpolant of the
    // recorded positions and velocities (interpolation error O(dt^4) ~ 1e-12 at dt = 1 ms).
    let mut crossings = Vec::new();
    for i in 0..t.len() - 1 {
        let (x0, x1) = (pos[i][0], pos[i + 1][0]);
        if x0 < 0.0 && x1 >= 0.0 {
            let h = t[i + 1] - t[i];
            let (v0, v1) = (vel[i][0], vel[i + 1][0]);
            let p = |s: f64| {
                (2.0 * s * s * s - 3.0 * s * s + 1.0) * x0
                    + (s * s * s - 2.0 * s * s + s) * h * v0
                    + (-2.0 * s * s * s + 3.0 * s * s) * x1
                    + (s * s * s - s * s) * h * v1
            };
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..60 {
                let m = 0.5 * (lo + hi);
                if p(m) < 0.0 { lo = m } else { hi = m }
            }
            crossings.push(t[i] + 0.5 * (lo + hi) * h);
        }
    }
    assert!(crossings.len() >= 4, "only {} crossings", crossings.len());
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    // The scene: L = 1 m, m = 1 kg, I_c = 1e-3 kg m^2, g = 9.81 m/s^2, released from 60 degrees.
    let theta0 = std::f64::consts::FRAC_PI_3;
    let i_o = 1.0e-3 + 1.0;
    let exact = 4.0 * (i_o / 9.81f64).sqrt() * ellip_k((theta0 / 2.0).sin());
    let rel = ((measured - exact) / exact).abs();
    // Required: 1e-6 relative at the scene's tight tolerance (rtol 1e-11).
    assert!(
        rel < 1e-6,
        "period {measured} s vs {exact} s: relative error {rel:e}"
    );

    // Layout and units.
    let unit = |path: &str| -> String {
        let ds = file.dataset(path).unwrap();
        ds.attr("unit")
            .unwrap()
            .read_scalar::<hdf5::types::VarLenUnicode>()
            .unwrap()
            .to_string()
    };
    assert_eq!(unit("time"), "s");
    assert_eq!(unit("bodies/bob/position"), "m");
    assert_eq!(unit("bodies/bob/acceleration"), "m/s^2");
    assert_eq!(unit("joints/pivot/reaction_force"), "N");
    assert_eq!(unit("diagnostics/energy"), "J");
    let scene_text = file
        .attr("scene")
        .unwrap()
        .read_scalar::<hdf5::types::VarLenUnicode>()
        .unwrap();
    assert!(scene_text.as_str().contains("name = \"pendulum\""));
    assert!(file.attr("program_version").is_ok());
    // The bob hangs from the pivot: at rest at the bottom the reaction would be m g; over the swing
    // the reaction magnitude stays between m g cos(theta0) and m g (3 - 2 cos(theta0)).
    let f = read2(&file, "joints/pivot/reaction_force");
    for r in &f {
        let n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        assert!(
            n > 9.81 * 0.5 * 0.99 && n < 9.81 * 2.0 * 1.01,
            "reaction {n} N"
        );
    }
    assert!(!dir.path().join("pendulum.h5.partial").exists());
}

/// A run streams its file in the 1.8 format whatever `--hdf5-format` says (its superblock,
/// version 0, the byte after the signature, has no "open for writing" flag that a killed run
/// would leave set: see `h5::create_streamed`), and both options write the same datasets with the
/// same values. (The option's effect on the files written whole, sweeps, shards and merges, is
/// tested in tests/shards.rs.)
#[test]
fn the_hdf5_format_option_writes_the_same_values_in_the_oldest_format() {
    let dir = tempfile::tempdir().unwrap();
    let run = |format: Option<&str>, sub: &str| {
        let mut c = bin();
        if let Some(f) = format {
            c.args(["--hdf5-format", f]);
        }
        let out = c
            .args(["run", "--no-plots", "-q"])
            .arg(scenes().join("slider-crank-clearance.toml"))
            .arg("--out")
            .arg(dir.path().join(sub))
            .output()
            .unwrap();
        assert!(out.status.success(), "{:?}", text(&out));
        dir.path().join(sub).join("slider-crank-clearance.h5")
    };
    let (new, old) = (run(None, "new"), run(Some("1.8"), "old"));
    let superblock = |p: &Path| std::fs::read(p).unwrap()[8];
    assert_eq!((superblock(&new), superblock(&old)), (0, 0));
    let (a, b) = (
        hdf5::File::open(&new).unwrap(),
        hdf5::File::open(&old).unwrap(),
    );
    let mut names = Vec::new();
    for g in ["bodies/slider", "bodies/rod", "joints/piston_pin"] {
        for n in b.group(g).unwrap().member_names().unwrap() {
            names.push(format!("{g}/{n}"));
        }
    }
    names.push("time".into());
    assert!(names.len() > 20, "{names:?}");
    for n in &names {
        let (x, y) = (a.dataset(n).unwrap(), b.dataset(n).unwrap());
        if x.dtype().unwrap().size() == 1 {
            assert_eq!(
                x.read_raw::<u8>().unwrap(),
                y.read_raw::<u8>().unwrap(),
                "{n}"
            );
        } else {
            let (x, y) = (x.read_raw::<f64>().unwrap(), y.read_raw::<f64>().unwrap());
            assert!(
                x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits()) && x.len() == y.len(),
                "{n}"
            );
        }
    }
    let bad = bin()
        .args(["--hdf5-format", "1.6", "check"])
        .arg(scenes().join("pendulum.toml"))
        .output()
        .unwrap();
    assert!(
        !bad.status.success() && text(&bad).1.contains("1.6"),
        "{:?}",
        text(&bad)
    );
}

#[test]
fn check_reports_four_dof_and_one_redundant_drive_for_the_4ups_rpu() {
    let out = bin()
        .arg("check")
        .arg(scenes().join("4ups-rpu.toml"))
        .output()
        .unwrap();
    let (so, se) = text(&out);
    assert!(out.status.success(), "{se}");
    assert!(so.contains("degrees of freedom  4 "), "{so}");
    assert!(so.contains("redundant drives  1 "), "{so}");
    assert!(so.contains("redundant joint rows  0"), "{so}");
    assert!(so.contains("67 rows, numerical rank 66"), "{so}");
    assert!(so.contains("gravity"), "{so}");
}

#[test]
fn check_reports_the_redundant_rows_of_a_planar_mechanism() {
    let out = bin()
        .arg("check")
        .arg(scenes().join("slider-crank.toml"))
        .output()
        .unwrap();
    let (so, se) = text(&out);
    assert!(out.status.success(), "{se}");
    assert!(so.contains("degrees of freedom  1 "), "{so}");
    assert!(so.contains("redundant joint rows  3"), "{so}");
}

/// Writes the study `text` (its `SCENE` replaced by the path of the bundled `scene`) to
/// `dir/file` and runs it quietly with `--out dir`.
fn run_study(dir: &Path, file: &str, scene: &str, text: &str) -> Output {
    let scene = scenes().join(scene);
    let study = write_scene(
        dir,
        file,
        &text.replace("SCENE", &scene.display().to_string()),
    );
    bin()
        .arg("run")
        .arg(&study)
        .arg("--out")
        .arg(dir)
        .arg("-q")
        .output()
        .unwrap()
}

fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const PENDULUM: &str = include_str!("../data/scenes/pendulum.toml");

/// Runs `check` on a modified pendulum scene and returns the error message.
fn check_error(name: &str, from: &str, to: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    assert!(
        PENDULUM.contains(from),
        "test setup: '{from}' not in the scene"
    );
    let p = write_scene(dir.path(), name, &PENDULUM.replacen(from, to, 1));
    let out = bin().arg("check").arg(&p).output().unwrap();
    let (_, se) = text(&out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "expected a clean error exit: {se}"
    );
    assert!(!se.contains("panicked"), "{se}");
    assert!(se.contains(name), "the message must name the file: {se}");
    se
}

#[test]
fn bad_input_gets_an_error_naming_file_and_field() {
    let cases = [
        ("mass = 1.0", "mass = -1.0", "bodies[0].mass"),
        ("mass = 1.0", "mass = nan", "bodies[0].mass"),
        (
            "ixx = 1.0e-3, iyy = 1.0e-3, izz = 1.0e-3",
            "ixx = 1.0e-3, iyy = 1.0e-3, izz = 3.0e-3",
            "bodies[0].inertia",
        ),
        (
            "ixx = 1.0e-3, iyy = 1.0e-3, izz = 1.0e-3",
            "ixx = -1.0e-3, iyy = 1.0e-3, izz = 1.0e-3",
            "bodies[0].inertia",
        ),
        (
            "axes = { z = [0.0, 0.0, 1.0] }\n\n[[joints]]",
            "axes = { z = [0.0, 0.0, 0.0] }\n\n[[joints]]",
            "bodies[0].axes.z",
        ),
        (
            "body_a = \"ground\"",
            "body_a = \"bob\"",
            "joints[0].body_b",
        ),
        (
            "body_a = \"ground\"",
            "body_a = \"grund\"",
            "joints[0].body_a",
        ),
        (
            "point_b = \"pivot\"",
            "point_b = \"pivt\"",
            "joints[0].point_b",
        ),
        ("end_time = 10.0", "end_time = inf", "solver.end_time"),
        ("end_time = 10.0", "end_time = -1.0", "solver.end_time"),
        ("end_time = 10.0", "periods = 2", "solver.periods"),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = 0",
            "output.significant_bits",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = 53",
            "output.significant_bits",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = -3",
            "output.significant_bits",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = \"all\"",
            "output.significant_bits",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = { default = 28, positon = 16 }",
            "output.significant_bits.positon",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = { default = 28, velocity = 60 }",
            "output.significant_bits.velocity",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = { contact_state = 8 }",
            "output.significant_bits.contact_state",
        ),
        (
            "interval = 1e-3",
            "interval = 1e-3\nsignificant_bits = { energy = 1.5 }",
            "output.significant_bits.energy",
        ),
        (
            "axis_b = \"z\"\n",
            "axis_b = \"z\"\nclearance = { journal_radius = 0.01, radial_clearance = -1e-4, bushing_length = 0.02, normal = { law = \"hertz\", stiffness = 1e10 } }\n",
            "joints[0].clearance.radial_clearance",
        ),
        (
            "axis_b = \"z\"\n",
            "axis_b = \"z\"\nclearance = { journal_radius = 0.01, radial_clearance = 1e-4, bushing_length = 0.02, normal = { law = \"lankarani_nikravesh\", stiffness = 1e10 } }\n",
            "joints[0].clearance.normal.restitution",
        ),
        (
            "kind = \"revolute\"",
            "kind = \"prismatic\"\nclearance = { journal_radius = 0.01, radial_clearance = 1e-4, normal = { law = \"hertz\", stiffness = 1e10 } }",
            "joints[0].clearance",
        ),
    ];
    for (from, to, field) in cases {
        let msg = check_error("bad.toml", from, to);
        assert!(msg.contains(field), "'{to}' should name {field}: {msg}");
    }
}

#[test]
fn malformed_toml_and_unknown_fields_are_reported_with_their_location() {
    let msg = check_error("syntax.toml", "mass = 1.0", "mass = = 1.0");
    assert!(msg.contains("line"), "{msg}");
    let msg = check_error("unknown.toml", "mass = 1.0", "mass = 1.0\nmas = 2.0");
    assert!(msg.contains("mas"), "{msg}");
    let msg = check_error("kind.toml", "kind = \"revolute\"", "kind = \"hinge\"");
    assert!(msg.contains("hinge"), "{msg}");
}

#[test]
fn an_unknown_joint_in_a_drive_is_named() {
    let dir = tempfile::tempdir().unwrap();
    // [[drives]] is an array of tables, so it may follow the [output] table at the end.
    let scene = format!(
        "{PENDULUM}\n[[drives]]\nname = \"m\"\njoint = \"pivott\"\nprofile = {{ kind = \"constant_rate\", initial = 0.0, rate = 1.0 }}\n"
    );
    let p = write_scene(dir.path(), "drive.toml", &scene);
    let out = bin().arg("check").arg(&p).output().unwrap();
    let (_, se) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{se}");
    assert!(
        se.contains("drives[0].joint") && se.contains("pivott"),
        "{se}"
    );
}

#[test]
fn a_missing_file_is_an_error_not_a_panic() {
    let out = bin().args(["run", "no/such/scene.toml"]).output().unwrap();
    let (_, se) = text(&out);
    assert_eq!(out.status.code(), Some(1));
    assert!(se.contains("no/such/scene.toml"), "{se}");
}

#[test]
fn slider_crank_with_clearance_writes_contact_outputs_and_check_lists_the_joint() {
    let scene = scenes().join("slider-crank-clearance.toml");
    let out = bin().arg("check").arg(&scene).output().unwrap();
    let (so, se) = text(&out);
    assert!(out.status.success(), "{se}");
    assert!(so.contains("clearance contact: 1 joints"), "{so}");
    assert!(
        so.contains("piston_pin: planar revolute") && so.contains("contact: radial"),
        "{so}"
    );
    assert!(
        so.contains("piston_pin: normal law Lankarani-Nikravesh") && so.contains("c_e = 0.9"),
        "{so}"
    );
    assert!(so.contains("piston_pin: no friction"), "{so}");

    let dir = tempfile::tempdir().unwrap();
    let out = bin()
        .args(["run", "-q"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    assert!(
        dir.path()
            .join("slider-crank-clearance-piston_pin-clearance.png")
            .exists()
    );
    let file = hdf5::File::open(dir.path().join("slider-crank-clearance.h5")).unwrap();
    let g = file.group("joints/piston_pin").unwrap();
    let unit = |name: &str| {
        g.dataset(name)
            .unwrap()
            .attr("unit")
            .unwrap()
            .read_scalar::<hdf5::types::VarLenUnicode>()
            .unwrap()
            .to_string()
    };
    assert_eq!(unit("eccentricity"), "m");
    assert_eq!(unit("penetration_rate"), "m/s");
    assert_eq!(unit("normal_force"), "N");
    assert_eq!(unit("moment_on_journal"), "N m");
    // The planar model keeps three out-of-plane rows: their reaction is recorded too.
    assert!(g.dataset("reaction_force").is_ok());
    let ecc = read2(&file, "joints/piston_pin/eccentricity");
    let fnorm = g
        .dataset("normal_force")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    let state = g
        .dataset("contact_state")
        .unwrap()
        .read_raw::<u8>()
        .unwrap();
    let pen = g.dataset("penetration").unwrap().read_raw::<f64>().unwrap();
    let c = 5e-4;
    let peak = fnorm.iter().cloned().fold(0.0, f64::max);
    // The journal stays in the bearing: its eccentricity exceeds the clearance only by the
    // contact penetration, which Hertz bounds by (F_max / K)^(2/3) with K = 6.61e10 N/m^1.5.
    let max_pen = (peak / 6.61e10f64).powf(2.0 / 3.0);
    for (e, d) in ecc.iter().zip(&pen) {
        let r = (e[0] * e[0] + e[1] * e[1]).sqrt();
        assert!(
            (r - c - d).abs() < 1e-12,
            "penetration {d} inconsistent with eccentricity {r}"
        );
        assert!(
            *d <= max_pen * 1.001,
            "penetration {d} above the Hertz bound {max_pen}"
        );
        assert!(e[2].abs() < 1e-9, "out-of-plane eccentricity {}", e[2]);
    }
    // Impacts happen, and the contact state agrees with the force.
    assert!(
        peak > 1e3 && peak.is_finite(),
        "peak contact force {peak} N"
    );
    for (s, f) in state.iter().zip(&fnorm) {
        assert_eq!(*s == 1, *f > 0.0);
    }
    assert!(state.contains(&0) && state.contains(&1));
}

#[test]
fn a_study_runs_its_cases_into_one_file_and_its_table_is_regenerated_from_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_study(
        dir.path(),
        "study.toml",
        "slider-crank-clearance.toml",
        r#"
[study]
name = "pin"
scene = "SCENE"
set = { "solver.periods" = 0.25, "output.interval" = 1e-4 }
[[cases]]
label = "ideal"
remove = ["joints.piston_pin.clearance"]
[[cases]]
label = "c-0_5mm"
[report]
body = "slider"
axes = ["x"]
joints = ["piston_pin"]
reference = "ideal"
published = [{ case = "c-0_5mm", quantity = "offset_max_x", value = 1e-4, source = "made up" }]
"#,
    );
    assert!(out.status.success(), "{:?}", text(&out));
    let file = hdf5::File::open(dir.path().join("pin.h5")).unwrap();
    let ideal = read2(&file, "cases/ideal/bodies/slider/position");
    let play = read2(&file, "cases/c-0_5mm/bodies/slider/position");
    assert_eq!(ideal.len(), play.len());
    assert!(
        file.dataset("cases/c-0_5mm/joints/piston_pin/force_on_journal")
            .is_ok()
    );
    assert!(
        file.dataset("cases/ideal/joints/piston_pin/reaction_force")
            .is_ok()
    );
    // The table's offset is the largest slider deviation, recomputed here from the file.
    let dev = ideal
        .iter()
        .zip(&play)
        .map(|(a, b)| (a[0] - b[0]).abs())
        .fold(0.0f64, f64::max);
    assert!(dev > 0.0 && dev < 1e-3, "{dev}");
    let md = std::fs::read_to_string(dir.path().join("pin.md")).unwrap();
    let row = md
        .lines()
        .find(|l| l.starts_with("| `offset_max_x`"))
        .unwrap();
    let ours: f64 = row.split('|').nth(4).unwrap().trim().parse().unwrap();
    assert!((ours - dev).abs() <= 1e-3 * dev, "{row} vs {dev}");
    assert!(
        md.contains("| c-0_5mm | `offset_max_x` (m) | 1.000e-4 |"),
        "{md}"
    );
    // `jointplay report` gives the same table from the file alone.
    let rep = bin()
        .arg("report")
        .arg(dir.path().join("pin.h5"))
        .output()
        .unwrap();
    assert!(rep.status.success(), "{:?}", text(&rep));
    assert_eq!(text(&rep).0, md);
    for f in ["pin-motion.png", "pin-forces.svg", "pin-orbits.png"] {
        assert!(dir.path().join(f).exists(), "{f}");
    }
    // `jointplay export` takes one case of the study's file, and lists them when none is given.
    let export = |extra: &[&str]| {
        bin()
            .arg("export")
            .arg(dir.path().join("pin.h5"))
            .args(["--format", "csv", "--out"])
            .arg(dir.path())
            .args(extra)
            .output()
            .unwrap()
    };
    let (_, err) = text(&export(&[]));
    assert!(
        err.contains("choose a case with --case (ideal, c-0_5mm)"),
        "{err}"
    );
    let out = export(&["--case", "c-0_5mm", "--dataset", "bodies/slider/position"]);
    assert!(out.status.success(), "{:?}", text(&out));
    let csv = std::fs::read_to_string(dir.path().join("pin-c-0_5mm.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "time [s],bodies.slider.position.x [m],bodies.slider.position.y [m],bodies.slider.position.z [m]"
    );
    let xs: Vec<f64> = lines
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(xs, play.iter().map(|p| p[0]).collect::<Vec<_>>());
}

#[test]
fn a_study_edit_that_matches_nothing_names_the_study_field() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_study(
        dir.path(),
        "bad.toml",
        "slider-crank-clearance.toml",
        r#"
[study]
name = "bad"
scene = "SCENE"
[[cases]]
label = "a"
set = { "joints.nope.clearance.radial_clearance" = 1e-4 }
"#,
    );
    let (_, err) = text(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("bad.toml")
            && err.contains("cases[0].set")
            && err.contains("no element 'nope'"),
        "{err}"
    );
    assert!(!dir.path().join("bad.h5").exists());
}

#[test]
fn a_study_case_that_diverges_is_recorded_and_the_others_are_kept() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_study(
        dir.path(),
        "fail.toml",
        "pendulum.toml",
        r#"
[study]
name = "fail"
scene = "SCENE"
[[cases]]
label = "fine"
set = { "solver.end_time" = 1.0 }
[[cases]]
label = "diverges"
set = { "solver.integrator" = "rk4", "solver.step" = 3.0, "solver.end_time" = 300.0 }
remove = ["solver.rtol", "solver.atol"]
[report]
body = "bob"
reference = "fine"
"#,
    );
    let (_, err) = text(&out);
    // RK4 with a 3 s step on a 1 m pendulum is far past its stability limit: the divergence
    // guard stops it at the first runaway constraint residual, naming the joint and the time.
    assert!(!out.status.success());
    assert!(
        err.contains("1 of 2 cases")
            && err.contains("diverges")
            && err.contains("integration stopped at t = ")
            && err.contains("joint 'pivot'")
            && err.matches("integration stopped").count() == 1,
        "{err}"
    );
    let file = hdf5::File::open(dir.path().join("fail.h5")).unwrap();
    assert!(file.dataset("cases/fine/bodies/bob/position").is_ok());
    let g = file.group("cases/diverges").unwrap();
    assert!(g.attr("error").is_ok());
    assert!(g.dataset("time").is_err());
    let md = std::fs::read_to_string(dir.path().join("fail.md")).unwrap();
    assert!(md.contains("| diverges | failed:"), "{md}");
}

#[test]
fn check_lists_disabled_effects_and_rejects_a_disable_that_disables_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(scenes().join("4ups-rpu-mixed.toml")).unwrap();
    let with =
        |list: &str| base.replacen("\n[ground]", &format!("\ndisable = {list}\n\n[ground]"), 1);
    let ok = write_scene(
        dir.path(),
        "ok.toml",
        &with(r#"["R1.axial_contact", "friction"]"#),
    );
    let out = bin().arg("check").arg(&ok).output().unwrap();
    let (so, se) = text(&out);
    assert!(out.status.success(), "{se}");
    assert!(so.contains("effects disabled"), "{so}");
    assert!(so.contains("axial contact in R1"), "{so}");
    assert!(so.contains("friction in R1, S2, S5"), "{so}");
    assert!(
        so.contains("axial position held by a constraint row"),
        "{so}"
    );
    for (list, msg) in [
        (
            r#"["S3.friction"]"#,
            "disable[0]: nothing to disable: joint 'S3' has no friction",
        ),
        (
            r#"["gravity", "wobble"]"#,
            "disable[1]: unknown effect 'wobble'",
        ),
        (r#"["X9.clearance"]"#, "disable[0]: no joint 'X9'"),
    ] {
        let bad = write_scene(dir.path(), "bad.toml", &with(list));
        let out = bin().arg("check").arg(&bad).output().unwrap();
        let (_, se) = text(&out);
        assert!(!out.status.success());
        assert!(se.contains("bad.toml") && se.contains(msg), "{se}");
    }
}

const SLIDER_ANALYSIS: &str = r#"
[study]
name = "slider-sections"
scene = "SCENE"

[analysis]
periods = 6
transient = 2
samples_per_period = 50

[[observables]]
name = "slider_x"
path = "bodies.slider.position.x"

[[observables]]
name = "slider_vx"
path = "bodies.slider.velocity.x"

[[observables]]
name = "pin_ex"
path = "joints.piston_pin.eccentricity_global.x"

[[observables]]
name = "pin_ey"
path = "joints.piston_pin.eccentricity_global.y"

[[sections]]
name = "dead_point"
terms = { slider_vx = 1.0 }
direction = "down"

[[figures]]
kind = "phase"
x = "slider_x"
y = "slider_vx"

[[figures]]
kind = "poincare"
x = "slider_x"
y = "slider_vx"
section = "dead_point"

[[figures]]
kind = "orbit"
x = "pin_ex"
y = "pin_ey"
circle = 5e-4
"#;

#[test]
fn an_analysis_study_of_a_mechanism_writes_sections_and_plot_redraws_its_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_study(
        dir.path(),
        "slider.toml",
        "slider-crank-clearance.toml",
        SLIDER_ANALYSIS,
    );
    let (so, se) = text(&out);
    assert!(out.status.success(), "{so}\n{se}");
    let file = hdf5::File::open(dir.path().join("slider-sections.h5")).unwrap();
    assert_eq!(
        file.attr("complete").unwrap().read_scalar::<u8>().unwrap(),
        1
    );
    let period = file.attr("period").unwrap().read_scalar::<f64>().unwrap();
    // 5000 rpm.
    assert!((period - 60.0 / 5000.0).abs() < 1e-15);
    let t = file
        .dataset("sections/strobe/time")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert_eq!(t.len(), 4);
    for (i, tk) in t.iter().enumerate() {
        assert_eq!(*tk, (3 + i) as f64 * period, "strobe times are t0 + k T");
    }
    // The slider's velocity vanishes at the located dead points (the root-finder's precision on
    // the dense output; velocities are of order 10 m/s), at least one per kept period.
    let v = file
        .dataset("sections/dead_point/slider_vx")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert!(v.len() >= 4, "{} dead points", v.len());
    assert!(v.iter().all(|x| x.abs() < 1e-6), "{v:?}");
    let hist = file
        .dataset("history/slider_x")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert_eq!(hist.len(), 4 * 50 + 1);
    let unit: String = file
        .dataset("history/slider_vx")
        .unwrap()
        .attr("unit")
        .unwrap()
        .read_scalar::<hdf5::types::VarLenUnicode>()
        .unwrap()
        .to_string();
    assert_eq!(unit, "m/s");
    for stem in [
        "slider-sections-phase-slider_x-slider_vx",
        "slider-sections-poincare-slider_x-slider_vx",
        "slider-sections-orbit-pin_ex-pin_ey",
    ] {
        for ext in ["png", "svg"] {
            assert!(
                dir.path().join(format!("{stem}.{ext}")).exists(),
                "{stem}.{ext}"
            );
        }
    }
    // Redraw from the file alone, into another directory.
    let again = dir.path().join("again");
    let out = bin()
        .arg("plot")
        .arg(dir.path().join("slider-sections.h5"))
        .args(["--format", "svg", "--out"])
        .arg(&again)
        .output()
        .unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    let a = std::fs::read(dir.path().join("slider-sections-orbit-pin_ex-pin_ey.svg")).unwrap();
    let b = std::fs::read(again.join("slider-sections-orbit-pin_ex-pin_ey.svg")).unwrap();
    assert_eq!(a, b, "plot redraws the same figure");
    assert!(
        !again
            .join("slider-sections-orbit-pin_ex-pin_ey.png")
            .exists()
    );
}

const DUFFING_SWEEP: &str = r#"
[study]
name = "duffing-small"
system = { kind = "duffing", gamma = 0.2, initial = [1.0, 0.0] }
[analysis]
periods = 30
transient = 20
samples_per_period = 20
[[observables]]
name = "x"
path = "x"
[sweep]
parameter = "gamma"
values = [0.2, 0.25, 0.28, 0.3]
"#;

#[test]
fn a_sweep_stopped_early_is_marked_incomplete_and_resume_completes_it() {
    let dir = tempfile::tempdir().unwrap();
    let study = write_scene(dir.path(), "duffing.toml", DUFFING_SWEEP);
    let run = |extra: &[&str]| {
        bin()
            .arg("run")
            .arg(&study)
            .arg("--out")
            .arg(dir.path())
            .arg("-q")
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&["--max-jobs", "2"]);
    let (so, se) = text(&out);
    assert!(out.status.success(), "{so}\n{se}");
    assert!(so.contains("incomplete"), "{so}");
    let h5 = dir.path().join("duffing-small.h5");
    {
        let f = hdf5::File::open(&h5).unwrap();
        assert_eq!(f.attr("complete").unwrap().read_scalar::<u8>().unwrap(), 0);
    }
    let out = run(&["--resume"]);
    let (so, se) = text(&out);
    assert!(out.status.success(), "{so}\n{se}");
    assert!(
        so.contains("2 run now") && !so.contains("incomplete"),
        "{so}"
    );
    let f = hdf5::File::open(&h5).unwrap();
    assert_eq!(f.attr("complete").unwrap().read_scalar::<u8>().unwrap(), 1);
    let done = f.dataset("sweep/done").unwrap().read_raw::<u8>().unwrap();
    assert_eq!(done, vec![1, 1, 1, 1]);
    assert!(dir.path().join("duffing-small-bifurcation-x.svg").exists());
    // Release the file: HDF5 locks it while it is open.
    drop(f);
    // A changed study does not resume into the old file.
    std::fs::write(
        &study,
        DUFFING_SWEEP.replace("periods = 30", "periods = 31"),
    )
    .unwrap();
    let out = run(&["--resume"]);
    let (_, se) = text(&out);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        se.contains("--resume") && se.contains("duffing-small.h5"),
        "{se}"
    );
}

#[test]
fn bad_analysis_studies_name_the_file_and_the_field() {
    let cases = [
        (
            "path = \"x\"",
            "path = \"q\"",
            "observables[0].path",
            "unknown observable 'q'",
        ),
        (
            "kind = \"duffing\"",
            "kind = \"vanderpol\"",
            "study.system.kind",
            "vanderpol",
        ),
        (
            "transient = 20",
            "transient = 30",
            "analysis.transient",
            "less than",
        ),
        (
            "transient = 20",
            "transient = 20\nsignificant_bits = 0",
            "analysis.significant_bits",
            "between 1 and 52",
        ),
        (
            "transient = 20",
            "transient = 20\nsignificant_bits = 53",
            "analysis.significant_bits",
            "between 1 and 52",
        ),
        (
            "parameter = \"gamma\"",
            "parameter = \"gama\"",
            "sweep.parameter",
            "gama",
        ),
        (
            "gamma = 0.2,",
            "gamma = nan,",
            "study.system.gamma",
            "finite",
        ),
    ];
    for (from, to, field, what) in cases {
        let dir = tempfile::tempdir().unwrap();
        assert!(DUFFING_SWEEP.contains(from), "test setup: {from}");
        let study = write_scene(dir.path(), "bad.toml", &DUFFING_SWEEP.replacen(from, to, 1));
        let out = bin()
            .arg("run")
            .arg(&study)
            .arg("--out")
            .arg(dir.path())
            .output()
            .unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{to}: {se}");
        assert!(!se.contains("panicked"), "{se}");
        assert!(
            se.contains("bad.toml") && se.contains(field) && se.contains(what),
            "expected file, '{field}' and '{what}' in: {se}"
        );
        assert!(!dir.path().join("duffing-small.h5").exists());
    }
}

#[test]
fn a_sweep_gives_bit_identical_datasets_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let study = write_scene(dir.path(), "duffing.toml", DUFFING_SWEEP);
    let mut files = Vec::new();
    for threads in ["1", "2"] {
        let out_dir = dir.path().join(format!("t{threads}"));
        let out = bin()
            .env("RAYON_NUM_THREADS", threads)
            .arg("run")
            .arg(&study)
            .arg("--out")
            .arg(&out_dir)
            .args(["-q", "--no-plots"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{:?}", text(&out));
        // Two threads report how busy they were: a percentage of at most 100.
        let (so, _) = text(&out);
        let line = so
            .lines()
            .find(|l| l.starts_with("parallel     efficiency "));
        assert_eq!(line.is_some(), threads == "2", "{so}");
        if let Some(l) = line {
            let pct: f64 = l["parallel     efficiency ".len()..]
                .split(' ')
                .next()
                .unwrap()
                .parse()
                .unwrap();
            assert!(
                pct > 0.0 && pct <= 100.0 && l.contains("on 2 threads"),
                "{l}"
            );
        }
        files.push(hdf5::File::open(out_dir.join("duffing-small.h5")).unwrap());
    }
    for name in [
        "sweep/x",
        "sweep/strobe_time",
        "sweep/history/x",
        "sweep/history/time",
        "sweep/final_state",
    ] {
        let a = files[0].dataset(name).unwrap().read_raw::<f64>().unwrap();
        let b = files[1].dataset(name).unwrap().read_raw::<f64>().unwrap();
        assert!(
            a.len() == b.len() && a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{name} differs between thread counts"
        );
    }
}

#[test]
fn a_diverging_run_keeps_its_samples_in_a_file_marked_incomplete() {
    // The clearance slider-crank with RK4 at h = 1e-4 s: the piston-pin contact has a mode of
    // 7.4e4 rad/s (h w = 7.4, beyond RK4's 2.83). The step-size guard names the joint and a step
    // at its first contact (0.3 ms); the next step throws the journal through its bearing and
    // the divergence guard stops the run at 0.4 ms.
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(scenes().join("slider-crank-clearance.toml")).unwrap();
    let solver = "integrator = \"dopri5\"\nrtol = 1e-9\natol = 1e-12\nmax_step = 1e-5\n";
    assert!(src.contains(solver));
    let scene = dir.path().join("coarse.toml");
    std::fs::write(
        &scene,
        src.replace(solver, "integrator = \"rk4\"\nstep = 1e-4\n"),
    )
    .unwrap();
    let out = bin()
        .args(["run", "-q", "--no-plots", "--out"])
        .arg(dir.path())
        .arg(&scene)
        .output()
        .unwrap();
    let (_, err) = text(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("coarse.toml")
            && err.contains("integration stopped at t = 0.0004 s")
            && err.contains("clearance joint 'piston_pin'")
            && err.contains("penetration")
            && err.contains("marked incomplete"),
        "{err}"
    );
    // The guard's effective mass is that of the constrained mechanism along the contact normal
    // (about the slider's 0.14 kg), not of the rod alone.
    assert!(
        err.contains("warning:")
            && err.contains("'piston_pin'")
            && err.contains("effective mass of 1.3")
            && err.contains("use step = 1e-5 s"),
        "{err}"
    );
    let file = hdf5::File::open(dir.path().join("slider-crank-clearance.h5")).unwrap();
    let complete: u8 = file.attr("complete").unwrap().read_scalar().unwrap();
    assert_eq!(complete, 0);
    let stopped: f64 = file.attr("stopped_at").unwrap().read_scalar().unwrap();
    assert!((stopped - 4e-4).abs() < 1e-12, "{stopped}");
    assert!(file.attr("error").is_ok() && file.attr("warnings").is_ok());
    // Everything before the failure is there, finite and aligned.
    let time: Vec<f64> = file.dataset("time").unwrap().read_raw().unwrap();
    assert_eq!(time.len(), 31);
    assert!(*time.last().unwrap() < 4e-4);
    let pos = read2(&file, "bodies/slider/position");
    assert_eq!(pos.len(), time.len());
    assert!(pos.iter().flatten().all(|x| x.is_finite()));
    let fn_: Vec<f64> = file
        .dataset("joints/piston_pin/normal_force")
        .unwrap()
        .read_raw()
        .unwrap();
    assert_eq!(fn_.len(), time.len());
    assert!(fn_.iter().all(|x| x.is_finite()));
    drop(file);
    // A run that finishes says so.
    let out = bin()
        .args(["run", "-q", "--no-plots", "--out"])
        .arg(dir.path())
        .arg(scenes().join("pendulum.toml"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let file = hdf5::File::open(dir.path().join("pendulum.h5")).unwrap();
    let complete: u8 = file.attr("complete").unwrap().read_scalar().unwrap();
    assert_eq!(complete, 1);
    assert!(file.attr("error").is_err());
}

/// Paths of every f64 dataset under `g` (recursively).
fn float_datasets(g: &hdf5::Group, prefix: &str, out: &mut Vec<String>) {
    for name in g.member_names().unwrap() {
        let path = format!("{prefix}/{name}");
        if let Ok(sub) = g.group(&name) {
            float_datasets(&sub, &path, out);
        } else if let Ok(ds) = g.dataset(&name)
            && ds.dtype().unwrap().is::<f64>()
        {
            out.push(path);
        }
    }
}

#[test]
fn the_same_scene_gives_bit_identical_datasets_run_after_run() {
    // Two runs of the clearance slider-crank (impacts, onsets, dense samples): every float
    // dataset must be equal bit for bit.
    let dir = tempfile::tempdir().unwrap();
    for k in ["a", "b"] {
        let out = bin()
            .args(["run", "-q", "--no-plots", "--out"])
            .arg(dir.path().join(k))
            .arg(scenes().join("slider-crank-clearance.toml"))
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", text(&out).1);
    }
    let open =
        |k: &str| hdf5::File::open(dir.path().join(k).join("slider-crank-clearance.h5")).unwrap();
    let (a, b) = (open("a"), open("b"));
    let mut names = Vec::new();
    float_datasets(&a, "", &mut names);
    assert!(names.len() > 20, "{names:?}");
    for name in &names {
        let x = a.dataset(name).unwrap().read_raw::<f64>().unwrap();
        let y = b.dataset(name).unwrap().read_raw::<f64>().unwrap();
        assert!(
            x.len() == y.len() && x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits()),
            "{name} differs between runs"
        );
    }
}

#[test]
fn a_diverging_analysis_run_keeps_what_it_computed_in_a_file_marked_incomplete() {
    // The slider-crank analysis with RK4 at h = 1e-4 s diverges at 0.4 ms (see the scene-run
    // test above); the study's file keeps the history sampled before, marked incomplete.
    let dir = tempfile::tempdir().unwrap();
    let study = SLIDER_ANALYSIS
        .replace(
            "scene = \"SCENE\"\n",
            "scene = \"SCENE\"\nset = { \"solver.integrator\" = \"rk4\", \"solver.step\" = 1e-4 }\nremove = [\"solver.rtol\", \"solver.atol\", \"solver.max_step\"]\n",
        )
        .replace("transient = 2", "transient = 0");
    let out = run_study(
        dir.path(),
        "slider.toml",
        "slider-crank-clearance.toml",
        &study,
    );
    let (_, err) = text(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("slider.toml")
            && err.contains("integration stopped at t = 0.0004 s")
            && err.contains("'piston_pin'")
            && err.contains("marked incomplete"),
        "{err}"
    );
    let file = hdf5::File::open(dir.path().join("slider-sections.h5")).unwrap();
    assert_eq!(
        file.attr("complete").unwrap().read_scalar::<u8>().unwrap(),
        0
    );
    assert_eq!(
        file.attr("stopped_at")
            .unwrap()
            .read_scalar::<f64>()
            .unwrap(),
        4e-4
    );
    assert!(file.attr("error").is_ok());
    let t = file
        .dataset("history/time")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    // Samples every T/50 = 0.24 ms: t = 0 and 0.24 ms come before the failure.
    assert_eq!(t.len(), 2, "{t:?}");
}

fn read_runs(file: &Path, name: &str) -> Vec<f64> {
    let f = hdf5::File::open(file).unwrap();
    f.dataset(&format!("runs/{name}"))
        .unwrap()
        .read_1d::<f64>()
        .unwrap()
        .to_vec()
}

const DUFFING_PRECISION: &str = r#"
[study]
name = "wp"
system = { kind = "duffing", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = 0.2, omega = 1.2, initial = [1.0, 0.0], solver = { integrator = "dopri5", rtol = 1e-8, atol = 1e-10 } }

[analysis]
periods = 4
samples_per_period = 50

[[observables]]
name = "x"
path = "x"

[precision]
restarts = 4
min_time = 0.0

[[precision.methods]]
integrator = "rk4"
settings = [0.05235987755982988, 0.02617993877991494, 0.01308996938995747]

[[precision.methods]]
integrator = "dopri5"
settings = [1e-4, 1e-6, 1e-8]
"#;

#[test]
fn work_precision_measures_rk4_at_order_four_and_writes_its_table_figure_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let study = dir.path().join("wp.toml");
    std::fs::write(&study, DUFFING_PRECISION).unwrap();
    let out = precision(&study, dir.path());
    let (so, se) = text(&out);
    assert!(out.status.success(), "{so}\n{se}");
    for ext in ["h5", "md", "png", "svg"] {
        assert!(dir.path().join(format!("wp.{ext}")).exists(), "wp.{ext}");
    }
    let md = std::fs::read_to_string(dir.path().join("wp.md")).unwrap();
    assert_eq!(md.matches("| rk4 |").count(), 3, "{md}");
    assert_eq!(md.matches("| dopri5 |").count(), 3, "{md}");
    let h5 = dir.path().join("wp.h5");
    let restart = read_runs(&h5, "restart_error");
    let position = read_runs(&h5, "position_error");
    let rhs = read_runs(&h5, "rhs_evals");
    assert_eq!(restart.len(), 6);
    // RK4 at T/100, T/200, T/400 (h omega <= 0.063, in the asymptotic range): the one-period error
    // falls by 2^4 = 16 per halving; the next term of the error expansion is O(h omega) relative,
    // so 16 within 25 %.
    for i in 0..2 {
        let ratio = restart[i] / restart[i + 1];
        assert!(
            (12.0..20.0).contains(&ratio),
            "rk4 ratio {ratio}: {restart:?} {position:?}"
        );
        let ratio = position[i] / position[i + 1];
        assert!(
            (12.0..20.0).contains(&ratio),
            "rk4 ratio {ratio}: {position:?}"
        );
        // Halving the step doubles the work: 4 evaluations per step.
        assert!((rhs[i + 1] / rhs[i] - 2.0).abs() < 0.01, "{rhs:?}");
    }
    // DOPRI5: a hundredfold tighter tolerance gives a smaller error.
    assert!(
        restart[3] > restart[4] && restart[4] > restart[5],
        "{restart:?}"
    );
    // The reference is confirmed far below every tested error.
    let f = hdf5::File::open(&h5).unwrap();
    let floor: f64 = f
        .group("floor")
        .unwrap()
        .attr("restart")
        .unwrap()
        .read_scalar()
        .unwrap();
    let smallest = restart.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(floor < 0.01 * smallest, "floor {floor} vs {smallest}");
    drop(f);
    // `plot` redraws the figure from the file alone, identical to the one `precision` drew.
    let again = dir.path().join("again");
    let out = bin()
        .args(["plot", "--format", "svg", "--out"])
        .arg(&again)
        .arg(&h5)
        .output()
        .unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    assert_eq!(
        std::fs::read(dir.path().join("wp.svg")).unwrap(),
        std::fs::read(again.join("wp.svg")).unwrap()
    );
}

#[test]
fn bad_work_precision_input_names_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let out = precision(&p, dir.path());
        assert!(!out.status.success());
        text_err(&out)
    };
    let e = run(
        "a.toml",
        &DUFFING_PRECISION.replace("integrator = \"rk4\"", "integrator = \"rk5\""),
    );
    assert!(
        e.contains("a.toml") && e.contains("precision.methods[0].settings[0]") && e.contains("rk5"),
        "{e}"
    );
    let e = run("b.toml", &DUFFING_PRECISION.replace("1e-6", "-1e-6"));
    assert!(e.contains("precision.methods[1].settings[1]"), "{e}");
    let e = run(
        "d.toml",
        &DUFFING_PRECISION.replace("samples_per_period = 50", "samples_per_period = 0"),
    );
    assert!(
        e.contains("d.toml") && e.contains("analysis.samples_per_period"),
        "{e}"
    );
    let e = run(
        "e.toml",
        &DUFFING_PRECISION.replace("0.05235987755982988", "1e-13"),
    );
    assert!(
        e.contains("precision.methods[0].settings[0]") && e.contains("1e12"),
        "{e}"
    );
    let e = run(
        "c.toml",
        &DUFFING_PRECISION.replace("restarts = 4", "position = [\"y\"]"),
    );
    assert!(
        e.contains("precision.position[0]") && e.contains("'y'"),
        "{e}"
    );
    // A scene without a periodic drive has no strobe times.
    let out = precision(&scenes().join("pendulum.toml"), dir.path());
    assert!(!out.status.success());
    let e = text_err(&out);
    assert!(e.contains("pendulum.toml") && e.contains("drives"), "{e}");
    assert!(std::fs::read_dir(dir.path()).unwrap().all(|f| {
        let p = f.unwrap().path();
        p.extension().is_none_or(|x| x != "h5")
    }));
}

/// `jointplay precision -q FILE --out DIR`.
fn precision(file: &Path, dir: &Path) -> Output {
    bin()
        .args(["precision", "-q"])
        .arg(file)
        .arg("--out")
        .arg(dir)
        .output()
        .unwrap()
}

fn text_err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_work_precision_run_whose_every_method_diverges_lists_the_failures_and_finishes() {
    let dir = tempfile::tempdir().unwrap();
    let study = dir.path().join("wp.toml");
    let i = DUFFING_PRECISION.find("[[precision.methods]]").unwrap();
    // RK4 at 3 s on a period of 5.2 s: the state overflows within a few steps.
    let body = format!(
        "{}[[precision.methods]]\nintegrator = \"rk4\"\nsettings = [3.0]\n",
        &DUFFING_PRECISION[..i]
    );
    std::fs::write(&study, body).unwrap();
    let out = precision(&study, dir.path());
    assert!(out.status.success(), "{:?}", text(&out));
    let md = std::fs::read_to_string(dir.path().join("wp.md")).unwrap();
    assert!(md.contains("failed: integration stopped"), "{md}");
    assert!(read_runs(&dir.path().join("wp.h5"), "position_error")[0].is_nan());
    assert!(dir.path().join("wp.svg").exists());
}

/// `run --from` continues a run from its file as if it had never stopped: the mixed-clearance
/// 4-UPS/RPU to 0.5 s equals the run to 0.25 s continued from its file to 0.5 s, bit for bit
/// (a step of 2^-14 s puts both end times on the RK4 grid exactly).
#[test]
fn run_from_a_file_continues_the_run_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let source = std::fs::read_to_string(scenes().join("4ups-rpu-mixed.toml"))
        .unwrap()
        .replace("step = 1e-4", "step = 6.103515625e-5");
    let scene = |end: &str| {
        let p = dir.path().join(format!("end-{end}.toml"));
        std::fs::write(
            &p,
            source.replace("periods = 2.0", &format!("end_time = {end}")),
        )
        .unwrap();
        p
    };
    let (half, whole) = (scene("0.25"), scene("0.5"));
    let run = |scene: &Path, out: &str, from: Option<&Path>| {
        let mut cmd = bin();
        cmd.args(["run", "--no-plots", "-q"])
            .arg(scene)
            .arg("--out")
            .arg(dir.path().join(out));
        if let Some(f) = from {
            cmd.arg("--from").arg(f);
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{:?}", text(&o));
        hdf5::File::open(dir.path().join(out).join("4ups-rpu-mixed.h5")).unwrap()
    };
    let a = run(&whole, "a", None);
    let b = run(&half, "b", None);
    let c = run(
        &whole,
        "c",
        Some(&dir.path().join("b").join("4ups-rpu-mixed.h5")),
    );
    let bits = |f: &hdf5::File, name: &str| -> Vec<u64> {
        let v: Vec<f64> = f.dataset(name).unwrap().read_raw().unwrap();
        v.iter().map(|x| x.to_bits()).collect()
    };
    for name in ["final_state", "final_onset", "final_time", "final_stepper"] {
        assert_eq!(bits(&c, name), bits(&a, name), "{name}");
    }
    // The continued file records after 0.25 s, where the first file's samples end: its samples
    // are the tail of the whole run's, and the two files together are the whole run's.
    let (ta, tc) = (bits(&a, "time"), bits(&c, "time"));
    let tb = bits(&b, "time");
    assert_eq!(f64::from_bits(*tb.last().unwrap()), 0.25);
    assert!(f64::from_bits(tc[0]) > 0.25);
    assert_eq!(tc, ta[ta.len() - tc.len()..]);
    assert_eq!(tb.len() + tc.len(), ta.len());
    let (pa, pc) = (
        bits(&a, "bodies/platform/position"),
        bits(&c, "bodies/platform/position"),
    );
    assert_eq!(pc, pa[pa.len() - pc.len()..]);
    // A run file that stopped early, or a study, is refused with the reason.
    let o = bin()
        .args(["run", "--no-plots", "-q"])
        .arg(scenes().join("../../analyses/duffing/cascade.toml"))
        .arg("--from")
        .arg(dir.path().join("b").join("4ups-rpu-mixed.h5"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(
        text(&o).1.contains("--from continues a scene's run"),
        "{:?}",
        text(&o)
    );
}

/// The chaos measures of a single run, as a user gets them: the summary lines, the `/chaos`
/// group and the convergence figure; and the errors of bad settings, naming the field.
#[test]
fn a_single_run_reports_its_lyapunov_exponents_k_and_class() {
    let dir = tempfile::tempdir().unwrap();
    let study = |extra: &str, periods: usize| {
        format!(
            "[study]\nname = \"duffing-chaos\"\nsystem = {{ kind = \"duffing\", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = 0.5, omega = 1.2, initial = [1.0, 0.0], solver = {{ rtol = 1e-9, atol = 1e-11 }} }}\n[analysis]\nperiods = {periods}\ntransient = 20\nsamples_per_period = 0\n{extra}"
        )
    };
    let path = dir.path().join("chaos.toml");
    std::fs::write(
        &path,
        study(
            "[lyapunov]\nexponents = 2\nperiods = 200\nper_period = 2\ntwo_trajectory = true\n[zero_one]\nobservable = \"x\"\n",
            540,
        ),
    )
    .unwrap();
    let o = bin()
        .args(["run", "-q"])
        .arg(&path)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}\n{se}");
    assert!(
        so.contains("lyapunov     0.") && so.contains("class        chaotic"),
        "{so}"
    );
    // The summary says how long the estimate averaged, and its rate counts the Lyapunov run's
    // evaluations, which share the wall time.
    assert!(
        so.contains("averaged     ") && so.contains("in the Lyapunov run"),
        "{so}"
    );
    assert!(dir.path().join("out/duffing-chaos-lyapunov.png").exists());
    let f = hdf5::File::open(dir.path().join("out/duffing-chaos.h5")).unwrap();
    let ex: Vec<f64> = f
        .dataset("chaos/lyapunov/exponents")
        .unwrap()
        .read_raw()
        .unwrap();
    // The stroboscopic map contracts areas by exp(-0.3 T): the exponents sum to -0.3.
    assert!((ex[0] + ex[1] + 0.3).abs() < 1e-7, "{ex:?}");
    assert!(ex[0] > 0.05, "{ex:?}");
    // Bad settings, each named.
    for (extra, periods, field) in [
        (
            "[lyapunov]\nexponents = 3\nperiods = 200\n",
            40,
            "lyapunov.exponents",
        ),
        ("[lyapunov]\nperiods = 5\n", 40, "lyapunov.periods"),
        ("[zero_one]\nobservable = \"x\"\n", 40, "zero_one"),
        (
            "[zero_one]\nobservable = \"y\"\n",
            540,
            "zero_one.observable",
        ),
    ] {
        std::fs::write(&path, study(extra, periods)).unwrap();
        let o = bin()
            .args(["run", "-q", "--no-plots"])
            .arg(&path)
            .arg("--out")
            .arg(dir.path().join("bad"))
            .output()
            .unwrap();
        let (so, se) = text(&o);
        assert!(!o.status.success(), "{extra}: {so}");
        assert!(
            se.contains(field) && se.contains("chaos.toml"),
            "{extra}: {se}"
        );
    }
}

/// A continuation stopped with `--max-jobs` (points) leaves its file marked unfinished, with a
/// line per point when not on a terminal; `--resume` goes on to the file an uninterrupted run
/// writes (its branches bit for bit), and a second `--resume` has nothing left to do (and says
/// so without failing).
#[test]
fn a_continuation_stopped_after_some_points_resumes_from_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let study =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("analyses/duffing/continuation.toml");
    let run = |out: &str, extra: &[&str]| {
        bin()
            .arg("run")
            .arg(&study)
            .args(["--no-plots", "--out"])
            .arg(dir.path().join(out))
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run("full", &[]);
    assert!(o.status.success(), "{:?}", text(&o));
    let o = run("part", &["--max-jobs", "3"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(
        so.contains("point        branch 0 point 3: parameter"),
        "{so}"
    );
    assert!(so.contains("incomplete   stopped after 3 points"), "{so}");
    let file = dir.path().join("part/duffing-continuation.h5");
    {
        let f = hdf5::File::open(&file).unwrap();
        let g = f.group("continuation").unwrap();
        assert_eq!(g.attr("finished").unwrap().read_scalar::<u8>().unwrap(), 0);
    }
    let o = run("part", &["--resume"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(so.contains("resume       1 branches"), "{so}");
    let read = |f: &Path, name: &str| -> Vec<f64> {
        let f = hdf5::File::open(f).unwrap();
        f.dataset(name).unwrap().read_raw().unwrap()
    };
    let full = dir.path().join("full/duffing-continuation.h5");
    for name in [
        "continuation/branch_0/parameter",
        "continuation/branch_0/state",
        "continuation/branch_1/state",
        "continuation/branch_1/multipliers_re",
        "continuation/special/parameter",
    ] {
        assert_eq!(read(&full, name), read(&file, name), "{name}");
    }
    // A finished continuation has nothing left to resume: said, and not an error.
    let o = run("part", &["--resume"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(so.contains("is finished: nothing to resume"), "{so}");
}

/// A continuation's `start` state off the constraint manifold (a run file's final state with the
/// crank moved by 1 mm) is refused when the study loads, naming the field and the residual; a
/// mechanism whose drives prescribe its whole motion has no orbit to shoot, and says so.
#[test]
fn a_continuation_start_off_the_constraint_manifold_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let o = bin()
        .args(["run", "-q", "--no-plots", "--out"])
        .arg(dir.path())
        .arg(scenes().join("slider-crank.toml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    let run_file = dir.path().join("slider-crank.h5");
    let study = |name: &str| {
        let text = format!(
            "[study]\nname = \"{name}\"\nscene = \"{}\"\n[analysis]\nperiods = 1\ntransient = 0\nsamples_per_period = 0\n[[observables]]\nname = \"x\"\npath = \"bodies.slider.position.x\"\n[continuation]\nparameter = \"bodies.slider.mass\"\nfrom = 0.14\nto = 0.2\nstep = 0.01\nstart = {{ file = \"slider-crank.h5\" }}\n",
            scenes().join("slider-crank.toml").display()
        );
        write_scene(dir.path(), &format!("{name}.toml"), &text)
    };
    // The run's own final state is taken; the ideal slider-crank then has no free degree of
    // freedom to shoot in, which is an error too, not a panic.
    let p = study("on");
    let o = bin()
        .args(["run", "-q", "--no-plots", "--out"])
        .arg(dir.path().join("on"))
        .arg(&p)
        .output()
        .unwrap();
    let (so, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{so}{se}");
    assert!(!se.contains("continuation.start"), "{so}{se}");
    assert!(se.contains("no free degree of freedom"), "{se}");
    assert!(!se.contains("panicked"), "{se}");
    {
        let f = hdf5::File::open_rw(&run_file).unwrap();
        let ds = f.dataset("final_state").unwrap();
        let mut y: Vec<f64> = ds.read_raw().unwrap();
        y[0] += 1e-3;
        ds.write_raw(&y).unwrap();
        drop(ds);
        f.close().unwrap();
    }
    let p = study("off");
    let o = bin()
        .args(["run", "-q", "--no-plots", "--out"])
        .arg(dir.path().join("o"))
        .arg(&p)
        .output()
        .unwrap();
    let (_, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{se}");
    assert!(
        se.contains("continuation.start.file") && se.contains("off the constraint manifold"),
        "{se}"
    );
    assert!(!se.contains("panicked"), "{se}");
}

/// A drive's `ramp_time` must be zero or a positive number of seconds; a negative or non-finite
/// one is refused naming the drive's field.
#[test]
fn a_bad_ramp_time_names_the_drive_field() {
    let scene = std::fs::read_to_string(scenes().join("4ups-rpu-mixed.toml")).unwrap();
    assert!(scene.contains("omega = 3.14 }"), "test setup");
    for bad in ["-1.0", "nan"] {
        let dir = tempfile::tempdir().unwrap();
        let edited = scene.replacen(
            "omega = 3.14 }",
            &format!("omega = 3.14, ramp_time = {bad} }}"),
            1,
        );
        let p = write_scene(dir.path(), "ramp.toml", &edited);
        let o = bin().arg("check").arg(&p).output().unwrap();
        let (_, se) = text(&o);
        assert_eq!(o.status.code(), Some(1), "{se}");
        assert!(se.contains("drives[0].profile.ramp_time"), "{se}");
    }
}

/// Error messages echoed up to 10 MB of input.
#[test]
fn an_error_message_echoes_at_most_200_characters_of_a_huge_value() {
    let huge = "x".repeat(10_000_000);
    for (from, to) in [
        (
            "gravity = [0.0, -9.81, 0.0]",
            format!("gravity = \"{huge}\""),
        ),
        ("body_a = \"ground\"", format!("body_a = \"{huge}\"")),
    ] {
        let msg = check_error("huge.toml", from, &to);
        assert!(msg.len() < 2000, "{} characters", msg.len());
        assert!(msg.contains("more characters)"), "{msg}");
    }
}

/// `gravity = [0, -9.81, 0, 5]` was taken as its first three components.
#[test]
fn a_vector_with_extra_components_is_refused_naming_the_field() {
    let cases = [
        (
            "gravity = [0.0, -9.81, 0.0]",
            "gravity = [0, -9.81, 0, 5]",
            "gravity",
        ),
        (
            "gravity = [0.0, -9.81, 0.0]",
            "gravity = [0, -9.81]",
            "gravity",
        ),
        (
            "position = [0.8660254037844386, -0.5, 0.0]",
            "position = [0.8660254037844386, -0.5, 0.0, 0.0]",
            "bodies[0].position",
        ),
        (
            "points = { pivot = [0.0, 0.0, 0.0] }",
            "points = { pivot = [0.0, 0.0, 0.0, 1.0] }",
            "ground.points.pivot",
        ),
        (
            "point_a = \"pivot\"",
            "point_a = [0.0, 0.0, 0.0, 1.0]",
            "joints[0].point_a",
        ),
        (
            "axis = [0.0, 0.0, 1.0]",
            "axis = [0.0, 0.0, 1.0, 0.0]",
            "bodies[0].orientation.axis",
        ),
    ];
    for (from, to, field) in cases {
        let msg = check_error("long.toml", from, to);
        assert!(msg.contains(field), "'{to}' should name {field}: {msg}");
    }
}

/// `check` hung on a body placed at 1e200 m: the assembly's corrections overflowed to NaN, which
/// the residual test missed, and the rank analysis iterated on it without end. Such a number is
/// refused naming the field; one just below the bound fails the assembly instead, at once.
#[test]
fn check_does_not_hang_on_a_coordinate_of_1e200() {
    let from = "position = [0.8660254037844386, -0.5, 0.0]";
    let msg = check_error("far.toml", from, "position = [1e200, -0.5, 0.0]");
    assert!(
        msg.contains("bodies[0].position[0]") && msg.contains("1e100"),
        "{msg}"
    );
    let msg = check_error("far.toml", from, "position = [1e99, -0.5, 0.0]");
    assert!(msg.contains("initial assembly failed"), "{msg}");
}

/// `analysis.period = 1e12` passed the guard against runs that cannot finish.
#[test]
fn an_analysis_period_that_cannot_finish_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (from, to, field) in [
        (
            "periods = 30\n",
            "periods = 30\nperiod = 1e12\n",
            "analysis.period",
        ),
        (
            "periods = 30\n",
            "periods = 100000000000000\n",
            "analysis.periods",
        ),
    ] {
        let edited = DUFFING_SWEEP.replacen(from, to, 1);
        let study = write_scene(dir.path(), "long.toml", &edited);
        let out = bin().arg("check").arg(&study).output().unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{se}");
        assert!(
            se.contains("long.toml") && se.contains(field) && se.contains("at most 1e12"),
            "{se}"
        );
    }
}

/// A run resumed (`--from`) from a file whose final_time is -1e300 would integrate forever.
#[test]
fn run_from_a_file_whose_final_time_is_minus_1e300_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        "pendulum.toml",
        &PENDULUM.replace("end_time = 10.0", "end_time = 0.01"),
    );
    let out = bin()
        .args(["run", "--no-plots", "-q"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("a"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    let file = dir.path().join("a/pendulum.h5");
    for (t, what) in [
        (-1e300, "not before the scene's start time"),
        (f64::NAN, "final_time"),
        (-1.0, "not before the scene's start time"),
    ] {
        {
            let f = hdf5::File::open_rw(&file).unwrap();
            f.dataset("final_time").unwrap().write_scalar(&t).unwrap();
        }
        let out = bin()
            .args(["run", "--no-plots", "-q"])
            .arg(&scene)
            .arg("--out")
            .arg(dir.path().join("b"))
            .arg("--from")
            .arg(&file)
            .output()
            .unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{t}: {se}");
        assert!(
            se.contains("a/pendulum.h5") && se.contains(what),
            "{t}: {se}"
        );
    }
}

/// `figures[].values` took NaN and infinities.
#[test]
fn figure_values_that_are_not_finite_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for v in ["nan", "inf", "-inf"] {
        let edited = format!(
            "{DUFFING_SWEEP}[[figures]]\nkind = \"bifurcation\"\ny = \"x\"\nvalues = [0.2, {v}]\n"
        );
        let study = write_scene(dir.path(), "fig.toml", &edited);
        let out = bin().arg("check").arg(&study).output().unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{v}: {se}");
        assert!(
            se.contains("fig.toml") && se.contains("figures[0].values[1]"),
            "{v}: {se}"
        );
    }
}

/// An unknown `report.joints` entry was found only after every case had run.
#[test]
fn an_unknown_report_joint_is_refused_when_the_study_is_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let study = r#"
[study]
name = "rep"
scene = "SCENE"
[[cases]]
label = "a"
[report]
joints = ["piston_pin", "nope"]
"#;
    let path = write_scene(
        dir.path(),
        "rep.toml",
        &study.replace(
            "SCENE",
            &scenes()
                .join("slider-crank-clearance.toml")
                .display()
                .to_string(),
        ),
    );
    for cmd in ["check", "run"] {
        let mut c = bin();
        c.arg(cmd).arg(&path);
        if cmd == "run" {
            c.arg("--out").arg(dir.path()).arg("-q");
        }
        let out = c.output().unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{cmd}: {se}");
        assert!(
            se.contains("rep.toml") && se.contains("report.joints[1]") && se.contains("'nope'"),
            "{cmd}: {se}"
        );
        assert!(!dir.path().join("rep.h5").exists());
    }
}

/// `plot` panicked on a sweep file whose /sweep/done was shorter than /sweep/parameter.
/// The small Duffing sweep ([`DUFFING_SWEEP`]) run into `dir` without figures: its file.
fn small_sweep_file(dir: &Path) -> PathBuf {
    let study = write_scene(dir, "duffing.toml", DUFFING_SWEEP);
    let out = bin()
        .arg("run")
        .arg(&study)
        .arg("--out")
        .arg(dir)
        .args(["-q", "--no-plots"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    dir.join("duffing-small.h5")
}

#[test]
fn plot_of_a_sweep_file_with_a_short_done_dataset_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let h5 = small_sweep_file(dir.path());
    {
        let f = hdf5::File::open_rw(&h5).unwrap();
        let g = f.group("sweep").unwrap();
        g.unlink("done").unwrap();
        g.new_dataset_builder()
            .with_data(&[1u8, 1])
            .create("done")
            .unwrap();
    }
    let out = bin()
        .arg("plot")
        .arg(&h5)
        .arg("--out")
        .arg(dir.path().join("figs"))
        .output()
        .unwrap();
    let (_, se) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{se}");
    assert!(
        se.contains("duffing-small.h5") && se.contains("/sweep/done has 2 rows"),
        "{se}"
    );
}

/// A huge thread count started threads until the machine stalled.
#[test]
fn a_huge_thread_count_is_refused() {
    for var in ["RAYON_NUM_THREADS", "SLURM_CPUS_PER_TASK"] {
        let out = bin()
            .env_remove("RAYON_NUM_THREADS")
            .env(var, "1000000")
            .arg("check")
            .arg(scenes().join("pendulum.toml"))
            .output()
            .unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{var}: {se}");
        assert!(se.contains(var) && se.contains("threads allowed"), "{se}");
    }
}

/// Found by scripts/fuzz-formats: an error in a value the study's own `set` put into its scene
/// named the scene alone, and a built-in system took infinite tolerances.
#[test]
fn errors_in_a_study_edited_scene_name_the_study_and_system_tolerances_are_finite() {
    let dir = tempfile::tempdir().unwrap();
    let study = format!(
        "[study]\nname = \"p\"\nscene = \"{}\"\nset = {{ \"solver.rtol\" = -1.0 }}\n\
         [analysis]\nperiods = 2\nperiod = 1.0\n[[observables]]\nname = \"x\"\n\
         path = \"bodies.bob.position.x\"\n",
        scenes().join("pendulum.toml").display()
    );
    let system = DUFFING_SWEEP.replace(
        "initial = [1.0, 0.0] }",
        "initial = [1.0, 0.0], solver = { rtol = inf } }",
    );
    for (input, field) in [
        (study, "solver.rtol: must be positive"),
        (system, "study.system.solver.rtol"),
    ] {
        let p = write_scene(dir.path(), "edited.toml", &input);
        let out = bin().arg("check").arg(&p).output().unwrap();
        let (_, se) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{se}");
        assert!(se.contains("edited.toml") && se.contains(field), "{se}");
    }
}

/// Writes the study `text` as `DIR/<name>.toml`.
fn study_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// `jointplay run --no-plots -q STUDY --out DIR`.
fn run_quietly(study: &Path, out: &Path) -> Output {
    bin()
        .args(["run", "--no-plots", "-q"])
        .arg(study)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// `report` makes a comparison study's table: an analysis study's file, and a TOML file, get the
/// command that fits them instead of a parse error of the stored study.
#[test]
fn report_names_the_command_that_fits_another_kind_of_file() {
    let dir = tempfile::tempdir().unwrap();
    let study = study_file(
        dir.path(),
        "single",
        "[study]\nname = \"single\"\nsystem = { kind = \"duffing\", initial = [1.0, 0.0] }\n\
         [analysis]\nperiods = 4\ntransient = 1\nsamples_per_period = 10\n\
         [[observables]]\nname = \"x\"\npath = \"x\"\n",
    );
    let o = run_quietly(&study, dir.path());
    assert!(o.status.success(), "{:?}", text(&o));
    for (file, says) in [
        (dir.path().join("single.h5"), "jointplay plot FILE"),
        (study.clone(), "reads the HDF5 file of a comparison study"),
    ] {
        let o = bin().arg("report").arg(&file).output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
        let (_, err) = text(&o);
        assert!(
            err.contains(says) && err.contains(&*file.to_string_lossy()),
            "{err}"
        );
    }
}

/// A figure's `values` pick sweep values to draw: one the sweep lacks is an error naming it, not
/// a panel left out without a word.
#[test]
fn a_figure_value_not_in_the_sweep_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let study = study_file(
        dir.path(),
        "fig",
        "[study]\nname = \"fig\"\nsystem = { kind = \"duffing\", initial = [1.0, 0.0] }\n\
         [analysis]\nperiods = 4\ntransient = 1\nsamples_per_period = 10\n\
         [[observables]]\nname = \"x\"\npath = \"x\"\n[[observables]]\nname = \"v\"\npath = \"v\"\n\
         [sweep]\nparameter = \"gamma\"\nvalues = [0.2, 0.3]\n\
         [[figures]]\nkind = \"phase\"\nx = \"x\"\ny = \"v\"\nvalues = [0.2, 0.25]\n",
    );
    let o = bin().arg("check").arg(&study).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    let (_, err) = text(&o);
    assert!(
        err.contains("figures[0].values[1]") && err.contains("0.25 is not a value of the sweep"),
        "{err}"
    );
}

/// A sweep writes its table beside its file, in Markdown and CSV: one row per value with its
/// status, period, class, lambda_1 and K, and the range of every observable's strobe points;
/// `report` prints the same table from the file.
#[test]
fn a_sweep_writes_its_table_and_report_prints_it() {
    let dir = tempfile::tempdir().unwrap();
    let study = study_file(
        dir.path(),
        "table",
        "[study]\nname = \"table\"\nsystem = { kind = \"duffing\", initial = [1.0, 0.0], solver = { rtol = 1e-9 } }\n\
         [analysis]\nperiods = 60\ntransient = 40\nsamples_per_period = 0\n\
         [[observables]]\nname = \"x\"\npath = \"x\"\n\
         [lyapunov]\nperiods = 300\n\
         [sweep]\nparameter = \"gamma\"\nvalues = [0.2, 0.5]\n",
    );
    let o = run_quietly(&study, dir.path());
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(so.contains("table.md") && so.contains("table.csv"), "{so}");
    let md = std::fs::read_to_string(dir.path().join("table.md")).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("table.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    assert_eq!(
        lines[0],
        "value (1),status,period,class,lambda_1 (1/s),lambda_1 stderr (1/s),x min (1),x max (1)"
    );
    // gamma = 0.2: the period-1 orbit, one strobe point; 0.5: the chaotic attractor.
    assert!(lines[1].starts_with("0.2,done,1,periodic,-"), "{csv}");
    assert!(lines[2].starts_with("0.5,done,,chaotic,0."), "{csv}");
    let o = bin()
        .arg("report")
        .arg(dir.path().join("table.h5"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    assert_eq!(text(&o).0, md);
}
/// A scene whose poses leave a clearance joint off its housing centre starts closed: `check`
/// says the joint was assembled as its ideal joint and how far the open start was, and no
/// journal starts inside a wall. With `start = "free"` the declared poses decide, and the
/// journal inside the wall is a warning of `check` and of the run at t = 0.
#[test]
fn a_journal_off_its_housing_starts_closed_and_a_free_one_inside_its_wall_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("book/src/tutorial/four-bar.toml"),
    )
    .unwrap();
    // The rocker turned by about 0.4 degrees: its pin end moves 0.74 mm, past the 0.25 mm
    // clearance.
    let off = good.replace(
        "orientation = { x = [-0.05, 0.12, 0.0], y = [-0.12, -0.05, 0.0] }",
        "orientation = { x = [-0.0492, 0.12, 0.0], y = [-0.12, -0.0492, 0.0] }",
    );
    assert_ne!(good, off, "the tutorial's rocker orientation moved");
    // A tenth of a turn is enough to start: the stiff strike that follows is slow to integrate.
    let off = off.replace("periods = 5 ", "periods = 0.1 ");
    assert!(off.contains("periods = 0.1 "));
    let free = off.replace(
        "friction = { law = \"ambrosio\"",
        "start = \"free\"\nfriction = { law = \"ambrosio\"",
    );
    assert_ne!(free, off, "the tutorial's friction line moved");
    let (g, c, b) = (
        study_file(dir.path(), "good", &good),
        study_file(dir.path(), "closed", &off),
        study_file(dir.path(), "bad", &free),
    );
    let check = |p: &Path| text(&bin().arg("check").arg(p).output().unwrap()).0;
    let so = check(&g);
    assert!(
        !so.contains("start        warning")
            && so.contains("start        clearance joints already closed at the assembled start, kept as it is: coupler_pin (concentric)"),
        "{so}"
    );
    let so = check(&c);
    assert!(
        !so.contains("start        warning")
            && so.contains("start        clearance joints closed as ideal joints, then released: coupler_pin (concentric); the start assembled without closing them was 6.84e-4 (m, rad)"),
        "{so}"
    );
    let so = check(&b);
    assert!(
        so.contains("start        warning: clearance joint 'coupler_pin', contact 'radial': the journal starts 4.90")
            && so.contains("m inside the housing's wall")
            && !so.contains("start        clearance joints"),
        "{so}"
    );
    let o = run_quietly(&b, &dir.path().join("out"));
    let (_, se) = text(&o);
    assert!(
        se.contains("warning: ")
            && se.contains("at the start, t = 0 s: clearance joint 'coupler_pin'"),
        "{se}"
    );
}

/// `plot FILE --figures EDITED.toml` draws the edited figures from the file alone, without
/// running the study again; a figure that does not fit the file's study is refused naming the
/// edited file and the field.
#[test]
fn plot_draws_edited_figures_without_running_again() {
    let dir = tempfile::tempdir().unwrap();
    let h5 = small_sweep_file(dir.path());
    let before = std::fs::read(&h5).unwrap();
    let plot = |figures: &str| {
        let f = write_scene(dir.path(), "figures.toml", figures);
        bin()
            .arg("plot")
            .arg(&h5)
            .arg("--figures")
            .arg(&f)
            .args(["--format", "svg", "--out"])
            .arg(dir.path().join("figs"))
            .output()
            .unwrap()
    };
    let edited = "[[figures]]\nkind = \"time\"\ny = \"x\"\nname = \"edited\"\n\
                  title = \"An edited title\"\nvalues = [0.28]\n";
    let out = plot(edited);
    let (so, se) = text(&out);
    assert!(out.status.success(), "{so}\n{se}");
    let svg = std::fs::read_to_string(dir.path().join("figs/edited.svg")).unwrap();
    assert!(svg.contains("An edited title"), "{so}");
    // The study's own default figure was not drawn, and the file is untouched.
    assert!(
        !dir.path()
            .join("figs/duffing-small-bifurcation-x.svg")
            .exists()
    );
    assert_eq!(std::fs::read(&h5).unwrap(), before);
    let out = plot(&edited.replace("0.28", "0.29"));
    let (_, se) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{se}");
    assert!(
        se.contains("figures.toml") && se.contains("figures[0].values[0]: 0.29 is not a value"),
        "{se}"
    );
    let out = plot(&edited.replace("y = \"x\"", "y = \"v\""));
    let (_, se) = text(&out);
    assert!(
        se.contains("figures[0].y: 'v' is not an observable of this study"),
        "{se}"
    );
}

/// The width and height of a PNG file, from its header.
fn png_size(path: &Path) -> (u32, u32) {
    let b = std::fs::read(path).unwrap();
    let be = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    (be(16), be(20))
}

/// `--figure-size`, `--figure-scale` and `--font-scale` size every figure; a value out of range
/// is refused naming the option, before anything is drawn.
#[test]
fn figure_size_scale_and_fonts_are_options_of_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let h5 = small_sweep_file(dir.path());
    let draw = |args: &[&str], out: &str| {
        let o = bin()
            .args(args)
            .arg("plot")
            .arg(&h5)
            .args(["--format", "png", "--out"])
            .arg(dir.path().join(out))
            .output()
            .unwrap();
        assert!(o.status.success(), "{:?}", text(&o));
        let png = std::fs::read_dir(dir.path().join(out))
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.extension().is_some_and(|e| e == "png"))
            .unwrap();
        png_size(&png)
    };
    let (w, h) = draw(&[], "plain");
    assert_eq!(w % 560, 0, "{w} x {h}");
    assert_eq!(h % 380, 0, "{w} x {h}");
    let (cols, rows) = (w / 560, h / 380);
    assert_eq!(draw(&["--figure-scale", "2"], "print"), (2 * w, 2 * h));
    assert_eq!(
        draw(&["--figure-size", "800x300", "--font-scale", "1.5"], "wide"),
        (800 * cols, 300 * rows)
    );
    for (args, named) in [
        (["--figure-scale", "20"], "figure scale: 20"),
        (["--font-scale", "0.1"], "font scale: 0.1"),
        (["--figure-size", "10x10"], "figure size: 10 x 10"),
    ] {
        let o = bin().args(args).arg("plot").arg(&h5).output().unwrap();
        let (_, e) = text(&o);
        assert!(!o.status.success() && e.contains(named), "{e}");
    }
    let o = bin()
        .args(["--figure-size", "wide"])
        .arg("plot")
        .arg(&h5)
        .output()
        .unwrap();
    assert!(text(&o).1.contains("WIDTHxHEIGHT"), "{:?}", text(&o));
}

/// A time history marks a hyperplane section's crossings: on the Newton impact oscillator the
/// clock-sampled history misses the stop (its largest sample is 0.904 at 20 samples a period),
/// and the section on the impact surface puts every impact at x = 1, one per period on this
/// period-1 orbit. A time figure cannot name the stroboscopic section.
#[test]
fn a_time_history_marks_the_impacts_its_samples_miss() {
    let dir = tempfile::tempdir().unwrap();
    let study = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("analyses/impact/history.toml");
    let o = bin()
        .arg("run")
        .arg(&study)
        .arg("--out")
        .arg(dir.path())
        .arg("-q")
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    let f = hdf5::File::open(dir.path().join("impact-history.h5")).unwrap();
    let x: Vec<f64> = f.dataset("history/x").unwrap().read_raw().unwrap();
    let at_impacts: Vec<f64> = f.dataset("sections/impact/x").unwrap().read_raw().unwrap();
    let top = x.iter().fold(f64::MIN, |m, v| m.max(*v));
    // The located crossings lie on the stop to the locator's tolerance (1e-13 of a step, far
    // below any sampling error); the samples fall short of it by a tenth.
    assert!(top < 0.95, "the samples reach {top}");
    assert_eq!(at_impacts.len(), 20);
    assert!(
        at_impacts.iter().all(|v| (v - 1.0).abs() < 1e-9),
        "{at_impacts:?}"
    );
    assert!(dir.path().join("impact-history-time-x.png").exists());

    let text_of = std::fs::read_to_string(&study).unwrap();
    let bad = text_of.replace("section = \"impact\"", "section = \"strobe\"");
    let bad_file = dir.path().join("bad.toml");
    std::fs::write(&bad_file, bad).unwrap();
    let (_, e) = text(&bin().arg("check").arg(&bad_file).output().unwrap());
    assert!(
        e.contains("figures[0].section") && e.contains("hyperplane"),
        "{e}"
    );
}

#[test]
fn a_lubricated_bearing_records_its_film_and_a_fixed_step_too_long_for_the_film_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(scenes().join("journal-bearing.toml")).unwrap();
    // RK4 at 1 ms: the settled film (stiffness about 2.5e7 N/m, damping 7e4 N s/m on the 20
    // kg rotor) has a mode at about -3000 1/s, outside RK4's stability region at that step.
    let coarse = good
        .replace(
            "integrator = \"dopri5\"",
            "integrator = \"rk4\"\nstep = 1e-3",
        )
        .replace("rtol = 1e-9\n", "")
        .replace("atol = 1e-12\n", "");
    assert!(coarse.contains("step = 1e-3") && !coarse.contains("rtol"));
    let run = |name: &str, scene: &str| {
        let p = write_scene(dir.path(), name, scene);
        bin()
            .args(["run", "--no-plots", "-q", "--out"])
            .arg(dir.path())
            .arg(&p)
            .output()
            .unwrap()
    };
    let (_, err) = text(&run("coarse.toml", &coarse));
    assert!(
        err.contains("lubricated joint 'bearing', oil film: at t = ")
            && err.contains("unstable for rk4, fixed step 1e-3 s"),
        "{err}"
    );
    // The scene as bundled: the film's force is recorded, and once settled it carries the
    // rotor's weight (20 kg x 9.81 m/s^2) along +y.
    let out = run("good.toml", &good);
    let (_, err) = text(&out);
    assert!(out.status.success() && !err.contains("warning"), "{err}");
    let file = hdf5::File::open(dir.path().join("journal-bearing.h5")).unwrap();
    let film = read2(&file, "joints/bearing/film_force");
    let last = film.last().unwrap();
    // Settled to far below 1e-9 of the load (the orbit decays by e every 8 ms over 0.5 s).
    assert!(
        last[0].abs() < 1e-6 && (last[1] - 196.2).abs() < 1e-6,
        "{last:?}"
    );
    let unit = file
        .dataset("joints/bearing/film_force")
        .unwrap()
        .attr("unit")
        .unwrap()
        .read_scalar::<hdf5::types::VarLenUnicode>()
        .unwrap();
    assert_eq!(unit.as_str(), "N");
}

/// Runs `input` (a scene or a study) into `dir` without figures; fails the test if it fails.
fn run_ok(dir: &Path, input: &Path) {
    let o = run_quietly(input, dir);
    assert!(o.status.success(), "{:?}", text(&o));
}

/// A pendulum drawn with the scene's own shapes: a sphere, a cylinder, and meshes from an STL
/// and an OBJ file beside the scene.
fn pendulum_with_shapes(dir: &Path) -> PathBuf {
    std::fs::write(
        dir.join("tetra.stl"),
        "solid t\n\
         facet normal 0 0 -1\n outer loop\n vertex 0 0 0\n vertex 0 10 0\n vertex 10 0 0\n endloop\nendfacet\n\
         facet normal 0 -1 0\n outer loop\n vertex 0 0 0\n vertex 10 0 0\n vertex 0 0 10\n endloop\nendfacet\n\
         facet normal -1 0 0\n outer loop\n vertex 0 0 0\n vertex 0 0 10\n vertex 0 10 0\n endloop\nendfacet\n\
         facet normal 1 1 1\n outer loop\n vertex 10 0 0\n vertex 0 10 0\n vertex 0 0 10\n endloop\nendfacet\n\
         endsolid t\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("quad.obj"),
        "v 0 0 0\nv 0.02 0 0\nv 0.02 0.02 0\nv 0 0.02 0\nf 1 2 3 4\n",
    )
    .unwrap();
    let scene = PENDULUM
        .replace("end_time = 10.0", "end_time = 0.5")
        .replace(
            "axes = { z = [0.0, 0.0, 1.0] }\n\n[[joints]]",
            "axes = { z = [0.0, 0.0, 1.0] }\n\
             visual = [\n\
               { shape = \"sphere\", radius = 0.05, color = \"#cc3311\" },\n\
               { shape = \"cylinder\", radius = 0.005, length = 1.0, at = [0.0, 0.5, 0.0], axis = [0.0, 1.0, 0.0] },\n\
               { shape = \"mesh\", file = \"tetra.stl\", scale = 0.001, at = [0.0, 1.0, 0.0] },\n\
               { shape = \"box\", size = [0.02, 0.02, 0.02], orientation = { axis = [0.0, 0.0, 1.0], angle = \"45 deg\" } },\n\
               { shape = \"mesh\", file = \"quad.obj\" },\n\
             ]\n\n[[joints]]",
        );
    assert!(
        scene.contains("tetra.stl"),
        "test setup: the scene's bob not found"
    );
    write_scene(dir, "pendulum-shapes.toml", &scene)
}

#[test]
fn animate_writes_a_self_contained_page_and_a_glb_of_a_run_with_its_shapes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = pendulum_with_shapes(dir.path());
    let out = bin().arg("check").arg(&scene).output().unwrap();
    assert!(out.status.success(), "{:?}", text(&out));
    assert!(
        text(&out).0.contains("drawn with 5 shapes"),
        "{:?}",
        text(&out)
    );
    run_ok(dir.path(), &scene);
    let h5 = dir.path().join("pendulum.h5");
    let out = bin()
        .arg("animate")
        .arg(&h5)
        .arg("--out")
        .arg(dir.path())
        .args(["--glb", "--frames", "100"])
        .output()
        .unwrap();
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}{stderr}");
    // 0.5 s at 1 ms: 501 samples, of which 101 evenly spaced frames (no clearance joint).
    assert!(stdout.contains("(101 frames of 501 samples"), "{stdout}");
    let html = std::fs::read_to_string(dir.path().join("pendulum.html")).unwrap();
    assert!(html.contains("id=\"jointplay-data\"") && html.contains("window.jointplay"));
    // Self-contained: nothing is fetched from anywhere.
    assert!(!html.contains("http:") && !html.contains("https:") && !html.contains("src="));
    let glb = std::fs::read(dir.path().join("pendulum.glb")).unwrap();
    assert_eq!(&glb[..4], b"glTF");
    assert_eq!(
        u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize,
        glb.len()
    );
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let doc = String::from_utf8(glb[20..20 + json_len].to_vec()).unwrap();
    assert!(
        doc.contains("\"name\":\"bob\"") && doc.contains("\"animations\""),
        "{doc}"
    );
    // Five shapes: five primitives in the bob's mesh.
    assert_eq!(doc.matches("\"POSITION\"").count(), 5 + 1, "{doc}");
}

#[test]
fn bad_shapes_and_bad_animate_input_get_errors_that_name_them() {
    let dir = tempfile::tempdir().unwrap();
    let scene = pendulum_with_shapes(dir.path());
    let text_of = |s: &str| {
        std::fs::read_to_string(&scene)
            .unwrap()
            .replace("radius = 0.05,", s)
    };
    for (edit, field, says) in [
        (
            "radius = -0.05,",
            "bodies[0].visual[0].radius",
            "must be positive",
        ),
        (
            "radius = 0.05, color = \"red\",",
            "bodies[0].visual[0].color",
            "#rrggbb",
        ),
    ] {
        let p = write_scene(
            dir.path(),
            "bad.toml",
            &text_of(edit)
                .replace("color = \"#cc3311\"", "")
                .replace(", }", " }"),
        );
        let out = bin().arg("check").arg(&p).output().unwrap();
        let (_, err) = text(&out);
        assert!(
            !out.status.success() && err.contains(field) && err.contains(says),
            "{edit}: {err}"
        );
    }
    let p = write_scene(
        dir.path(),
        "bad.toml",
        &std::fs::read_to_string(&scene)
            .unwrap()
            .replace("quad.obj", "quad.ply"),
    );
    let (_, err) = text(&bin().arg("check").arg(&p).output().unwrap());
    assert!(
        err.contains("bodies[0].visual[4].file") && err.contains("neither an OBJ"),
        "{err}"
    );

    // A mesh missing when the run is animated: named, with the body.
    run_ok(dir.path(), &scene);
    std::fs::remove_file(dir.path().join("tetra.stl")).unwrap();
    let animate = |args: &[&str]| bin().arg("animate").args(args).output().unwrap();
    let h5 = dir.path().join("pendulum.h5");
    let h5s = h5.to_str().unwrap();
    let out = dir.path().to_str().unwrap();
    let (_, err) = text(&animate(&[h5s, "--out", out]));
    assert!(
        err.contains("tetra.stl") && err.contains("body 'bob'"),
        "{err}"
    );

    // The wrong file kinds and options.
    let (_, err) = text(&animate(&[scene.to_str().unwrap()]));
    assert!(
        err.contains("a TOML file") && err.contains("jointplay run"),
        "{err}"
    );
    let (_, err) = text(&animate(&[h5s, "--frames", "1"]));
    assert!(err.contains("--frames"), "{err}");
    let (_, err) = text(&animate(&[h5s, "--speed=-1"]));
    assert!(err.contains("--speed"), "{err}");
    let (_, err) = text(&animate(&[h5s, "--case", "x"]));
    assert!(err.contains("no cases"), "{err}");
    assert!(!dir.path().join("pendulum.html").exists());
}

#[test]
fn animate_keeps_every_impact_and_takes_a_case_of_a_study() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_study(
        dir.path(),
        "study.toml",
        "slider-crank-clearance.toml",
        "[study]\nname = \"s\"\nscene = \"SCENE\"\n[[cases]]\nlabel = \"a\"\n\
         [[cases]]\nlabel = \"b\"\nset = { \"joints.piston_pin.clearance.journal_radius\" = 0.0098 }\n",
    );
    assert!(out.status.success(), "{:?}", text(&out));
    let h5 = dir.path().join("s.h5");
    let animate = |args: &[&str]| {
        bin()
            .arg("animate")
            .arg(&h5)
            .arg("--out")
            .arg(dir.path())
            .args(args)
            .output()
            .unwrap()
    };
    let (_, err) = text(&animate(&[]));
    assert!(err.contains("--case") && err.contains("a, b"), "{err}");
    let (_, err) = text(&animate(&["--case", "c"]));
    assert!(err.contains("no case 'c'"), "{err}");
    // 50 evenly spaced frames of a run full of impacts: the contacts' changes and peaks are kept
    // besides them.
    let o = animate(&["--case", "b", "--frames", "50"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let kept: usize = stdout
        .split(" samples, ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(kept > 20, "{stdout}");
    assert!(dir.path().join("s-b.html").exists());
}

#[test]
fn animate_runs_a_sweep_value_and_a_periodic_orbit_again_from_the_analysis_file() {
    let dir = tempfile::tempdir().unwrap();
    let tutorial = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("book/src/tutorial");
    std::fs::copy(
        tutorial.join("four-bar.toml"),
        dir.path().join("four-bar.toml"),
    )
    .unwrap();
    let sweep = write_scene(
        dir.path(),
        "sweep.toml",
        &std::fs::read_to_string(tutorial.join("four-bar-sweep.toml"))
            .unwrap()
            .replace("periods = 40\ntransient = 20", "periods = 4\ntransient = 2")
            .replace("count = 10", "count = 2"),
    );
    run_ok(dir.path(), &sweep);
    // The scene the study read is gone: the file's own copy of the flow is used.
    std::fs::remove_file(dir.path().join("four-bar.toml")).unwrap();
    let h5 = dir.path().join("four-bar-sweep.h5");
    let animate = |file: &Path, args: &[&str]| {
        bin()
            .arg("animate")
            .arg(file)
            .arg("--out")
            .arg(dir.path())
            .args(args)
            .output()
            .unwrap()
    };
    let (_, err) = text(&animate(&h5, &[]));
    assert!(
        err.contains("--value V") && err.contains("--orbit"),
        "{err}"
    );
    let (_, err) = text(&animate(&h5, &["--value", "1e-4"]));
    assert!(
        err.contains("no done sweep value 0.0001") && err.contains("values: 0.00005, 0.0005"),
        "{err}"
    );
    let (_, err) = text(&animate(&h5, &["--orbit", "0:0"]));
    assert!(
        err.contains("no periodic orbits") && err.contains("--value"),
        "{err}"
    );
    let o = animate(&h5, &["--value", "5e-4", "--periods", "0.5", "--glb"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    // Half a crank turn at no coarser than the scene's interval: at least 2000 intervals.
    assert!(stdout.contains("(2001 frames of 2001 samples"), "{stdout}");
    assert!(dir.path().join("four-bar-sweep-value-0.0005.html").exists());
    assert!(dir.path().join("four-bar-sweep-value-0.0005.glb").exists());

    let periodic = write_scene(
        dir.path(),
        "periodic.toml",
        &std::fs::read_to_string(tutorial.join("four-bar-periodic.toml"))
            .unwrap()
            .replace(
                "four-bar.toml",
                &tutorial.join("four-bar.toml").display().to_string(),
            ),
    );
    run_ok(dir.path(), &periodic);
    let h5 = dir.path().join("four-bar-periodic.h5");
    let (_, err) = text(&animate(&h5, &["--orbit", "3:0"]));
    assert!(
        err.contains("no branch 3") && err.contains("branch 0: 2 points"),
        "{err}"
    );
    let (_, err) = text(&animate(&h5, &["--orbit", "zero"]));
    assert!(err.contains("BRANCH:POINT"), "{err}");
    let o = animate(&h5, &["--orbit", "0:1"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert!(dir.path().join("four-bar-periodic-orbit-0-1.html").exists());
    // An analysis file has no cases.
    let (_, err) = text(&animate(&h5, &["--case", "a"]));
    assert!(err.contains("not a run's file"), "{err}");
}
