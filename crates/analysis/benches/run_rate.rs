//! What a run costs besides its right-hand sides: the rate of a whole run of the mixed
//! 4-UPS/RPU (evaluations per second, everything included: steps, error control, onset
//! bookkeeping, guards, events, the recording streamed to its HDF5 file) against the rate of
//! the right-hand side alone, measured in the same benchmark run.
//!
//! `cargo bench -p jointplay-analysis --bench run_rate`
//!
//! The run is `data/scenes/4ups-rpu-mixed.toml` over its first 10 s (five drive periods, five
//! blocks of samples for the file's writer thread; over 2 s the one block was compressed after
//! the integration, not beside it) with DOPRI5 at rtol 1e-6 (atol 1e-9) and the scene's 1 ms
//! output, with contact onsets as events off and on, (`whole_run_unrecorded`) with one sample a
//! second instead, which leaves out the recording's work (its evaluation at each sample, its
//! observables and its compression, all on the file's writer thread, beside the integration),
//! and (`whole_run_50_periods`) over the 50 drive periods of section 3, where the file's fixed
//! costs weigh ten times less. Divan reports each as items per second, one item being one
//! right-hand-side evaluation of the integrator (the run's count, fixed: the run is
//! deterministic); the `rhs` bench is one evaluation at the state the run reaches after 0.15 s,
//! repeated, `rhs_along_the_run` one at each of 1 000 states along the run, in turn (the check
//! that the one state stands for the run's), and `rhs_at_the_runs_stages` one at every tenth
//! state the run's integrator evaluates it at (its stages, not only the sample times). The ratio of a whole run's rate to the
//! right-hand side's is the share of the run's time spent in its integrator's evaluations.
//!
//! On a machine whose speed drifts within minutes (a shared one), the benches' rates, measured
//! one after the other, can be far apart in time. With `RUN_RATE_PAIRED=N` the bench instead
//! takes N rounds, each a whole 10 s run (onset events off) between two timings of the
//! right-hand side at the run's stage states and at its sample states, and reports every
//! round's ratio of the run's rate to the mean of the two right-hand-side rates around it, then
//! their median and range; `RUN_RATE_PAIRED_50=M` adds M rounds with the 50-period run:
//!
//! `RUN_RATE_PAIRED=12 RUN_RATE_PAIRED_50=3 cargo bench -p jointplay-analysis --bench run_rate`

use std::path::PathBuf;

use jointplay_analysis::storage::run_file::Meta;
use jointplay_analysis::study::run::simulate_to_file;
use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::{Flow, OdeSystem, integrate};
use jointplay_solver::scene::{SceneFile, SceneSpec};

fn main() {
    let rounds = |name: &str| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse::<usize>().ok())
    };
    match rounds("RUN_RATE_PAIRED") {
        Some(n) => paired(n, rounds("RUN_RATE_PAIRED_50").unwrap_or(0)),
        None => divan::main(),
    }
}

/// Rounds of a whole run between two timings of the right-hand side (see the module
/// documentation): `short` rounds with the 10 s run, `long` with the 50 periods.
fn paired(short: usize, long: usize) {
    use std::time::Instant;
    let (model, mut state, _) = scene(false);
    model.assemble(&mut state).unwrap();
    let (mut sys, stages) = stage_states(&model, &state);
    let samples = sample_states(&model, &state);
    let mut dy = vec![0.0; state.y.len()];
    // Evaluations per second over `states` (at least 0.1 s of them).
    let mut rate = |states: &StatesAt| {
        let (start, mut count) = (Instant::now(), 0usize);
        while count == 0 || start.elapsed().as_secs_f64() < 0.1 {
            evaluate_at(&mut sys, states, &mut dy);
            count += states.len();
        }
        count as f64 / start.elapsed().as_secs_f64()
    };
    let dir = tempfile::tempdir().unwrap();
    let runs = [
        ("whole_run, 10 s", scene(false), short),
        (
            "whole_run_50_periods",
            scene_sampled(false, None, "periods = 50.0"),
            long,
        ),
    ];
    println!(
        "| run | round | run (evaluations/s) | of rhs_at_the_runs_stages | of rhs_along_the_run |"
    );
    println!("|---|---|---|---|---|");
    for (name, (model, state, file), rounds) in &runs {
        let mut ratios: Vec<(f64, f64)> = Vec::new();
        for round in 0..*rounds {
            let (stage0, sample0) = (rate(&stages), rate(&samples));
            let start = Instant::now();
            let evals = run(model, state, file, dir.path());
            let whole = evals as f64 / start.elapsed().as_secs_f64();
            let (stage1, sample1) = (rate(&stages), rate(&samples));
            let r = (
                whole / (0.5 * (stage0 + stage1)),
                whole / (0.5 * (sample0 + sample1)),
            );
            println!(
                "| {name} | {round} | {whole:.0} | {:.1} % | {:.1} % |",
                100.0 * r.0,
                100.0 * r.1
            );
            ratios.push(r);
        }
        if ratios.is_empty() {
            continue;
        }
        let summary = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            let median = 0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2]);
            format!(
                "{:.1} % ({:.1} to {:.1} %)",
                100.0 * median,
                100.0 * v[0],
                100.0 * v[v.len() - 1]
            )
        };
        println!(
            "| {name} | median (range) of {} | | {} | {} |",
            ratios.len(),
            summary(ratios.iter().map(|r| r.0).collect()),
            summary(ratios.iter().map(|r| r.1).collect())
        );
    }
}

