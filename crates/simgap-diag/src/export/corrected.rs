//! The corrected files of one diagnosis: what every front end writes (the CLI's
//! `--export-urdf` and `--export-mjcf`, Python's `report.export_urdf` and `report.export_mjcf`),
//! read from the report and the diagnosis' [`ExportBasis`](super::ExportBasis) alone, so that
//! they write the same bytes.

use simgap_core::Model;

use super::{export_mjcf, export_urdf, ExportError, ExportedFile, MjcfOptions, ServoActuators};
use crate::Diagnosis;

/// The input URDF `urdf` (read from `source_name`) with the selected effects of `diagnosis`
/// written in, and its sidecar: [`export_urdf`] on the report's `selected_effects`.
///
/// # Errors
/// As [`export_urdf`].
pub fn corrected_urdf(urdf: &str, source_name: &str, model: &Model, diagnosis: &Diagnosis) -> Result<ExportedFile, ExportError> {
    export_urdf(urdf, source_name, model, &diagnosis.report.selected_effects)
}

/// The MJCF of the corrected robot of `diagnosis`, and its sidecar: [`export_mjcf`] on the
/// report's `selected_effects`, with the time step [s], the passive joints and (servo runs)
/// the servo firmware the diagnosis decided from its prepared runs
/// ([`Diagnosis::export`](crate::Diagnosis::export)), and the report's effective servo
/// constants.
///
/// # Errors
/// [`ExportError::Option`] when the logs have no sample period or a servo's firmware cannot be
/// read (what is missing, in which log); otherwise as [`export_mjcf`].
pub fn corrected_mjcf(model: &Model, diagnosis: &Diagnosis) -> Result<ExportedFile, ExportError> {
    let basis = &diagnosis.export;
    // the logs' time step
    let timestep = basis.timestep.ok_or_else(|| ExportError::Option("the logs have no sample period (no experiment sample_period and fewer than two stamps)".into()))?;
    // a servo diagnosis: the report's constants with the logs' firmware
    let servo = match (&diagnosis.report.servo, &basis.servo) {
        (Some(report), Some(firmware)) => {
            let firmware = firmware.as_ref().map_err(|e| ExportError::Option(e.clone()))?;
            Some(ServoActuators::with_firmware(model, report, firmware)?)
        }
        _ => None,
    };
    // the MJCF
    let options = MjcfOptions { passive: basis.passive.clone(), servo, ..MjcfOptions::new(timestep) };
    export_mjcf(model, &diagnosis.report.selected_effects, &options)
}
