//! Durable results, end to end through the program (book/src/explanation/durability.md): a sweep's journal
//! survives the end of its process and a damaged record of it is computed again; a value whose
//! row in the file does not match its checksum is computed again; a second writer is refused
//! before it touches anything. The kills themselves are in `scripts/crash-test`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_jointplay"))
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A sweep of 6 Duffing values with histories and a section: a fraction of a second.
const STUDY: &str = r#"
[study]
name = "durable"
system = { kind = "duffing", gamma = 0.3, initial = [1.0, 0.0], solver = { rtol = 1e-9 } }
[analysis]
periods = 40
transient = 20
samples_per_period = 20
history_periods = 4
[[observables]]
name = "x"
path = "x"
[[observables]]
name = "v"
path = "v"
[[sections]]
name = "turn"
terms = { v = 1.0 }
value = 0.0
[sweep]
parameter = "gamma"
from = 0.2
to = 0.5
count = 6
"#;

fn study(dir: &Path) -> PathBuf {
    let p = dir.join("durable.toml");
    std::fs::write(&p, STUDY).unwrap();
    p
}

fn run(study: &Path, out: &Path, extra: &[&str]) -> Output {
    bin()
        .arg("run")
        .arg(study)
        .args(["--no-plots", "-q", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// Every dataset under `/sweep` but the wall times, as raw bytes.
fn sweep_data(file: &Path) -> Vec<(String, Vec<u8>)> {
    let f = hdf5::File::open(file).unwrap();
    let mut out = Vec::new();
    let mut names = vec![];
    let g = f.group("sweep").unwrap();
    for n in g.member_names().unwrap() {
        if g.dataset(&n).is_ok() {
            names.push(n);
        }
    }
    for n in ["history/time", "history/x", "history/v"] {
        names.push(n.into());
    }
    for n in names {
        if n == "wall_time" {
            continue;
        }
        let ds = g.dataset(&n).unwrap();
        let bytes = match ds.dtype().unwrap().size() {
            8 => ds
                .read_raw::<u64>()
                .unwrap()
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect(),
            4 => ds
                .read_raw::<u32>()
                .unwrap()
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect(),
            _ => ds.read_raw::<u8>().unwrap(),
        };
        out.push((n, bytes));
    }
    out
}

fn ran_now(stdout: &str) -> usize {
    let i = stdout.find(" run now").expect(stdout);
    stdout[..i]
        .rsplit(' ')
        .next()
        .unwrap()
        .trim_end_matches(';')
        .parse()
        .unwrap()
}

#[test]
fn a_stopped_sweep_keeps_its_journal_and_a_damaged_record_is_computed_again() {
    let dir = tempfile::tempdir().unwrap();
    let st = study(dir.path());
    let full = dir.path().join("full");
    assert!(run(&st, &full, &[]).status.success());
    assert!(
        !full.join("durable.journal").exists(),
        "a complete sweep ends its journal"
    );
    let part = dir.path().join("part");
    let o = run(&st, &part, &["--max-jobs", "4"]);
    assert!(o.status.success(), "{:?}", text(&o));
    let journal = part.join("durable.journal");
    let mut bytes = std::fs::read(&journal).unwrap();
    // Damage the last byte of the journal: the last value record fails its check.
    let n = bytes.len();
    bytes[n - 1] ^= 0x5a;
    std::fs::write(&journal, &bytes).unwrap();
    // The file written at the stop holds the 4 values too, each checked against its checksum:
    // the damaged record's value is kept from it.
    let o = run(&st, &part, &["--resume", "--max-jobs", "0"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(se.contains("skipped"), "{se}");
    assert_eq!(ran_now(&so), 0, "{so}");
    // Without the file (a kill before it was written), the journal alone.
    std::fs::remove_file(part.join("durable.h5")).unwrap();
    std::fs::write(&journal, &bytes).unwrap();
    let o = run(&st, &part, &["--resume"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(se.contains("skipped"), "{se}");
    // 6 values, 3 kept: the damaged one is computed again with the 2 never run.
    assert_eq!(ran_now(&so), 3, "{so}");
    assert_eq!(
        sweep_data(&part.join("durable.h5")),
        sweep_data(&full.join("durable.h5"))
    );
}

#[test]
fn a_row_that_does_not_match_its_checksum_is_computed_again() {
    let dir = tempfile::tempdir().unwrap();
    let st = study(dir.path());
    let out = dir.path().join("o");
    assert!(run(&st, &out, &[]).status.success());
    let file = out.join("durable.h5");
    let good = sweep_data(&file);
    {
        // A value falsified in place: row 2 of the strobe points.
        let f = hdf5::File::open_rw(&file).unwrap();
        let ds = f.dataset("sweep/x").unwrap();
        let mut v = ds.read_2d::<f64>().unwrap();
        v[[2, 0]] += 1e-12;
        ds.write(&v).unwrap();
    }
    let o = run(&st, &out, &["--resume"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}{se}");
    assert!(
        se.contains("row 2: its data do not match its checksum; computed again"),
        "{se}"
    );
    assert_eq!(ran_now(&so), 1, "{so}");
    assert_eq!(sweep_data(&file), good);
}

#[test]
fn a_second_writer_is_refused_before_it_touches_anything() {
    let dir = tempfile::tempdir().unwrap();
    let st = study(dir.path());
    let out = dir.path().join("o");
    std::fs::create_dir_all(&out).unwrap();
    // Another writer holds the output's lock (a lock of its own open file, as another process).
    let lock = std::fs::File::create(out.join("durable.h5.lock")).unwrap();
    lock.try_lock().unwrap();
    std::fs::write(out.join("durable.h5.lock"), "31337\n").unwrap();
    std::fs::write(out.join("durable.h5"), b"the other writer's file").unwrap();
    for extra in [&[][..], &["--resume"][..]] {
        let o = run(&st, &out, extra);
        let (so, se) = text(&o);
        assert!(!o.status.success(), "{so}{se}");
        assert!(se.contains("process 31337 is writing this output"), "{se}");
    }
    let o = bin()
        .arg("merge")
        .arg(out.join("durable.shard-0-of-2.h5"))
        .arg("--out")
        .arg(out.join("durable.h5"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let mut left: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["durable.h5", "durable.h5.lock"]);
    assert_eq!(
        std::fs::read(out.join("durable.h5")).unwrap(),
        b"the other writer's file"
    );
    drop(lock);
    assert!(run(&st, &out, &[]).status.success());
}

fn read_f64s(file: &Path, name: &str) -> Vec<f64> {
    let f = hdf5::File::open(file).unwrap();
    f.dataset(name).unwrap().read_raw::<f64>().unwrap()
}

fn attr_u8(file: &Path, name: &str) -> Option<u8> {
    let f = hdf5::File::open(file).unwrap();
    f.attr(name).and_then(|a| a.read_scalar::<u8>()).ok()
}

/// A scene run stopped by SIGINT exits with status 130 and keeps a file marked interrupted, and
/// `--from` that file (into another directory) ends where the run never stopped would have: the
/// same final state, bit for bit, and the samples the first part lacks. `--from` into the
/// directory of the file it continues is refused: it would replace the run's first part.
#[test]
fn a_run_stopped_by_sigint_is_continued_with_from_to_the_uninterrupted_end() {
    let dir = tempfile::tempdir().unwrap();
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/crash/run.toml");
    let (whole, part, rest) = (
        dir.path().join("whole"),
        dir.path().join("part"),
        dir.path().join("rest"),
    );
    let started = std::time::Instant::now();
    let o = bin()
        .arg("run")
        .arg(&scene)
        .args(["--no-plots", "-q", "--out"])
        .arg(&whole)
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    let wall = started.elapsed();
    // Stopped part-way: at 40% of the uninterrupted run's wall time, or earlier if the machine
    // got faster and the run finished first.
    let mut stopped = None;
    for fraction in [0.4, 0.2, 0.1] {
        let _ = std::fs::remove_dir_all(&part);
        let child = bin()
            .arg("run")
            .arg(&scene)
            .args(["--no-plots", "-q", "--out"])
            .arg(&part)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(wall.mul_f64(fraction));
        Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        let o = child.wait_with_output().unwrap();
        if o.status.success() {
            continue; // finished before the signal
        }
        assert_eq!(o.status.code(), Some(130), "{:?}", text(&o));
        let (_, err) = text(&o);
        assert!(err.contains("--from"), "{err}");
        stopped = Some(o);
        break;
    }
    assert!(stopped.is_some(), "the run always finished before SIGINT");
    let first = part.join("crash-run.h5");
    assert_eq!(attr_u8(&first, "complete"), Some(0));
    assert_eq!(attr_u8(&first, "interrupted"), Some(1));

    // Continuing into the directory of the file continued would replace it: refused.
    let o = bin()
        .arg("run")
        .arg(&scene)
        .args(["--no-plots", "-q", "--out"])
        .arg(&part)
        .arg("--from")
        .arg(&first)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    assert!(text(&o).1.contains("another --out"), "{:?}", text(&o));
    assert_eq!(
        attr_u8(&first, "interrupted"),
        Some(1),
        "the first part is kept"
    );

    let o = bin()
        .arg("run")
        .arg(&scene)
        .args(["--no-plots", "-q", "--out"])
        .arg(&rest)
        .arg("--from")
        .arg(&first)
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    let second = rest.join("crash-run.h5");
    let reference = whole.join("crash-run.h5");
    assert_eq!(attr_u8(&second, "complete"), Some(1));
    assert_eq!(
        read_f64s(&second, "final_state"),
        read_f64s(&reference, "final_state"),
        "the continued run ends where the run never stopped ends"
    );
    let (a, b) = (read_f64s(&first, "time"), read_f64s(&second, "time"));
    let whole = read_f64s(&reference, "time");
    let joined: Vec<f64> = a.iter().chain(&b).copied().collect();
    let differ = joined.iter().zip(&whole).position(|(x, y)| x != y);
    assert!(
        joined.len() == whole.len() && differ.is_none(),
        "samples: {} + {} against {}; first difference at {differ:?}; the first part ends at \
         {:?}, the second starts at {:?}",
        a.len(),
        b.len(),
        whole.len(),
        a.last(),
        b.first()
    );
}
