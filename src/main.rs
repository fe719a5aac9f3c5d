//! `jointplay`: simulate mechanisms with ideal and clearance joints from TOML scene files.
//!
//! * `jointplay check SCENE`: validate and compile a scene and print what will be simulated;
//!   `jointplay check STUDY` checks a study as `run` does before anything runs.
//! * `jointplay run SCENE --out DIR`: simulate it and write `DIR/<scene>.h5` plus figures.
//! * `jointplay run STUDY --out DIR`: run a comparison study or a nonlinear-analysis study
//!   (N-period runs, Poincare sections, bifurcation sweeps with `--resume`).
//! * `jointplay run STUDY --out DIR --shard I/N`: compute shard I of N of a sweep's values into
//!   `DIR/<study>.shard-I-of-N.h5` (in a Slurm job array, from its `SLURM_ARRAY_*` variables).
//! * `jointplay merge DIR/<study>.shard-*.h5 --out DIR/<study>.h5`: the study file from its shards.
//! * `jointplay slurm STUDY --out DIR --shards N`: batch scripts for a Slurm job array of shards
//!   and the merge job after it; `--submit` submits them.
//! * `jointplay plot FILE.h5`: redraw an analysis file's figures without simulating.
//! * `jointplay precision STUDY_OR_SCENE --out DIR`: work-precision of every integrator.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use jointplay_analysis::figures::plot::{Format, figure};
use jointplay_analysis::figures::{overlay, redraw, run_figures};
use jointplay_analysis::flow::summary::Summary;
use jointplay_analysis::progress::{Progress, Tally};
use jointplay_analysis::storage::analysis_file::Shard;
use jointplay_analysis::storage::hybrid::read_run_file;
use jointplay_analysis::storage::inputs::{Input, Output};
use jointplay_analysis::storage::run_file::Meta;
use jointplay_analysis::study::analysis::{Loaded, Options, execute};
use jointplay_analysis::study::comparison::Comparison;
use jointplay_analysis::study::precision;
use jointplay_analysis::study::report::{self, markdown};
use jointplay_analysis::study::run::{resume_to_file, simulate_to_file};
use jointplay_analysis::study::shards::merge;
use jointplay_analysis::study::slurm::Batch;
use jointplay_analysis::study::spec::Study;
use jointplay_solver::model::Model;
use jointplay_solver::scene::SceneSpec;

/// The program version written into every output file.
const VERSION: &str = env!("CARGO_PKG_VERSION");

