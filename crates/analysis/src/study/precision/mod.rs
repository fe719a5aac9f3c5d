//! Work-precision: what accuracy costs. Every integrator, at a range of tolerances or steps, is
//! run against a tight reference, and the error of each run at the strobe points (or a run's
//! samples) is set against its right-hand-side evaluations and its wall time.
//!
//! * [`spec`]: the `[precision]` table;
//! * [`measure`]: the runs and their errors ([`Precision`]);
//! * [`outcome`]: the table of what they measured (the data and its file are
//!   [`crate::storage::precision_file`]).

pub mod measure;
pub mod outcome;
pub mod spec;

pub use crate::storage::precision_file::{Errors, Outcome, RunRecord, is_precision_file};
pub use measure::{Precision, scene_study};
pub use spec::{FamilySpec, MethodSpec, PrecisionSpec};
