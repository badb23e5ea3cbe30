//! Candidate terms: each unmodelled effect of the vocabulary, as columns of a linear model of the
//! nominal residual `r = τ_cmd − (H q̈ + C q̇ + g)`, each with the bounds physics puts on its
//! parameters (b, fc, fs − fc, ia, payload mass ≥ 0; a gain within [`GAIN_RANGE`]).
//!
//! With the effect present, the robot obeys `(H + diag(ia)) q̈ + C q̇ + g = τ_applied + τ_eff`, so
//!
//! ```text
//! viscous        r_j ∋  b_j q̇_j                        coulomb  r_j ∋ fc_j tanh(q̇_j / w)
//! stribeck       r_j ∋  (fc + (fs − fc) e^{−(q̇/vs)²}) tanh(q̇/w)
//! armature       r_j ∋  ia_j q̈_j                       gain     r_j ∋ (1 − k_j) τ_j
//! offset         r_j ∋ −offset_j                        cogging  r_j ∋ A_j sin(N_j q_j)
//! saturation     r_j ∋  τ_j − clamp(τ_j, ±L_j)          (fixed coefficient, L searched)
//! time_delay     r   ∋  τ(t) − τ(t − d)                 (fixed coefficient, d searched)
//! coriolis       r   ∋  (C_other − C) q̇                 (fixed coefficient, no parameter)
//! payload        r   ∋  m Y_last π_point(c)             (m linear, c searched)
//! inertial_error r   ∋  Y Δπ                            (Δπ physically consistent, see inertial)
//! ```

pub(crate) mod effects;

pub use effects::{EffectReport, Param};

use std::sync::Arc;

use nalgebra::Vector3;
use simgap_core::PARAMS_PER_LINK;

use crate::lsq::inertial::InertialPrior;
use crate::prepare::dataset::FitData;

/// Width [rad/s] of the tanh that smooths sign(q̇) in fitting and in simulation.
pub(crate) const COULOMB_WIDTH: f64 = simgap_sim::DEFAULT_COULOMB_WIDTH;

/// One candidate term.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Term {
    /// Viscous friction on a joint.
    Viscous(usize),
    /// Coulomb friction on a joint.
    Coulomb(usize),
    /// Stribeck friction on a joint with Stribeck velocity `vs`.
    Stribeck {
        /// Joint index.
        joint: usize,
        /// Stribeck velocity [rad/s].
        vs: f64,
    },
    /// Rotor inertia on a joint.
    Armature(usize),
    /// Torque gain on a joint.
    Gain(usize),
    /// Torque offset on a joint.
    Offset(usize),
    /// Torque saturation on a joint.
    Saturation {
        /// Joint index.
        joint: usize,
        /// Limit [N·m].
        limit: f64,
    },
    /// Cogging on a joint.
    Cogging {
        /// Joint index.
        joint: usize,
        /// Periods per revolution.
        periods: f64,
    },
    /// Whole-robot actuation delay.
    Delay {
        /// Delay [s].
        delay: f64,
    },
    /// The other formulation of C.
    CoriolisStructure,
    /// A point mass on the last link at a searched centre of mass (its mass is the fitted
    /// parameter).
    Payload {
        /// Centre of mass [m], last link frame.
        com: [f64; 3],
        /// Largest plausible mass [kg] (twice the chain's mass: heavier is no payload).
        max_mass: f64,
    },
    /// Corrections of every link's inertial parameters, physically consistent and regularised
    /// toward the URDF (see [`crate::lsq::inertial`]); its parameters are the stacked corrections
    /// Δπ in units of `prior.scales`.
    InertialError {
        /// URDF parameters, scales, reach of every link and prior weight.
        prior: Arc<InertialPrior>,
    },
}

impl Term {
    /// The effect's contract name.
    pub(crate) fn effect_name(&self) -> &'static str {
        match self {
            Term::Viscous(_) => "viscous_friction",
            Term::Coulomb(_) => "coulomb_friction",
            Term::Stribeck { .. } => "stribeck_friction",
            Term::Armature(_) => "armature",
            Term::Gain(_) => "torque_gain",
            Term::Offset(_) => "torque_offset",
            Term::Saturation { .. } => "torque_saturation",
            Term::Cogging { .. } => "cogging",
            Term::Delay { .. } => "time_delay",
            Term::CoriolisStructure => "coriolis_structure",
            Term::Payload { .. } => "payload",
            Term::InertialError { .. } => "inertial_error",
        }
    }

    /// The joint of a per-joint term.
    pub(crate) fn joint(&self) -> Option<usize> {
        match *self {
            Term::Viscous(j) | Term::Coulomb(j) | Term::Armature(j) | Term::Gain(j) | Term::Offset(j) => Some(j),
            Term::Stribeck { joint, .. } | Term::Saturation { joint, .. } | Term::Cogging { joint, .. } => Some(joint),
            _ => None,
        }
    }

    /// Identity of the slot the term occupies: at most one term per slot is selected
    /// (Coulomb and Stribeck share one; payload and inertial error share one).
    pub(crate) fn slot(&self) -> (&'static str, Option<usize>) {
        let name = match self {
            Term::Coulomb(_) | Term::Stribeck { .. } => "dry_friction",
            Term::Payload { .. } | Term::InertialError { .. } => "inertia",
            other => other.effect_name(),
        };
        (name, self.joint())
    }
}

