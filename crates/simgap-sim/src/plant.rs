//! The plant: the nominal model plus unmodelled [`Effect`]s, as the simulator integrates it.

use nalgebra::DMatrix;
use simgap_core::{forward_dynamics_armature_into, mass_matrix, mass_matrix_into, try_forward_dynamics_into, Formulation, Model, Workspace};

use crate::effects::{apply_inertial_effects, armature, backlash, encoder_offset, friction_torque, friction_torque_smooth, total_delay, Effect};
use crate::error::Result;

/// What the simulator integrates:
///
/// ```text
/// (H(q̄) + diag(ia)) q̈ = τ_applied + τ_friction(q, q̇) − C(q̄, q̇) q̇ − g(q̄),   q̄ = q + δ
/// ```
///
/// with `q` the measured positions, `δ` the encoder offset, `H`, `C`, `g` of the model after
/// payload and inertial errors, `C` of `formulation.other()` when [`Effect::CoriolisStructure`]
/// is present, `ia` the armature and `τ_friction` from [`friction_torque`]. See
/// [`crate::effects`] for `τ_applied`.
#[derive(Clone, Debug)]
pub struct Plant {
    model: Model,
    formulation: Formulation,
    effects: Vec<Effect>,
    armature: Vec<f64>,
    /// The encoder offset `δ` [rad or m] (`None` when 0 on every joint).
    offset: Option<Vec<f64>>,
    /// The backlash widths [rad or m] (`None` when no joint with a rotor inertia has play).
    backlash: Option<Vec<f64>>,
    /// H is positive definite at q = 0 and no armature is added: the one-pass
    /// `try_forward_dynamics_into` can be used (a model whose inertia is not physical can still
    /// lose definiteness elsewhere: the acceleration is then NaN).
    fast_path: bool,
    delay: f64,
    effort_limits: Vec<f64>,
}

/// Scratch space of [`Plant::acceleration`]: create once per thread with [`Plant::workspace`].
#[derive(Clone, Debug)]
pub struct PlantWorkspace {
    /// The dynamics workspace.
    pub ws: Workspace,
    friction: Vec<f64>,
    h: DMatrix<f64>,
    /// The true positions `q + δ` (with an encoder offset).
    q_true: Vec<f64>,
    /// The armature coupled to each link now: the plant's, 0 on a joint whose drive side is
    /// inside its backlash's gap ([`PlantWorkspace::couple_rotor`]).
    armature: Vec<f64>,
}

impl PlantWorkspace {
    /// Couples joint `i`'s rotor inertia `ia` [kg·m² or kg] to its link (`ia` the plant's
    /// armature), or uncouples it (`ia = 0`) while a backlash's gap is open: the accelerations
    /// and inertias that follow use it.
    ///
    /// # Panics
    /// If `i` is not a joint.
    pub fn couple_rotor(&mut self, i: usize, ia: f64) {
        self.armature[i] = ia;
    }
}

impl Plant {
    /// The model under `formulation` with `effects`.
    ///
    /// # Errors
    /// [`Error::Invalid`](crate::Error::Invalid) for an effect of the wrong size or sign;
    /// [`Error::Model`](crate::Error::Model) when payload or inertial errors make a link
    /// non-physical.
    pub fn new(model: &Model, formulation: Formulation, effects: &[Effect]) -> Result<Plant> {
        let changed = apply_inertial_effects(model, effects)?;
        let n = model.dof();
        let mut ia = vec![0.0; n];
        armature(effects, &mut ia);
        let mut offset = vec![0.0; n];
        encoder_offset(effects, &mut offset);
        let mut play = vec![0.0; n];
        backlash(effects, &mut play);
        let has_play = play.iter().zip(&ia).any(|(w, a)| *w > 0.0 && *a > 0.0);
        let coriolis_flip = effects.iter().filter(|e| matches!(e, Effect::CoriolisStructure)).count() % 2 == 1;
        let h_ok = {
            let mut h = mass_matrix(&changed, &mut Workspace::new(&changed), &vec![0.0; n]);
            let mut b = vec![1.0; n];
            simgap_core::try_solve_spd_in_place(&mut h, &mut b)
        };
        Ok(Plant {
            fast_path: h_ok && ia.iter().all(|x| *x == 0.0),
            formulation: if coriolis_flip { formulation.other() } else { formulation },
            effects: effects.to_vec(),
            armature: ia,
            offset: offset.iter().any(|x| *x != 0.0).then_some(offset),
            backlash: has_play.then_some(play),
            delay: total_delay(effects),
            effort_limits: model.joints().iter().map(|j| j.limits.effort).collect(),
            model: changed,
        })
    }

    /// The model the plant integrates (payload and inertial errors applied).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The formulation of C the plant integrates (flipped by [`Effect::CoriolisStructure`]).
    pub fn formulation(&self) -> Formulation {
        self.formulation
    }

    /// The effects.
    pub fn effects(&self) -> &[Effect] {
        &self.effects
    }

    /// The reflected rotor inertias `ia` [kg·m² or kg] (the armature effects, summed).
    pub fn armature(&self) -> &[f64] {
        &self.armature
    }

    /// The backlash widths [rad or m] per joint, `None` when no joint with a rotor inertia has
    /// play (without one, the drive's side crosses the gap at once and the link moves as
    /// without play).
    pub fn backlash(&self) -> Option<&[f64]> {
        self.backlash.as_deref()
    }

