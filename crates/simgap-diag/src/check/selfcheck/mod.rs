//! The self-check: blind scenarios (robot, hidden effects, references, controllers; random ones
//! and named families, [`scenario()`]), diagnosed like real logs and scored against the hidden
//! truth by each family's rule ([`run_scenario`]); for found effects whose truth is known, whether
//! the true parameter lies within the reported 95 % interval ([`Summary::coverage`]).
//!
//! One file per job: the scenario cycle (`scenarios.rs`), the servo scenarios (`servo.rs`), the
//! truth against what a diagnosis found (`truth.rs`), the scoring by each family's rule
//! (`score.rs`) and the summary (`summary.rs`).

pub(super) mod scenarios;
mod score;
pub(super) mod servo;
mod summary;
mod truth;

pub use scenarios::{double_pendulum, family_of, inertia_about_axis_as_com, robots, scenario, Scenario, CYCLE, FAMILIES, GLITCH_VALUE};
pub use score::{
    run_backlash_scenario, run_drive_scenario, run_encoder_offset_scenario, run_mixed_scenario, run_scenario, run_servo_scenario, ScenarioScore, MIXED_CYCLE, MOTOR_CONSTANTS,
};
pub use servo::{backlash_scenario, encoder_offset_scenario, servo_draw, servo_scenario, SATURATION_EVERY};
pub use summary::{summarise, Summary};
pub use truth::{contradicted, found_set, implausible, truth_set};
// the crate's tests replay runs and score their own scenarios by the self-check's paths
#[cfg(test)]
pub(crate) use scenarios::as_replay;
#[cfg(test)]
pub(crate) use score::score;