/// A column of the design: per-joint (values per sample, on that joint's rows) or global
/// (values per sample and joint, row-major).
#[derive(Clone, Debug)]
pub(crate) struct Column {
    /// `Some(j)`: nonzero only on joint j's rows.
    pub joint: Option<usize>,
    /// Values: length = samples (per-joint) or samples × dof (global).
    pub values: Vec<f64>,
}

impl Column {
    /// Value at (sample, joint).
    #[inline]
    pub(crate) fn at(&self, s: usize, j: usize, dof: usize) -> f64 {
        match self.joint {
            Some(jj) => {
                if jj == j {
                    self.values[s]
                } else {
                    0.0
                }
            }
            None => self.values[s * dof + j],
        }
    }
}

/// The columns of a term: free columns (one per fitted parameter) and a fixed offset
/// (coefficient 1) subtracted from the residual, with the physical constraints on the
/// parameters.
#[derive(Clone, Debug, Default)]
pub(crate) struct TermDesign {
    /// Free columns.
    pub cols: Vec<Column>,
    /// Fixed part.
    pub offset: Option<Column>,
    /// Lower bound of each column's coefficient (empty: none).
    pub lo: Vec<f64>,
    /// Upper bound of each column's coefficient (empty: none).
    pub hi: Vec<f64>,
    /// The columns are a physically consistent inertial correction with this prior.
    pub inertial: Option<Arc<InertialPrior>>,
}

/// Plausible range of a torque gain `k` (fitted as `1 − k`).
pub(crate) const GAIN_RANGE: (f64, f64) = (0.2, 5.0);

impl TermDesign {
    /// Columns without constraints.
    pub(crate) fn free(cols: Vec<Column>) -> TermDesign {
        TermDesign { cols, ..Default::default() }
    }

    /// Columns whose coefficients are at least `lo` each.
    fn at_least(cols: Vec<Column>, lo: f64) -> TermDesign {
        let k = cols.len();
        TermDesign { cols, lo: vec![lo; k], hi: vec![f64::INFINITY; k], ..Default::default() }
    }

    /// A fixed offset and no parameter.
    fn fixed(offset: Column) -> TermDesign {
        TermDesign { offset: Some(offset), ..Default::default() }
    }
}

/// Concatenation of a per-joint signal over runs.
fn per_joint(data: &[FitData], j: usize, f: impl Fn(&FitData, usize) -> f64) -> Column {
    let mut v = Vec::new();
    for d in data {
        for s in 0..d.len() {
            v.push(f(d, s * d.dof + j));
        }
    }
    Column { joint: Some(j), values: v }
}

/// The ten inertial parameters `(1, c, |c|² 1 − c cᵀ)` of a unit point mass at `com` [m],
/// in the regressor's order (mass, first moment, rotational inertia about the joint frame).
pub(crate) fn point_mass_parameters(com: [f64; 3]) -> [f64; PARAMS_PER_LINK] {
    let c = Vector3::from(com);
    [1.0, c.x, c.y, c.z, c.y * c.y + c.z * c.z, -c.x * c.y, -c.x * c.z, c.x * c.x + c.z * c.z, -c.y * c.z, c.x * c.x + c.y * c.y]
}

/// The torque of a unit point mass at `com` on the last link (its ten inertial parameters
/// [`point_mass_parameters`] through the regressor), as a global column.
pub(crate) fn payload_column(data: &[FitData], com: [f64; 3]) -> Column {
    let pi = point_mass_parameters(com);
    let rows = payload_basis_rows(data);
    Column { joint: None, values: rows.chunks_exact(PARAMS_PER_LINK).map(|row| row.iter().zip(&pi).map(|(a, b)| a * b).sum()).collect() }
}

/// The last link's ten regressor entries of every row (sample × joint, over runs), row-major:
/// a payload's column is their combination by [`point_mass_parameters`].
pub(crate) fn payload_basis_rows(data: &[FitData]) -> Vec<f64> {
    let dof = data[0].dof;
    let last = dof - 1;
    let width = PARAMS_PER_LINK * dof;
    let mut v = Vec::with_capacity(data.iter().map(|d| d.len() * dof * PARAMS_PER_LINK).sum());
    for d in data {
        for s in 0..d.len() {
            for j in 0..dof {
                v.extend_from_slice(&d.regressor[(s * dof + j) * width + PARAMS_PER_LINK * last..(s * dof + j) * width + PARAMS_PER_LINK * (last + 1)]);
            }
        }
    }
    v
}

/// The largest commanded torque over the fit runs [N·m] (what bounds a payload's mass).
pub(crate) fn largest_command(data: &[FitData]) -> f64 {
    data.iter().flat_map(|d| d.tau.iter()).fold(0.0f64, |m, v| m.max(v.abs()))
}