const EVENTS: [bool; 2] = [false, true];

/// The scene with the benchmark's solver settings.
fn scene(events: bool) -> (Model, State, SceneFile) {
    scene_sampled(events, None, "end_time = 10.0")
}

/// [`scene`] with its output interval set to `interval` (s) when given, and its span given by
/// `span` (a `[solver]` line).
fn scene_sampled(events: bool, interval: Option<f64>, span: &str) -> (Model, State, SceneFile) {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/4ups-rpu-mixed.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text.find("[solver]").unwrap();
    let end = start + text[start..].find("\n[").unwrap();
    let text = format!(
        "{}[solver]\nintegrator = \"dopri5\"\nrtol = 1e-6\natol = 1e-9\n{span}\nonset_events = {events}\n{}",
        &text[..start],
        &text[end..]
    );
    let text = match interval {
        Some(i) => {
            let at = "[output]\ninterval = 1e-3";
            assert!(text.contains(at), "the scene's output interval has moved");
            text.replace(at, &format!("[output]\ninterval = {i}"))
        }
        None => text,
    };
    let spec = SceneSpec::parse(&text, &path).unwrap();
    let file = SceneFile { path, text, spec };
    let (model, state) = Model::compile(&file).unwrap();
    (model, state, file)
}

/// One whole run to a file in `dir`; its right-hand-side evaluations.
fn run(model: &Model, state: &State, file: &SceneFile, dir: &std::path::Path) -> u64 {
    let meta = Meta::of(model, &file.path, &file.text, "bench");
    let (result, _) = simulate_to_file(model, state.clone(), &mut |_| {}, dir, &meta).unwrap();
    assert!(result.stopped.is_none());
    result.stats.rhs_evals
}

#[divan::bench(args = EVENTS, sample_count = 5)]
fn whole_run(bencher: divan::Bencher, events: bool) {
    let (model, state, file) = scene(events);
    let dir = tempfile::tempdir().unwrap();
    let evals = run(&model, &state, &file, dir.path());
    bencher
        .counter(divan::counter::ItemsCount::new(evals))
        .bench_local(|| run(&model, &state, &file, dir.path()));
}

/// [`whole_run`] (onset events off) sampled once a second instead of every millisecond: what the
/// run costs besides its evaluations without the recording's work beside it (its evaluation at
/// each sample, its observables and its file's compression).
#[divan::bench(sample_count = 5)]
fn whole_run_unrecorded(bencher: divan::Bencher) {
    let (model, state, file) = scene_sampled(false, Some(1.0), "end_time = 10.0");
    let dir = tempfile::tempdir().unwrap();
    let evals = run(&model, &state, &file, dir.path());
    bencher
        .counter(divan::counter::ItemsCount::new(evals))
        .bench_local(|| run(&model, &state, &file, dir.path()));
}

/// [`whole_run`] (onset events off) over the 50 drive periods of section 3 (100 s), where the
/// file's fixed costs (creating its datasets, the samples left after the integration, closing it)
/// weigh ten times less than over 10 s.
#[divan::bench(sample_count = 3)]
fn whole_run_50_periods(bencher: divan::Bencher) {
    let (model, state, file) = scene_sampled(false, None, "periods = 50.0");
    let dir = tempfile::tempdir().unwrap();
    let evals = run(&model, &state, &file, dir.path());
    bencher
        .counter(divan::counter::ItemsCount::new(evals))
        .bench_local(|| run(&model, &state, &file, dir.path()));
}

/// The mixed 4-UPS/RPU's system keeping every [`EVERY`]-th state it is evaluated at, with the
/// contacts' onset history then: the states a run's integrator evaluates the right-hand side at
/// (its stages), not only those at the sample times.
struct Keeping<'m> {
    sys: Mechanism<'m>,
    calls: usize,
    kept: StatesAt,
}

const EVERY: usize = 10;

/// States of a run, each with its time and the contacts' onset history.
type StatesAt = Vec<(f64, Vec<f64>, Vec<f64>)>;

