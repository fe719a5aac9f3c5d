//! Batch scripts that run a sweep on a Slurm cluster: a job array of shards (see
//! [`crate::study::shards`]) and a merge job that depends on it.
//!
//! The scripts are plain bash with `#SBATCH` lines, written to be read and edited for a site
//! (account, partition, limits). Each array task passes its shard to `jointplay run` explicitly
//! (`--shard "$SLURM_ARRAY_TASK_ID/N"`), so a task resubmitted alone (`sbatch --array=I`) still
//! computes shard I of N, and with `--resume` only what its file lacks. The merge job is
//! submitted with `--dependency=afterok:<array job>`: it runs once every task has succeeded and
//! stays pending (reason `DependencyNeverSatisfied`) when one has failed.

use std::path::{Path, PathBuf};

/// What the scripts run and the resources they ask for.
#[derive(Debug, Clone)]
pub struct Batch {
    /// The `jointplay` program (an absolute path, reachable from the compute nodes).
    pub program: PathBuf,
    /// The directory the jobs run in (where the study and output paths are relative to).
    pub workdir: PathBuf,
    /// The study file and the output directory, as given (relative to `workdir` or absolute).
    pub study: PathBuf,
    pub out: PathBuf,
    /// The study's name and its number of sweep values.
    pub name: String,
    pub values: usize,
    pub shards: usize,
    pub partition: Option<String>,
    pub time: Option<String>,
    pub cpus_per_task: usize,
    pub mem: Option<String>,
    pub max_running: Option<usize>,
    /// The program version, for the header.
    pub version: String,
    /// The format the jobs write their files in (`jointplay --hdf5-format`), passed on to
    /// every command.
    pub hdf5_format: crate::storage::h5::Format,
}

/// Quotes `s` for bash (single quotes).
fn quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:+,@%".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

fn path(p: &Path) -> String {
    quote(&p.display().to_string())
}

impl Batch {
    /// Refuses settings that would make a broken script; the message names the option.
    pub fn check(&self) -> Result<(), String> {
        if self.shards == 0 {
            return Err("--shards: give at least 1 shard".into());
        }
        if self.shards > self.values {
            return Err(format!(
                "--shards {}: the sweep has {} values; use at most {} shards",
                self.shards, self.values, self.values
            ));
        }
        if self.cpus_per_task == 0 {
            return Err("--cpus-per-task: give at least 1".into());
        }
        // Each task's threads are its CPUs: a million would stall the node.
        if self.cpus_per_task > crate::max_threads() {
            return Err(format!(
                "--cpus-per-task {}: more than the {} threads allowed",
                self.cpus_per_task,
                crate::max_threads()
            ));
        }
        if self.max_running == Some(0) {
            return Err("--max-running: give at least 1".into());
        }
        for (opt, v) in [
            ("--partition", &self.partition),
            ("--time", &self.time),
            ("--mem", &self.mem),
        ] {
            if let Some(v) = v
                && (v.is_empty() || v.chars().any(|c| c.is_whitespace() || "'\"#\\".contains(c)))
            {
                return Err(format!(
                    "{opt} '{v}': give one word without spaces or quotes (it goes into an \
                     #SBATCH line)"
                ));
            }
        }
        for (what, p) in [
            ("the working directory", &self.workdir),
            ("--out", &self.out),
        ] {
            if p.display().to_string().chars().any(char::is_whitespace) {
                return Err(format!(
                    "{what} '{}' contains white space, which #SBATCH lines cannot hold: use a \
                     path without spaces",
                    p.display()
                ));
            }
        }
        Ok(())
    }

    /// `DIR/<study>.slurm-array.sh`.
    pub fn array_file(&self) -> PathBuf {
        self.out.join(format!("{}.slurm-array.sh", self.name))
    }

    /// `DIR/<study>.slurm-merge.sh`.
    pub fn merge_file(&self) -> PathBuf {
        self.out.join(format!("{}.slurm-merge.sh", self.name))
    }

    /// The merged study file, `DIR/<study>.h5`.
    pub fn merged_file(&self) -> PathBuf {
        self.out.join(format!("{}.h5", self.name))
    }