    /// Total actuation delay [s].
    pub fn delay(&self) -> f64 {
        self.delay
    }

    /// Actuator effort limits of the model's joints (URDF `effort`, `+∞` when absent).
    pub fn effort_limits(&self) -> &[f64] {
        &self.effort_limits
    }

    /// Number of degrees of freedom.
    pub fn dof(&self) -> usize {
        self.model.dof()
    }

    /// Scratch space for [`Plant::acceleration`].
    pub fn workspace(&self) -> PlantWorkspace {
        let n = self.dof();
        PlantWorkspace { ws: Workspace::new(&self.model), friction: vec![0.0; n], h: DMatrix::zeros(n, n), q_true: vec![0.0; n], armature: self.armature.clone() }
    }

    /// Joint accelerations q̈ for applied torques `tau_applied` (see the type's equation; each
    /// dry friction smooths `sign(q̇)` with its own width). Never allocates.
    ///
    /// When `H + diag(ia)` is not positive definite (a negative armature) or the state is not
    /// finite, `out` is filled with NaN; the simulator reports that as divergence.
    ///
    /// # Panics
    /// If a length does not match the model.
    pub fn acceleration(&self, pws: &mut PlantWorkspace, q: &[f64], qd: &[f64], tau_applied: &[f64], out: &mut [f64]) {
        self.acceleration_parts(pws, q, qd, tau_applied, true, out);
    }

    /// [`Plant::acceleration`] without the dry frictions of width `w = 0`, which the caller
    /// applies (as the stick–slip of [`crate::step::Stepper`]) inside `tau_applied`.
    ///
    /// # Panics
    /// As [`Plant::acceleration`].
    pub fn acceleration_smooth(&self, pws: &mut PlantWorkspace, q: &[f64], qd: &[f64], tau_applied: &[f64], out: &mut [f64]) {
        self.acceleration_parts(pws, q, qd, tau_applied, false, out);
    }

    /// The diagonal of `H(q) + diag(ia)` [kg·m² or kg] into `out`: the inertia each joint
    /// moves alone.
    ///
    /// # Panics
    /// If a length does not match the model.
    pub fn inertia_diagonal(&self, pws: &mut PlantWorkspace, q: &[f64], out: &mut [f64]) {
        let q = true_positions(self.offset.as_deref(), q, &mut pws.q_true);
        mass_matrix_into(&self.model, &mut pws.ws, q, &mut pws.h);
        for (i, o) in out.iter_mut().enumerate() {
            *o = pws.h[(i, i)] + pws.armature[i];
        }
    }

    /// `H(q) + diag(ia)` [kg·m² or kg] into `out` (`dof × dof`). Never allocates.
    ///
    /// # Panics
    /// If a size does not match the model.
    pub fn inertia_matrix(&self, pws: &mut PlantWorkspace, q: &[f64], out: &mut DMatrix<f64>) {
        let q = true_positions(self.offset.as_deref(), q, &mut pws.q_true);
        mass_matrix_into(&self.model, &mut pws.ws, q, out);
        for i in 0..self.dof() {
            out[(i, i)] += pws.armature[i];
        }
    }

    fn acceleration_parts(&self, pws: &mut PlantWorkspace, q: &[f64], qd: &[f64], tau_applied: &[f64], exact: bool, out: &mut [f64]) {
        let friction = if exact { friction_torque } else { friction_torque_smooth };
        let n = self.dof();
        assert!(q.len() == n && qd.len() == n && tau_applied.len() == n && out.len() == n, "Plant::acceleration: lengths must be model.dof()");
        if q.iter().chain(qd).any(|x| !x.is_finite()) {
            out.fill(f64::NAN);
            return;
        }
        // the frictions at the measured positions, the rigid body at the true ones
        friction(&self.effects, q, qd, &mut pws.friction);
        for i in 0..n {
            pws.friction[i] += tau_applied[i];
        }
        let q = true_positions(self.offset.as_deref(), q, &mut pws.q_true);
        // fast path: one kinematics pass, q̈ = H⁻¹ (τ + friction − C q̇ − g)
        if self.fast_path {
            // a model whose inertia is not physical (a fitted correction) cannot accelerate: NaN,
            // which the caller reads as divergence
            if !try_forward_dynamics_into(&self.model, &mut pws.ws, q, qd, &pws.friction, self.formulation, out) {
                out.fill(f64::NAN);
            }
            return;
        }
        // q̈ = (H + diag(ia))⁻¹ (τ + friction − C q̇ − g) with one kinematics pass for the bias
        // torques and H
        if !forward_dynamics_armature_into(&self.model, &mut pws.ws, q, qd, &pws.friction, &pws.armature, self.formulation, out) {
            out.fill(f64::NAN);
        }
    }
}

/// The true positions `q + δ` in `buf` with an encoder offset `δ`, else `q` itself.
fn true_positions<'a>(offset: Option<&[f64]>, q: &'a [f64], buf: &'a mut [f64]) -> &'a [f64] {
    match offset {
        Some(d) => {
            for ((b, x), o) in buf.iter_mut().zip(q).zip(d) {
                *b = x + o;
            }
            buf
        }
        None => q,
    }
}
