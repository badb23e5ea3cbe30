//! The stage runner: the one place where [`crate::diagnose`] reports its progress and honours its
//! stop flag.

use crate::error::Result;
use crate::options::{check_stop, DiagnoseOptions, Progress};

/// Runs the stages of a diagnosis: reports each to the progress callback and stops with
/// [`crate::Error::Interrupted`] after any stage once the stop flag is set. A stage that loops over
/// candidates reports counted steps ([`Stages::count`], [`Stages::tick`]) and checks the flag
/// within the loop ([`Stages::check`], [`Stages::stopped`]), so a Ctrl-C stops within one
/// candidate.
pub(crate) struct Stages<'a> {
    /// The progress callback of [`crate::diagnose`].
    progress: &'a mut dyn FnMut(Progress),
    /// The options of the diagnosis (its stop flag; stages inside `select/` read it too).
    pub(crate) options: &'a DiagnoseOptions,
    /// Counted steps done so far.
    step: usize,
    /// Counted steps in all (0 until [`Stages::count`]).
    total: usize,
}

impl<'a> Stages<'a> {
    /// A runner reporting to `progress` and stopping on `options.stop`.
    pub(crate) fn new(options: &'a DiagnoseOptions, progress: &'a mut dyn FnMut(Progress)) -> Stages<'a> {
        Stages { progress, options, step: 0, total: 0 }
    }

    /// Runs one stage: reports `announce` (when given), runs `stage`, then checks the stop flag.
    ///
    /// # Errors
    /// The stage's error, or [`crate::Error::Interrupted`] when the stop flag is set once it is done.
    pub(crate) fn run<T>(&mut self, announce: Option<Progress>, stage: impl FnOnce(&mut Self) -> Result<T>) -> Result<T> {
        if let Some(p) = announce {
            self.announce(p);
        }
        let out = stage(self)?;
        self.check()?;
        Ok(out)
    }

    /// Reports `p` to the progress callback.
    pub(crate) fn announce(&mut self, p: Progress) {
        (self.progress)(p);
    }

    /// The progress callback, for a stage that reports its own steps.
    pub(crate) fn progress(&mut self) -> &mut dyn FnMut(Progress) {
        &mut *self.progress
    }

    /// Whether the stop flag is set.
    pub(crate) fn stopped(&self) -> bool {
        self.check().is_err()
    }

    /// Stops with [`crate::Error::Interrupted`] when the stop flag is set.
    ///
    /// # Errors
    /// [`crate::Error::Interrupted`] when the stop flag is set.
    pub(crate) fn check(&self) -> Result<()> {
        check_stop(self.options)
    }

    /// Starts counting steps: `total` steps in all, reported by [`Stages::tick`].
    pub(crate) fn count(&mut self, total: usize) {
        self.step = 0;
        self.total = total;
    }

    /// One counted step of `stage` done.
    pub(crate) fn tick(&mut self, stage: &'static str) {
        self.step += 1;
        (self.progress)(Progress { stage, done: self.step.min(self.total), total: self.total });
    }
}

/// The progress a stage is announced with: `stage` with `done` of `total` steps.
pub(crate) fn shown(stage: &'static str, done: usize, total: usize) -> Option<Progress> {
    Some(Progress { stage, done, total })
}
