//! Sweeps split over processes or machines: shards, their files and an exact merge.
//!
//! **Assignment.** Shard `I` of `N` (`0 <= I < N`) computes the jobs `j` of the sweep with
//! `j mod N = I`: interleaved, not contiguous blocks, so that neighbouring values (which cost
//! about the same) go to different shards and every shard gets a fair share of the expensive
//! part of the sweep. `N` may not exceed the number of values. A continuation sweep cannot be
//! sharded: each of its values starts from the previous value's final state.
//!
//! **Shard files.** Shard `I` of `N` writes `DIR/<study>.shard-I-of-N.h5`: a sweep file (layout in
//! book/src/reference/hdf5.md) whose rows are the shard's jobs alone, in order, with the root attributes `shard`
//! (`I`) and `shards` (`N`) and the dataset `/sweep/job` (each row's index in the whole sweep).
//! It records each value's status in `/sweep/done` like any sweep file, so `run --resume`
//! computes only what the shard lacks, and `plot` draws the shard's values.
//!
//! **Merge.** [`merge`] checks that every shard file comes from the same program version and the
//! same study (every root attribute but the wall time), that no shard is given twice and that
//! every value is done exactly once, then writes the study file through the code a single
//! process writes it with, copying each shard's rows into place. Each job's result depends only
//! on its inputs, so the merged datasets are bit-identical to a single-process run; only the wall
//! times differ (`/sweep/wall_time` per job, and the root `wall_time`, which in a merged file is
//! the sum of the shards'). Missing or failed values make the merge refuse and name the shards to
//! rerun, unless `partial`, which writes them as not done (root `complete` = 0) for
//! `run --resume` to finish.

use std::path::{Path, PathBuf};

use crate::storage::analysis_file::{Shard, SweepLayout};
use crate::storage::rows::Outcome as Kept;
use crate::storage::shard_file::ShardFile;
use crate::study::analysis::load::Loaded;
use crate::study::analysis::spec::{AnalysisStudy, sweep_jobs};
use crate::study::spec::invalid;
use crate::{Error, Result};

/// Refuses a study whose sweep cannot be split as `shard` says: a continuation sweep, or more
/// shards than values. The error names the study file and the field.
pub fn check(st: &Loaded, shard: Shard) -> Result<()> {
    if st.spec.sweep.as_ref().is_some_and(|s| s.continuation) {
        return Err(invalid(
            &st.path,
            "sweep.continuation",
            "a continuation sweep cannot be split into shards: each value starts from the \
             previous value's final state, so its values run in order in one process; run it \
             without --shard and outside a job array",
        ));
    }
    let n = st.jobs.len();
    if shard.count > n {
        return Err(invalid(
            &st.path,
            "sweep",
            format!(
                "{} shards for {n} values: use at most {n} shards",
                shard.count
            ),
        ));
    }
    Ok(())
}

/// What [`merge`] wrote, and what the values cost.
#[derive(Debug, Clone)]
pub struct Merged {
    pub file: PathBuf,
    /// Values of the sweep.
    pub jobs: usize,
    pub shards: usize,
    /// Jobs written as not done (with `partial`), by index in the sweep.
    pub not_done: Vec<usize>,
    /// Wall time of each done value (s), from the shards' `/sweep/wall_time`.
    pub value_walls: Vec<f64>,
    /// Each shard given, with its file's `wall_time` (s): the time its last run took.
    pub shard_walls: Vec<(Shard, f64)>,
    /// The sweep's table beside the merged file ([`crate::storage::table`]).
    pub tables: Vec<PathBuf>,
}

fn io(file: &Path, message: impl Into<String>) -> Error {
    Error::Io {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

/// True when `a` and `b` name the same file (`b` need not exist).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => {
            // `b` does not exist yet: compare its directory and name.
            let dir = |p: &Path| {
                p.parent()
                    .filter(|d| !d.as_os_str().is_empty())
                    .unwrap_or(Path::new("."))
                    .canonicalize()
                    .ok()
            };
            a.file_name() == b.file_name() && dir(a).is_some() && dir(a) == dir(b)
        }
    }
}

/// Up to eight parameter values, then how many more.
fn some_values(name: &str, values: &[f64]) -> String {
    let mut s: Vec<String> = values.iter().take(8).map(|v| v.to_string()).collect();
    if values.len() > 8 {
        s.push(format!("... ({} more)", values.len() - 8));
    }
    format!("{name} = {}", s.join(", "))
}

