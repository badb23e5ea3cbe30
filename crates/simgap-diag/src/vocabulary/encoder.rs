//! `encoder_offset`: the joint's measured zero is not the model's; the joint is at
//! `q_measured + δ` (a per-unit calibration, as on hobby servos zeroed by hand).
//!
//! The robot's torque is the model's at the true position, `τ = ID(q + δ) ≈ ID(q) + Σ_j
//! ∂ID/∂q_j δ_j`, so the residual holds `∂ID/∂q_j δ_j`: one global column per joint
//! ([`FitData::offset_slope`], the slope of the model torque in joint `j`'s position, on every
//! joint's rows), its coefficient the offset, bounded by [`OFFSET_MAX`]. What the column sees is
//! the gravity and inertia a wrong angle moves: on a joint whose position changes neither (a
//! vertical axis with no link offset) the offset is not identifiable and its interval says so.
//! The multiple shooting refits it through the simulator, where the plant evaluates the rigid
//! body at `q + δ` (see `simgap_sim::Effect::EncoderOffset`).

use simgap_sim::Effect;

use super::effects::{per_joint as reported, sig3, unit_of};
use super::{Column, EffectReport, TermDesign};
use crate::prepare::dataset::FitData;

/// Largest offset tried [rad or m] (20° on a turning joint): a zero further off is a wrong
/// model or a wrong joint, not a calibration.
pub(crate) const OFFSET_MAX: f64 = 0.35;

/// The global column of an offset on joint `j`: the model torque's slope in `q_j`.
pub(super) fn design(j: usize, data: &[FitData]) -> TermDesign {
    let v: Vec<f64> = data.iter().flat_map(|d| d.offset_slope[j].iter().copied()).collect();
    TermDesign { cols: vec![Column::new(None, v)], lo: vec![-OFFSET_MAX], hi: vec![OFFSET_MAX], ..Default::default() }
}

/// Adds the offset of joint `j` to the simulator's.
pub(super) fn apply(j: usize, theta: &[f64], n: usize, out: &mut Vec<Effect>) {
    if let Effect::EncoderOffset { offset } = super::effects::slot(out, Effect::EncoderOffset { offset: vec![0.0; n] }) {
        offset[j] = theta[0];
    }
}

/// The offsets in words, in degrees as well on turning joints.
pub(super) fn describe(e: &EffectReport) -> String {
    let unit = unit_of(e, "offset");
    let parts: Vec<String> = reported(e, "offset")
        .iter()
        .map(|(j, d)| if unit == "rad" { format!("{} rad ({}°) on {j}", sig3(*d), sig3(d.to_degrees())) } else { format!("{} {unit} on {j}", sig3(*d)) })
        .collect();
    format!(
        "encoder offset: the joint is at its measured position plus {} (its zero is not the model's; correct the calibration, or add the offset to the measured positions)",
        parts.join(", ")
    )
}
