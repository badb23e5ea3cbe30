//! Errors of `simgap-log`.

use std::path::{Path, PathBuf};

/// Everything that can go wrong reading or writing a log.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A log could not be read or is not what was expected.
    #[error("{path}: {message}")]
    Read {
        /// The file or bag folder.
        path: PathBuf,
        /// What was expected and what was found (and where, in the file).
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
    /// A run that is not valid, or whose joints do not match the ones asked for.
    #[error(transparent)]
    Run(#[from] simgap_sim::Error),
}

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// An [`Error::Read`] for `path`.
pub(crate) fn read_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Read { path: PathBuf::from(path), message: message.into() }
}

/// An [`Error::Write`] for `path`.
pub(crate) fn write_error(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::Write { path: PathBuf::from(path), message: message.to_string() }
}

/// A run check for a log at `path`: the run's own [`simgap_sim::Error::Log`] becomes an
/// [`Error::Read`] naming `path`.
pub(crate) fn check_run(run: &simgap_sim::Run, path: &Path) -> Result<()> {
    simgap_sim::validate_run(run).map_err(|e| match e {
        simgap_sim::Error::Log { message, .. } => read_error(path, message),
        other => Error::Run(other),
    })
}

impl From<Error> for simgap_sim::Error {
    /// For [`simgap_sim::Sink`] implementations, whose errors are the simulator's.
    fn from(e: Error) -> simgap_sim::Error {
        match e {
            Error::Read { path, message } => simgap_sim::Error::Log { path, message },
            Error::Write { path, message } => simgap_sim::Error::Write { path, message },
            Error::Run(e) => e,
        }
    }
}
