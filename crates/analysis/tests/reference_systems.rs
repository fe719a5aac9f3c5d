//! The nonlinear-analysis pipeline (study file, sections, sweeps, HDF5) against the known
//! behaviour of the built-in reference systems.

use std::path::{Path, PathBuf};

use jointplay_analysis::storage::analysis_file::JobResult;
use jointplay_analysis::study::analysis::{Loaded, Options, execute};

/// `text` (a sweep study) as a continuation when `continuation`, as it is otherwise.
fn sweep_text(text: &str, continuation: bool) -> String {
    match continuation {
        true => format!("{text}continuation = true\n"),
        false => text.to_string(),
    }
}

fn study(text: &str) -> Loaded {
    Loaded::parse(text, Path::new("reference.toml")).unwrap()
}

fn tmp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("jointplay-ref-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Number of distinct points among (x, v) pairs: a point is new when it is farther than `tol`
/// from every point seen so far.
fn distinct(x: &[f64], v: &[f64], tol: f64) -> usize {
    let mut seen: Vec<(f64, f64)> = Vec::new();
    for (a, b) in x.iter().zip(v) {
        if !seen.iter().any(|(p, q)| (a - p).hypot(b - q) < tol) {
            seen.push((*a, *b));
        }
    }
    seen.len()
}

const DUFFING: &str = r#"
[study]
name = "duffing"
system = { kind = "duffing", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = 0.2, omega = 1.2, initial = [1.0, 0.0], solver = { integrator = "dopri5", rtol = 1e-10, atol = 1e-12 } }

[analysis]
periods = 264
transient = 200
samples_per_period = 0

[[observables]]
name = "x"
path = "x"

[[observables]]
name = "v"
path = "v"

[sweep]
parameter = "gamma"
values = [0.20, 0.28, 0.29, 0.50]
"#;

/// Each value of the sweep `st` run on its own, as its job runs in the sweep: in a continuation
/// from the previous value's final state.
fn run_alone(st: &Loaded, values: &[f64], continuation: bool) -> Vec<JobResult> {
    let mut runs: Vec<JobResult> = Vec::new();
    for &g in values {
        let r = match runs.last() {
            Some(prev) if continuation => st
                .run_value_from(g, &prev.trace.final_state, &mut |_| {})
                .unwrap(),
            _ => st.run_value(g, &mut |_| {}).unwrap(),
        };
        runs.push(r);
    }
    runs
}

/// The study `text` without its `[sweep]` table (and what follows it): a single run.
fn without_sweep(text: &str) -> Loaded {
    study(&text[..text.find("[sweep]").unwrap()])
}

/// The sweep `st` run as two shards into `dir`, merged into `dir/merged.h5`.
fn two_shards_merged(st: &Loaded, dir: &Path) -> PathBuf {
    use jointplay_analysis::storage::analysis_file::Shard;
    use jointplay_analysis::study::shards::merge;
    let shards: Vec<_> = (0..2)
        .map(|index| {
            let o = Options {
                shard: Some(Shard { index, count: 2 }),
                ..Options::default()
            };
            execute(st, dir, o, "test", &|_| {}).unwrap().file
        })
        .collect();
    let merged = dir.join("merged.h5");
    merge(&shards, &merged, "test", false).unwrap();
    merged
}

fn read2(file: &hdf5::File, name: &str) -> Vec<Vec<f64>> {
    let ds = file.dataset(name).unwrap();
    let shape = ds.shape();
    let raw = ds.read_raw::<f64>().unwrap();
    raw.chunks(shape[1]).map(<[f64]>::to_vec).collect()
}

#[test]
fn duffing_period_doubling_through_the_whole_pipeline() {
    // x'' + 0.3 x' - x + x^3 = gamma cos(1.2 t) from (1, 0): 1, 2 and 4 distinct stroboscopic
    // points at gamma = 0.20, 0.28, 0.29 and none repeating at 0.50 (period doubling to chaos).
    // An independent DOP853 run at rtol 1e-11 puts periodic points within 1e-11 of each other
    // and distinct points at least 3e-3 apart, so a 1e-6 tolerance separates them with margin
    // for DOPRI5 at rtol 1e-10.
    let st = study(DUFFING);
    let dir = tmp_dir("duffing");
    let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
    assert!(out.complete && out.failed.is_empty());
    let file = hdf5::File::open(&out.file).unwrap();
    assert_eq!(
        file.attr("complete").unwrap().read_scalar::<u8>().unwrap(),
        1
    );
    let x = read2(&file, "sweep/x");
    let v = read2(&file, "sweep/v");
    let counts: Vec<usize> = (0..4).map(|i| distinct(&x[i], &v[i], 1e-6)).collect();
    assert_eq!(
        counts,
        vec![1, 2, 4, 64],
        "distinct strobe points per gamma"
    );
    // The period-1 point of gamma = 0.20 agrees with the DOP853 reference (0.568389, 0.412727)
    // to its six printed digits.
    assert!((x[0][0] - 0.568389).abs() < 1e-6 && (v[0][0] - 0.412727).abs() < 1e-6);
    // Strobe times are t0 + k T exactly (to rounding): k = 201..264.
    let t = read2(&file, "sweep/strobe_time");
    let period = 2.0 * std::f64::consts::PI / 1.2;
    for (i, tk) in t[0].iter().enumerate() {
        let exact = (201 + i) as f64 * period;
        assert!(
            (tk - exact).abs() <= 2.0 * f64::EPSILON * exact,
            "{tk} vs {exact}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The state after one period from (x0, v0).
fn strobe_map(x0: f64, v0: f64) -> [f64; 2] {
    let st = study(&format!(
        r#"
[study]
name = "map"
system = {{ kind = "duffing", gamma = 0.3, initial = [{x0:e}, {v0:e}], solver = {{ rtol = 1e-13, atol = 1e-14 }} }}
[analysis]
periods = 1
samples_per_period = 0
[[observables]]
name = "x"
path = "x"
[[observables]]
name = "v"
path = "v"
"#
    ));
    let r = st.run_single(&mut |_| {}).unwrap();
    [r.trace.strobe[0][0], r.trace.strobe[1][0]]
}

#[test]
fn stroboscopic_map_contracts_areas_by_exp_minus_delta_t() {
    // Liouville: the divergence of the Duffing vector field is -delta, so det DP = exp(-delta T).
    // Central differences with eps = 1e-5 have truncation error ~eps^2 * |P'''| ~ 1e-9 and
    // rounding/tolerance error ~1e-13 / eps = 1e-8, so 1e-6 relative is a safe bound.
    let eps = 1e-5;
    let (x0, v0) = (0.4, -0.2);
    let px = (strobe_map(x0 + eps, v0), strobe_map(x0 - eps, v0));
    let pv = (strobe_map(x0, v0 + eps), strobe_map(x0, v0 - eps));
    let j = [
        [
            (px.0[0] - px.1[0]) / (2.0 * eps),
            (pv.0[0] - pv.1[0]) / (2.0 * eps),
        ],
        [
            (px.0[1] - px.1[1]) / (2.0 * eps),
            (pv.0[1] - pv.1[1]) / (2.0 * eps),
        ],
    ];
    let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let exact = (-0.3 * 2.0 * std::f64::consts::PI / 1.2f64).exp();
    assert!(
        ((det - exact) / exact).abs() < 1e-6,
        "det {det} vs exp(-0.3 T) = {exact}"
    );
}

#[test]
fn strobe_points_equal_runs_stopped_at_the_strobe_time() {
    // Dense output (RK4 with a step that does not divide T, so strobe times fall inside steps)
    // against runs that end exactly at t = k T, where the integrator's last step is shortened to
    // land on it. Both carry RK4's error (~1e-9 at h = 0.01); their difference is the Hermite
    // interpolation error, O(h^4) ~ 1e-8 here.
    let make = |periods: usize| {
        study(&format!(
            r#"
[study]
name = "dense"
system = {{ kind = "duffing", gamma = 0.28, initial = [1.0, 0.0], solver = {{ integrator = "rk4", step = 0.01 }} }}
[analysis]
periods = {periods}
samples_per_period = 0
[[observables]]
name = "x"
path = "x"
"#
        ))
        .run_single(&mut |_| {})
        .unwrap()
    };
    let long = make(6);
    for k in [1usize, 3, 5] {
        let short = make(k);
        let a = long.trace.strobe[0][k - 1];
        let b = short.trace.strobe[0][k - 1];
        assert!((a - b).abs() < 1e-7, "k = {k}: {a} vs {b}");
    }
}

#[test]
fn forced_pendulum_matches_baker_and_gollub() {
    // theta'' + 0.5 theta' + sin theta = g cos(2t/3) from rest: period 1 at g = 0.9, period 2 at
    // g = 1.07, chaotic at g = 1.15 (Baker & Gollub, ch. 3; the counts agree with an independent
    // DOP853 run, clusters within 1e-10, distinct points at least 9e-4 apart).
    let st = study(
        r#"
[study]
name = "pendulum"
system = { kind = "pendulum", damping = 0.5, forcing = 0.9, omega = 0.6666666666666666 }
[analysis]
periods = 364
transient = 300
samples_per_period = 0
[[observables]]
name = "theta"
path = "theta_wrapped"
[[observables]]
name = "theta_dot"
path = "theta_dot"
[sweep]
parameter = "forcing"
values = [0.9, 1.07, 1.15]
"#,
    );
    let counts: Vec<usize> = [0.9, 1.07, 1.15]
        .iter()
        .map(|&g| {
            let r = st.run_value(g, &mut |_| {}).unwrap();
            distinct(&r.trace.strobe[0], &r.trace.strobe[1], 1e-6)
        })
        .collect();
    assert_eq!(counts, vec![1, 2, 64]);
}

#[test]
fn pendulum_small_forcing_has_the_linear_amplitude() {
    // For small forcing the pendulum is the linear oscillator theta'' + b theta' + theta =
    // A cos(w t) with amplitude A / sqrt((1 - w^2)^2 + (b w)^2). The extrema are found by the
    // hyperplane section theta_dot = 0; the cubic term of sin shifts the amplitude by a relative
    // ~theta^2/8 ~ 3e-5 at theta ~ 0.015, so 2e-4 relative is the bound.
    let st = study(
        r#"
[study]
name = "linear"
system = { kind = "pendulum", damping = 0.5, forcing = 0.01, omega = 0.6666666666666666 }
[analysis]
periods = 80
transient = 70
samples_per_period = 0
[[observables]]
name = "theta"
path = "theta"
[[observables]]
name = "theta_dot"
path = "theta_dot"
[[sections]]
name = "turning"
terms = { theta_dot = 1.0 }
direction = "down"
"#,
    );
    let r = st.run_single(&mut |_| {}).unwrap();
    let c = &r.trace.crossings[0];
    assert_eq!(c.time.len(), 10, "one maximum per period");
    let (b, w, a) = (0.5f64, 2.0 / 3.0f64, 0.01);
    let amp = a / ((1.0 - w * w).powi(2) + (b * w).powi(2)).sqrt();
    for (th, thd) in c.values[0].iter().zip(&c.values[1]) {
        assert!(thd.abs() < 1e-12, "theta_dot at the section {thd}");
        assert!(((th - amp) / amp).abs() < 2e-4, "max {th} vs linear {amp}");
    }
}

#[test]
fn lorenz_hyperplane_crossings_are_located_on_the_dense_output() {
    // Upward crossings of z = 27 for sigma 10, rho 28, beta 8/3 from (1, 1, 1) after t = 20.
    // The first lies at t = 20.69014 (independent DOP853 runs agree to 1e-6 across tolerances,
    // before the chaotic divergence); every located point has z = 27 to the root-finder's
    // precision and z increasing.
    let st = study(
        r#"
[study]
name = "lorenz"
system = { kind = "lorenz", initial = [1.0, 1.0, 1.0], solver = { rtol = 1e-12, atol = 1e-12 } }
[analysis]
period = 1.0
periods = 30
transient = 20
samples_per_period = 0
[[observables]]
name = "x"
path = "x"
[[observables]]
name = "y"
path = "y"
[[observables]]
name = "z"
path = "z"
[[sections]]
name = "z27"
terms = { z = 1.0 }
value = 27.0
"#,
    );
    let r = st.run_single(&mut |_| {}).unwrap();
    let c = &r.trace.crossings[0];
    assert!(
        (c.time[0] - 20.69014).abs() < 1e-5,
        "first crossing {}",
        c.time[0]
    );
    // About 0.75 between crossings (0.748-0.759 in the reference runs): 10 to 16 in 10 units.
    assert!(
        (10..=16).contains(&c.time.len()),
        "{} crossings",
        c.time.len()
    );
    for i in 0..c.time.len() {
        let (x, y, z) = (c.values[0][i], c.values[1][i], c.values[2][i]);
        assert!((z - 27.0).abs() < 1e-9, "z = {z}");
        assert!(x * y - 8.0 / 3.0 * z > 0.0, "crossing not upward");
        assert!((10.0..16.7).contains(&x.abs()), "x = {x}");
    }
}

#[test]
fn an_interrupted_sweep_resumed_equals_an_uninterrupted_one() {
    let text = DUFFING
        .replace("periods = 264", "periods = 40")
        .replace("transient = 200", "transient = 30")
        .replace("samples_per_period = 0", "samples_per_period = 16")
        .replace(
            "values = [0.20, 0.28, 0.29, 0.50]",
            "from = 0.2\nto = 0.5\ncount = 7",
        );
    for continuation in [false, true] {
        let st = study(&sweep_text(&text, continuation));
        let (a, b) = (tmp_dir("whole"), tmp_dir("parts"));
        let whole = execute(&st, &a, Options::default(), "test", &|_| {}).unwrap();
        let part = execute(
            &st,
            &b,
            Options {
                resume: false,
                max_jobs: Some(3),
                shard: None,
            },
            "test",
            &|_| {},
        )
        .unwrap();
        assert!(!part.complete && part.ran == 3);
        {
            let f = hdf5::File::open(&part.file).unwrap();
            assert_eq!(f.attr("complete").unwrap().read_scalar::<u8>().unwrap(), 0);
            let done = f.dataset("sweep/done").unwrap().read_raw::<u8>().unwrap();
            assert_eq!(done.iter().filter(|&&d| d == 1).count(), 3);
        }
        let rest = execute(
            &st,
            &b,
            Options {
                resume: true,
                max_jobs: None,
                shard: None,
            },
            "test",
            &|_| {},
        )
        .unwrap();
        assert!(rest.complete);
        assert_eq!(rest.ran, whole.jobs - 3);
        let (fa, fb) = (
            hdf5::File::open(&whole.file).unwrap(),
            hdf5::File::open(&rest.file).unwrap(),
        );
        let names = [
            "sweep/parameter",
            "sweep/strobe_time",
            "sweep/x",
            "sweep/v",
            "sweep/history/time",
            "sweep/history/x",
            "sweep/final_state",
        ];
        for n in names {
            let (x, y) = (
                fa.dataset(n).unwrap().read_raw::<f64>().unwrap(),
                fb.dataset(n).unwrap().read_raw::<f64>().unwrap(),
            );
            assert!(x.iter().all(|v| v.is_finite()), "{n} has unfilled rows");
            let same =
                x.len() == y.len() && x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits());
            assert!(same, "{n} differs (continuation {continuation})");
        }
        for n in ["sweep/done", "sweep/direction"] {
            let (x, y) = (
                fa.dataset(n).unwrap().read_raw::<i16>().unwrap(),
                fb.dataset(n).unwrap().read_raw::<i16>().unwrap(),
            );
            assert_eq!(x, y, "{n}");
        }
        let _ = std::fs::remove_dir_all(&a);
        let _ = std::fs::remove_dir_all(&b);
    }
}

/// `[analysis] significant_bits` rounds the values of the time histories in the file (the
/// single run's and every sweep row's, written block by block, and those a merge copies) to
/// exactly `jointplay_analysis::storage::bitround::round` of the run's own; the sample times, strobe points
/// and final states are written exactly, and the file and each rounded dataset say how many bits
/// were kept.
#[test]
fn histories_keep_the_significant_bits_asked_for_and_nothing_else_is_rounded() {
    use jointplay_analysis::storage::bitround::round;
    let text = DUFFING
        .replace("periods = 264", "periods = 120")
        .replace("transient = 200", "transient = 0")
        .replace(
            "samples_per_period = 0",
            "samples_per_period = 100\nsignificant_bits = 20",
        )
        .replace("values = [0.20, 0.28, 0.29, 0.50]", "values = [0.28, 0.5]");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let rounded = |v: &[f64]| {
        let mut v = v.to_vec();
        round(&mut v, 20);
        bits(&v)
    };
    let marked = |l: &hdf5::Location| {
        l.attr("significant_bits")
            .and_then(|a| a.read_scalar::<u64>())
            .ok()
    };
    let dir = tmp_dir("significant-bits");
    // The parallel sweep and its two shards merged; the continuation, which writes its rows
    // through its own loop, each value from the previous one's final state.
    for continuation in [false, true] {
        let st = study(&sweep_text(&text, continuation));
        let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
        let mut files = vec![out.file.clone()];
        if !continuation {
            files.push(two_shards_merged(&st, &dir));
        }
        for path in &files {
            let file = hdf5::File::open(path).unwrap();
            assert_eq!(marked(&file), Some(20));
            assert_eq!(marked(&file.dataset("sweep/history/x").unwrap()), Some(20));
            for name in ["sweep/history/time", "sweep/x", "sweep/final_state"] {
                assert_eq!(marked(&file.dataset(name).unwrap()), None, "{name}");
            }
            let (time, x, v, strobe) = (
                read2(&file, "sweep/history/time"),
                read2(&file, "sweep/history/x"),
                read2(&file, "sweep/history/v"),
                read2(&file, "sweep/x"),
            );
            for (row, r) in run_alone(&st, &[0.28, 0.5], continuation)
                .iter()
                .enumerate()
            {
                assert_eq!(r.trace.history_time.len(), 12_001);
                assert_eq!(bits(&time[row]), bits(&r.trace.history_time), "{row}");
                assert_eq!(bits(&x[row]), rounded(&r.trace.history[0]), "{row}");
                assert_eq!(bits(&v[row]), rounded(&r.trace.history[1]), "{row}");
                assert_eq!(bits(&strobe[row]), bits(&r.trace.strobe[0]), "{row}");
                assert_ne!(
                    bits(&x[row]),
                    bits(&r.trace.history[0]),
                    "{row}: nothing rounded"
                );
            }
        }
    }
    let st = without_sweep(&text);
    let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
    let file = hdf5::File::open(&out.file).unwrap();
    let r = st.run_single(&mut |_| {}).unwrap();
    assert_eq!(marked(&file), Some(20));
    for (name, want, mark) in [
        ("history/time", bits(&r.trace.history_time), None),
        ("history/x", rounded(&r.trace.history[0]), Some(20)),
        ("history/v", rounded(&r.trace.history[1]), Some(20)),
        ("sections/strobe/x", bits(&r.trace.strobe[0]), None),
    ] {
        let ds = file.dataset(name).unwrap();
        assert_eq!(bits(&ds.read_raw::<f64>().unwrap()), want, "{name}");
        assert_eq!(marked(&ds), mark, "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn histories_written_block_by_block_equal_those_of_a_run_kept_in_memory() {
    // 200 periods of 100 samples: 20 001 samples, more than two blocks of the file's writer
    // (jointplay_analysis::measures::sections::HISTORY_BLOCK), so every row is written in pieces while its
    // job runs. The file's rows must be the run's own histories, bit for bit.
    let text = DUFFING
        .replace("periods = 264", "periods = 200")
        .replace("transient = 200", "transient = 0")
        .replace("samples_per_period = 0", "samples_per_period = 100")
        .replace("values = [0.20, 0.28, 0.29, 0.50]", "values = [0.28, 0.5]");
    const { assert!(200 * 100 > 2 * jointplay_analysis::measures::sections::HISTORY_BLOCK) };
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for continuation in [false, true] {
        let st = study(&sweep_text(&text, continuation));
        let dir = tmp_dir(&format!("blocks-{continuation}"));
        let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
        let file = hdf5::File::open(&out.file).unwrap();
        let (time, x) = (
            read2(&file, "sweep/history/time"),
            read2(&file, "sweep/history/x"),
        );
        if !continuation {
            // Two shards merged: the rows are copied a block at a time.
            let m = hdf5::File::open(two_shards_merged(&st, &dir)).unwrap();
            for name in ["sweep/history/time", "sweep/history/x", "sweep/x"] {
                let (a, b) = (read2(&file, name), read2(&m, name));
                let same = a.iter().zip(&b).all(|(p, q)| bits(p) == bits(q));
                assert!(a.len() == b.len() && same, "{name} differs after the merge");
            }
        }
        for (row, r) in run_alone(&st, &[0.28, 0.5], continuation)
            .iter()
            .enumerate()
        {
            assert_eq!(r.trace.history_time.len(), 20_001);
            assert_eq!(bits(&time[row]), bits(&r.trace.history_time), "{row}");
            assert_eq!(bits(&x[row]), bits(&r.trace.history[0]), "{row}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    // The single run's histories: extendable datasets appended block by block.
    let st = without_sweep(&text);
    let dir = tmp_dir("blocks-single");
    let out = execute(&st, &dir, Options::default(), "test", &|_| {}).unwrap();
    let file = hdf5::File::open(&out.file).unwrap();
    let r = st.run_single(&mut |_| {}).unwrap();
    for (name, kept) in [
        ("history/time", &r.trace.history_time),
        ("history/v", &r.trace.history[1]),
    ] {
        let ds = file.dataset(name).unwrap();
        assert_eq!(bits(&ds.read_raw::<f64>().unwrap()), bits(kept), "{name}");
        assert!(
            ds.attr("unit").is_ok() && ds.attr("description").is_ok(),
            "{name}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
