//! Sweeps split into shards: separate processes (by `--shard` or by Slurm's array variables),
//! their merge into the file one process writes, the merge's refusals, `--partial` with
//! `--resume`, and the Slurm batch scripts (submitted to a stand-in `sbatch`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hdf5::types::{TypeDescriptor, VarLenUnicode};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_jointplay"));
    // The test process opens run files while other tests spawn the program;
    // HDF5 opens files without close-on-exec, so a child spawned at that
    // moment inherits the descriptor and its lock and holds it until it exits.
    // A program run that writes the same file would then fail to lock it
    // (errno 11). The tests run the program without HDF5's advisory locks.
    c.env("HDF5_USE_FILE_LOCKING", "FALSE");
    // The tests set Slurm's variables themselves where they want them.
    for v in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_COUNT",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_MAX",
        "SLURM_CPUS_PER_TASK",
    ] {
        c.env_remove(v);
    }
    c
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Seven values of the Duffing cascade, with a hyperplane section (copied per job by the merge).
const SWEEP: &str = r#"
[study]
name = "duffing-shards"
system = { kind = "duffing", gamma = 0.2, initial = [1.0, 0.0] }
[analysis]
periods = 30
transient = 20
samples_per_period = 20
[[observables]]
name = "x"
path = "x"
[[observables]]
name = "v"
path = "v"
[[sections]]
name = "turn"
terms = { v = 1.0 }
direction = "down"
[sweep]
parameter = "gamma"
values = [0.2, 0.25, 0.28, 0.29, 0.3, 0.37, 0.5]
"#;

const NAME: &str = "duffing-shards";

struct Setup {
    dir: tempfile::TempDir,
    study: PathBuf,
}

impl Setup {
    fn new(text: &str) -> Setup {
        let dir = tempfile::tempdir().unwrap();
        let study = dir.path().join("sweep.toml");
        std::fs::write(&study, text).unwrap();
        Setup { dir, study }
    }

    fn path(&self, rel: &str) -> PathBuf {
        self.dir.path().join(rel)
    }

    /// `jointplay run STUDY --out DIR -q --no-plots ARGS`, which must succeed.
    fn run(&self, out: &str, args: &[&str]) -> String {
        let o = self.run_env(out, args, &[]);
        let (so, se) = text(&o);
        assert!(o.status.success(), "{args:?}: {so}\n{se}");
        so
    }

    fn run_env(&self, out: &str, args: &[&str], env: &[(&str, &str)]) -> Output {
        bin()
            .arg("run")
            .arg(&self.study)
            .arg("--out")
            .arg(self.path(out))
            .args(["-q", "--no-plots"])
            .args(args)
            .envs(env.iter().copied())
            .output()
            .unwrap()
    }

    fn shard(&self, out: &str, i: usize, n: usize) -> PathBuf {
        self.path(out).join(format!("{NAME}.shard-{i}-of-{n}.h5"))
    }

    fn merge(&self, files: &[PathBuf], out: &Path, args: &[&str]) -> Output {
        bin()
            .arg("merge")
            .args(files)
            .arg("--out")
            .arg(out)
            .args(args)
            .output()
            .unwrap()
    }
}

/// The content of an attribute or dataset: its type, shape and values (floats bit for bit).
fn content(c: &hdf5::Container) -> String {
    let d = c.dtype().unwrap().to_descriptor().unwrap();
    let v = match &d {
        TypeDescriptor::Float(_) => format!(
            "{:?}",
            c.read_raw::<f64>()
                .unwrap()
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        ),
        TypeDescriptor::Unsigned(_) => format!("{:?}", c.read_raw::<u64>().unwrap()),
        TypeDescriptor::Integer(_) => format!("{:?}", c.read_raw::<i64>().unwrap()),
        TypeDescriptor::VarLenUnicode => format!(
            "{:?}",
            c.read_raw::<VarLenUnicode>()
                .unwrap()
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
        ),
        other => panic!("unexpected HDF5 type {other:?}"),
    };
    format!("{d:?} {:?} {v}", c.shape())
}

