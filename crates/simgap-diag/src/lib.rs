//! Sim-to-real gap diagnosis: given a model and logs from a real robot, **where** the gap lies,
//! **which** unmodelled effect causes it, and **how far** it shrinks once that effect is added,
//! measured on held-out runs the fit never saw.
//!
//! [`diagnose`] runs these stages, in this order (`pipeline.rs` reads as this list):
//!
//! 1. **prepare** (`prepare/`): each log aligned to the model by joint name, checked (its
//!    experiment, its sample period against the stamps, a held-out log that repeats a fit log),
//!    glitch samples repaired, sensors inferred, passive joints found; every fit run smoothed and
//!    differentiated once, with the nominal residual `r = τ_cmd − (H q̈ + C q̇ + g)`.
//! 2. **locate** (`locate.rs`): where the gap lies: joints, phases, residual correlations.
//! 3. **select on the torque residual** (`select/`): every effect of the vocabulary
//!    (`vocabulary/`, one file per family) is a family of candidate terms fitted by bounded
//!    least squares (`lsq/`) and compared by block cross-validation; a forward stepwise
//!    selection proposes a set.
//! 4. **prune and complete by prediction** (`select/prediction.rs`): the set pruned, completed
//!    with whole effects and exchanged, by cross-validated k-step prediction of the fit runs
//!    (`prediction/`); the whole-run closed-loop gap never drives selection.
//! 5. **refine by multiple shooting** (`select/refine.rs`, open-loop fit runs only).
//! 6. **fit the selected set** with its 95 % intervals (`select/uncertainty.rs`).
//! 7. **how far** (`prediction/`): held-out runs, never used to fit or to select, predicted k steps
//!    ahead and re-simulated in closed loop, nominal and corrected.
//! 8. **screen**: every candidate alone, scored on the fit runs and, for the report, on the
//!    held-out runs.
//! 9. **report** (`report/`): alternatives, notes, what is left, one verdict, the report.
//!
//! Conventions: SI units throughout, in model joint order; revolute joints in rad, rad/s, N·m,
//! prismatic joints in m, m/s, N (units by joint type come from [`simgap_sim::EffectKind`]).

#[cfg(feature = "check")]
pub mod check;
mod error;
pub mod export;
mod locate;
mod lsq;
mod options;
mod pipeline;
mod prediction;
mod prepare;
mod report;
mod select;
mod vocabulary;

#[cfg(feature = "check")]
pub use check::{bench, drives, selfcheck};
pub use error::{Error, Result};
pub use locate::{JointGap, Segment, Where};
pub use options::{DiagnoseOptions, Progress};
pub use pipeline::{diagnose, predict};
pub use prediction::resim::RunGap;
pub use prepare::sensors::InferredSensors;
pub use prepare::{DryWidth, FitData, PrepareOptions};
#[cfg(feature = "html")]
pub use report::html;
pub use report::residual::ResidualTest;
pub use report::units::Units;
pub use report::{Alternative, Candidate, Decision, Diagnosis, EffectiveConstants, Gap, KStep, Report, RunKStep, ServoReport, WindowStart};
pub use select::SelectOptions;
pub use vocabulary::{EffectReport, Param};

#[cfg(test)]
mod tests;
