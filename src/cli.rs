//! The command line: the commands, their arguments and their help texts (`jointplay --help`,
//! reproduced in book/src/reference/cli-help.md).

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use jointplay_analysis::storage::analysis_file::Shard;

#[derive(Parser)]
#[command(
    name = "jointplay",
    version,
    about = "Nonlinear dynamics of mechanisms with joint clearance"
)]
pub struct Cli {
    /// The oldest HDF5 library the files written must open in: 1.10 (default; smaller files:
    /// chunk indexes and object headers of the 1.10 format) or 1.8 (the oldest format).
    #[arg(long, global = true, value_name = "VERSION", default_value = "1.10")]
    pub hdf5_format: jointplay_analysis::storage::h5::Format,
    /// The size of one figure panel, WIDTHxHEIGHT in px at scale 1 (a figure of several panels
    /// is a grid of them).
    #[arg(long, global = true, value_name = "WxH", default_value = "560x380",
          value_parser = jointplay_analysis::figures::plot::parse_panel_size)]
    pub figure_size: (u32, u32),
    /// The figures' resolution factor: every pixel dimension (size, lines, points, fonts)
    /// times this, 0.25 to 8 (2 for print: a 1120 x 760 px panel that looks as the default).
    #[arg(long, global = true, value_name = "F", default_value_t = 1.0)]
    pub figure_scale: f64,
    /// The figures' font size factor, 0.5 to 4 (tick labels 13 px, axis labels 15 px, titles
    /// 20 px at 1, before --figure-scale).
    #[arg(long, global = true, value_name = "F", default_value_t = 1.0)]
    pub font_scale: f64,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
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
        /// Draw the [[figures]] of this TOML file (the study edited, or a file of figures
        /// alone) instead of the study's own: a title, a scale or a picked value changed without
        /// running the study again.
        #[arg(long)]
        figures: Option<PathBuf>,
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
    /// Export a run's samples for spreadsheets (CSV: a table with a header of observable paths
    /// and SI units) or MATLAB and Octave (MAT level 5: a matrix per dataset, `time`, and the
    /// structs `units` and `columns`). Writes DIR/<file>.csv or .mat (DIR/<file>-<case>.* for a
    /// case of a comparison study).
    Export {
        /// Run file written by `jointplay run SCENE`, or a comparison study's file with --case.
        file: PathBuf,
        /// csv or mat.
        #[arg(long, value_enum)]
        format: ExportFormat,
        /// The case of a comparison study's file to export.
        #[arg(long)]
        case: Option<String>,
        /// Only this dataset (repeat for several), e.g. bodies/slider/acceleration; default all
        /// with a row per sample.
        #[arg(long)]
        dataset: Vec<String>,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Animate a run: one self-contained HTML page (DIR/<file>.html, DIR/<file>-<case>.html for a
    /// case of a comparison study; a sweep value or a periodic orbit of an analysis study is run
    /// again from the state its file keeps) that shows the mechanism in 3D with play, pause, a time
    /// slider, speeds and a turning camera, and beside it each clearance joint's orbit in its
    /// magnified clearance, coloured by the contact force; with --glb also a glTF 2.0 file
    /// (.glb) with the motion as node animation, for Blender and any glTF viewer.
    Animate {
        /// Run file written by `jointplay run SCENE`, or a comparison study's file with --case.
        file: PathBuf,
        /// The case of a comparison study's file to animate.
        #[arg(long, conflicts_with_all = ["value", "orbit"])]
        case: Option<String>,
        /// An analysis study's sweep value to animate: the motion is run again for --periods
        /// drive periods from the state that value's run ended in (DIR/<file>-value-<V>.html).
        #[arg(long, conflicts_with = "orbit")]
        value: Option<f64>,
        /// Drive periods shown of a sweep value.
        #[arg(long, default_value_t = 1.0, requires = "value")]
        periods: f64,
        /// A periodic orbit of an analysis study's continuation, BRANCH:POINT (e.g. 0:3): one
        /// period of it, run again from its strobe point (DIR/<file>-orbit-<B>-<P>.html).
        #[arg(long, value_name = "BRANCH:POINT")]
        orbit: Option<String>,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Evenly spaced frames kept from the run's samples (besides every sample where a
        /// contact opens or closes and each contact's force peak).
        #[arg(long, default_value_t = 4000)]
        frames: usize,
        /// Simulated seconds per second of playback when the page opens (default: a round
        /// number near a tenth of the run's duration).
        #[arg(long)]
        speed: Option<f64>,
        /// Also write DIR/<file>.glb: the mechanism and its motion as glTF 2.0.
        #[arg(long)]
        glb: bool,
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

/// The formats `jointplay export` writes.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum ExportFormat {
    Csv,
    Mat,
}
