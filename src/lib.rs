#![doc = include_str!("../README.md")]
//!
//! The umbrella crate re-exports [`core`] (dynamics), [`sim`] (closed-loop simulation),
//! [`log`] (ROS 2 MCAP, bag and CSV logs) and [`diag`] (sim-to-real gap diagnosis), and owns the
//! `simgap` command-line tool.

pub use simgap_core as core;
pub use simgap_diag as diag;
pub use simgap_log as log;
pub use simgap_sim as sim;
