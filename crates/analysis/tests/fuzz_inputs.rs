//! Mutation fuzzing of everything that reads user input: the scene parser and compiler (with the
//! initial assembly and a few integration steps of whatever compiles), the comparison-study
//! parser and the analysis-study parser.
//!
//! Every bundled scene and study is mutated many times, at the text level (deleted, duplicated,
//! swapped and truncated lines, random characters) and at the value level (a leaf replaced by an
//! extreme or non-finite number, a wrong type or an unknown name; a key removed; an element of an
//! array of tables duplicated, giving duplicate names). The test asserts that nothing panics and
//! that every error names the file it came from. The mutation stream is seeded, so a failure is
//! reproducible; the counts are printed (`--nocapture`). More cases:
//! `JOINTPLAY_FUZZ_CASES=20000 cargo test --release -p jointplay-analysis --test fuzz_inputs -- --nocapture`.
//!
//! The generator is a 64-bit xorshift written here rather than a property-testing crate: the
//! inputs are whole files mutated structurally, which needs no shrinking machinery, and the
//! stream stays identical across dependency versions.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use jointplay_analysis::study::analysis::{Loaded, is_analysis};
use jointplay_analysis::study::spec::Study;
use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::Model;
use jointplay_solver::ode::{Flow, Step, integrate_steps};
use jointplay_solver::scene::{SceneFile, SceneSpec};
use toml::{Table, Value};

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        // xorshift64* (Vigna, "An experimental exploration of Marsaglia's xorshift generators",
        // ACM TOMS 42, 2016).
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Cases per input file (each bundled scene and study).
fn cases() -> usize {
    std::env::var("JOINTPLAY_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

/// One step of the path to a leaf of a TOML tree.
#[derive(Clone, Debug)]
enum Key {
    Name(String),
    Index(usize),
}

fn leaves(v: &Value, path: &mut Vec<Key>, out: &mut Vec<Vec<Key>>) {
    match v {
        Value::Table(t) => {
            for (k, x) in t {
                path.push(Key::Name(k.clone()));
                leaves(x, path, out);
                path.pop();
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                path.push(Key::Index(i));
                leaves(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
    out.push(path.clone());
}

fn at<'a>(v: &'a mut Value, path: &[Key]) -> &'a mut Value {
    path.iter().fold(v, |v, k| match (k, v) {
        (Key::Name(n), Value::Table(t)) => t.get_mut(n).unwrap(),
        (Key::Index(i), Value::Array(a)) => &mut a[*i],
        _ => unreachable!("paths come from the tree"),
    })
}

const EXTREMES: [f64; 12] = [
    0.0,
    -0.0,
    -1.0,
    1e308,
    -1e308,
    5e-324,
    1e-300,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e30,
    -1e-12,
];

/// A value-level mutation of `text`, or None when it does not parse as TOML.
fn mutate_tree(text: &str, rng: &mut Rng) -> Option<String> {
    let mut root = Value::Table(text.parse::<Table>().ok()?);
    let mut all = Vec::new();
    leaves(&root, &mut Vec::new(), &mut all);
    let path = all[rng.below(all.len())].clone();
    match rng.below(8) {
        0..=2 => *at(&mut root, &path) = Value::Float(EXTREMES[rng.below(EXTREMES.len())]),
        3 => {
            *at(&mut root, &path) = match rng.below(5) {
                0 => Value::String("nope".into()),
                1 => Value::Integer(i64::MAX),
                2 => Value::Boolean(true),
                3 => Value::Array(vec![]),
                _ => Value::Table(Table::new()),
            }
        }
        4 | 5 => {
            // Remove the leaf from its parent.
            if let Some((last, parent)) = path.split_last() {
                match (last, at(&mut root, parent)) {
                    (Key::Name(n), Value::Table(t)) => {
                        t.remove(n);
                    }
                    (Key::Index(i), Value::Array(a)) => {
                        a.remove(*i);
                    }
                    _ => {}
                }
            }
        }
        6 => {
            // Duplicate an element of the nearest enclosing array (duplicate names).
            if let Some(p) = path.iter().rposition(|k| matches!(k, Key::Index(_)))
                && let (Key::Index(i), Value::Array(a)) = (&path[p], at(&mut root, &path[..p]))
            {
                let dup = a[*i].clone();
                a.push(dup);
            }
        }
        _ => {
            // A numeric leaf scaled by a large or tiny factor (keeps the type).
            if let Value::Float(x) = at(&mut root, &path) {
                *x *= [1e6, 1e-6, -1.0, 1e12][rng.below(4)];
            }
        }
    }
    toml::to_string(&root).ok()
}

/// A text-level mutation of `text`.
fn mutate_text(text: &str, rng: &mut Rng) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    if lines.is_empty() {
        return String::new();
    }
    let n = lines.len();
    match rng.below(6) {
        0 => {
            lines.remove(rng.below(n));
        }
        1 => {
            let l = lines[rng.below(n)].clone();
            lines.insert(rng.below(n), l);
        }
        2 => lines.swap(rng.below(n), rng.below(n)),
        3 => lines.truncate(rng.below(n)),
        4 => {
            let i = rng.below(n);
            let chars: Vec<char> = lines[i].chars().collect();
            let at = rng.below(chars.len() + 1);
            let junk = [
                "=", "[", "]", "\"", "{", "}", ",", "-", "e", "0", "\u{e9}", "#",
            ];
            let mut s: String = chars[..at].iter().collect();
            s.push_str(junk[rng.below(junk.len())]);
            s.extend(&chars[at..]);
            lines[i] = s;
        }
        _ => {
            let i = rng.below(n);
            let keep = rng.below(lines[i].len() + 1);
            let cut: String = lines[i].chars().take(keep).collect();
            lines[i] = cut;
        }
    }
    lines.join("\n")
}

/// Tallies of one input file's cases.
#[derive(Default, Debug)]
struct Tally {
    cases: usize,
    accepted: usize,
    rejected: usize,
    panics: Vec<String>,
    unnamed: Vec<String>,
}

/// Compiles a scene, assembles it and integrates a few steps: the whole path user input takes.
fn exercise_scene(text: &str, path: &Path) -> Result<(), String> {
    let spec = SceneSpec::parse(text, path).map_err(|e| e.to_string())?;
    let f = SceneFile {
        path: path.to_path_buf(),
        text: text.to_string(),
        spec,
    };
    let (model, mut state) = Model::compile(&f).map_err(|e| e.to_string())?;
    model.assemble(&mut state).map_err(|e| e.to_string())?;
    let mut sys = Mechanism::new(&model);
    let t0 = model.settings.start_time;
    // At most 20 steps: enough to exercise the right-hand side, the guards and the onsets.
    let mut steps = 0;
    let mut count = |_: &mut Mechanism, _: &Step| {
        steps += 1;
        if steps < 20 {
            Flow::Continue
        } else {
            Flow::Stop
        }
    };
    integrate_steps(
        &mut sys,
        model.settings.method,
        t0,
        &mut state.y,
        model.settings.end_time,
        &[],
        |_, _, _| Flow::Continue,
        Some(&mut count),
    )
    // The program names the scene file around a run's error, as here.
    .map_err(|e| format!("simulating {}: {e}", path.display()))?;
    Ok(())
}

fn exercise_study(text: &str, path: &Path) -> Result<(), String> {
    if is_analysis(text) {
        Loaded::parse(text, path)
            .map(|_| ())
            .map_err(|e| e.to_string())
    } else {
        Study::parse(text, path)
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

fn fuzz(file: &Path, seed: u64, exercise: fn(&str, &Path) -> Result<(), String>) -> Tally {
    let text = std::fs::read_to_string(file).unwrap();
    let name = file.file_name().unwrap().to_string_lossy().into_owned();
    let mut rng = Rng(seed | 1);
    let mut t = Tally::default();
    for _ in 0..cases() {
        let mut m = text.clone();
        for _ in 0..=rng.below(3) {
            m = if rng.below(3) == 0 {
                mutate_text(&m, &mut rng)
            } else {
                mutate_tree(&m, &mut rng).unwrap_or_else(|| mutate_text(&m, &mut rng))
            };
        }
        t.cases += 1;
        match catch_unwind(AssertUnwindSafe(|| exercise(&m, file))) {
            Ok(Ok(())) => t.accepted += 1,
            Ok(Err(e)) => {
                t.rejected += 1;
                // Every error names the file (or, for a study, the file of the scene it read).
                if !e.contains(&name) && !e.contains(".toml") {
                    t.unnamed.push(e);
                }
            }
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                t.panics.push(format!("{msg}\n--- input ---\n{m}"));
            }
        }
    }
    t
}

fn report(label: &str, tallies: &[(PathBuf, Tally)]) {
    let total: usize = tallies.iter().map(|t| t.1.cases).sum();
    println!("{label}: {total} mutated inputs");
    for (f, t) in tallies {
        println!(
            "  {}: {} cases, {} accepted, {} rejected with an error, {} panics",
            f.display(),
            t.cases,
            t.accepted,
            t.rejected,
            t.panics.len()
        );
    }
    for (f, t) in tallies {
        assert!(
            t.panics.is_empty(),
            "{}: {} panics; first:\n{}",
            f.display(),
            t.panics.len(),
            t.panics[0]
        );
        assert!(
            t.unnamed.is_empty(),
            "{}: errors that do not name the file: {:?}",
            f.display(),
            &t.unnamed[..t.unnamed.len().min(3)]
        );
        // The mutations must reach both outcomes, or they test nothing.
        assert!(t.rejected > 0, "{}: nothing rejected", f.display());
    }
}

#[test]
fn mutated_scenes_never_panic_and_every_error_names_the_file() {
    // Silence the default hook: caught panics are reported by the test itself.
    std::panic::set_hook(Box::new(|_| {}));
    let dir = root().join("data/scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    let tallies: Vec<(PathBuf, Tally)> = files
        .iter()
        .enumerate()
        .map(|(i, f)| {
            (
                f.clone(),
                fuzz(f, 0x9E37_79B9_7F4A_7C15 ^ i as u64, exercise_scene),
            )
        })
        .collect();
    let _ = std::panic::take_hook();
    report("scenes", &tallies);
}

#[test]
fn mutated_studies_never_panic_and_every_error_names_the_file() {
    std::panic::set_hook(Box::new(|_| {}));
    let mut files = Vec::new();
    for d in ["analyses/4ups-rpu", "analyses/duffing"] {
        for e in std::fs::read_dir(root().join(d)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                files.push(p);
            }
        }
    }
    files.sort();
    let tallies: Vec<(PathBuf, Tally)> = files
        .iter()
        .enumerate()
        .map(|(i, f)| {
            (
                f.clone(),
                fuzz(f, 0xD1B5_4A32_D192_ED03 ^ i as u64, exercise_study),
            )
        })
        .collect();
    let _ = std::panic::take_hook();
    report("studies", &tallies);
}
