//! The options of a diagnosis, its progress reports and its stop flag: what every stage reads.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::prepare::PrepareOptions;
use crate::select::SelectOptions;

/// Options of [`crate::diagnose`].
#[derive(Clone, Debug, Default)]
pub struct DiagnoseOptions {
    /// Data preparation.
    pub prepare: PrepareOptions,
    /// Selection thresholds.
    pub select: SelectOptions,
    /// Prediction horizons [s] of the k-step figures; empty = 0.1, 0.25 and 0.5 s.
    pub horizons: Vec<f64>,
    /// When set (e.g. by Ctrl-C), the diagnosis stops at its next step with
    /// [`Error::Interrupted`].
    pub stop: Option<Arc<AtomicBool>>,
}

/// Progress of a diagnosis, for a progress bar.
#[derive(Clone, Debug)]
pub struct Progress {
    /// What is being done (the stage, and the candidate when there is one).
    pub stage: &'static str,
    /// Steps done.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
}

pub(crate) fn check_stop(options: &DiagnoseOptions) -> Result<()> {
    match &options.stop {
        Some(s) if s.load(Ordering::Relaxed) => Err(Error::Interrupted),
        _ => Ok(()),
    }
}