#[derive(Parser)]
#[command(
    name = "jointplay",
    version,
    about = "Nonlinear dynamics of mechanisms with joint clearance"
)]
struct Cli {
    /// The oldest HDF5 library the files written must open in: 1.10 (default; smaller files:
    /// chunk indexes and object headers of the 1.10 format) or 1.8 (the oldest format).
    #[arg(long, global = true, value_name = "VERSION", default_value = "1.10")]
    hdf5_format: jointplay_analysis::storage::h5::Format,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Validate a scene and print its compiled summary: bodies, constraints, rank, degrees of
    /// freedom, redundancy, drives and the effects that will be simulated. A study is checked
    /// as `run` checks it before anything runs (every case's scene compiled, or the analysis
    /// study and its first flow), without running it.
    Check {
        /// Scene or study file (TOML).
        scene: PathBuf,
    },
    /// Simulate a scene, or run a study. A scene writes DIR/<name>.h5 and the figures of its
    /// positions, drives and diagnostics (PNG and SVG). A comparison study (a [study] table and
    /// [[cases]]) writes DIR/<study>.h5 with every case, DIR/<study>.md (its comparison table) and
    /// the figures it asks for. An analysis study (a [study] and an [analysis] table) writes
    /// DIR/<study>.h5 (histories, sections, the sweep, Lyapunov exponents, periodic orbits, as it
    /// asks) and its figures, and a sweep its table DIR/<study>.md and .csv (a row per value);
    /// while a sweep runs its finished values are in DIR/<study>.journal, and a continuation's
    /// state in DIR/<study>.continuation.h5.
    Run {
        /// Scene or study file (TOML; a study has a [study] table).
        scene: PathBuf,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Skip the figures.
        #[arg(long)]
        no_plots: bool,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
        /// Analysis sweeps: keep the finished values of an existing DIR/<name>.h5 (with --shard,
        /// of the shard's file) and compute only the rest. Continuations: go on from where the
        /// continuation in DIR/<name>.h5 stopped.
        #[arg(long)]
        resume: bool,
        /// Analysis sweeps: stop after this many values have finished (resume later). A
        /// continuation without a sweep: stop after this many branch points.
        #[arg(long)]
        max_jobs: Option<usize>,
        /// Analysis sweeps: compute only shard I of N of the values (those whose index j has
        /// j mod N = I) into DIR/<name>.shard-I-of-N.h5, for `jointplay merge`. In a Slurm job
        /// array it defaults to the task's SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of
        /// SLURM_ARRAY_TASK_COUNT.
        #[arg(long, value_name = "I/N")]
        shard: Option<Shard>,
        /// Scenes: continue from the final state of a run file of this scene (written by
        /// `jointplay run`) to the scene's end time, as if the run had never stopped.
        #[arg(long, value_name = "RUN.h5")]
        from: Option<PathBuf>,
    },
    /// Merge the shard files of a sweep into the study file a single run writes (its datasets
    /// bit-identical, wall times aside), and draw its figures. Refuses when a value is missing
    /// or failed, naming the shards to rerun.
    Merge {
        /// Shard files written by `jointplay run STUDY --shard I/N`.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// The merged file, DIR/<study>.h5 (replaced if it exists).
        #[arg(long)]
        out: PathBuf,
        /// Write missing and failed values as not done (the file is marked incomplete), for
        /// `jointplay run STUDY --out DIR --resume` to finish.
        #[arg(long)]
        partial: bool,
        /// Skip the figures.
        #[arg(long)]
        no_plots: bool,
    },
    /// Write Slurm batch scripts for a sweep: a job array of N shards and a merge job that runs
    /// after every task has succeeded; print the sbatch commands, or submit them with --submit.
    Slurm {
        /// Analysis study with a [sweep] (not a continuation sweep).
        study: PathBuf,
        /// Output directory of the shards, the merged file and the scripts (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Number of shards (array tasks).
        #[arg(long)]
        shards: usize,
        /// Slurm partition.
        #[arg(long)]
        partition: Option<String>,
        /// Time limit of each job, in Slurm's format (e.g. 01:00:00).
        #[arg(long)]
        time: Option<String>,
        /// CPUs per array task (the threads of each shard).
        #[arg(long, default_value_t = 1)]
        cpus_per_task: usize,
        /// Memory of each job, in Slurm's format (e.g. 4G).
        #[arg(long)]
        mem: Option<String>,
        /// At most this many tasks run at once (--array=0-(N-1)%M).
        #[arg(long)]
        max_running: Option<usize>,
        /// Submit the array and the merge job with sbatch.
        #[arg(long)]
        submit: bool,
    },
    /// Redraw every figure of a nonlinear-analysis or work-precision file without simulating
    /// again.
    Plot {
        /// File written by `jointplay run STUDY` for an analysis study.
        file: PathBuf,
        /// png, svg or both.
        #[arg(long, default_value = "both")]
        format: String,
        /// Output directory (default: the file's directory).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Work-precision: run every integrator over a range of steps or tolerances against a tight
    /// reference; write DIR/<name>.h5, DIR/<name>.md (the table) and the figure DIR/<name>.png
    /// and .svg (error against wall time, log-log).
    Precision {
        /// An analysis study (its [precision] table, or the defaults) or a scene (every body's
        /// position and every clearance joint's contact force over the scene's span).
        file: PathBuf,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Skip the figure.
        #[arg(long)]
        no_plots: bool,
        /// No progress lines.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Print the table of a comparison study or of a sweep (markdown) from its HDF5 file.
    Report {
        /// Study file written by `jointplay run STUDY`.
        file: PathBuf,
        /// Write the table here instead of standard output.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Overlay one recorded quantity from several run files in one figure (PNG and SVG).
    Compare {
        /// Run files written by `jointplay run`.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Dataset path inside the files, e.g. bodies/slider/acceleration.
        #[arg(long)]
        dataset: String,
        /// Column of a two-dimensional dataset (0 = x).
        #[arg(long, default_value_t = 0)]
        component: usize,
        /// Output path without extension.
        #[arg(long)]
        out: PathBuf,
        /// Figure title (default: the dataset path).
        #[arg(long)]
        title: Option<String>,
    },
}

fn main() {
    // Output piped into a reader that stops early (`jointplay check SCENE | head`) ends the
    // program as it ends any Unix tool, by SIGPIPE, instead of a panic in `println!` (Rust
    // ignores SIGPIPE by default). What a killed computation leaves is what any kill leaves.
    // SAFETY: setting a signal's disposition to its default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    // SIGINT (Ctrl-C) and SIGTERM (a Slurm time limit, `scancel`, `kill`) stop the computation
    // cleanly: finished values are kept, the current one is abandoned, the file is left to
    // resume. A second signal ends the process at once (what is finished is on disk anyway).
    let _ = ctrlc::set_handler(|| {
        if jointplay_analysis::progress::process_stop_requested() {
            eprintln!("jointplay: second stop signal: exiting now");
            std::process::exit(130);
        }
        eprintln!(
            "jointplay: stop signal received: keeping what is finished and stopping (send it again to exit at once)"
        );
        jointplay_analysis::progress::request_process_stop();
    });
    jointplay_analysis::storage::h5::set_format(cli.hdf5_format);
    if let Err(e) = threads_from_slurm() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
    let res = match cli.command {
        Command::Check { scene } => check(&scene),
        Command::Run {
            scene,
            out,
            no_plots,
            quiet,
            resume,
            max_jobs,
            shard,
            from,
        } => run(
            &scene,
            &out,
            !no_plots,
            quiet,
            Options {
                resume,
                max_jobs,
                shard,
            },
            from.as_deref(),
        ),
        Command::Merge {
            files,
            out,
            partial,
            no_plots,
        } => merge_cmd(&files, &out, partial, !no_plots),
        Command::Slurm {
            study,
            out,
            shards,
            partition,
            time,
            cpus_per_task,
            mem,
            max_running,
            submit,
        } => slurm_cmd(
            &study,
            &out,
            SlurmOptions {
                shards,
                partition,
                time,
                cpus_per_task,
                mem,
                max_running,
            },
            submit,
        ),
        Command::Plot { file, format, out } => plot_cmd(&file, &format, out.as_deref()),
        Command::Report { file, out } => report_cmd(&file, out.as_deref()),
        Command::Precision {
            file,
            out,
            no_plots,
            quiet,
        } => precision_cmd(&file, &out, !no_plots, quiet),
        Command::Compare {
            files,
            dataset,
            component,
            out,
            title,
        } => compare(&files, &dataset, component, &out, title),
    };
    if let Err(e) = res {
        // A huge value in an input is echoed at most in part, wherever the message quotes it.
        eprintln!(
            "error: {}",
            jointplay_analysis::clip_lines(&format!("{e:#}"), jointplay_analysis::MESSAGE_LIMIT)
        );
        // A computation stopped by a signal exits as the signal asked, whatever it reports.
        let stopped = jointplay_analysis::progress::process_stop_requested();
        std::process::exit(if stopped { 130 } else { 1 });
    }
    if jointplay_analysis::progress::process_stop_requested() {
        eprintln!(
            "stopped      on a signal (SIGINT or SIGTERM): what was finished is kept; a sweep or \
             a continuation goes on with the same command and --resume, a scene's run with \
             --from its file"
        );
        std::process::exit(130);
    }
}

fn check(path: &Path) -> Result<()> {
    match Input::read(path)?.0 {
        Input::Scene => check_scene(path),
        Input::Comparison => {
            // Everything `run` checks before the first case starts: the study, every case's
            // edited scene compiled and assembled.
            let study = Study::load(path)?;
            println!(
                "study        {} ({}), comparison of {} cases",
                study.spec.study.name,
                path.display(),
                study.cases.len()
            );
            for c in &study.cases {
                let (model, mut state) = Model::compile(&c.scene)?;
                for w in &model.warnings {
                    eprintln!("warning: {w}");
                }
                let s = Summary::new(&c.scene.path, &model, &mut state)?;
                println!(
                    "case         {}: {} bodies, {} joints, {} s to {} s",
                    c.label,
                    s.bodies.len(),
                    s.joints.len(),
                    s.start_time,
                    s.end_time
                );
            }
            Ok(())
        }
        kind => {
            // The study and the flow of its first value, as `run` builds them before running.
            let st = Loaded::load(path)?;
            let what = if kind == Input::Precision {
                let p = precision::Precision::new(st)?;
                println!(
                    "study        {} ({}), work-precision, {} runs",
                    p.study().spec.study.name,
                    path.display(),
                    p.total_runs()
                );
                return Ok(());
            } else if st.spec.sweep.is_some() {
                format!("analysis sweep of {} values", st.jobs.len())
            } else {
                "analysis".to_string()
            };
            println!(
                "study        {} ({}), {what}",
                st.spec.study.name,
                path.display()
            );
            Ok(())
        }
    }
}

fn check_scene(path: &Path) -> Result<()> {
    let scene = SceneSpec::load(path)?;
    let (model, mut state) = Model::compile(&scene)?;
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    for line in Summary::new(path, &model, &mut state)?.lines() {
        println!("{line}");
    }
    Ok(())
}

fn report_cmd(file: &Path, out: Option<&Path>) -> Result<()> {
    // The table is a comparison study's: other files get the command that fits them.
    let toml = file.extension().is_some_and(|e| e == "toml");
    let other = match Output::read(file) {
        _ if toml => Some(match Input::read(file) {
            Ok((Input::Comparison, _)) => format!(
                "a comparison study's TOML file: `jointplay report` reads the HDF5 file its run \
                 wrote (`jointplay run {}` writes DIR/<study>.h5, and its table DIR/<study>.md)",
                file.display()
            ),
            _ => "a TOML file: `jointplay report` reads the HDF5 file of a comparison study's \
                  run (DIR/<study>.h5)"
                .to_string(),
        }),
        Ok(Output::Comparison) => None,
        Ok(Output::Analysis) => match jointplay_analysis::storage::table::of_file(file)? {
            // A sweep's table: one row per value.
            Some(t) => {
                return emit(&t.markdown, out);
            }
            None => Some(
                "a single analysis run's file: `jointplay report` makes the table of a sweep or a \
                 comparison study; `jointplay plot FILE` redraws this file's figures, and its \
                 datasets are read as the book's HDF5 reference describes"
                    .to_string(),
            ),
        },
        Ok(Output::Precision) => Some(
            "a work-precision file: its table is DIR/<name>.md, written beside it by \
             `jointplay precision`; `jointplay plot FILE` redraws its figure"
                .to_string(),
        ),
        Ok(Output::Run) => Some(
            "a scene's run file: `jointplay report` makes a comparison study's table; \
             `jointplay compare` overlays a recorded quantity of several runs"
                .to_string(),
        ),
        Err(e) => return Err(e.into()),
    };
    if let Some(why) = other {
        anyhow::bail!("{}: {why}", file.display());
    }
    emit(&markdown(&report::compute(file)?), out)
}

/// A table to `out` (whole or not at all) or to standard output.
fn emit(md: &str, out: Option<&Path>) -> Result<()> {
    match out {
        Some(p) => {
            jointplay_analysis::storage::durable::write_new(p, md.as_bytes())?;
            println!("wrote        {}", p.display());
        }
        None => print!("{md}"),
    }
    Ok(())
}

/// A hidden progress bar of `len` steps drawn with `template` (shown by the caller on stderr).
fn progress_bar(len: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
    // The templates are literals of this file; a bad one falls back to the default style.
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}

fn run_study(path: &Path, out: &Path, plots: bool, quiet: bool) -> Result<()> {
    let study = Study::load(path)?;
    let bar = progress_bar(
        study.cases.len() as u64,
        "[{elapsed_precise}] {bar:40} {pos}/{len} cases (eta {eta}) {msg}",
    );
    if !quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    bar.tick();
    let progress = |p: Progress| {
        if let Progress::Done { job, ok: true } = p {
            bar.inc(1);
            bar.set_message(format!("{} done", study.cases[job].label));
        }
    };
    let cases = Comparison::run(&study, &progress);
    bar.finish_and_clear();
    // Every finished case is kept even when others fail: they are written, the failures are
    // recorded in the file and reported, and the program exits with an error.
    let cases = cases?;
    for w in cases.warnings() {
        eprintln!("warning: {w}");
    }
    let file = cases.write(out, VERSION)?;
    for line in cases.lines() {
        println!("{line}");
    }
    println!("wrote        {}", file.display());
    println!("wrote        {}", cases.write_table(&file, out)?.display());
    if plots {
        for f in cases.figures(out)? {
            println!("wrote        {}", f.display());
        }
    }
    cases.finish()?;
    Ok(())
}

fn run(
    path: &Path,
    out: &Path,
    plots: bool,
    quiet: bool,
    opts: Options,
    from: Option<&Path>,
) -> Result<()> {
    let (kind, _) = Input::read(path)?;
    if from.is_some() && kind != Input::Scene {
        anyhow::bail!(
            "{}: --from continues a scene's run; this is a study",
            path.display()
        );
    }
    if kind.is_analysis() {
        return run_analysis(path, out, plots, quiet, opts);
    }
    if opts.resume || opts.max_jobs.is_some() || opts.shard.is_some() {
        anyhow::bail!(
            "{}: --resume, --max-jobs and --shard apply to analysis studies with a [sweep]",
            path.display()
        );
    }
    if kind == Input::Comparison {
        return run_study(path, out, plots, quiet);
    }
    let scene = SceneSpec::load(path)?;
    let (model, state) = Model::compile(&scene)?;
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    let target = out.join(format!("{}.h5", model.name));
    if let Some(f) = from
        && let (Ok(a), Ok(b)) = (f.canonicalize(), target.canonicalize())
        && a == b
    {
        // The continuation holds the samples after the file's final state only: written over
        // the file it continues, it would replace the only copy of the run's first part.
        anyhow::bail!(
            "{}: --from {} would be replaced by the run continued from it: write the \
             continuation to another --out directory",
            path.display(),
            f.display()
        );
    }
    let start = Instant::now();
    let bar = progress_bar(
        1000,
        "{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% (eta {eta})",
    );
    let mut shown = false;
    let mut progress = |f: f64| {
        if !quiet && !shown && start.elapsed().as_secs_f64() > 1.0 {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            shown = true;
        }
        bar.set_position((f * 1000.0) as u64);
    };
    // The run goes to its file as it is recorded: memory does not grow with its length.
    let meta = Meta::of(&model, path, &scene.text, VERSION);
    let mut begin = model.settings.start_time;
    let (result, written) = match from {
        None => {
            simulate_to_file(&model, state, &mut progress, out, &meta).map_err(anyhow::Error::new)
        }
        Some(f) => {
            let from_state = read_run_file(f)?;
            begin = from_state.t;
            resume_to_file(&model, from_state, &mut progress, out, &meta).map_err(|e| {
                anyhow::Error::new(e).context(format!("continuing from {}", f.display()))
            })
        }
    }
    .with_context(|| format!("simulating {}", path.display()))?;
    bar.finish_and_clear();
    for w in &result.warnings {
        eprintln!("warning: {}: {}", path.display(), w.message);
    }
    let file = &written.path;
    if result.interrupted() {
        eprintln!(
            "stopped      {}\nwrote        {} with the {} samples recorded before the stop, marked \
             incomplete (attributes complete = 0, interrupted = 1); continue it with\n             \
             jointplay run {} --out OTHER_DIR --from {}",
            result
                .stopped
                .as_ref()
                .map_or(String::new(), |s| s.to_string()),
            file.display(),
            written.samples,
            path.display(),
            file.display()
        );
        return Ok(());
    }
    if let Some(s) = &result.stopped {
        anyhow::bail!(
            "simulating {}: {}\nwrote {} with the {} samples recorded before the failure, marked incomplete (attribute complete = 0)",
            path.display(),
            s,
            file.display(),
            written.samples
        );
    }
    let st = &result.stats;
    let wall = st.wall.as_secs_f64();
    println!("scene        {} ({})", model.name, path.display());
    println!(
        "span         {} s to {} s, {} samples",
        begin, model.settings.end_time, written.samples
    );
    println!("integrator   {}", model.settings.method.describe());
    println!(
        "steps        {} accepted, {} rejected, {} ended at an event",
        st.accepted, st.rejected, st.events
    );
    println!(
        "RHS          {} evaluations, {:.0} per second of integration",
        st.rhs_evals,
        st.rhs_evals as f64 / wall.max(1e-9)
    );
    // The recording is evaluated and written beside the integration, by the file's own thread;
    // the whole run also holds its last block and closing the file.
    println!(
        "wall time    {wall:.3} s integrating, {:.3} s with the file written",
        start.elapsed().as_secs_f64()
    );
    if let Some((p, v)) = written.max_drift {
        println!("drift        max |Phi| {p:.3e} (m, rad), max |Phi'| {v:.3e} (m/s, rad/s)");
    }
    println!("wrote        {}", file.display());
    if plots {
        if written.stride > 1 {
            println!(
                "figures      drawn from one sample in {} (the file holds them all)",
                written.stride
            );
        }
        for f in run_figures(out, &model.name, &result)? {
            println!("wrote        {}", f.display());
        }
    }
    Ok(())
}

fn plot_cmd(file: &Path, format: &str, out: Option<&Path>) -> Result<()> {
    let dir = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| file.parent().unwrap_or(Path::new(".")).to_path_buf());
    let formats =
        Format::list(format).with_context(|| format!("--format {format}: use png, svg or both"))?;
    for f in redraw(file, &dir, &formats)? {
        println!("wrote        {}", f.display());
    }
    Ok(())
}

/// Work-precision of a scene or an analysis study: the table on standard output and in
/// DIR/<name>.md, the numbers in DIR/<name>.h5, the figure drawn from that file.
fn precision_cmd(path: &Path, out: &Path, plots: bool, quiet: bool) -> Result<()> {
    let study = match Input::read(path)? {
        (Input::Analysis | Input::Precision, text) => Loaded::parse(&text, path)?,
        (Input::Comparison, _) => anyhow::bail!(
            "{}: a comparison study has several cases; give one scene or an analysis study",
            path.display()
        ),
        (Input::Scene, _) => precision::scene_study(path)?,
    };
    let start = Instant::now();
    let mut p = precision::Precision::new(study)?;
    let mut report = |pr: Progress| {
        if quiet {
            return;
        }
        let el = start.elapsed().as_secs_f64();
        match pr {
            Progress::Reference => eprintln!("[{el:7.1} s] reference"),
            Progress::Check => eprintln!("[{el:7.1} s] check of the reference"),
            Progress::Run { done, total, what } => {
                eprintln!("[{el:7.1} s] run {}/{total}: {what}", done + 1)
            }
            Progress::Start { .. } | Progress::Fraction { .. } | Progress::Done { .. } => {}
        }
    };
    let o = p
        .execute(&mut report)
        .with_context(|| format!("work-precision of {}", path.display()))?;
    let file = o.write(out, p.study())?;
    let md = out.join(format!("{}.md", o.name));
    let table = o.markdown();
    std::fs::write(&md, &table).with_context(|| format!("writing {}", md.display()))?;
    let mut figs = Vec::new();
    if plots {
        figs = redraw(&file, out, &[Format::Png, Format::Svg])?;
    }
    print!("{table}");
    println!();
    println!("wrote        {}", file.display());
    println!("             {}", md.display());
    for f in figs {
        println!("             {}", f.display());
    }
    println!("wall time    {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// Runs an analysis study (a single N-period run or a sweep) with a progress bar showing the
/// values done and the time left.
fn run_analysis(
    path: &Path,
    out: &Path,
    plots: bool,
    quiet: bool,
    mut opts: Options,
) -> Result<()> {
    let st = Loaded::load(path)?;
    let continuation_only = st.spec.sweep.is_none() && st.spec.continuation.is_some();
    if st.spec.sweep.is_none()
        && (opts.shard.is_some()
            || (!continuation_only && (opts.resume || opts.max_jobs.is_some())))
    {
        anyhow::bail!(
            "{}: --resume and --max-jobs apply to studies with a [sweep] or a [continuation], --shard to studies with a [sweep]",
            path.display()
        );
    }
    // A continuation's start state, read before the analysis rewrites the output file (it may
    // be the file named by `continuation.start`).
    let start_state = st.continuation_start()?;
    // A continuation goes on from its file; with none begun (stopped before its first point),
    // it starts afresh, as a sweep with nothing kept does.
    let file = out.join(format!("{}.h5", st.spec.study.name));
    if continuation_only && opts.resume && jointplay_analysis::study::continuation::begun(&file) {
        return resume_continuation(&st, path, out, plots, quiet, opts.max_jobs);
    }
    // In a Slurm job array, a sweep is sharded by the task's id unless --shard says otherwise.
    let mut from_env = false;
    if opts.shard.is_none() && st.spec.sweep.is_some() {
        opts.shard = Shard::from_slurm(|k| std::env::var(k).ok())
            .map_err(|m| anyhow::anyhow!("{}: {m}", path.display()))?;
        from_env = opts.shard.is_some();
    }
    // One writer of the study's file from the sweep or run to the end of its continuation (a
    // shard's file is locked by the shard's run).
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let _lock = match opts.shard {
        None => Some(jointplay_analysis::storage::lock::Lock::acquire(
            &out.join(format!("{}.h5", st.spec.study.name)),
        )?),
        Some(_) => None,
    };
    let bar = progress_bar(
        1000,
        "{spinner} [{elapsed_precise}] {bar:40} {msg} (eta {eta})",
    );
    let start = Instant::now();
    let tally = Mutex::new(Tally::default());
    let progress = |p: Progress| {
        let mut t = tally.lock().unwrap_or_else(|e| e.into_inner());
        t.update(p);
        let (done, total) = t.jobs();
        bar.set_position((t.fraction() * 1000.0) as u64);
        bar.set_message(format!("{done} of {total} values done"));
        if !quiet && start.elapsed().as_secs_f64() > 1.0 && bar.is_hidden() {
            bar.set_draw_target(ProgressDrawTarget::stderr());
        }
    };
    let res = execute(&st, out, opts, VERSION, &progress);
    bar.finish_and_clear();
    let o = res.with_context(|| match (from_env, opts.shard) {
        (true, Some(sh)) => format!(
            "running {} as shard {sh} (from SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT and \
             SLURM_ARRAY_TASK_MIN)",
            path.display()
        ),
        _ => format!("running {}", path.display()),
    })?;
    for w in &o.warnings {
        eprintln!("warning: {w}");
    }
    println!("study        {} ({})", st.spec.study.name, path.display());
    if let Some(sw) = &st.spec.sweep {
        println!(
            "sweep        {} over {} values{}; {} run now",
            sw.parameter,
            o.jobs,
            if sw.continuation {
                " (continuation, up and back down)"
            } else {
                ""
            },
            o.ran
        );
    }
    if let Some(sh) = opts.shard {
        println!(
            "shard        {sh}: {} of the {} values (index j with j mod {} = {})",
            o.jobs,
            st.jobs.len(),
            sh.count,
            sh.index
        );
    }
    println!(
        "periods      {} ({} transient), {} samples per period",
        st.spec.analysis.periods, st.spec.analysis.transient, st.spec.analysis.samples_per_period
    );
    // A single run's Lyapunov run evaluates the right-hand side too, within the same wall time.
    match jointplay_analysis::storage::chaos::lyapunov_rhs_evals(&o.file)? {
        Some(ly) => println!(
            "RHS          {} evaluations in the analysis run and {ly} in the Lyapunov run, {:.0} \
             per second of wall time",
            o.rhs_evals,
            (o.rhs_evals + ly) as f64 / o.wall.max(1e-9)
        ),
        None => println!(
            "RHS          {} evaluations, {:.0} per second of wall time",
            o.rhs_evals,
            o.rhs_evals as f64 / o.wall.max(1e-9)
        ),
    }
    println!("wall time    {:.3} s", o.wall);
    if o.threads > 1 {
        println!(
            "parallel     efficiency {:.0} % on {} threads (jobs {:.1} s of {} x {:.1} s)",
            100.0 * o.efficiency(),
            o.threads,
            o.busy,
            o.threads,
            o.wall
        );
    }
    for line in jointplay_analysis::storage::chaos::summary(&o.file)? {
        println!("{line}");
    }
    // Periodic orbits: followed once the analysis file is written, into the same file (not by a
    // shard, which holds only part of a sweep).
    let mut continuation_error = None;
    if st.spec.continuation.is_some()
        && opts.shard.is_none()
        && !jointplay_analysis::progress::process_stop_requested()
    {
        let begin = jointplay_analysis::study::continuation::Begin::Fresh(start_state);
        let limit = opts.max_jobs.filter(|_| continuation_only);
        continuation_error = follow_orbits(&st, &o.file, begin, quiet, limit)?;
    }
    println!("wrote        {}", o.file.display());
    for t in &o.tables {
        println!("wrote        {}", t.display());
    }
    if opts.shard.is_some() {
        // Shards may run side by side into one directory: the figures come from the merge.
        if plots {
            println!("figures      drawn by `jointplay merge` from the merged file");
        }
    } else if plots {
        for f in redraw(&o.file, out, &[Format::Png, Format::Svg])? {
            println!("wrote        {}", f.display());
        }
    }
    if !o.complete && st.spec.sweep.is_none() {
        // One run has no finished values to keep: it runs again from its start.
        println!("incomplete   stopped before its end: run the same command again to redo it");
    } else if !o.complete {
        println!(
            "incomplete   stopped after {} values: rerun with --resume{} to compute the rest",
            o.ran,
            opts.shard
                .map(|s| format!(" --shard {s}"))
                .unwrap_or_default()
        );
    }
    if !o.failed.is_empty() {
        if st.jobs.is_empty() {
            anyhow::bail!(
                "{}: {}\nwrote {} with what was computed before the failure, marked incomplete (attribute complete = 0)",
                path.display(),
                o.failed[0].1,
                o.file.display()
            );
        }
        for (j, m) in &o.failed {
            eprintln!("failed       value {} ({}): {m}", j, st.jobs[*j].0);
        }
        anyhow::bail!(
            "{} of {} values failed; the others are in {}",
            o.failed.len(),
            o.jobs,
            o.file.display()
        );
    }
    if let Some(e) = continuation_error {
        anyhow::bail!(
            "{}: the continuation could not start: {e}\n(the analysis is in {}; /continuation holds the error)",
            path.display(),
            o.file.display()
        );
    }
    Ok(())
}

/// Follows the periodic orbits of a study's `[continuation]` into its analysis file `file`,
/// writing the file after every point (a stopped run keeps what it computed, for `--resume`),
/// with a progress bar on a terminal and a line per point otherwise. At most `limit` points are
/// computed now. Returns the error of a continuation that could not start (written into the
/// file).
fn follow_orbits(
    st: &Loaded,
    file: &Path,
    begin: jointplay_analysis::study::continuation::Begin,
    quiet: bool,
    limit: Option<usize>,
) -> Result<Option<jointplay_analysis::Error>> {
    use jointplay_analysis::study::continuation;
    let bar = progress_bar(
        1000,
        "{spinner} [{elapsed_precise}] {bar:40} continuation (eta {eta})",
    );
    if !quiet && std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let mut points = 0usize;
    let res = continuation::run_into(st, file, begin, limit, &mut |r| {
        bar.set_position((r.fraction * 1000.0) as u64);
        if !quiet && bar.is_hidden() {
            println!("point        {}", r.line);
        }
        points += 1;
        !jointplay_analysis::progress::process_stop_requested()
    });
    bar.finish_and_clear();
    let res = res.context("writing the continuation into the analysis file")?;
    match res {
        Ok(c) => {
            for line in continuation::summary(&c) {
                println!("{line}");
            }
            if c.unfinished.is_some() {
                println!(
                    "incomplete   stopped after {points} points: rerun with --resume to go on"
                );
            }
            Ok(None)
        }
        Err(e) => Ok(Some(e)),
    }
}

/// `jointplay run STUDY --resume` for a study with a `[continuation]` and no sweep: goes on with
/// the unfinished continuation of DIR/<name>.h5.
fn resume_continuation(
    st: &Loaded,
    path: &Path,
    out: &Path,
    plots: bool,
    quiet: bool,
    limit: Option<usize>,
) -> Result<()> {
    let file = out.join(format!("{}.h5", st.spec.study.name));
    if !file.exists() {
        anyhow::bail!(
            "{}: nothing to resume: {} does not exist (run without --resume)",
            path.display(),
            file.display()
        );
    }
    let Some(prior) = jointplay_analysis::study::continuation::read_unfinished(&file, st)? else {
        if jointplay_analysis::study::continuation::is_finished(&file)? {
            println!(
                "finished     the continuation in {} is finished: nothing to resume",
                file.display()
            );
            return Ok(());
        }
        anyhow::bail!(
            "{}: nothing to resume: {} has no continuation (run without --resume)",
            path.display(),
            file.display()
        );
    };
    println!("study        {} ({})", st.spec.study.name, path.display());
    println!(
        "resume       {} branches and {} special points kept",
        prior.branches.len(),
        prior.specials.len()
    );
    let begin = jointplay_analysis::study::continuation::Begin::Resume(prior);
    if let Some(e) = follow_orbits(st, &file, begin, quiet, limit)? {
        anyhow::bail!("{}: the continuation could not go on: {e}", path.display());
    }
    println!("wrote        {}", file.display());
    if plots {
        for f in redraw(&file, out, &[Format::Png, Format::Svg])? {
            println!("wrote        {}", f.display());
        }
    }
    Ok(())
}

fn compare(
    files: &[PathBuf],
    dataset: &str,
    component: usize,
    out: &Path,
    title: Option<String>,
) -> Result<()> {
    let panel = overlay(files, dataset, component, title)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    for fmt in [Format::Png, Format::Svg] {
        println!(
            "wrote        {}",
            figure(out, fmt, std::slice::from_ref(&panel), 1)?.display()
        );
    }
    Ok(())
}

/// In a Slurm job, rayon uses the job's CPUs per task (`SLURM_CPUS_PER_TASK`) unless
/// `RAYON_NUM_THREADS` is set.
fn threads_from_slurm() -> Result<()> {
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

/// Merges shard files into the study file, prints what the values cost and draws the figures.
fn merge_cmd(files: &[PathBuf], out: &Path, partial: bool, plots: bool) -> Result<()> {
    let m = merge(files, out, VERSION, partial)?;
    println!(
        "merged       {} shard files of {} into {} values",
        files.len(),
        m.shards,
        m.jobs
    );
    let w = &m.value_walls;
    if !w.is_empty() {
        let total: f64 = w.iter().sum();
        let max = w.iter().fold(0.0f64, |a, &b| a.max(b));
        println!(
            "cost         {total:.3} s of computing over {} values: {:.4} s per value on \
             average, {max:.4} s at most",
            w.len(),
            total / w.len() as f64
        );
    }
    if let (Some(lo), Some(hi)) = (
        m.shard_walls.iter().min_by(|a, b| a.1.total_cmp(&b.1)),
        m.shard_walls.iter().max_by(|a, b| a.1.total_cmp(&b.1)),
    ) {
        println!(
            "shards       {:.3} s (shard {}) to {:.3} s (shard {}) of wall time each",
            lo.1, lo.0, hi.1, hi.0
        );
    }
    println!("wrote        {}", m.file.display());
    for t in &m.tables {
        println!("wrote        {}", t.display());
    }
    if plots {
        let dir = out
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        for f in redraw(&m.file, dir, &[Format::Png, Format::Svg])? {
            println!("wrote        {}", f.display());
        }
    }
    if !m.not_done.is_empty() {
        println!(
            "incomplete   {} values written as not done: finish with `jointplay run STUDY --out \
             DIR --resume`",
            m.not_done.len()
        );
    }
    Ok(())
}

/// What `jointplay slurm` asks of the cluster.
struct SlurmOptions {
    shards: usize,
    partition: Option<String>,
    time: Option<String>,
    cpus_per_task: usize,
    mem: Option<String>,
    max_running: Option<usize>,
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
fn slurm_cmd(study: &Path, out: &Path, o: SlurmOptions, submit: bool) -> Result<()> {
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