    /// The `#SBATCH` lines both jobs share.
    fn common(&self, out: &mut Vec<String>) {
        if let Some(p) = &self.partition {
            out.push(format!("#SBATCH --partition={p}"));
        }
        if let Some(t) = &self.time {
            out.push(format!("#SBATCH --time={t}"));
        }
        if let Some(m) = &self.mem {
            out.push(format!("#SBATCH --mem={m}"));
        }
        out.push(format!("#SBATCH --chdir={}", self.workdir.display()));
    }

    /// The job-array script.
    pub fn array_script(&self) -> String {
        let n = self.shards;
        let per = self.values.div_ceil(n);
        let throttle = self
            .max_running
            .map(|m| format!("%{m}"))
            .unwrap_or_default();
        let mut l = vec![
            "#!/bin/bash".to_string(),
            format!(
                "# The sweep of {} ({} values) as a Slurm job array of {n} shards; written by",
                self.study.display(),
                self.values
            ),
            format!(
                "# `jointplay slurm` (jointplay {}). Edit the #SBATCH lines for your site.",
                self.version
            ),
            "#".into(),
            format!(
                "# Task I computes the sweep's values j with j mod {n} = I (at most {per} values) into"
            ),
            format!(
                "# {}, using SLURM_CPUS_PER_TASK threads.",
                self.out
                    .join(format!("{}.shard-I-of-{n}.h5", self.name))
                    .display()
            ),
            "# The shard is passed explicitly, so one task can be rerun alone:".into(),
            format!("#   sbatch --array=I {}", self.array_file().display()),
            "# and --resume makes a rerun compute only what its shard file lacks.".into(),
            "#".into(),
            format!("#SBATCH --job-name={}", self.name),
            format!("#SBATCH --array=0-{}{throttle}", n - 1),
            format!("#SBATCH --cpus-per-task={}", self.cpus_per_task),
            "# SIGTERM a minute before the time limit, to the program itself (B:, as the script"
                .into(),
            "# execs it): it keeps its finished values and stops cleanly before Slurm's SIGKILL."
                .into(),
            "#SBATCH --signal=B:TERM@60".into(),
        ];
        self.common(&mut l);
        l.push(format!(
            "#SBATCH --output={}",
            self.out.join("slurm-%A_%a.out").display()
        ));
        l.push("set -euo pipefail".into());
        l.push(format!(
            "exec {}{} run {} --out {} --shard \"$SLURM_ARRAY_TASK_ID/{n}\" --resume --quiet",
            path(&self.program),
            self.format_option(),
            path(&self.study),
            path(&self.out)
        ));
        l.join("\n") + "\n"
    }