fn attrs(loc: &hdf5::Location, path: &str, out: &mut BTreeMap<String, String>) {
    for a in loc.attr_names().unwrap() {
        // Wall-clock times are the only values that differ between identical computations.
        let v = if a.contains("wall") {
            "(wall time)".to_string()
        } else {
            content(&loc.attr(&a).unwrap())
        };
        out.insert(format!("{path}@{a}"), v);
    }
}

/// Every group, dataset and attribute under `g` with its content.
fn tree(g: &hdf5::Group, prefix: &str, out: &mut BTreeMap<String, String>) {
    attrs(g, prefix, out);
    for name in g.member_names().unwrap() {
        let path = format!("{prefix}/{name}");
        if let Ok(sub) = g.group(&name) {
            out.insert(path.clone(), "group".into());
            tree(&sub, &path, out);
        } else {
            let ds = g.dataset(&name).unwrap();
            let v = if name.contains("wall") {
                format!("{:?} (wall times)", ds.shape())
            } else {
                content(&ds)
            };
            out.insert(path.clone(), v);
            attrs(&ds, &path, out);
        }
    }
}

/// Asserts that two files hold the same groups, datasets and attributes, bit for bit (wall
/// times aside).
fn assert_same(a: &Path, b: &Path) {
    let (mut ta, mut tb) = (BTreeMap::new(), BTreeMap::new());
    tree(&hdf5::File::open(a).unwrap(), "", &mut ta);
    tree(&hdf5::File::open(b).unwrap(), "", &mut tb);
    let diff: Vec<String> = ta
        .keys()
        .chain(tb.keys())
        .filter(|k| ta.get(*k) != tb.get(*k))
        .map(|k| {
            let cut = |s: Option<&String>| {
                s.map(|s| s.chars().take(160).collect::<String>())
                    .unwrap_or_else(|| "(absent)".into())
            };
            format!("{k}: {} | {}", cut(ta.get(k)), cut(tb.get(k)))
        })
        .collect();
    assert!(
        diff.is_empty(),
        "{} and {} differ:\n{}",
        a.display(),
        b.display(),
        diff.join("\n")
    );
    assert!(ta.len() > 40, "{ta:?}");
}

fn attr_u8(file: &Path, name: &str) -> u8 {
    hdf5::File::open(file)
        .unwrap()
        .attr(name)
        .unwrap()
        .read_scalar()
        .unwrap()
}

fn done(file: &Path) -> Vec<u8> {
    hdf5::File::open(file)
        .unwrap()
        .dataset("sweep/done")
        .unwrap()
        .read_raw()
        .unwrap()
}

