//! # jointplay-analysis
//!
//! Runs of a compiled model and what comes out of them: [`run`] integrates a model and records the
//! requested outputs, observables of [`observe`], at exact sample times; [`h5`] writes a
//! recording to HDF5 (layout in book/src/reference/hdf5.md) and holds the helpers every file kind is written and
//! read with; [`study`] reads study files (several cases of a scene, edited by path) and
//! [`report`] computes their comparison table from the written file; [`figures`] draws every
//! figure (runs, studies, analysis files, work-precision) over [`plot`], which draws PNG and SVG
//! with an embedded font (no system fonts needed).
//!
//! Nonlinear analysis works on any flow: [`sections`] runs N periods of an ODE and keeps the
//! stroboscopic and hyperplane Poincare sections; [`observe`] addresses a mechanism's quantities
//! by path; [`systems`] holds the built-in reference ODEs (Duffing, pendulum, Lorenz); and
//! [`nonlinear`] reads analysis studies, runs their sweeps in parallel and streams them to HDF5;
//! [`storage`] keeps what is finished through kills, full disks and second writers (a journal of
//! checksummed values, files replaced atomically, one lock per output);
//! [`shards`] splits a sweep over processes or machines and merges the shard files exactly, and
//! [`slurm`] writes the batch scripts that run the shards as a Slurm job array;
//! [`hybrid`] saves and loads the hybrid state of a run (continue a run as if it never stopped);
//! [`tangent`], [`lyapunov`], [`zero_one`] and [`chaos`] say whether a motion is chaotic: Lyapunov
//! spectra through contacts and impacts, the 0-1 test, and a classification of each run or sweep
//! value;
//! [`precision`] measures what accuracy costs: every integrator against a tight reference.
//!
//! Around them: [`summary`] is the compiled summary of a scene (what `jointplay check` prints);
//! [`inputs`] tells what kind of TOML input or written HDF5 file a path is; [`comparison`] runs a
//! comparison study end to end (its file, its table, its figures); [`progress`] is the one type in
//! which every long computation reports its progress.
//!
//! Every analysis is written against one flow interface ([`flow::Flow`]: mechanisms and built-in
//! systems alike) and one hybrid state ([`jointplay_solver::state::HybridState`], saved and loaded
//! by [`hybrid`]). Kept on purpose: sections generic over any flow; atomic and bit-reproducible
//! HDF5 output (a file is complete or absent, and the same run writes the same bits); errors that
//! name the file and the field.

pub mod bitround;
pub mod chaos;
mod chunk;
pub mod comparison;
pub mod continuation;
pub mod figures;
pub mod flow;
pub mod h5;
pub mod hybrid;
pub mod inputs;
pub mod lyapunov;
pub mod nonlinear;
pub mod observe;
pub mod periodic;
pub mod plot;
pub mod precision;
pub mod progress;
pub mod report;
pub mod run;
pub mod schedule;
pub mod sections;
pub mod shards;
pub mod slurm;
pub mod storage;
pub mod study;
pub mod summary;
pub mod sweep_table;
pub mod systems;
pub mod tangent;
pub mod zero_one;

use std::path::PathBuf;

pub use jointplay_solver::error::{MESSAGE_LIMIT, clip, clip_lines};

/// Errors of the analysis crate.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Solver(#[from] jointplay_solver::Error),
    #[error("{file}: HDF5: {message}")]
    Hdf5 { file: PathBuf, message: String },
    #[error("{file}: {message}")]
    Io { file: PathBuf, message: String },
    #[error("{file}: {field}: {message}")]
    Study {
        file: PathBuf,
        field: String,
        message: String,
    },
    /// A computation stopped on request ([`progress::Stop`]), at simulated time `time` (s) when
    /// it stopped inside a run.
    #[error("interrupted on request{}", .time.map(|t| format!(" at t = {t} s")).unwrap_or_default())]
    Interrupted { time: Option<f64> },
    /// A periodic orbit could not be found or followed: what failed.
    #[error("periodic orbit: {0}")]
    Orbit(String),
    #[error("case '{label}': {inner}")]
    Case { label: String, inner: Box<Error> },
    #[error("{file}: plot: {message}")]
    Plot { file: PathBuf, message: String },
    #[error("reading {file}: {message}")]
    Read { file: PathBuf, message: String },
    #[error("writing {file}: {message}")]
    Write { file: PathBuf, message: String },
    /// No case of a comparison study finished; one message per case.
    #[error("running study {file}: every case failed:\n  {}", .failures.join("\n  "))]
    EveryCaseFailed {
        file: PathBuf,
        failures: Vec<String>,
    },
    /// Some cases of a comparison study failed (the others are written); one message per failure.
    #[error(
        "{} of {cases} cases of study {file} failed (the others are written; the file records the failures):\n  {}",
        .failures.len(),
        .failures.join("\n  ")
    )]
    CasesFailed {
        file: PathBuf,
        cases: usize,
        failures: Vec<String>,
    },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The most threads a computation may be given: 1024, or 64 per available core on a machine
/// with more than 16. A count beyond it is a mistake (`threads=10**6` started threads until
/// the machine stalled), not a setting.
pub fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    1024usize.max(cores.saturating_mul(64))
}

/// Whether `name` is non-empty and made of ASCII letters, digits and the characters of `also`:
/// the names that become HDF5 paths or parts of file names.
pub(crate) fn plain_name(name: &str, also: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || also.contains(c))
}
