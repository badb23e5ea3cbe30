//! Closed-loop simulation of serial manipulators sampled like a real controller, logs in ROS 2
//! MCAP and CSV, and the L² index.

pub mod error;
pub mod run;
pub mod sink;

pub use error::{Error, Result};
pub use run::{ControllerKind, Experiment, Run, Sample};
pub use sink::{MemorySink, RunEnd, Sink};
