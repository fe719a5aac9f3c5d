//! The hybrid state is the whole state of a run: a run of the mixed-clearance 4-UPS/RPU to 2T
//! equals a run to T, written to its HDF5 file, read back and continued for T more, bit for bit,
//! with contacts in progress at the split. Without the contact-onset history the continued run
//! is a different run, which shows the comparison can tell.

use std::path::PathBuf;

use jointplay_analysis::storage::hybrid::read_state;
use jointplay_analysis::storage::run::RunResult;
use jointplay_analysis::storage::run_file::{Meta, write_run};
use jointplay_analysis::study::run::{resume, simulate};
use jointplay_solver::model::Model;
use jointplay_solver::scene::SceneSpec;

fn scenes() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes")
}

fn meta(model: &Model) -> Meta<'_> {
    Meta {
        scene_name: &model.name,
        scene_file: &model.file,
        scene_text: "",
        program_version: "test",
        integrator: model.settings.method.describe(),
        baumgarte_alpha: model.settings.alpha,
        baumgarte_beta: model.settings.beta,
        drive_period: model.settings.period,
        scene_warnings: &[],
    }
}

/// Body positions of every sample after `t`, as bits.
fn positions_after(run: &RunResult, t: f64) -> Vec<u64> {
    let rec = &run.recording;
    let first = rec.time.iter().position(|&s| s > t).unwrap();
    rec.members("bodies")
        .flat_map(|b| {
            let p = rec.channel(&format!("bodies/{b}/position")).unwrap();
            p.values[first * p.width()..].to_vec()
        })
        .map(f64::to_bits)
        .collect()
}