impl OdeSystem for Keeping<'_> {
    fn dim(&self) -> usize {
        self.sys.dim()
    }

    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) {
        if self.calls.is_multiple_of(EVERY) {
            self.kept.push((t, y.to_vec(), self.sys.ws.onset.clone()));
        }
        self.calls += 1;
        self.sys.rhs(t, y, dydt);
    }

    fn error_dim(&self) -> usize {
        self.sys.error_dim()
    }

    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        self.sys.step_accepted(t0, y0, t1, y1)
    }

    fn check_step(&mut self, t: f64, y: &[f64]) -> Option<String> {
        self.sys.check_step(t, y)
    }
}

/// One right-hand side at every tenth state the integrator of [`whole_run`] (onset events off)
/// evaluates it at over the 10 s, about 21 000 states, in turn, each with its onset history: the
/// states of the run's stages, which `rhs_along_the_run` (states at sample times) does not
/// repeat. Against this rate a whole run's rate is the share of its time spent in evaluations
/// like its own.
#[divan::bench(sample_count = 10)]
fn rhs_at_the_runs_stages(bencher: divan::Bencher) {
    let (model, mut state, _) = scene(false);
    model.assemble(&mut state).unwrap();
    let (mut sys, kept) = stage_states(&model, &state);
    let mut dy = vec![0.0; state.y.len()];
    bencher
        .counter(divan::counter::ItemsCount::new(kept.len() as u64))
        .bench_local(|| {
            evaluate_at(&mut sys, &kept, &mut dy);
        });
}

/// One right-hand side at each of `states` in turn, each with its onset history, into `dy`.
fn evaluate_at(sys: &mut Mechanism, states: &StatesAt, dy: &mut [f64]) {
    for (t, y, onset) in states {
        sys.ws.onset.copy_from_slice(onset);
        sys.rhs(*t, std::hint::black_box(y), dy);
        std::hint::black_box(&*dy);
    }
}

/// Every [`EVERY`]-th state the 10 s run from `state` (assembled) evaluates its right-hand side
/// at, with its time and onset history, and the system the run ends with.
fn stage_states<'m>(model: &'m Model, state: &State) -> (Mechanism<'m>, StatesAt) {
    let mut keeping = Keeping {
        sys: Mechanism::new(model),
        calls: 0,
        kept: Vec::new(),
    };
    let mut y = state.y.clone();
    integrate(
        &mut keeping,
        model.settings.method,
        0.0,
        &mut y,
        10.0,
        &[],
        |_, _, _| Flow::Continue,
    )
    .unwrap();
    (keeping.sys, keeping.kept)
}

/// The states of the 10 s run from `state` (assembled) every 10 ms, with their times and onset
/// histories.
fn sample_states(model: &Model, state: &State) -> StatesAt {
    let mut sys = Mechanism::new(model);
    let times: Vec<f64> = (1..=1000).map(|i| i as f64 * 0.01).collect();
    let mut states = Vec::new();
    let mut y = state.y.clone();
    integrate(
        &mut sys,
        model.settings.method,
        0.0,
        &mut y,
        10.0,
        &times,
        |sys, t, y| {
            states.push((t, y.to_vec(), sys.ws.onset.clone()));
            Flow::Continue
        },
    )
    .unwrap();
    states
}

#[divan::bench(sample_count = 200)]
fn rhs(bencher: divan::Bencher) {
    let (model, mut state, _) = scene(false);
    model.assemble(&mut state).unwrap();
    let mut sys = Mechanism::new(&model);
    integrate(
        &mut sys,
        model.settings.method,
        0.0,
        &mut state.y,
        0.15,
        &[],
        |_, _, _| Flow::Continue,
    )
    .unwrap();
    let y = state.y.clone();
    let mut dy = vec![0.0; y.len()];
    bencher
        .counter(divan::counter::ItemsCount::new(1u64))
        .bench_local(|| {
            sys.rhs(0.15, divan::black_box(&y), &mut dy);
            divan::black_box(&dy);
        });
}

/// One right-hand side at each of 1 000 states along the run's first 10 s (every 10 ms), in
/// turn, each with its onset history: the evaluations of a run meet states that change from one
/// to the next, with closed and open contacts in their own proportions, where the `rhs` bench
/// repeats one state.
#[divan::bench(sample_count = 20)]
fn rhs_along_the_run(bencher: divan::Bencher) {
    let (model, mut state, _) = scene(false);
    model.assemble(&mut state).unwrap();
    let mut sys = Mechanism::new(&model);
    let states = sample_states(&model, &state);
    let mut dy = vec![0.0; state.y.len()];
    bencher
        .counter(divan::counter::ItemsCount::new(states.len() as u64))
        .bench_local(|| {
            evaluate_at(&mut sys, &states, &mut dy);
        });
}
