//! Periodic orbits followed across a parameter: pseudo-arclength continuation on the
//! stroboscopic map, with the bifurcations and grazings of each branch located and the period
//! doublings switched to the doubled branch.
//!
//! The files, in the order they build on each other:
//!
//! * [`spec`]: the study's `[continuation]` table as data, checked, and the numerical
//!   [`Settings`] it gives;
//! * [`branch`]: what a continuation reports while it runs and its summary lines (what it
//!   finds, [`Continuation`]: branches of [`Point`]s and their special points, is data of
//!   [`crate::storage::branches`]);
//! * [`follow`]: the algorithm (predictor, corrector, step control, test functions, location,
//!   branch switching) over any flow ([`continuation`], [`resume`]);
//! * [`start`]: a start state read from an earlier file and checked;
//! * [`run`]: a continuation study end to end ([`run_study`], [`run_into`]), fresh or resumed,
//!   its files written by [`crate::storage::continuation_file`] (the state kept after every
//!   point in `<study>.continuation.h5`, and the group of the analysis file).

pub mod branch;
pub mod follow;
pub mod run;
pub mod spec;
pub mod start;

pub use crate::storage::branches::{Branch, Continuation, Kind, Point, Special, Unfinished};
pub use crate::storage::continuation_file::{
    begun, is_finished, read_unfinished, snapshot_path, write, write_snapshot,
};
pub use branch::{Report, summary};
pub use follow::{continuation, resume};
pub use run::{Begin, layout, run_into, run_study};
pub use spec::{ContinuationSpec, GrazingSpec, Settings, StartSpec};