#[test]
fn a_run_split_through_its_file_is_the_same_run() {
    // The scene with gravity along -X: its balls strike their sockets again and again, so the
    // onset velocity of a contact in progress matters (in the default scene they settle onto
    // one side and a lost onset history is hidden by the onset-velocity floor).
    let file =
        SceneSpec::load(&scenes().join("variants/4ups-rpu-mixed-gravity-minus-x.toml")).unwrap();
    let (mut model, state) = Model::compile(&file).unwrap();
    let h = model.settings.method.fixed_step().unwrap();
    // The split on the step grid t_k = k h (the scene starts at 0), a quarter of a second in:
    // the balls of S2 and S5 are in contact there (asserted below).
    assert_eq!(model.settings.start_time, 0.0);
    let t_split = 3000.0 * h;
    let t_end = 6000.0 * h;

    model.settings.end_time = t_end;
    let whole = simulate(&model, state.clone(), &mut |_| {}).unwrap();

    model.settings.end_time = t_split;
    let first = simulate(&model, state, &mut |_| {}).unwrap();
    let dir = std::env::temp_dir().join(format!("jointplay-split-{}", std::process::id()));
    let path = write_run(&dir, &meta(&model), &first).unwrap();
    let saved = read_state(&hdf5::File::open(&path).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let f = &first.final_state;
    assert_eq!(saved.t, t_split);
    assert_eq!(f.t, t_split);
    // Equality of hybrid states is bitwise.
    assert_eq!(&saved, f);
    let active = saved.onset.iter().filter(|v| !v.is_nan()).count();
    assert!(
        active > 0,
        "no contact in progress at the split: {:?}",
        saved.onset
    );

    model.settings.end_time = t_end;
    let second = resume(&model, saved.clone(), &mut |_| {}).unwrap();
    assert_eq!(second.final_state, whole.final_state);
    // The first half holds the split's own sample and the continued run the samples after it,
    // each equal to the uninterrupted run's, and the two halves together took the whole run's
    // steps.
    assert_eq!(first.recording.time.last(), Some(&t_split));
    assert!(second.recording.time[0] > t_split);
    assert_eq!(
        second.recording.time.len() + first.recording.time.len(),
        whole.recording.time.len()
    );
    assert_eq!(
        positions_after(&second, t_split),
        positions_after(&whole, t_split)
    );
    assert_eq!(
        first.stats.accepted + second.stats.accepted,
        whole.stats.accepted
    );

    // The same continuation without the onset history: the contacts in progress take their
    // current approach rate as onset velocity, and the run departs from the uninterrupted one.
    let mut forgetful = saved;
    forgetful.onset.clear();
    let other = resume(&model, forgetful, &mut |_| {}).unwrap();
    assert_ne!(other.final_state.y, whole.final_state.y);
}

/// The same with LuGre friction, whose bristle deflections are part of the continuous state: the
/// block of `data/scenes/lugre-stick-slip.toml`, with RK4 at 10 us, split half a second in
/// while it sticks in presliding (its bristles deflected), is the same run; continued with the
/// bristles undeflected, it is another.
#[test]
fn a_lugre_run_split_through_its_file_is_the_same_run() {
    let path = scenes().join("lugre-stick-slip.toml");
    let text = std::fs::read_to_string(&path).unwrap().replacen(
        "integrator = \"dopri5\"",
        "integrator = \"rk4\"\nstep = 1e-5",
        1,
    );
    let file = jointplay_solver::scene::SceneFile {
        spec: SceneSpec::parse(&text, &path).unwrap(),
        path,
        text,
    };
    let (mut model, state) = Model::compile(&file).unwrap();
    let (t_split, t_end) = (50_000.0 * 1e-5, 100_000.0 * 1e-5);
    model.settings.end_time = t_end;
    let whole = simulate(&model, state.clone(), &mut |_| {}).unwrap();
    model.settings.end_time = t_split;
    let first = simulate(&model, state, &mut |_| {}).unwrap();
    let dir = std::env::temp_dir().join(format!("jointplay-lugre-split-{}", std::process::id()));
    let written = write_run(&dir, &meta(&model), &first).unwrap();
    let saved = read_state(&hdf5::File::open(&written).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(&saved, &first.final_state);
    let bristles = &saved.y[model.bristle_offset()..];
    assert_eq!(bristles.len(), 12);
    // Presliding at 0.5 s: the spring pulls with 0.1 N, which the bristles of the two lower
    // corners hold at sigma0 z m g = 0.1 N, z = 1e-6 m.
    assert!(bristles.iter().any(|z| z.abs() > 5e-7), "{bristles:?}");
    model.settings.end_time = t_end;
    let second = resume(&model, saved.clone(), &mut |_| {}).unwrap();
    assert_eq!(second.final_state, whole.final_state);
    let mut fresh = saved;
    let o = model.bristle_offset();
    fresh.y[o..].fill(0.0);
    let other = resume(&model, fresh, &mut |_| {}).unwrap();
    assert_ne!(other.final_state.y, whole.final_state.y);
}

/// A continuation sweep of the mixed 4-UPS/RPU over the friction coefficient, one drive period
/// per value, with RK4 at the scene's step; gravity along -X, whose rattling contacts make the
/// onset history matter (see above).
const CONTINUATION: &str = r#"
[study]
name = "continuation-onset"
scene = "variants/4ups-rpu-mixed-gravity-minus-x.toml"

[analysis]
periods = 1
transient = 0
samples_per_period = 0

[[observables]]
name = "platform_x"
path = "bodies.platform.position.x"

[sweep]
parameter = "joints.*.clearance.friction.coefficient"
from = 0.05
to = 0.06
count = 2
continuation = true
"#;

#[test]
fn a_continuation_sweep_hands_over_the_onset_history() {
    use jointplay_analysis::storage::hybrid::read_row;
    use jointplay_analysis::study::analysis::{Loaded, Options, execute};

    let st = Loaded::parse(CONTINUATION, &scenes().join("continuation-onset.toml")).unwrap();
    let dir = std::env::temp_dir().join(format!("jointplay-continuation-{}", std::process::id()));
    let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
    let file = hdf5::File::open(&out.file).unwrap();
    let sweep = file.group("sweep").unwrap();
    let (first, second) = (read_row(&sweep, 0).unwrap(), read_row(&sweep, 1).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
    // Contacts are in progress at the hand-over, so there is an onset history to keep.
    let active = first.onset.iter().filter(|v| !v.is_nan()).count();
    assert!(active > 0, "no contact at the hand-over: {:?}", first.onset);
    // Up the list, the second value (index 1; the sweep then comes back down) started from the
    // first one's final state with its onset history: running it so again gives the same run.
    let v1 = st.jobs[1].0;
    let again = st.run_value_from(v1, &first, &mut |_| {}).unwrap();
    assert_eq!(again.trace.final_state, second);
    // Handed over without the history, the contacts in progress would have taken their
    // current approach rate as onset velocity: another run.
    let mut forgetful = first.clone();
    forgetful.onset.clear();
    let other = st.run_value_from(v1, &forgetful, &mut |_| {}).unwrap();
    assert_ne!(other.trace.final_state.y, second.y);
}

#[test]
fn a_study_sets_any_parameter_by_path() {
    use jointplay_analysis::flow::Target;
    use jointplay_analysis::study::analysis::Loaded;

    let st = Loaded::parse(CONTINUATION, &scenes().join("continuation-onset.toml")).unwrap();
    let clearance = |t: &Target, name: &str| match t {
        Target::Scene { model, .. } => model
            .clearances
            .iter()
            .find(|c| c.name == name)
            .unwrap()
            .geometry
            .radial_clearance(),
        Target::System { .. } => unreachable!("a scene study"),
    };
    let t = st
        .target_with(&[("joints.S2.clearance.radial_clearance", 4e-4)])
        .unwrap();
    assert_eq!(clearance(&t, "S2"), 4e-4);
    // The other joints keep the scene's 0.3 mm.
    assert_eq!(clearance(&t, "S5"), 3e-4);
    let t = st
        .target_with(&[("joints.*.clearance.radial_clearance", 2e-4)])
        .unwrap();
    // R1's clearance is the difference of its two radii: equal up to their rounding.
    assert_eq!(clearance(&t, "S2"), 2e-4);
    assert!((clearance(&t, "R1") - 2e-4).abs() < 1e-17);
    let e = st
        .target_with(&[("joints.S9.clearance.radial_clearance", 4e-4)])
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("parameter 'joints.S9.clearance.radial_clearance'") && e.contains("S9"),
        "{e}"
    );
}

/// A continuation sweep of the forced LuGre block over its bristles' damping, one drive period
/// per value: each value starts from the previous one's final state, bristle deflections
/// included.
const LUGRE_CONTINUATION: &str = r#"
[study]
name = "continuation-lugre"
scene = "variants/lugre-stick-slip-forced.toml"

[analysis]
periods = 1
transient = 0
samples_per_period = 0

[[observables]]
name = "x"
path = "bodies.block.position.x"

[sweep]
parameter = "joints.floor.clearance.friction.bristle_damping"
from = 30.0
to = 34.0
count = 2
continuation = true
"#;

#[test]
fn a_continuation_sweep_hands_over_the_bristle_deflections() {
    use jointplay_analysis::storage::hybrid::read_row;
    use jointplay_analysis::study::analysis::{Loaded, Options, execute};

    let st = Loaded::parse(
        LUGRE_CONTINUATION,
        &scenes().join("continuation-lugre.toml"),
    )
    .unwrap();
    let dir = std::env::temp_dir().join(format!("jointplay-lugre-cont-{}", std::process::id()));
    let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
    let file = hdf5::File::open(&out.file).unwrap();
    let sweep = file.group("sweep").unwrap();
    let (first, second) = (read_row(&sweep, 0).unwrap(), read_row(&sweep, 1).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
    // 26 body coordinates, then the 12 bristle states, deflected at the hand-over.
    assert_eq!(first.y.len(), 38);
    assert!(
        first.y[26..].iter().any(|z| z.abs() > 1e-7),
        "{:?}",
        &first.y[26..]
    );
    let v1 = st.jobs[1].0;
    let again = st.run_value_from(v1, &first, &mut |_| {}).unwrap();
    assert_eq!(again.trace.final_state, second);
    let mut fresh = first.clone();
    fresh.y[26..].fill(0.0);
    let other = st.run_value_from(v1, &fresh, &mut |_| {}).unwrap();
    assert_ne!(other.trace.final_state.y, second.y);
}

/// `joints.J.bristle.K_A` reads a LuGre contact's bristle state; a name that is not a contact
/// and an axis, or a joint without LuGre, is refused naming what there is.
#[test]
fn the_bristle_observable_reads_the_state_and_refuses_what_is_not_there() {
    use jointplay_analysis::flow::observe::Observable;
    let file = SceneSpec::load(&scenes().join("lugre-stick-slip.toml")).unwrap();
    let (model, mut state) = Model::compile(&file).unwrap();
    model.assemble(&mut state).unwrap();
    let o = model.bristle_offset();
    state.y[o + 3 * 3 + 1] = 1.5e-6; // rear_lower, y
    let ob = Observable::for_run(&model, "joints.floor.bristle.rear_lower_y").unwrap();
    assert_eq!(ob.unit, "m");
    let mut ws = jointplay_solver::dynamics::Workspace::new(&model);
    model.kinematics(&state.y, &mut ws);
    assert_eq!(ob.eval_model(&model, &ws, state.t, &state.y), 1.5e-6);
    let e = Observable::for_run(&model, "joints.floor.bristle.rear_lower_w").unwrap_err();
    assert!(
        e.contains("front_upper") && e.contains("front_upper_x"),
        "{e}"
    );
    let file = SceneSpec::load(&scenes().join("slider-in-guide.toml")).unwrap();
    let (plain, _) = Model::compile(&file).unwrap();
    let e = Observable::for_run(&plain, "joints.guide.bristle.front_lower_x").unwrap_err();
    assert!(e.contains("no LuGre friction"), "{e}");
}