/// Merges the shard files `inputs` into the study file `out` (written under a temporary name and
/// renamed once complete); `version` is this program's version. See the module documentation.
pub fn merge(inputs: &[PathBuf], out: &Path, version: &str, partial: bool) -> Result<Merged> {
    let Some(first) = inputs.first() else {
        return Err(io(out, "no shard files given"));
    };
    let shards = open_shards(inputs, out)?;
    let o = &shards[0];
    let shards_layout = o.layout.clone();
    if o.version != version {
        return Err(io(
            first,
            format!(
                "written by jointplay {}; this is jointplay {version}: merge with the version \
                 that computed the shards",
                o.version
            ),
        ));
    }
    let study_path = PathBuf::from(&o.root.study_file);
    let spec = AnalysisStudy::parse_spec(&o.root.study, &study_path)?;
    let jobs = sweep_jobs(&spec, &study_path)?;
    let n = shards[0].shard.count;
    if jobs.is_empty() || n > jobs.len() {
        return Err(io(
            first,
            format!("{n} shards of a sweep of {} values", jobs.len()),
        ));
    }
    check_rows(&shards, &jobs)?;
    let pname = spec
        .sweep
        .as_ref()
        .map(|s| s.parameter.clone())
        .unwrap_or_default();
    let (lines, not_done) = missing(&shards, &jobs, &pname, first);
    if !not_done.is_empty() && !partial {
        return Err(io(
            out,
            format!(
                "not written: {} of {} values are missing or failed; rerun the shards named \
                 below (a rerun computes only what its file lacks) and merge again, or merge \
                 with --partial and finish the merged file with `jointplay run {} --out {} \
                 --resume`:\n  {}",
                not_done.len(),
                jobs.len(),
                o.root.study_file,
                out.parent()
                    .filter(|d| !d.as_os_str().is_empty())
                    .unwrap_or(Path::new("."))
                    .display(),
                lines.join("\n  ")
            ),
        ));
    }
    write_merged(shards, &shards_layout, &jobs, out, version, not_done)
}

/// Opens the shard files `inputs` in order, refusing the output among them and a shard that does
/// not match the first (program version, study text, flow, split) or is given twice.
fn open_shards(inputs: &[PathBuf], out: &Path) -> Result<Vec<ShardFile>> {
    for p in inputs {
        if same_file(p, out) {
            return Err(io(
                out,
                "the output is one of the shard files: give another --out (the merged file is \
                 DIR/<study>.h5)",
            ));
        }
    }
    let mut shards: Vec<ShardFile> = Vec::new();
    for p in inputs {
        let s = ShardFile::open(p, &|root, path| {
            AnalysisStudy::parse_spec(&root.study, path)?.declared(path)
        })?;
        if let Some(o) = shards.first() {
            s.check_matches(p, o, &shards)?;
        }
        shards.push(s);
    }
    Ok(shards)
}

impl ShardFile {
    /// Refuses this shard (read from `p`) unless it comes from the same program version, study
    /// text, flow and split as the first shard `o`, and is not one of `shards` already.
    fn check_matches(&self, p: &Path, o: &ShardFile, shards: &[ShardFile]) -> Result<()> {
        let s = self;
        if s.version != o.version {
            return Err(io(
                p,
                format!(
                    "written by jointplay {} but {} by jointplay {}: every shard must come \
                     from the same program version; rerun the shards with one version",
                    s.version,
                    o.path.display(),
                    o.version
                ),
            ));
        }
        if s.root.study != o.root.study {
            return Err(io(
                p,
                format!(
                    "comes from another study text than {} (its 'study' attribute differs): \
                     shards of different studies, or of a study edited between runs, cannot \
                     be merged; rerun the shards of the study as it is now",
                    o.path.display()
                ),
            ));
        }
        let diff = s.root.differences(&o.root);
        if !diff.is_empty() || s.layout != o.layout {
            return Err(io(
                p,
                format!(
                    "differs from {} in {}: the shards were not computed from the same flow \
                     (was the scene edited between runs?); rerun them",
                    o.path.display(),
                    if diff.is_empty() {
                        "the shape of its datasets".to_string()
                    } else {
                        format!("the attribute(s) {}", diff.join(", "))
                    }
                ),
            ));
        }
        if s.shard.count != o.shard.count {
            return Err(io(
                p,
                format!(
                    "is shard {} but {} is shard {}: every shard must come from one split \
                     of the sweep",
                    s.shard,
                    o.path.display(),
                    o.shard
                ),
            ));
        }
        if let Some(d) = shards.iter().find(|d| d.shard == s.shard) {
            return Err(io(
                p,
                format!(
                    "shard {} is given twice (also {})",
                    s.shard,
                    d.path.display()
                ),
            ));
        }
        Ok(())
    }
}

