//! The solver crate's one error type.
//!
//! Every variant carries what a user needs to find the cause: the scene file, the field path inside
//! it (`joints[3].axis_a`), the joint or drive name, or the simulated time at which the numerics
//! failed. Nothing in this crate panics on user input.

use std::path::PathBuf;

/// Errors raised while reading, validating, compiling or simulating a scene.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene file could not be read.
    #[error("{file}: cannot read")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The scene is not valid TOML or does not match the scene schema.
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    /// A field has a value the solver cannot accept.
    #[error("{file}: {field}: {message}")]
    Invalid {
        file: PathBuf,
        field: String,
        message: String,
    },
    /// The initial configuration could not be brought onto the constraints.
    #[error("{file}: initial assembly failed at t = {time} s: {message}")]
    Assembly {
        file: PathBuf,
        time: f64,
        message: String,
    },
    /// The integration produced a non-finite state or could not continue.
    #[error("integration stopped at t = {time} s: {message}")]
    Diverged { time: f64, message: String },
}

/// Result alias of the solver crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
