//! # jointplay-solver
//!
//! Rigid multibody dynamics of mechanisms in Cartesian coordinates: Newton-Euler equations of each
//! body, ideal joints as constraints enforced by Lagrange multipliers with Baumgarte stabilisation,
//! prescribed joint motions (drives), and the ODE integrators that advance them.
//!
//! Data flows one way: a scene file ([`scene::SceneSpec`], TOML) is validated and compiled into an
//! immutable [`model::Model`] and an initial [`model::State`]; [`model::Model::assemble`] puts that
//! state on the constraints; [`dynamics::Mechanism`] exposes the model as an [`ode::OdeSystem`] that
//! [`ode::integrate`] advances. All quantities are SI: m, kg, s, rad, N, N m. A run's whole state,
//! memories included, is a [`state::HybridState`] that [`ode::advance`] continues.
//!
//! Kept on purpose, and to be kept: the split between the immutable model and the
//! [`workspace::Workspace`], so that no step allocates; contact laws as pure functions with their
//! sources ([`contact`]); joints as sums of constraint primitives ([`model::Prim`]); the
//! hand-written sparse LDL^T with its minimum-norm solution for redundant constraints
//! ([`linalg`]); `disable` meaning the scene without the effect ([`disable`]); errors that name the
//! file and the field ([`error`]); modules that import each other without cycles (small shared
//! types in the leaf [`kin`]; `tests/module_graph.rs` checks it).

// Index loops over small fixed-size blocks mirror the formulas they implement (rows, columns,
// vector components); iterator chains would hide the math.
#![allow(clippy::needless_range_loop)]

pub mod clearance;
mod compile;
pub mod contact;
pub mod coupling;
pub mod disable;
pub mod dynamics;
pub mod error;
pub mod film;
pub mod guard;
pub mod kin;
pub mod linalg;
pub mod model;
pub mod ode;
pub mod profile;
pub mod scene;
pub mod state;
pub mod workspace;

pub use error::{Error, Result};
