//! Where a simulation writes what it does: the [`Sink`] trait and the in-memory sink.

use crate::error::Result;
use crate::run::{Experiment, Run, Sample};

/// How a run ended, told to [`Sink::finish`].
#[derive(Clone, Debug, PartialEq)]
pub enum RunEnd {
    /// Reached the requested duration.
    Completed,
    /// Stopped early (Ctrl-C or a caller's request) at time `t`.
    Interrupted {
        /// Time of the last sample [s].
        t: f64,
    },
    /// The state diverged.
    Diverged {
        /// Time [s].
        t: f64,
        /// The joint whose state was not finite or exceeded the bound.
        joint: String,
    },
}

impl RunEnd {
    /// `Ok` for a completed run; the matching [`Error`](crate::Error) for an interrupted or a
    /// diverged one.
    ///
    /// # Errors
    /// [`Error::Interrupted`](crate::Error::Interrupted) or
    /// [`Error::Diverged`](crate::Error::Diverged).
    pub fn into_result(self) -> Result<()> {
        match self {
            RunEnd::Completed => Ok(()),
            RunEnd::Interrupted { t } => Err(crate::Error::Interrupted { t }),
            RunEnd::Diverged { t, joint } => Err(crate::Error::Diverged { t, joint, detail: "state not finite or |q̇| above the divergence bound".into() }),
        }
    }
}

/// Receives the samples of a run as it goes. Implementations must leave a complete, readable
/// result after [`Sink::finish`], whatever the [`RunEnd`].
pub trait Sink {
    /// Called once before the first sample.
    ///
    /// # Errors
    /// When the sink cannot be written.
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> Result<()>;
    /// Called for every controller sample.
    ///
    /// # Errors
    /// When the sink cannot be written.
    fn record(&mut self, sample: &Sample<'_>) -> Result<()>;
    /// Called once at the end, also when the run failed.
    ///
    /// # Errors
    /// When the sink cannot be finished.
    fn finish(&mut self, end: &RunEnd) -> Result<()>;
}

/// Collects a run in memory.
#[derive(Clone, Debug, Default)]
pub struct MemorySink {
    run: Option<Run>,
    /// How the run ended (after `finish`).
    pub end: Option<RunEnd>,
}

impl MemorySink {
    /// An empty sink.
    pub fn new() -> Self {
        Self::default()
    }

    /// The collected run.
    ///
    /// # Panics
    /// If `begin` was never called.
    pub fn into_run(self) -> Run {
        self.run.expect("MemorySink::into_run before begin")
    }
}

impl Sink for MemorySink {
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> Result<()> {
        let mut run = Run::new(joints.to_vec());
        run.experiment = Some(experiment.clone());
        run.source = "simulation".into();
        self.run = Some(run);
        Ok(())
    }

    fn record(&mut self, s: &Sample<'_>) -> Result<()> {
        let run = self.run.as_mut().expect("record before begin");
        run.t.push(s.t);
        run.q.extend_from_slice(s.q);
        run.qd.extend_from_slice(s.qd);
        run.tau.extend_from_slice(s.tau);
        run.q_ref.extend_from_slice(s.q_ref);
        run.qd_ref.extend_from_slice(s.qd_ref);
        if let Some(d) = &s.drive {
            run.drive.duty.extend_from_slice(d.duty);
            run.drive.torque_enable.extend_from_slice(d.torque_enable);
            run.drive.voltage.push(d.voltage);
        }
        Ok(())
    }

    fn finish(&mut self, end: &RunEnd) -> Result<()> {
        self.end = Some(end.clone());
        Ok(())
    }
}