    /// ` --hdf5-format 1.8` when the files are to be written in the oldest format, else nothing
    /// (the program's default, 1.10).
    fn format_option(&self) -> &'static str {
        match self.hdf5_format {
            crate::storage::h5::Format::V18 => " --hdf5-format 1.8",
            crate::storage::h5::Format::V110 => "",
        }
    }

    /// The merge job's script.
    pub fn merge_script(&self) -> String {
        let n = self.shards;
        let mut l = vec![
            "#!/bin/bash".to_string(),
            format!(
                "# Merges the {n} shard files of the sweep of {} into {}; written by",
                self.study.display(),
                self.merged_file().display()
            ),
            format!(
                "# `jointplay slurm` (jointplay {}). The merge checks that every shard comes from",
                self.version
            ),
            "# the same study text and program version and that every value is done exactly once,"
                .into(),
            "# then writes the file a single machine would have written, and its figures.".into(),
            "#".into(),
            "# Submitted with --dependency=afterok:<array job>, it runs once every task has".into(),
            "# succeeded. If a task fails, this job stays pending (DependencyNeverSatisfied):"
                .into(),
            "# rerun the task alone (sbatch --array=I ...slurm-array.sh), cancel this job and"
                .into(),
            "# submit it again with --dependency=afterok:<rerun job>, or run the command below."
                .into(),
            "#".into(),
            format!("#SBATCH --job-name={}-merge", self.name),
            "#SBATCH --cpus-per-task=1".into(),
        ];
        self.common(&mut l);
        l.push(format!(
            "#SBATCH --output={}",
            self.out.join("slurm-merge-%j.out").display()
        ));
        l.push("set -euo pipefail".into());
        l.push(format!(
            "exec {}{} merge {}/{}.shard-*-of-{n}.h5 --out {}",
            path(&self.program),
            self.format_option(),
            path(&self.out),
            self.name,
            path(&self.merged_file())
        ));
        l.join("\n") + "\n"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn batch() -> Batch {
        Batch {
            program: "/opt/jp/bin/jointplay".into(),
            workdir: "/home/u/work".into(),
            study: "analyses/duffing/cascade.toml".into(),
            out: "out/duffing".into(),
            name: "duffing-cascade".into(),
            values: 601,
            shards: 20,
            partition: Some("short".into()),
            time: Some("00:30:00".into()),
            cpus_per_task: 4,
            mem: None,
            max_running: Some(5),
            version: "0.1.0".into(),
            hdf5_format: crate::storage::h5::Format::V110,
        }
    }

    #[test]
    fn the_array_script_runs_each_task_as_its_shard() {
        let s = batch().array_script();
        for line in [
            "#SBATCH --array=0-19%5",
            "#SBATCH --cpus-per-task=4",
            "#SBATCH --partition=short",
            "#SBATCH --time=00:30:00",
            "#SBATCH --chdir=/home/u/work",
            "#SBATCH --signal=B:TERM@60",
            "exec /opt/jp/bin/jointplay run analyses/duffing/cascade.toml --out out/duffing \
             --shard \"$SLURM_ARRAY_TASK_ID/20\" --resume --quiet",
        ] {
            assert!(s.lines().any(|l| l == line), "no line {line:?} in\n{s}");
        }
        assert!(!s.contains("--mem"), "{s}");
        assert!(s.contains("at most 31 values"), "{s}");
    }

    #[test]
    fn the_merge_script_merges_every_shard_file() {
        let s = batch().merge_script();
        assert!(
            s.lines().any(|l| l
                == "exec /opt/jp/bin/jointplay merge out/duffing/duffing-cascade.shard-*-of-20.h5 \
                    --out out/duffing/duffing-cascade.h5"),
            "{s}"
        );
        assert!(
            s.contains("#SBATCH --job-name=duffing-cascade-merge"),
            "{s}"
        );
    }

    /// Files asked for in the oldest HDF5 format are written so by every job, the merge included.
    #[test]
    fn the_jobs_keep_the_hdf5_format_asked_for() {
        let mut b = batch();
        b.hdf5_format = crate::storage::h5::Format::V18;
        let (array, merge) = (b.array_script(), b.merge_script());
        assert!(
            array.contains("exec /opt/jp/bin/jointplay --hdf5-format 1.8 run "),
            "{array}"
        );
        assert!(
            merge.contains("exec /opt/jp/bin/jointplay --hdf5-format 1.8 merge "),
            "{merge}"
        );
    }

    #[test]
    fn paths_are_quoted_for_the_shell() {
        let mut b = batch();
        b.study = "my study's.toml".into();
        assert!(
            b.array_script().contains(r"run 'my study'\''s.toml' --out"),
            "{}",
            b.array_script()
        );
    }

    #[test]
    fn bad_settings_name_the_option() {
        type Edit = fn(&mut Batch);
        let cases: [(Edit, &str); 6] = [
            (|b| b.shards = 0, "--shards"),
            (|b| b.shards = 602, "at most 601"),
            (|b| b.cpus_per_task = 0, "--cpus-per-task"),
            (|b| b.cpus_per_task = 1_000_000, "--cpus-per-task 1000000"),
            (|b| b.max_running = Some(0), "--max-running"),
            (|b| b.time = Some("1 day".into()), "--time '1 day'"),
        ];
        for (edit, what) in cases {
            let mut b = batch();
            edit(&mut b);
            let e = b.check().unwrap_err();
            assert!(e.contains(what), "{what}: {e}");
        }
        assert!(batch().check().is_ok());
    }
}
