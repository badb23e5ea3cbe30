//! The corrected model where the user simulates: a URDF ([`export_urdf`]) and an MJCF
//! ([`export_mjcf`]) of the diagnosed robot with the selected effects written in, each with a
//! sidecar ([`Sidecar`], written to `PATH.effects.json`) holding the selected effects its format
//! cannot hold.
//!
//! Both take plain inputs: the [`Model`](simgap_core::Model) the diagnosis ran on, the report's
//! `selected_effects` ([`EffectReport`](crate::EffectReport)), and for the URDF the
//! input URDF text; for the MJCF the logs' sample period ([`MjcfOptions`]). They return the
//! text and the sidecar ([`ExportedFile`]) and write nothing. Units follow the joint type:
//! revolute rad, N·m, kg·m²; prismatic m, N, kg.
//!
//! What goes where (also in `docs/guide/export.md`):
//!
//! | effect | URDF | MJCF |
//! |---|---|---|
//! | `inertial_error`, `payload` | `<inertial>` of the link | body `<inertial>` |
//! | `viscous_friction` | `<dynamics damping>` | joint `damping` |
//! | `coulomb_friction` | `<dynamics friction>` | joint `frictionloss` |
//! | `armature` | sidecar | joint `armature` |
//! | `torque_gain` | sidecar | motor `gear` |
//! | `torque_saturation` | sidecar | motor `forcerange` |
//! | `joint_spring` | sidecar | joint `stiffness`, `springref` |
//! | servo runs (the report's `servo` key) | sidecar | a `position` actuator per joint: `kp = kt/R·V·duty_gain`, `kv = kt²/R`, `forcerange = ±kt/R·V·max_duty` ([`ServoActuators`]) |
//! | `torque_gain`, `back_emf` on servo runs | sidecar | folded into the servo's `kp`, `kv` |
//! | everything else | sidecar | sidecar |

mod effects;
mod mjcf;
mod servo;
mod sidecar;
mod urdf;

use std::path::{Path, PathBuf};

pub use mjcf::{export_mjcf, MjcfOptions, FULL_TURN};
pub use servo::ServoActuators;
pub use sidecar::{HeldEntry, Sidecar, SidecarEntry};
pub use urdf::export_urdf;

/// What went wrong in an export.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// The input URDF cannot be edited as asked (malformed, or not the URDF the model came
    /// from).
    #[error("{source_name}: {element}: {message}")]
    Urdf {
        /// The URDF file (or `<string>`).
        source_name: String,
        /// The element (e.g. `link 'forearm'`, `<inertial>`).
        element: String,
        /// What was expected and what was found.
        message: String,
    },
    /// A selected effect does not fit the model (an unknown joint, a parameter of the wrong
    /// shape) or cannot be written (a correction that leaves a link non-physical).
    #[error("effect '{effect}': {message}")]
    Effect {
        /// The effect's name.
        effect: String,
        /// What was expected and what was found.
        message: String,
    },
    /// An option is out of range (e.g. a non-positive time step).
    #[error("{0}")]
    Option(String),
    /// The corrected model itself is not physical.
    #[error(transparent)]
    Model(#[from] simgap_core::Error),
    /// The corrected model cannot be built.
    #[error(transparent)]
    Sim(#[from] simgap_sim::Error),
}

/// One exported file: the text to write and its sidecar.
#[derive(Clone, Debug)]
pub struct ExportedFile {
    /// The URDF or MJCF document.
    pub text: String,
    /// The selected effects the format does not hold, and where the others went; written to
    /// [`sidecar_path`] beside the file.
    pub sidecar: Sidecar,
}

/// The sidecar's path beside an exported file: `PATH.effects.json` (e.g.
/// `corrected.urdf.effects.json`).
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_os_string();
    name.push(".effects.json");
    PathBuf::from(name)
}

/// The sample period of logs [s]: their experiment's `sample_period` where one states it,
/// else the median spacing of their stamps; `None` when no run has two samples.
pub fn sample_period_of(runs: &[simgap_sim::Run]) -> Option<f64> {
    if let Some(dt) = runs.iter().filter_map(|r| r.experiment.as_ref()).map(|e| e.sample_period).find(|dt| dt.is_finite() && *dt > 0.0) {
        return Some(dt);
    }
    let mut steps: Vec<f64> = runs.iter().flat_map(|r| r.t.windows(2).map(|w| w[1] - w[0])).filter(|d| d.is_finite() && *d > 0.0).collect();
    if steps.is_empty() {
        return None;
    }
    steps.sort_by(f64::total_cmp);
    Some(steps[steps.len() / 2])
}

/// The model's joints whose commanded torque is zero on every sample of every run (joints
/// matched by name; a run without the joint or without torques does not count as zero):
/// passive joints, which get no motor in the MJCF. Names in model order.
pub fn passive_joints(model: &simgap_core::Model, runs: &[simgap_sim::Run]) -> Vec<String> {
    if runs.is_empty() {
        return Vec::new();
    }
    model
        .joint_names()
        .into_iter()
        .filter(|name| {
            runs.iter().all(|r| match r.joints.iter().position(|j| j == name) {
                Some(j) if !r.tau.is_empty() && r.dof() > 0 => r.tau.iter().skip(j).step_by(r.dof()).all(|v| *v == 0.0),
                _ => false,
            })
        })
        .map(str::to_string)
        .collect()
}