/// Refuses a shard that does not hold exactly its jobs, with the values the study gives them.
fn check_rows(shards: &[ShardFile], jobs: &[(f64, i8)]) -> Result<()> {
    for s in shards {
        let expect = s.shard.jobs(jobs.len());
        let (rows, params) = (&s.jobs, &s.parameters);
        let same = rows.len() == expect.len()
            && s.done.len() == expect.len()
            && params.len() == expect.len()
            && rows.iter().zip(&expect).all(|(r, j)| *r as usize == *j)
            && params
                .iter()
                .zip(&expect)
                .all(|(p, &j)| p.to_bits() == jobs[j].0.to_bits());
        if !same {
            return Err(io(
                &s.path,
                format!(
                    "does not hold the values of shard {} of the study's sweep ({} of {} values)",
                    s.shard,
                    expect.len(),
                    jobs.len()
                ),
            ));
        }
    }
    Ok(())
}

/// What is missing, shard by shard: a line for each shard not given, each row that does not
/// check, the values not run and each failed value (with the command that reruns the shard,
/// its files in the directory of the first shard, `first`), and the jobs not done, sorted.
fn missing(
    shards: &[ShardFile],
    jobs: &[(f64, i8)],
    pname: &str,
    first: &Path,
) -> (Vec<String>, Vec<usize>) {
    let o = &shards[0];
    let n = o.shard.count;
    let dir = first
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let rerun = |sh: Shard| {
        format!(
            "jointplay run {} --out {} --shard {sh} --resume",
            o.root.study_file,
            dir.display()
        )
    };
    let mut lines = Vec::new();
    let mut not_done = Vec::new();
    for i in 0..n {
        let sh = Shard { index: i, count: n };
        let js = sh.jobs(jobs.len());
        let values = |idx: &[usize]| {
            let v: Vec<f64> = idx.iter().map(|&j| jobs[j].0).collect();
            some_values(pname, &v)
        };
        match shards.iter().find(|s| s.shard == sh) {
            None => {
                lines.push(format!(
                    "shard {sh}: no file given ({}); its {} values ({}); rerun: {}",
                    dir.join(sh.file_name(&o.root.study_name)).display(),
                    js.len(),
                    values(&js),
                    rerun(sh)
                ));
                not_done.extend(js);
            }
            Some(s) => {
                for b in &s.bad {
                    lines.push(format!(
                        "shard {sh}: {} {b}: counted as not run; rerun: {}",
                        s.path.display(),
                        rerun(sh)
                    ));
                }
                let missing: Vec<usize> = (0..js.len()).filter(|&r| s.done[r] == 0).collect();
                if !missing.is_empty() {
                    let idx: Vec<usize> = missing.iter().map(|&r| js[r]).collect();
                    lines.push(format!(
                        "shard {sh}: {} of its {} values not run in {} ({}); rerun: {}",
                        idx.len(),
                        js.len(),
                        s.path.display(),
                        values(&idx),
                        rerun(sh)
                    ));
                    not_done.extend(idx);
                }
                for (r, m) in &s.errors {
                    lines.push(format!(
                        "shard {sh}: value {} = {} (job {}) failed: {m} (the same inputs fail \
                         again: merge with --partial and finish with --resume to record the \
                         failure as one process does, or change the study)",
                        pname, jobs[js[*r]].0, js[*r]
                    ));
                    not_done.push(js[*r]);
                }
            }
        }
    }
    not_done.sort_unstable();
    (lines, not_done)
}

