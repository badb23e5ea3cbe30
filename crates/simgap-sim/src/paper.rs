//! The seed paper's experiment (Sánchez-Sánchez & Arteaga-Pérez 2012, §5): PD control of its
//! arm ([`Model::paper_arm`](simgap_core::Model::paper_arm), whose parameters are in
//! [`simgap_core::robots::paper_arm`]) from rest at q = 0 to [`Q_DESIRED`], sampled every
//! [`SAMPLE_PERIOD`], with the gains [`KP`] and [`KV`]. Joint order: shoulder, elbow.

use crate::controller::Pd;
use crate::reference::Step;

/// Proportional gains Kp of the experiment (§5, Table 3) [N·m/rad].
pub const KP: [f64; 2] = [64.72, 32.36];
/// Derivative gains Kv of the experiment (§5, Table 3) [N·m·s/rad].
pub const KV: [f64; 2] = [48.54, 6.472];
/// Desired position of the experiment, q_d = (π/4, π/2) [rad].
pub const Q_DESIRED: [f64; 2] = [std::f64::consts::FRAC_PI_4, std::f64::consts::FRAC_PI_2];
/// Controller sample period of the experiment [s].
pub const SAMPLE_PERIOD: f64 = 0.0025;

/// The experiment's controller: τ = Kp (q_d − q) − Kv q̇ with [`KP`] and [`KV`].
#[must_use]
pub fn controller() -> Pd {
    Pd { kp: KP.to_vec(), kv: KV.to_vec() }
}

/// The experiment's reference: a step to [`Q_DESIRED`] at t = 0.
#[must_use]
pub fn reference() -> Step {
    Step { target: Q_DESIRED.to_vec() }
}