#[test]
fn shards_run_as_separate_processes_merge_into_the_single_process_file() {
    let s = Setup::new(SWEEP);
    s.run("single", &[]);
    let single = s.path("single").join(format!("{NAME}.h5"));
    // Three processes with --shard.
    let mut files = Vec::new();
    for i in 0..3 {
        let so = s.run("sh", &["--shard", &format!("{i}/3")]);
        assert!(so.contains(&format!("shard        {i}/3")), "{so}");
        files.push(s.shard("sh", i, 3));
    }
    // Shard 0 holds values 0, 3 and 6 in its rows, and says which.
    {
        let f = hdf5::File::open(&files[0]).unwrap();
        let jobs: Vec<u64> = f.dataset("sweep/job").unwrap().read_raw().unwrap();
        assert_eq!(jobs, [0, 3, 6]);
        let p: Vec<f64> = f.dataset("sweep/parameter").unwrap().read_raw().unwrap();
        assert_eq!(p, [0.2, 0.29, 0.5]);
        assert_eq!(f.attr("complete").unwrap().read_scalar::<u8>().unwrap(), 1);
    }
    let merged = s.path("sh").join(format!("{NAME}.h5"));
    let o = s.merge(&files, &merged, &[]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}\n{se}");
    assert!(
        so.contains("merged       3 shard files of 3 into 7 values"),
        "{so}"
    );
    assert!(so.contains("s per value on average"), "{so}");
    assert!(
        s.path("sh")
            .join(format!("{NAME}-bifurcation-x.svg"))
            .exists()
    );
    assert_same(&single, &merged);
    // The merge writes the sweep's table too, the single process's to the byte.
    for ext in ["md", "csv"] {
        assert_eq!(
            std::fs::read(merged.with_extension(ext)).unwrap(),
            std::fs::read(single.with_extension(ext)).unwrap(),
            "{ext}"
        );
    }

    // The same split taken from Slurm's array variables (an array numbered from 10), with the
    // threads from SLURM_CPUS_PER_TASK.
    let mut files = Vec::new();
    for id in 10..13 {
        let id = id.to_string();
        let o = s.run_env(
            "slurm",
            &[],
            &[
                ("SLURM_ARRAY_TASK_ID", &id),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
                ("SLURM_ARRAY_TASK_MIN", "10"),
                ("SLURM_ARRAY_TASK_MAX", "12"),
                ("SLURM_CPUS_PER_TASK", "1"),
            ],
        );
        assert!(o.status.success(), "{:?}", text(&o));
    }
    for i in 0..3 {
        files.push(s.shard("slurm", i, 3));
    }
    let merged2 = s.path("slurm").join(format!("{NAME}.h5"));
    let o = s.merge(&files, &merged2, &["--no-plots"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_same(&single, &merged2);
}

/// A sweep's file, its shards and their merge are written in the HDF5 format asked for: the
/// superblock's version (the byte after the signature) is 3 in the 1.10 format (the default),
/// 0 in the oldest (`--hdf5-format 1.8`); the merged file of 1.8 shards equals the 1.10 one.
#[test]
fn sweeps_shards_and_merges_keep_the_hdf5_format_asked_for() {
    let s = Setup::new(SWEEP);
    let superblock = |p: &Path| std::fs::read(p).unwrap()[8];
    s.run("new", &[]);
    let new = s.path("new").join(format!("{NAME}.h5"));
    assert_eq!(superblock(&new), 3);
    let mut files = Vec::new();
    for i in 0..2 {
        let o = bin()
            .args(["--hdf5-format", "1.8", "run"])
            .arg(&s.study)
            .arg("--out")
            .arg(s.path("old"))
            .args(["-q", "--no-plots", "--shard", &format!("{i}/2")])
            .output()
            .unwrap();
        assert!(o.status.success(), "{:?}", text(&o));
        files.push(s.shard("old", i, 2));
        assert_eq!(superblock(&files[i]), 0);
    }
    let merged = s.path("old").join(format!("{NAME}.h5"));
    let o = bin()
        .args(["--hdf5-format", "1.8", "merge"])
        .args(&files)
        .arg("--out")
        .arg(&merged)
        .arg("--no-plots")
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    assert_eq!(superblock(&merged), 0);
    assert_same(&new, &merged);
}

#[test]
fn a_merge_with_a_shard_missing_or_of_another_study_refuses() {
    let s = Setup::new(SWEEP);
    for i in [0, 2] {
        s.run("sh", &["--shard", &format!("{i}/3")]);
    }
    let out = s.path("sh").join(format!("{NAME}.h5"));
    let files = [s.shard("sh", 0, 3), s.shard("sh", 2, 3)];
    let o = s.merge(&files, &out, &[]);
    let (_, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{se}");
    assert!(!se.contains("panicked"), "{se}");
    for what in [
        "not written: 2 of 7 values are missing or failed",
        "shard 1/3: no file given",
        "gamma = 0.25, 0.3",
        "--shard 1/3 --resume",
        "--partial",
    ] {
        assert!(se.contains(what), "expected '{what}' in: {se}");
    }
    assert!(!out.exists());
    assert!(!s.path("sh").join(format!("{NAME}.h5.partial")).exists());

    // Shard 1 of an edited study text.
    std::fs::write(
        &s.study,
        SWEEP.replace(
            "samples_per_period = 20",
            "samples_per_period = 20 # edited",
        ),
    )
    .unwrap();
    s.run("sh", &["--shard", "1/3"]);
    let all = [files[0].clone(), s.shard("sh", 1, 3), files[1].clone()];
    let o = s.merge(&all, &out, &[]);
    let (_, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{se}");
    assert!(
        se.contains("shard-1-of-3.h5") && se.contains("another study text"),
        "{se}"
    );
    assert!(!out.exists());

    // A shard of another program version.
    let other = s.path("other.shard.h5");
    std::fs::copy(&files[1], &other).unwrap();
    {
        let f = hdf5::File::open_rw(&other).unwrap();
        let v: VarLenUnicode = "0.0.9".parse().unwrap();
        f.attr("program_version").unwrap().write_scalar(&v).unwrap();
    }
    let o = s.merge(&[files[0].clone(), other.clone()], &out, &[]);
    let (_, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{se}");
    assert!(
        se.contains("other.shard.h5") && se.contains("jointplay 0.0.9"),
        "{se}"
    );

    // The output among the inputs, a shard twice, a file that is not a shard.
    let o = s.merge(&files, &files[1], &[]);
    let (_, se) = text(&o);
    assert!(se.contains("the output is one of the shard files"), "{se}");
    let o = s.merge(&[files[0].clone(), files[0].clone()], &out, &[]);
    let (_, se) = text(&o);
    assert!(se.contains("shard 0/3 is given twice"), "{se}");
    s.run("whole", &[]);
    let whole = s.path("whole").join(format!("{NAME}.h5"));
    let o = s.merge(&[whole], &out, &[]);
    let (_, se) = text(&o);
    assert!(se.contains("not a shard file"), "{se}");
    assert!(!out.exists());
}

#[test]
fn an_interrupted_shard_resumes_and_a_partial_merge_is_finished_by_resume() {
    let s = Setup::new(SWEEP);
    s.run("single", &[]);
    let single = s.path("single").join(format!("{NAME}.h5"));
    // Shard 1 stops after one of its two values; the merge names what it lacks.
    let so = s.run("sh", &["--shard", "1/3", "--max-jobs", "1"]);
    assert!(so.contains("--resume --shard 1/3"), "{so}");
    let s1 = s.shard("sh", 1, 3);
    assert_eq!(attr_u8(&s1, "complete"), 0);
    s.run("sh", &["--shard", "0/3"]);
    let files = [s.shard("sh", 0, 3), s1.clone()];
    let out = s.path("sh").join(format!("{NAME}.h5"));
    let o = s.merge(&files, &out, &[]);
    let (_, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{se}");
    assert!(
        se.contains("shard 1/3: 1 of its 2 values not run") && se.contains("shard 2/3: no file"),
        "{se}"
    );
    // --partial writes what there is, the rest not done; run --resume finishes the file.
    let o = s.merge(&files, &out, &["--partial", "--no-plots"]);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}\n{se}");
    assert!(so.contains("3 values written as not done"), "{so}");
    assert_eq!(attr_u8(&out, "complete"), 0);
    assert_eq!(
        done(&out).iter().filter(|&&d| d == 1).count(),
        4,
        "{:?}",
        done(&out)
    );
    let so = s.run("sh", &["--resume"]);
    assert!(so.contains("3 run now"), "{so}");
    assert_same(&single, &out);

    // The interrupted shard resumes with only its missing value, and merges with the others.
    let so = s.run("sh", &["--shard", "1/3", "--resume"]);
    assert!(so.contains("1 run now"), "{so}");
    assert_eq!(done(&s1), [1, 1]);
    s.run("sh", &["--shard", "2/3"]);
    let all: Vec<PathBuf> = (0..3).map(|i| s.shard("sh", i, 3)).collect();
    let merged = s.path("merged.h5");
    let o = s.merge(&all, &merged, &["--no-plots"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_same(&single, &merged);
}

#[test]
fn bad_shards_get_clear_errors() {
    let s = Setup::new(SWEEP);
    let err = |args: &[&str], env: &[(&str, &str)]| {
        let o = s.run_env("out", args, env);
        let (_, se) = text(&o);
        assert_ne!(o.status.code(), Some(0), "{args:?}");
        assert!(!se.contains("panicked"), "{se}");
        se
    };
    let se = err(&["--shard", "3/3"], &[]);
    assert!(
        se.contains("3/3: the shard index must be less than"),
        "{se}"
    );
    let se = err(&["--shard", "0/0"], &[]);
    assert!(
        se.contains("the number of shards must be at least 1"),
        "{se}"
    );
    let se = err(&["--shard", "two/3"], &[]);
    assert!(se.contains("'two' is not a whole number"), "{se}");
    let se = err(&["--shard", "0/8"], &[]);
    assert!(
        se.contains("sweep.toml: sweep: 8 shards for 7 values"),
        "{se}"
    );
    let se = err(
        &[],
        &[
            ("SLURM_ARRAY_TASK_ID", "4"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "6"),
        ],
    );
    assert!(se.contains("not one contiguous range"), "{se}");
    let se = err(
        &[],
        &[
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
            ("SLURM_CPUS_PER_TASK", "0"),
        ],
    );
    assert!(se.contains("SLURM_CPUS_PER_TASK='0'"), "{se}");
    // A continuation sweep runs in order in one process.
    std::fs::write(
        &s.study,
        SWEEP.replace("values = [", "continuation = true\nvalues = ["),
    )
    .unwrap();
    let se = err(&["--shard", "0/2"], &[]);
    assert!(
        se.contains("sweep.toml: sweep.continuation: a continuation sweep cannot be split"),
        "{se}"
    );
    let se = err(
        &[],
        &[
            ("SLURM_ARRAY_TASK_ID", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ],
    );
    assert!(
        se.contains("SLURM_ARRAY_TASK_ID") && se.contains("cannot be split"),
        "{se}"
    );
    assert!(!s.path("out").exists() || std::fs::read_dir(s.path("out")).unwrap().next().is_none());
}

/// A stand-in for Slurm's `sbatch`: logs its arguments and prints job ids 41, 42, ...
fn fake_sbatch(dir: &Path) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let bin = dir.join("fakebin");
    std::fs::create_dir_all(&bin).unwrap();
    let script = bin.join("sbatch");
    std::fs::write(
        &script,
        format!(
            "#!/bin/sh\necho \"$@\" >> {log}\nn=$(wc -l < {log})\necho $((40 + n))\n",
            log = dir.join("sbatch.log").display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    bin
}

#[test]
fn slurm_writes_an_array_and_a_merge_script_and_submits_them() {
    let s = Setup::new(SWEEP);
    let slurm = |args: &[&str], path: Option<&Path>| {
        let mut c = bin();
        c.current_dir(s.dir.path())
            .args(["slurm", "sweep.toml", "--out", "cluster"])
            .args(args);
        if !args.contains(&"--shards") {
            c.args(["--shards", "3"]);
        }
        if let Some(p) = path {
            let old = std::env::var("PATH").unwrap_or_default();
            c.env("PATH", format!("{}:{old}", p.display()));
        }
        c.output().unwrap()
    };
    let o = slurm(&["--max-running", "2", "--time", "00:10:00"], None);
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}\n{se}");
    assert!(
        so.contains("array=$(sbatch --parsable cluster/duffing-shards.slurm-array.sh)")
            && so.contains(
                "sbatch --dependency=afterok:${array%%;*} cluster/duffing-shards.slurm-merge.sh"
            ),
        "{so}"
    );
    let array = std::fs::read_to_string(s.path("cluster/duffing-shards.slurm-array.sh")).unwrap();
    for line in [
        "#SBATCH --array=0-2%2",
        "#SBATCH --time=00:10:00",
        "#SBATCH --cpus-per-task=1",
    ] {
        assert!(array.lines().any(|l| l == line), "{line}: {array}");
    }
    assert!(
        array.contains("run sweep.toml --out cluster --shard \"$SLURM_ARRAY_TASK_ID/3\" --resume"),
        "{array}"
    );
    let merge = std::fs::read_to_string(s.path("cluster/duffing-shards.slurm-merge.sh")).unwrap();
    assert!(
        merge.contains(
            "merge cluster/duffing-shards.shard-*-of-3.h5 --out cluster/duffing-shards.h5"
        ),
        "{merge}"
    );

    // The array script runs as a task would (its shard from the command line), and the merge
    // script merges what the tasks wrote.
    for id in 0..3 {
        let o = Command::new("bash")
            .arg(s.path("cluster/duffing-shards.slurm-array.sh"))
            .current_dir(s.dir.path())
            .env("SLURM_ARRAY_TASK_ID", id.to_string())
            .output()
            .unwrap();
        assert!(o.status.success(), "{:?}", text(&o));
    }
    let o = Command::new("bash")
        .arg(s.path("cluster/duffing-shards.slurm-merge.sh"))
        .current_dir(s.dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    // The single process from the same directory with the same study path (the file records
    // the path as given).
    let o = bin()
        .current_dir(s.dir.path())
        .args(["run", "sweep.toml", "--out", "single", "-q", "--no-plots"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}", text(&o));
    assert_same(
        &s.path("single").join(format!("{NAME}.h5")),
        &s.path("cluster").join(format!("{NAME}.h5")),
    );

    // --submit: the array, then the merge after it.
    let fake = fake_sbatch(s.dir.path());
    let o = slurm(&["--submit"], Some(&fake));
    let (so, se) = text(&o);
    assert!(o.status.success(), "{so}\n{se}");
    assert!(so.contains("array job    41 (3 tasks)"), "{so}");
    assert!(so.contains("merge job    42"), "{so}");
    let log = std::fs::read_to_string(s.path("sbatch.log")).unwrap();
    assert_eq!(
        log.lines().collect::<Vec<_>>(),
        [
            "--parsable cluster/duffing-shards.slurm-array.sh",
            "--parsable --dependency=afterok:41 cluster/duffing-shards.slurm-merge.sh",
        ]
    );

    // Refusals before anything is written or submitted.
    for (args, what) in [
        (&["--shards", "0"][..], "at least 1"),
        (&["--shards", "9"][..], "9 shards for 7 values"),
        (&["--max-running", "0"][..], "--max-running"),
        (&["--mem", "4 G"][..], "--mem '4 G'"),
    ] {
        let o = slurm(args, None);
        let (_, se) = text(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {se}");
        assert!(se.contains(what), "{what}: {se}");
    }
}

/// The study of `s` run as two shards (as separate processes) and merged, shards out of order:
/// the merged file equals `single` dataset by dataset.
fn two_shards_merge_into(s: &Setup, single: &Path) {
    for i in 0..2 {
        s.run("sh", &["--shard", &format!("{i}/2")]);
    }
    let merged = s.path("merged.h5");
    let o = s.merge(
        &[s.shard("sh", 1, 2), s.shard("sh", 0, 2)],
        &merged,
        &["--no-plots"],
    );
    assert!(o.status.success(), "{:?}", text(&o));
    assert_same(single, &merged);
}

#[test]
fn a_mechanism_sweep_with_contacts_merges_bit_for_bit() {
    // The clearance slider-crank over three bushing radii: rows of contact onsets and guard
    // flags, and hyperplane crossings, besides the observables.
    let scene =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/scenes/slider-crank-clearance.toml");
    let s = Setup::new(&format!(
        r#"
[study]
name = "{NAME}"
scene = "{}"
[analysis]
periods = 4
transient = 2
samples_per_period = 20
[[observables]]
name = "slider_vx"
path = "bodies.slider.velocity.x"
[[observables]]
name = "pin_ex"
path = "joints.piston_pin.eccentricity_global.x"
[[sections]]
name = "dead_point"
terms = {{ slider_vx = 1.0 }}
direction = "down"
[sweep]
parameter = "joints.piston_pin.clearance.bushing_radius"
unit = "m"
values = [0.0097, 0.0099, 0.0100]
"#,
        scene.display()
    ));
    s.run("single", &[]);
    let single = s.path("single").join(format!("{NAME}.h5"));
    {
        let f = hdf5::File::open(&single).unwrap();
        assert_eq!(f.dataset("sweep/final_warned").unwrap().shape(), [3, 1]);
        assert_eq!(f.dataset("sweep/final_onset").unwrap().shape(), [3, 1]);
        assert_eq!(
            f.group("sweep/sections")
                .unwrap()
                .member_names()
                .unwrap()
                .len(),
            3
        );
    }
    two_shards_merge_into(&s, &single);
}

#[test]
fn a_lugre_sweep_merges_bit_for_bit() {
    // The forced LuGre block over its bristles' stiffness: the bristle deflections are part of
    // each value's final state and recorded as observables.
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data/scenes/variants/lugre-stick-slip-forced.toml");
    let s = Setup::new(&format!(
        r#"
[study]
name = "{NAME}"
scene = "{}"
[analysis]
periods = 2
transient = 1
samples_per_period = 20
[[observables]]
name = "x"
path = "bodies.block.position.x"
[[observables]]
name = "z"
path = "joints.floor.bristle.front_lower_x"
[sweep]
parameter = "joints.floor.clearance.friction.bristle_stiffness"
unit = "1/m"
values = [8000.0, 10193.68, 12000.0]
"#,
        scene.display()
    ));
    s.run("single", &[]);
    let single = s.path("single").join(format!("{NAME}.h5"));
    {
        let f = hdf5::File::open(&single).unwrap();
        assert_eq!(f.dataset("sweep/final_state").unwrap().shape(), [3, 38]);
    }
    two_shards_merge_into(&s, &single);
}

#[test]
fn a_failed_value_is_refused_and_partial_with_resume_records_it_as_one_process_does() {
    // RK4 at 0.05 s is unstable once gamma = 1e6 drives the oscillator to |x| ~ 100.
    let s = Setup::new(
        &SWEEP
            .replace(
                "initial = [1.0, 0.0] }",
                "initial = [1.0, 0.0], solver = { integrator = \"rk4\", step = 0.05 } }",
            )
            .replace("0.3, 0.37, 0.5]", "0.3, 1e6, 0.5]"),
    );
    let o = s.run_env("single", &[], &[]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    let single = s.path("single").join(format!("{NAME}.h5"));
    assert_eq!(done(&single), [1, 1, 1, 1, 1, 2, 1]);
    for i in 0..3 {
        let o = s.run_env("sh", &["--shard", &format!("{i}/3")], &[]);
        // Value 5 (gamma = 1e6) belongs to shard 2, whose run reports the failure.
        assert_eq!(o.status.success(), i != 2, "{i}: {:?}", text(&o));
    }
    let files: Vec<PathBuf> = (0..3).map(|i| s.shard("sh", i, 3)).collect();
    let out = s.path("sh").join(format!("{NAME}.h5"));
    let o = s.merge(&files, &out, &[]);
    let (_, se) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{se}");
    assert!(
        se.contains("shard 2/3: value gamma = 1000000 (job 5) failed: integration stopped")
            && se.contains("the same inputs fail again"),
        "{se}"
    );
    assert!(!out.exists());
    let o = s.merge(&files, &out, &["--partial", "--no-plots"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_eq!(done(&out), [1, 1, 1, 1, 1, 0, 1]);
    let o = s.run_env("sh", &["--resume"], &[]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    assert_same(&single, &out);
}

/// A sweep with the chaos measures (Lyapunov exponents with the two-trajectory estimate, the
/// 0-1 test and the class of each value) merges bit for bit too.
#[test]
fn a_chaos_sweep_merges_bit_for_bit() {
    let study = SWEEP.replace("periods = 30\n", "periods = 520\n").replace(
        "[sweep]",
        "[lyapunov]\nexponents = 2\nperiods = 20\nper_period = 2\ntwo_trajectory = true\n[zero_one]\nobservable = \"x\"\n[sweep]",
    );
    let s = Setup::new(&study);
    s.run("single", &[]);
    let single = s.path("single").join(format!("{NAME}.h5"));
    let mut files = Vec::new();
    for i in 0..2 {
        s.run("sh", &["--shard", &format!("{i}/2")]);
        files.push(s.shard("sh", i, 2));
    }
    let merged = s.path("sh").join(format!("{NAME}.h5"));
    let o = s.merge(&files, &merged, &["--no-plots"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_same(&single, &merged);
    let f = hdf5::File::open(&merged).unwrap();
    let k: Vec<f64> = f.dataset("sweep/chaos/k").unwrap().read_raw().unwrap();
    let class: Vec<u8> = f.dataset("sweep/chaos/class").unwrap().read_raw().unwrap();
    // gamma = 0.5 is chaotic (K near 1, lambda_1 > 0); gamma = 0.2 is period 1 (a constant
    // strobe series repeats) and periodic.
    assert!(k[6] > 0.8 && class[6] == 3, "{k:?} {class:?}");
    assert!(k[0] < 0.2 && class[0] == 1, "{k:?} {class:?}");
}