/// Writes the study file `out` from the shards' values as a single process writes it (under the
/// output's lock), then its table beside it; `not_done` are the jobs written as not done.
fn write_merged(
    shards: Vec<ShardFile>,
    shards_layout: &SweepLayout,
    jobs: &[(f64, i8)],
    out: &Path,
    version: &str,
    not_done: Vec<usize>,
) -> Result<Merged> {
    let n = shards[0].shard.count;
    crate::storage::durable::create_dir(crate::storage::durable::parent(out))?;
    let _lock = crate::storage::lock::Lock::acquire(out)?;
    let mut values = Vec::new();
    let mut value_walls = Vec::new();
    let mut shard_walls = Vec::new();
    for s in shards {
        let js = s.shard.jobs(jobs.len());
        for v in s.values {
            if let Kept::Done(row) = &v.outcome {
                value_walls.push(row.f64s("wall_time").first().copied().unwrap_or(f64::NAN));
            }
            values.push(Some(crate::storage::rows::Value {
                row: js[v.row],
                outcome: v.outcome,
            }));
        }
        shard_walls.push((s.shard, s.wall));
    }
    let mut by_row = vec![None; jobs.len()];
    for v in values.into_iter().flatten() {
        let r = v.row;
        by_row[r] = Some(v);
    }
    let total: f64 = shard_walls
        .iter()
        .map(|w| w.1)
        .filter(|w| w.is_finite())
        .sum();
    crate::storage::sweep::write_file(out, shards_layout, version, jobs, None, &by_row, total)?;
    let tables = crate::storage::table::write_beside(out)?;
    shard_walls.sort_by_key(|w| w.0.index);
    Ok(Merged {
        file: out.to_path_buf(),
        jobs: jobs.len(),
        shards: n,
        not_done,
        value_walls,
        shard_walls,
        tables,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_interleave_the_values_and_cover_each_once() {
        let n = 10;
        let parts: Vec<Vec<usize>> = (0..3).map(|i| Shard::new(i, 3).unwrap().jobs(n)).collect();
        assert_eq!(parts[0], [0, 3, 6, 9]);
        assert_eq!(parts[1], [1, 4, 7]);
        assert_eq!(parts[2], [2, 5, 8]);
        let mut all: Vec<usize> = parts.concat();
        all.sort_unstable();
        assert_eq!(all, (0..n).collect::<Vec<_>>());
        assert_eq!(
            Shard::new(2, 3).unwrap().file_name("cascade"),
            "cascade.shard-2-of-3.h5"
        );
    }

    #[test]
    fn a_shard_is_parsed_from_i_slash_n() {
        assert_eq!("1/4".parse::<Shard>(), Ok(Shard { index: 1, count: 4 }));
        for (bad, what) in [
            ("4/4", "less than the number of shards (0 to 3)"),
            ("0/0", "at least 1"),
            ("1", "give the shard as I/N"),
            ("-1/4", "'-1' is not a whole number"),
        ] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }

    #[test]
    fn a_slurm_array_task_is_a_shard() {
        fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
            move |k: &str| {
                vars.iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            }
        }
        assert_eq!(Shard::from_slurm(env(&[])), Ok(None));
        let task: [(&str, &str); 4] = [
            ("SLURM_ARRAY_TASK_ID", "7"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "5"),
            ("SLURM_ARRAY_TASK_MAX", "8"),
        ];
        assert_eq!(
            Shard::from_slurm(env(&task[..])),
            Ok(Some(Shard { index: 2, count: 4 }))
        );
        // Without MIN the array starts at 0, and id 7 of 4 tasks is no shard.
        let e = Shard::from_slurm(env(&task[..2])).unwrap_err();
        assert!(e.contains("7/4: the shard index must be less"), "{e}");
        assert_eq!(
            Shard::from_slurm(env(&[
                ("SLURM_ARRAY_TASK_ID", "3"),
                ("SLURM_ARRAY_TASK_COUNT", "4")
            ])),
            Ok(Some(Shard { index: 3, count: 4 }))
        );
        // --array=0-6:2: ids 0, 2, 4, 6 are not shards 0 to 3.
        let stepped: [(&str, &str); 4] = [
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "6"),
        ];
        let e = Shard::from_slurm(env(&stepped[..])).unwrap_err();
        assert!(e.contains("not one contiguous range"), "{e}");
        let e = Shard::from_slurm(env(&[("SLURM_ARRAY_TASK_ID", "1")])).unwrap_err();
        assert!(e.contains("SLURM_ARRAY_TASK_COUNT is not"), "{e}");
        let e = Shard::from_slurm(env(&[
            ("SLURM_ARRAY_TASK_ID", "x"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ]))
        .unwrap_err();
        assert!(e.contains("SLURM_ARRAY_TASK_ID='x'"), "{e}");
    }
}
