//! Studies: what a user asks for in a file, loaded, checked and run, over the flows and
//! measures below and written through [`crate::storage`].
//!
//! * [`spec`]: comparison studies (cases of one scene edited by path) and the edits by path that
//!   every study kind uses; [`run`] one run of a scene, its samples recorded at exact times;
//!   [`comparison`] a comparison study end to end and [`report`] its table.
//! * [`analysis`]: analysis studies (a scene or a built-in system, sections, an optional sweep,
//!   chaos indicators), loaded and checked, and the sweep executor that runs their values in
//!   parallel; [`schedule`] the order of their jobs.
//! * [`continuation`]: periodic orbits followed across a parameter (pseudo-arclength), with
//!   their bifurcations and branch switching.
//! * [`precision`]: work-precision studies (what accuracy costs).
//! * [`shards`]: a sweep split over processes or machines and merged exactly; [`slurm`] the
//!   batch scripts that run the shards as a Slurm job array.

pub mod analysis;
pub mod comparison;
pub mod continuation;
pub mod precision;
pub mod report;
pub mod run;
pub mod schedule;
pub mod shards;
pub mod slurm;
pub mod spec;
