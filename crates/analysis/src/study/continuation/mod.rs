//! Periodic orbits followed across a parameter: pseudo-arclength continuation on the
//! stroboscopic map, with the bifurcations and grazings of each branch located and the period
//! doublings switched to the doubled branch.
//!
//! The files, in the order they build on each other:
//!
//! * [`spec`]: the study's `[continuation]` table as data, checked, and the numerical
//!   [`Settings`] it gives;
//! * [`branch`]: what a continuation finds ([`Continuation`]: branches of [`Point`]s, their
//!   special points) and its summary lines;
//! * [`follow`]: the algorithm (predictor, corrector, step control, test functions, location,
//!   branch switching) over any flow ([`continuation`], [`resume`]);
//! * [`start`]: a start state read from an earlier file and checked;
//! * [`file`](mod@file): the continuation in HDF5: the state kept after every point
//!   (`<study>.continuation.h5`) and the group of the analysis file;
//! * [`run`]: a continuation study end to end ([`run_study`], [`run_into`]), fresh or resumed.

pub mod branch;
pub mod file;
pub mod follow;
pub mod run;
pub mod spec;
pub mod start;

pub use branch::{Branch, Continuation, Kind, Point, Report, Special, Unfinished, summary};
pub use file::{begun, is_finished, read_unfinished, snapshot_path, write, write_snapshot};
pub use follow::{continuation, resume};
pub use run::{Begin, run_into, run_study};
pub use spec::{ContinuationSpec, GrazingSpec, Settings, StartSpec};
