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
//! The front ends (the CLI's `--export-urdf`, `--export-mjcf`, Python's `Report.export_urdf`,
//! `Report.export_mjcf`) call [`corrected_urdf`] and [`corrected_mjcf`], which read the
//! diagnosis alone: its report, and the time step, passive joints and servo firmware it decided
//! from its prepared runs ([`ExportBasis`]), so they write the same bytes.
//!
//! What goes where (also in `docs/guide/export.md`):
//!
//! | effect | URDF | MJCF |
//! |---|---|---|
//! | `inertial_error`, `payload` | `<inertial>` of the link | body `<inertial>` |
//! | `viscous_friction` | `<dynamics damping>` | joint `damping` |
//! | `coulomb_friction` | `<dynamics friction>` | joint `frictionloss`, with `solreffriction="0 −rate"` and `solimpfriction="d d …"` making MuJoCo's constraint the band of `tanh(q̇/w)`: `−fc·clip(q̇/(2 ln 2·w), ±1)`, no stiction |
//! | `armature` | sidecar | joint `armature` |
//! | `torque_gain` | sidecar | motor `gear` |
//! | `torque_saturation` | sidecar | motor `forcerange` |
//! | `joint_spring` | sidecar | joint `stiffness`, `springref` |
//! | servo runs (the report's `servo` key) | sidecar | a `position` actuator per joint: `kp = kt/R·V·duty_gain`, `kv = kt²/R`, `forcerange = ±kt/R·V·max_duty` ([`ServoActuators`]) |
//! | `torque_gain`, `back_emf` on servo runs | sidecar | folded into the servo's `kp`, `kv` |
//! | everything else | sidecar | sidecar |

mod corrected;
mod effects;
mod mjcf;
mod servo;
mod sidecar;
mod urdf;

use std::path::{Path, PathBuf};

pub use crate::report::export_basis::{passive_joints, sample_period_of, ExportBasis, ServoFirmware};
pub use corrected::{corrected_mjcf, corrected_urdf};
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
