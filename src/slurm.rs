//! Slurm: `jointplay slurm` (the batch scripts of a sweep's job array and its merge, submitted
//! with `--submit`) and the threads of a job's tasks.

use std::path::Path;

use anyhow::{Context, Result};
use jointplay_analysis::storage::analysis_file::Shard;
use jointplay_analysis::study::analysis::Loaded;
use jointplay_analysis::study::slurm::Batch;

use crate::VERSION;

/// In a Slurm job, rayon uses the job's CPUs per task (`SLURM_CPUS_PER_TASK`) unless
/// `RAYON_NUM_THREADS` is set.
pub fn threads_from_slurm() -> Result<()> {
    let max = jointplay_analysis::max_threads();
    // rayon starts this many threads at its first parallel loop: a huge count stalls the machine.
    if let Ok(v) = std::env::var("RAYON_NUM_THREADS") {
        if let Ok(n) = v.trim().parse::<usize>()
            && n > max
        {
            anyhow::bail!("RAYON_NUM_THREADS={n}: more than the {max} threads allowed");
        }
        return Ok(());
    }
    let Ok(v) = std::env::var("SLURM_CPUS_PER_TASK") else {
        return Ok(());
    };
    let n: usize = v
        .trim()
        .parse()
        .ok()
        .filter(|&n| n >= 1)
        .with_context(|| format!("SLURM_CPUS_PER_TASK='{v}' is not a positive whole number"))?;
    if n > max {
        anyhow::bail!("SLURM_CPUS_PER_TASK={n}: more than the {max} threads allowed");
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build_global()
        .context("setting the threads from SLURM_CPUS_PER_TASK")
}

/// What `jointplay slurm` asks of the cluster.
pub struct SlurmOptions {
    pub shards: usize,
    pub partition: Option<String>,
    pub time: Option<String>,
    pub cpus_per_task: usize,
    pub mem: Option<String>,
    pub max_running: Option<usize>,
}

/// Runs `sbatch --parsable ARGS` and returns the job id it prints.
fn sbatch(args: &[&str]) -> Result<String> {
    let out = std::process::Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .output()
        .context("cannot run sbatch (is this a machine of a Slurm cluster?)")?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        anyhow::bail!(
            "sbatch {} failed ({}): {}",
            args.join(" "),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    // --parsable prints "id" or "id;cluster".
    let id = stdout.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        anyhow::bail!(
            "sbatch {}: expected a job id, got '{}'",
            args.join(" "),
            stdout.trim()
        );
    }
    Ok(id)
}

/// Writes the array and merge scripts of a sweep, and prints or runs the sbatch commands.
pub fn slurm_cmd(study: &Path, out: &Path, o: SlurmOptions, submit: bool) -> Result<()> {
    let st = Loaded::load(study)?;
    if st.spec.sweep.is_none() {
        anyhow::bail!(
            "{}: a job array splits a sweep's values; this study has no [sweep]",
            study.display()
        );
    }
    // The same refusals as the shards would meet (continuation, too many shards), before
    // anything is written.
    let sh = Shard::new(0, o.shards).map_err(|m| anyhow::anyhow!("--shards: {m}"))?;
    jointplay_analysis::study::shards::check(&st, sh)?;
    let program = std::env::current_exe()
        .and_then(|p| p.canonicalize())
        .context("cannot find the path of this program for the batch script")?;
    let b = Batch {
        program,
        workdir: std::env::current_dir().context("cannot read the working directory")?,
        study: study.to_path_buf(),
        out: out.to_path_buf(),
        name: st.spec.study.name.clone(),
        values: st.jobs.len(),
        shards: o.shards,
        partition: o.partition,
        time: o.time,
        cpus_per_task: o.cpus_per_task,
        mem: o.mem,
        max_running: o.max_running,
        version: VERSION.into(),
        hdf5_format: jointplay_analysis::storage::h5::format(),
    };
    b.check().map_err(|m| anyhow::anyhow!("{m}"))?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let (array, merge) = (b.array_file(), b.merge_file());
    for (file, text) in [(&array, b.array_script()), (&merge, b.merge_script())] {
        std::fs::write(file, text).with_context(|| format!("writing {}", file.display()))?;
        println!("wrote        {}", file.display());
    }
    let (a, m) = (array.display().to_string(), merge.display().to_string());
    if !submit {
        println!("submit with:");
        println!("  array=$(sbatch --parsable {a})");
        println!("  sbatch --dependency=afterok:${{array%%;*}} {m}");
        return Ok(());
    }
    let id = sbatch(&[&a])?;
    println!(
        "array job    {id} ({} tasks{})",
        b.shards,
        b.max_running
            .map(|r| format!(", at most {r} at once"))
            .unwrap_or_default()
    );
    let dep = format!("--dependency=afterok:{id}");
    let mid = sbatch(&[&dep, &m]).with_context(|| {
        format!("the array job {id} is submitted; submit the merge with: sbatch {dep} {m}")
    })?;
    println!("merge job    {mid} (after every task of {id} has succeeded: {dep})");
    println!("merged file  {}", b.merged_file().display());
    Ok(())
}
