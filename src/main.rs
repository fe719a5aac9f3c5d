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

mod cli;
mod files;
mod print;
mod scene;
mod slurm;

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Parser;
use jointplay_analysis::execute::{Caller, ExecOptions, Source, check_options, execute};
use jointplay_analysis::progress::Stop;
use jointplay_analysis::storage::analysis_file::Shard;
use jointplay_analysis::storage::inputs::Input;

use cli::{Cli, Command};

/// The program version written into every output file.
const VERSION: &str = env!("CARGO_PKG_VERSION");

/// What `jointplay run` and `jointplay precision` were asked.
#[derive(Default)]
struct Options {
    out: PathBuf,
    plots: bool,
    quiet: bool,
    resume: bool,
    max_jobs: Option<usize>,
    shard: Option<Shard>,
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
    use jointplay_analysis::figures::plot::{Style, set_style};
    match Style::new(cli.figure_size, cli.figure_scale, cli.font_scale) {
        Ok(style) => set_style(style),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
    if let Err(e) = slurm::threads_from_slurm() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
    let res = match cli.command {
        Command::Check { scene } => scene::check(&scene),
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
            Options {
                out,
                plots: !no_plots,
                quiet,
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
        } => files::merge_cmd(&files, &out, partial, !no_plots),
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
        } => slurm::slurm_cmd(
            &study,
            &out,
            slurm::SlurmOptions {
                shards,
                partition,
                time,
                cpus_per_task,
                mem,
                max_running,
            },
            submit,
        ),
        Command::Plot {
            file,
            format,
            out,
            figures,
        } => files::plot_cmd(&file, &format, out.as_deref(), figures.as_deref()),
        Command::Report { file, out } => files::report_cmd(&file, out.as_deref()),
        Command::Export {
            file,
            format,
            case,
            dataset,
            out,
        } => files::export(&file, format, case.as_deref(), &dataset, &out),
        Command::Animate {
            file,
            case,
            value,
            periods,
            orbit,
            out,
            frames,
            speed,
            glb,
        } => files::animate(
            &file,
            files::Picked {
                case: case.as_deref(),
                value,
                periods,
                orbit: orbit.as_deref(),
            },
            &out,
            frames,
            speed,
            glb,
        ),
        Command::Precision {
            file,
            out,
            no_plots,
            quiet,
        } => study(
            &file,
            Options {
                out,
                plots: !no_plots,
                quiet,
                ..Options::default()
            },
            true,
            false,
        ),
        Command::Compare {
            files,
            dataset,
            component,
            out,
            title,
        } => files::compare(&files, &dataset, component, &out, title),
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

/// `jointplay run`: a scene simulated, or a study run.
fn run(path: &Path, o: Options, from: Option<&Path>) -> Result<()> {
    let (kind, _) = Input::read(path)?;
    if from.is_some() && kind != Input::Scene {
        anyhow::bail!(
            "{}: --from continues a scene's run; this is a study",
            path.display()
        );
    }
    if kind != Input::Scene {
        return study(path, o, false, kind == Input::Comparison);
    }
    // A scene takes none of a study's options.
    check_options(path, kind, &exec_options(&o, false))?;
    scene::run_scene(path, &o.out, o.plots, o.quiet, from)
}

fn exec_options(o: &Options, precision: bool) -> ExecOptions<'static> {
    static ENV: fn(&str) -> Option<String> = |k| std::env::var(k).ok();
    ExecOptions {
        out: o.out.clone(),
        plots: o.plots,
        precision,
        resume: o.resume,
        max_jobs: o.max_jobs,
        shard: o.shard,
        // In a Slurm job array, a sweep is sharded by the task's id unless --shard says otherwise.
        env: Some(&ENV),
        version: VERSION,
        caller: Caller::Program,
    }
}

/// A study run (`jointplay run STUDY`), or the work-precision of a study or a scene (`jointplay
/// precision`), with its progress on standard error and what it wrote on standard output.
fn study(path: &Path, o: Options, precision: bool, comparison: bool) -> Result<()> {
    let reporter = print::Reporter::new(path, o.quiet, precision, comparison);
    let res = execute(
        &Source::File(path.to_path_buf()),
        &exec_options(&o, precision),
        &|r| reporter.report(r),
        &Stop::new(),
    );
    reporter.finish();
    print::outcome(&res?)
}
