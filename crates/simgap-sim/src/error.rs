//! Errors of `simgap-sim`.

use std::path::PathBuf;

/// Everything that can go wrong reading, writing or simulating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A log file could not be read or is not what was expected.
    #[error("{path}: {message}")]
    Log {
        /// The file.
        path: PathBuf,
        /// What was expected and what was found.
        message: String,
    },
    /// Writing a log failed.
    #[error("{path}: cannot write log: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        message: String,
    },
    /// A log's joints do not match the model.
    #[error("{source_name}: joint '{joint}' {problem}")]
    JointMismatch {
        /// The log.
        source_name: String,
        /// The joint.
        joint: String,
        /// What is wrong (e.g. `is in the model but not in the log`).
        problem: String,
    },
    /// The simulation diverged.
    #[error("simulation diverged at t = {t} s on joint '{joint}': {detail}")]
    Diverged {
        /// Time [s].
        t: f64,
        /// The joint.
        joint: String,
        /// What happened.
        detail: String,
    },
    /// The run was interrupted.
    #[error("interrupted at t = {t} s")]
    Interrupted {
        /// Time [s].
        t: f64,
    },
    /// Bad parameters (gains, durations, references, effects).
    #[error("invalid {what}: {message}")]
    Invalid {
        /// Which parameter.
        what: String,
        /// What was expected.
        message: String,
    },
    /// A model error.
    #[error(transparent)]
    Model(#[from] simgap_core::Error),
}

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
