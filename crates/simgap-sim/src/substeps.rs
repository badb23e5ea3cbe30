//! The RK4 steps per sample: raised from [`SimParams::substeps`] so that the stiffness of
//! the friction effects keeps RK4 stable.

use crate::effects::{friction_slope_bound, moving_friction_slope_bound, Effect};
use crate::integrate::Integrator;
use crate::params::SimParams;
use crate::plant::Plant;

/// The RK4 steps per sample the simulator uses: `params.substeps`, raised so that
/// `h · λ <= 2` where `λ = λ_max(H⁻¹ diag(s))` is the largest rate of the friction stiffness
/// (`s` from [`friction_slope_bound`], `H` the plant's mass matrix plus armature at `q0`;
/// computed as the largest eigenvalue of the symmetric `S^½ H⁻¹ S^½`). RK4's stability interval
/// on the negative real axis is `h·λ < 2.785`, so the rule keeps a margin of 28 % for the change
/// of H along the run. At most 10,000.
/// Each dry friction counts with its own width `w`; one with `w = 0` (the exact sign) counts
/// not at all (see [`friction_slope_bound`]).
pub fn effective_substeps(plant: &Plant, params: &SimParams) -> usize {
    substeps_and_moving_rate(plant, params).0
}

/// [`effective_substeps`], and the largest rate of the friction stiffness while every joint
/// moves faster than its [`stiff_band`](crate::effects::stiff_band) [1/s]: the same `λ` with the
/// slopes of [`moving_friction_slope_bound`](crate::effects::moving_friction_slope_bound). A
/// sample interval clear of every band needs only the steps that rate asks for
/// ([`crate::Stepper::advance`]). The rate is `None` where [`effective_substeps`] does not raise
/// the substeps (no friction, the adaptive integrator, a singular H, or a stiffness the
/// requested substeps already resolve).
pub(crate) fn substeps_and_moving_rate(plant: &Plant, params: &SimParams) -> (usize, Option<f64>) {
    let n = plant.dof();
    let mut full = vec![0.0; n];
    friction_slope_bound(plant.effects(), &mut full);
    add_load_friction_slope(plant, &mut full);
    let Some(inv) = stiffness_inverse(plant, params, &full) else { return (params.substeps, None) };
    let substeps = substeps_for_rate(params.sample_period, largest_rate(&inv, &full), params.substeps);
    if substeps == params.substeps {
        return (substeps, None);
    }
    let mut moving = vec![0.0; n];
    moving_friction_slope_bound(plant.effects(), &mut moving);
    add_load_friction_slope(plant, &mut moving);
    (substeps, Some(largest_rate(&inv, &moving)))
}

/// The effects of `plant` with the dry frictions too stiff for the sample period made exact:
/// on a joint whose friction rate `s_i (H⁻¹)_ii` (its slope bound from
/// [`friction_slope_bound`] over its inertia at `params.q0`) would ask RK4 for more than
/// `max_substeps` steps per sample, every smoothed dry friction becomes the exact sign (`w = 0`),
/// integrated as stick–slip; the load frictions too where `held_drive` (the drive's torque held
/// over each sample, [`Effect::make_sign_exact`]). Such a band's time constant is below `period / (2 max_substeps)`:
/// the motion inside it is over within a small part of one sample and no log sampled at
/// `period` can tell it from the exact sign, while resolving it would cost that many RK4 steps
/// per sample (hundreds for a narrow band on a light wrist joint). `None` when no joint is
/// changed (no friction, the adaptive integrator, a singular H, or bands the steps resolve).
pub fn unresolved_bands_exact(plant: &Plant, params: &SimParams, max_substeps: usize, held_drive: bool) -> Option<Vec<Effect>> {
    let n = plant.dof();
    let mut slope = vec![0.0; n];
    friction_slope_bound(plant.effects(), &mut slope);
    add_load_friction_slope(plant, &mut slope);
    let inv = stiffness_inverse(plant, params, &slope)?;
    let exact: Vec<bool> = (0..n).map(|i| substeps_for_rate(params.sample_period, slope[i] * inv[(i, i)], 1) > max_substeps).collect();
    if !exact.contains(&true) {
        return None;
    }
    let mut effects = plant.effects().to_vec();
    for e in &mut effects {
        e.make_sign_exact(&exact, held_drive);
    }
    Some(effects)
}

/// `effects` as [`unresolved_bands_exact`] leaves them for the plant of `model` under
/// `formulation` sampled as `params` says: the same effects, with the dry frictions too stiff for
/// the sample period made exact (unchanged when the plant cannot be built: the simulation then
/// reports why).
pub fn resolvable_effects(
    model: &simgap_core::Model,
    formulation: simgap_core::Formulation,
    effects: &[Effect],
    params: &SimParams,
    max_substeps: usize,
    held_drive: bool,
) -> Vec<Effect> {
    match Plant::new(model, formulation, effects) {
        Ok(plant) => unresolved_bands_exact(&plant, params, max_substeps, held_drive).unwrap_or_else(|| effects.to_vec()),
        Err(_) => effects.to_vec(),
    }
}

