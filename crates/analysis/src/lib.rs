//! # jointplay-analysis
//!
//! Runs of a compiled model and what comes out of them, in layers that point one way (a module
//! uses its own layer and the layers below it, never above; `tests/module_graph.rs` holds the
//! crate to it and to having no import cycle):
//!
//! ```text
//! execute    the one entry point of the program and the Python package: a study run, the
//!            options that apply to it, and what it wrote, as data
//! figures    drawn from written files and the outcomes studies return, over figures::plot
//! study      what a user asks for in a file: specs, loading, one run, the sweep executor,
//!            continuation, work-precision, comparison studies, shards and Slurm
//! storage    every file kind (runs, analysis and sweep files, shards, checkpoints, tables)
//!            and the crash-safe writes and verified reads they share
//! measures   sections, Lyapunov spectra, the 0-1 test, chaos classes, periodic orbits
//! flow       flows of mechanisms and built-in systems, tangents, observables, the summary
//! progress   progress reports and stop requests, shared by every layer
//! ```
//!
//! * [`flow`]: one flow interface ([`flow::Flow`]) for mechanisms and the built-in reference
//!   systems ([`flow::systems`]: Duffing, pendulum, Lorenz, ...), their tangent dynamics
//!   ([`flow::tangent`]), quantities addressed by path ([`flow::observe`]), and the compiled
//!   summary of a scene ([`flow::summary`], what `jointplay check` prints).
//! * [`measures`]: what a motion is, over any flow: Poincare sections
//!   ([`measures::sections`]), Lyapunov spectra through contacts and impacts
//!   ([`measures::lyapunov`]), the 0-1 test ([`measures::zero_one`]), a classification
//!   ([`measures::chaos`]) and periodic orbits by shooting ([`measures::periodic`]).
//! * [`storage`]: every file kind and what keeps finished work through kills, full disks and
//!   second writers (a journal of checksummed values, files replaced atomically, one lock per
//!   output); the HDF5 helpers ([`storage::h5`], layout in book/src/reference/hdf5.md).
//! * [`study`]: comparison studies ([`study::spec`], [`study::comparison`], [`study::report`]),
//!   single runs ([`study::run`]), analysis studies and their sweeps ([`study::analysis`]),
//!   continuation ([`study::continuation`]), work-precision ([`study::precision`]), shards
//!   ([`study::shards`]) and Slurm batch scripts ([`study::slurm`]).
//! * [`execute`]: what `jointplay run STUDY`, `jointplay precision` and Python's `run_study`
//!   call ([`execute::execute`]); it returns what they print or convert ([`execute::Outcome`]).
//! * [`figures`]: every figure (runs, studies, analysis files, work-precision) as PNG and SVG
//!   over [`figures::plot`], with an embedded font (no system fonts needed).
//!
//! Every analysis is written against one flow interface and one hybrid state
//! ([`jointplay_solver::state::HybridState`], saved and loaded by [`storage::hybrid`]). Kept on
//! purpose: sections generic over any flow; atomic and bit-reproducible HDF5 output (a file is
//! complete or absent, and the same run writes the same bits); errors that name the file and
//! the field.

pub mod execute;
pub mod figures;
pub mod flow;
pub mod measures;
pub mod progress;
pub mod storage;
pub mod study;

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
    /// What was being done when `inner` happened ("running STUDY", "work-precision of FILE").
    #[error("{what}: {inner}")]
    Context { what: String, inner: Box<Error> },
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
