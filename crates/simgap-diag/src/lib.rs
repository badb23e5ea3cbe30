//! Sim-to-real gap diagnosis: given a model and logs from a real robot, **where** the gap lies,
//! **which** unmodelled effect causes it, and **how far** it shrinks once that effect is added,
//! measured on held-out runs the fit never saw.
//!
//! [`diagnose`] runs these stages, in this order, one call each (`pipeline/mod.rs` reads as this
//! list; each stage takes what the one before produced, and `pipeline/runner.rs` reports
//! progress and honours the stop flag between and within them):
//!
//! 1. **prepare** (`prepare/`): each log aligned to the model by joint name, checked (its
//!    experiment, its sample period against the stamps, a held-out log that repeats a fit log),
//!    glitch samples repaired, sensors inferred, passive joints found; every fit run smoothed and
//!    differentiated once, with the nominal residual `r = τ_cmd − (H q̈ + C q̇ + g)`, and cut into
//!    k-step prediction windows.
//! 2. **locate** (`pipeline/locate.rs`, `locate.rs`): where the gap lies: joints, phases,
//!    residual correlations, from the nominal model re-simulated in closed loop.
//! 3. **select** (`pipeline/select.rs`, `select/`): every effect of the vocabulary
//!    (`vocabulary/`, one file per family) is a family of candidate terms fitted by bounded
//!    least squares (`lsq/`) and compared by block cross-validation; a forward stepwise
//!    selection on the torque residual proposes a set.
//! 4. **candidates** (`pipeline/candidates.rs`, `select/screen.rs`): every effect alone, scored
//!    by cross-validated k-step prediction of the fit runs (`prediction/`, `select/scorer.rs`);
//!    the whole-run closed-loop gap never drives selection.
//! 5. **prune** (`pipeline/prune.rs`, `select/prediction.rs`): the set pruned, completed with
//!    whole effects and exchanged, by that prediction.
//! 6. **parsimony** (`pipeline/parsimony.rs`, `select/plausible.rs`): a richer effect that the
//!    simpler one nested in it matches becomes the simpler.
//! 7. **refine** (`pipeline/refine.rs`, `select/refine.rs`): on open-loop fit runs, the set
//!    fitted by multiple shooting, kept where prediction says so.
//! 8. **drive swap** (`pipeline/drive_swap.rs`, `select/refine.rs`): on a one-joint servo arm,
//!    the drive's gain and rotor inertia in place of an inertial correction that is the same
//!    dynamics.
//! 9. **intervals** (`pipeline/intervals.rs`, `select/uncertainty.rs`, `select/plausible.rs`):
//!    the set fitted with its 95 % intervals; a term that is no finding leaves, a richer one its
//!    data do not support becomes the simpler, and the rest is fitted again.
//! 10. **how far** (`pipeline/how_far.rs`, `prediction/`): held-out runs, never used to fit or to
//!     select, predicted k steps ahead and re-simulated in closed loop, nominal and corrected.
//! 11. **screen** (`pipeline/screen.rs`): every candidate alone, fitted on the fit runs and
//!     scored on the held-out runs, for the report's table.
//! 12. **notes** (`pipeline/notes.rs`, `select/alternatives.rs`, `report/`): alternatives, the
//!     URDF's pitfalls and the notes.
//! 13. **what is left** (`pipeline/what_is_left.rs`, `report/residual.rs`): the torque residual
//!     after the selected effects, tested joint by joint.
//! 14. **report** (`pipeline/report.rs`, `report/`): the headline, one verdict, the report.
//!
//! Conventions: SI units throughout, in model joint order; revolute joints in rad, rad/s, N·m,
//! prismatic joints in m, m/s, N (units by joint type come from [`simgap_sim::EffectKind`]).

#[cfg(feature = "check")]
pub mod check;
pub mod cost;
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
mod switches;
mod vocabulary;

#[cfg(feature = "check")]
pub use check::{bench, drives, selfcheck};
pub use error::{Error, Result};
pub use locate::{JointGap, Segment, Where};
pub use options::{DiagnoseOptions, Progress};
pub use pipeline::{diagnose, predict};
pub use prediction::resim::RunGap;
pub use prepare::locked::model_for_runs;
pub use prepare::sensors::InferredSensors;
pub use prepare::{DryWidth, FitData, PrepareOptions};
#[cfg(feature = "html")]
pub use report::html;
pub use report::residual::ResidualTest;
pub use report::units::Units;
pub use report::{Alternative, Candidate, Decision, Diagnosis, EffectiveConstants, Gap, KStep, Report, RunKStep, ServoReport, WindowStart};
pub use select::SelectOptions;
pub use switches::{options_with, switch, Switch, SWITCHES};
pub use vocabulary::{EffectReport, Param};

#[cfg(test)]
mod tests;