/// The RK4 steps per sample `period` with a drive's back-EMF coefficients `emf` [N·m·s/rad or
/// N·s/m] (a servo's `kt²/R` while enabled): at least `base`, raised so that `h · λ ≤ 2` for
/// the largest rate `λ` of the friction slopes plus `emf` against `(H + diag(ia))⁻¹` at `q`
/// (as [`effective_substeps`] does for friction alone). At most 10,000.
pub(crate) fn drive_substeps(plant: &Plant, q: &[f64], emf: &[f64], period: f64, base: usize) -> usize {
    drive_substeps_with(plant, q, emf, period, base, true)
}

/// [`drive_substeps`] for the back-EMF alone (`with_friction` false: without the frictions'
/// slopes): whether the drive itself is stiff against the link.
pub(crate) fn drive_substeps_with(plant: &Plant, q: &[f64], emf: &[f64], period: f64, base: usize, with_friction: bool) -> usize {
    let n = plant.dof();
    let mut slope = vec![0.0; n];
    if with_friction {
        friction_slope_bound(plant.effects(), &mut slope);
        add_load_friction_slope(plant, &mut slope);
    }
    for (s, e) in slope.iter_mut().zip(emf) {
        *s += e.max(0.0);
    }
    if slope.iter().all(|s| *s == 0.0) || q.len() != n || q.iter().any(|v| !v.is_finite()) {
        return base;
    }
    match inverse_inertia(plant, q) {
        Some(inv) => substeps_for_rate(period, largest_rate(&inv, &slope), base),
        None => base,
    }
}

/// The substeps of a sample interval of `period` seconds for friction rates `lambda` [1/s]
/// (`h · λ ≤ 2`, see [`effective_substeps`]): at least `base`, at most 10,000.
pub(crate) fn substeps_for_rate(period: f64, lambda: f64, base: usize) -> usize {
    let needed = (period * lambda / 2.0).ceil();
    if needed.is_finite() {
        base.max(needed.min(10_000.0) as usize)
    } else {
        base
    }
}

/// A load friction's slope grows with the drive's torque: bounded from the effort limits.
fn add_load_friction_slope(plant: &Plant, slope: &mut [f64]) {
    for e in plant.effects() {
        use crate::effects::Effect;
        // the load part's step over w (its largest per unit torque) and, in Stribeck form, its
        // rise over vs (slope at most 2 |mus − mu| |τ| / vs)
        let (mu, rise, w) = match e {
            Effect::LoadFriction { mu, w, .. } => (mu, None, w),
            Effect::LoadStribeckFriction { mu, mus, vs, w, .. } => (mu, Some((mus, vs)), w),
            _ => continue,
        };
        for (i, s) in slope.iter_mut().enumerate() {
            let limit = plant.effort_limits()[i];
            if w[i] > 0.0 && limit.is_finite() {
                let (most, hump) = match rise {
                    Some((mus, vs)) if vs[i] > 0.0 => (mu[i].max(mus[i]), 2.0 * (mus[i] - mu[i]).abs() / vs[i]),
                    Some((mus, _)) => (mu[i].max(mus[i]), 0.0),
                    None => (mu[i], 0.0),
                };
                *s += most * limit / w[i] + hump * limit;
            }
        }
    }
}

/// `(H + diag(ia))⁻¹` at `params.q0` when friction slopes `slope` make RK4's step matter
/// (`None` without friction, with the adaptive integrator, or for a singular H).
fn stiffness_inverse(plant: &Plant, params: &SimParams, slope: &[f64]) -> Option<nalgebra::DMatrix<f64>> {
    let n = plant.dof();
    if slope.iter().all(|s| *s == 0.0) || !matches!(params.integrator, Integrator::Rk4) {
        return None;
    }
    let q0 = if params.q0.len() == n { params.q0.clone() } else { vec![0.0; n] };
    inverse_inertia(plant, &q0)
}

/// `(H(q) + diag(ia))⁻¹` of `plant` ([`Plant::inertia_matrix`]; `None` for a singular H).
fn inverse_inertia(plant: &Plant, q: &[f64]) -> Option<nalgebra::DMatrix<f64>> {
    let n = plant.dof();
    let mut h = nalgebra::DMatrix::zeros(n, n);
    plant.inertia_matrix(&mut plant.workspace(), q, &mut h);
    h.try_inverse()
}

/// `λ_max(H⁻¹ diag(s)) = λ_max(S^½ H⁻¹ S^½)`, a symmetric positive semi-definite matrix, from
/// `inv = H⁻¹`.
fn largest_rate(inv: &nalgebra::DMatrix<f64>, slope: &[f64]) -> f64 {
    let n = slope.len();
    let root: Vec<f64> = slope.iter().map(|s| s.max(0.0).sqrt()).collect();
    let m = nalgebra::DMatrix::from_fn(n, n, |i, j| root[i] * inv[(i, j)] * root[j]);
    m.symmetric_eigenvalues().iter().copied().fold(0.0f64, f64::max)
}
