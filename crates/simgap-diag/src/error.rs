//! Errors of `simgap-diag`.

/// Everything that can stop a diagnosis.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A log does not fit the model or the diagnosis (joints, length, experiment).
    #[error("{log}: {message}")]
    Log {
        /// The log (file name).
        log: String,
        /// What was expected and what was found.
        message: String,
    },
    /// Nothing to fit or to hold out.
    #[error("{0}")]
    Input(String),
    /// A fit failed (singular data, no motion).
    #[error("fit failed: {0}")]
    Fit(String),
    /// Simulation or log error.
    #[error(transparent)]
    Sim(#[from] simgap_sim::Error),
    /// Model error.
    #[error(transparent)]
    Model(#[from] simgap_core::Error),
    /// Stopped on request (Ctrl-C) before the end.
    #[error("interrupted")]
    Interrupted,
    /// Writing a report failed.
    #[error("{path}: cannot write: {message}")]
    Write {
        /// The file.
        path: String,
        /// The cause.
        message: String,
    },
}

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