/// Upper bound of a payload's mass [kg] for a unit-mass column whose largest entry is
/// `col_max` [N·m/kg]: a payload whose torque would exceed three times the largest commanded
/// torque `tau_max` is no payload this robot carried, and none is heavier than `max_mass`.
pub(crate) fn payload_mass_bound(col_max: f64, tau_max: f64, max_mass: f64) -> f64 {
    let hi = if col_max > 0.0 && tau_max > 0.0 { 3.0 * tau_max / col_max } else { f64::INFINITY };
    hi.min(max_mass)
}

/// The linear first guess of a payload: mass and first moment of the last link, as four
/// global columns (rotational part ignored).
pub(crate) fn payload_linear_design(data: &[FitData]) -> TermDesign {
    let dof = data[0].dof;
    let last = dof - 1;
    let width = PARAMS_PER_LINK * dof;
    let cols = (0..4)
        .map(|p| {
            let mut v = Vec::new();
            for d in data {
                for s in 0..d.len() {
                    for j in 0..dof {
                        v.push(d.regressor[(s * dof + j) * width + PARAMS_PER_LINK * last + p]);
                    }
                }
            }
            Column { joint: None, values: v }
        })
        .collect();
    TermDesign::free(cols)
}

/// The design of a term over all runs.
pub(crate) fn design(term: &Term, data: &[FitData]) -> TermDesign {
    let dof = data[0].dof;
    let tanh = |x: f64| (x / COULOMB_WIDTH).tanh();
    match *term {
        Term::Viscous(j) => TermDesign::at_least(vec![per_joint(data, j, |d, i| d.qd[i])], 0.0),
        Term::Coulomb(j) => TermDesign::at_least(vec![per_joint(data, j, |d, i| tanh(d.qd[i]))], 0.0),
        Term::Stribeck { joint, vs } => {
            // fc tanh + (fs − fc) e tanh, with fc ≥ 0 and fs − fc ≥ 0
            let e = |v: f64| (-(v / vs).powi(2)).exp();
            TermDesign::at_least(vec![per_joint(data, joint, |d, i| tanh(d.qd[i])), per_joint(data, joint, |d, i| e(d.qd[i]) * tanh(d.qd[i]))], 0.0)
        }
        Term::Armature(j) => TermDesign::at_least(vec![per_joint(data, j, |d, i| d.qdd[i])], 0.0),
        Term::Gain(j) => TermDesign { cols: vec![per_joint(data, j, |d, i| d.tau[i])], lo: vec![1.0 - GAIN_RANGE.1], hi: vec![1.0 - GAIN_RANGE.0], ..Default::default() },
        Term::Offset(j) => TermDesign::free(vec![per_joint(data, j, |_, _| -1.0)]),
        Term::Cogging { joint, periods } => TermDesign::free(vec![per_joint(data, joint, |d, i| (periods * d.q[i]).sin())]),
        Term::Saturation { joint, limit } => {
            let mut v = Vec::new();
            for d in data {
                let m = d.smoothed_torque_map(|_, tau, out| {
                    out.fill(0.0);
                    out[joint] = tau[joint] - tau[joint].clamp(-limit, limit);
                });
                v.extend((0..d.len()).map(|s| m[s * dof + joint]));
            }
            TermDesign::fixed(Column { joint: Some(joint), values: v })
        }
        Term::Delay { delay } => {
            let mut v = Vec::new();
            for d in data {
                let period = d.raw.experiment.as_ref().map_or(d.raw.duration() / (d.raw.len().max(2) - 1) as f64, |e| e.sample_period);
                let m = d.smoothed_torque_map(|k, tau, out| {
                    for j in 0..dof {
                        out[j] = tau[j] - d.delayed_torque(k, delay, period, j);
                    }
                });
                v.extend(m);
            }
            TermDesign::fixed(Column { joint: None, values: v })
        }
        Term::CoriolisStructure => {
            let v = data.iter().flat_map(|d| d.coriolis_delta.iter().copied()).collect();
            TermDesign::fixed(Column { joint: None, values: v })
        }
        Term::Payload { com, max_mass } => {
            let col = payload_column(data, com);
            let col_max = col.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let hi = payload_mass_bound(col_max, largest_command(data), max_mass);
            TermDesign { cols: vec![col], lo: vec![0.0], hi: vec![hi], ..Default::default() }
        }
        Term::InertialError { ref prior } => {
            // every stacked parameter, in units of its scale
            let width = PARAMS_PER_LINK * dof;
            let mut cols: Vec<Column> = (0..width).map(|_| Column { joint: None, values: Vec::new() }).collect();
            for d in data {
                for s in 0..d.len() {
                    for j in 0..dof {
                        let row = &d.regressor[(s * dof + j) * width..(s * dof + j + 1) * width];
                        for (p, col) in cols.iter_mut().enumerate() {
                            col.values.push(row[p] * prior.scales[p]);
                        }
                    }
                }
            }
            TermDesign { cols, inertial: Some(prior.clone()), ..Default::default() }
        }
    }
}
