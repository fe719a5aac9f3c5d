//! Nonlinear-analysis studies: N-period runs, Poincare sections and bifurcation sweeps of a
//! mechanism scene or a built-in reference system, written to one HDF5 file.
//!
//! A study file with an `[analysis]` table (format in book/src/reference/analysis.md) names a
//! flow (`study.scene`, edited like a comparison study's cases, or `study.system`), the run
//! ([`Plan`](crate::measures::sections::Plan): periods, transient, phase, samples per period), the observables by path
//! ([`crate::flow::observe`]), hyperplane sections, an optional sweep and the figures.
//!
//! **Sweeps.** Each value of the swept parameter is one job. Independent jobs run in parallel on
//! rayon's pool; with `continuation = true` the jobs run in order up the list and back down, each
//! starting from the previous job's final state. Every job's results go into the sweep's journal
//! as soon as it finishes (the jobs run on the caller's rayon pool and send their results through
//! a channel to one writer thread, which forces each record to disk), and the file is written
//! from the journal when the sweep ends or stops ([`crate::storage::sweep`]), so an interrupted
//! sweep keeps every finished job: the file's `complete` attribute is 0 until all jobs are done, `/sweep/done` marks each job (0 not run,
//! 1 done, 2 failed, its message in `/sweep/errors`), and `resume` runs only the jobs not done.
//! Each job's result depends only on its inputs, so the datasets are bit-identical whatever the
//! number of threads and whether the sweep was interrupted.
//!
//! **Shards.** With [`Options::shard`](sweep::Options::shard), a sweep computes only the values of one shard into its
//! own file ([`crate::study::shards`]: assignment, shard files, the merge); the file is written by the
//! same code, its rows being the shard's jobs.

//!
//! The files, in the order they build on each other:
//!
//! * [`spec`]: the study file as data (`[study]`, `[analysis]`, `[[observables]]`, `[[sections]]`,
//!   `[sweep]`, `[[figures]]`, and the `[lyapunov]`, `[zero_one]`, `[continuation]` and
//!   `[precision]` tables of the measures and studies that read it), and the sweep's jobs;
//! * [`load`]: a study file read and checked against its scene or system ([`Loaded`]), every
//!   error naming the field, and the flow of each parameter value compiled from it;
//! * [`job`]: one job (one parameter value, or the single run): its sections, its chaos
//!   measures, and what it stores ([`crate::storage::analysis_file::JobResult`]);
//! * [`sweep`]: the executor ([`execute_until`]): the file set up or resumed, the jobs run in
//!   parallel (or in order for a continuation sweep), their results written through the journal.

pub mod job;
pub mod load;
pub mod spec;
pub mod sweep;

pub use load::Loaded;
pub use spec::{
    AnalysisSpec, AnalysisStudy, FigureKind, FigureSpec, Header, SectionSpec, SweepSpec,
    is_analysis,
};
pub use sweep::{Options, Outcome, execute, execute_until};
