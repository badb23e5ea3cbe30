//! The exact equivalences the report names as alternatives.

use simgap_core::{inverse_dynamics, Model, Workspace, PENDULUM_URDF};
use simgap_sim::effects::apply_inertial_effects;
use simgap_sim::{Effect, LinkDelta};

use crate::select::alternatives::one_joint_equivalent;

/// An inertial correction of the pendulum's bob (2 kg, its centre of mass 0.5 m below the
/// hinge, 0.1 kg·m² about it; H = 0.6 kg·m²): its mass ×0.6, `inertia` added about its centre
/// of mass, its centre of mass moved by `com` [m].
fn correction(inertia: f64, com: [f64; 3]) -> Effect {
    Effect::InertialError { deltas: vec![LinkDelta { joint: 0, mass: -0.8, com, inertia: [inertia, 0.0, 0.0, inertia, 0.0, inertia] }] }
}

#[test]
fn a_one_joint_inertial_correction_is_the_torque_gain_and_rotor_inertia_it_names() {
    // k τ = (H + ia) q̈ + g(q) + C q̇ of the nominal pendulum is τ = H' q̈ + g'(q) + C' q̇ of the
    // corrected one, at every state
    let model = Model::from_urdf_str(PENDULUM_URDF).unwrap();
    let effect = correction(2e-3, [0.0; 3]);
    let e = one_joint_equivalent(&model, std::slice::from_ref(&effect)).expect("a one-joint correction has an equivalent gain and rotor inertia");
    // by hand: k = 2 / 1.2, H' = 0.102 + 1.2 · 0.25 = 0.402, ia = k H' − H = 0.07
    assert!((e.k - 2.0 / 1.2).abs() < 1e-9 && (e.ia - 0.07).abs() < 1e-9 && e.turn.abs() < 1e-9, "{e:?}");
    let corrected = apply_inertial_effects(&model, &[effect]).unwrap();
    let (mut ws, mut ws_c) = (Workspace::new(&model), Workspace::new(&corrected));
    for (q, qd, qdd) in [(0.3, -1.2, 4.0), (-2.1, 0.5, -7.5), (1.4, 3.0, 0.0)] {
        let nominal = (inverse_dynamics(&model, &mut ws, &[q], &[qd], &[qdd])[0] + e.ia * qdd) / e.k;
        let tau = inverse_dynamics(&corrected, &mut ws_c, &[q], &[qd], &[qdd])[0];
        assert!((nominal - tau).abs() <= 1e-9 * tau.abs().max(1.0), "at q = {q}, q̇ = {qd}, q̈ = {qdd}: {nominal} against {tau}");
    }
}

#[test]
fn a_one_joint_correction_that_turns_the_weight_says_by_how_much_and_one_that_would_need_a_negative_rotor_inertia_has_no_equivalent() {
    let model = Model::from_urdf_str(PENDULUM_URDF).unwrap();
    // the centre of mass moved 0.1 m across the arm (x, normal to the hinge's y and to the arm)
    let turned = one_joint_equivalent(&model, &[correction(2e-3, [0.1, 0.0, 0.0])]).unwrap();
    assert!((turned.turn.abs() - (0.1f64 / 0.5).atan()).abs() < 1e-9, "{turned:?}");
    // 0.05 kg·m² less about the centre of mass: k H' = 0.583 < H = 0.6
    assert!(one_joint_equivalent(&model, &[correction(-0.05, [0.0; 3])]).is_none());
    // no inertial correction, or more than one joint: nothing to say
    assert!(one_joint_equivalent(&model, &[Effect::Armature { ia: vec![0.01] }]).is_none());
    let arm = Model::from_urdf_str(simgap_core::PAPER_ARM_URDF).unwrap();
    let two = Effect::InertialError { deltas: vec![LinkDelta { joint: 0, mass: -0.1, com: [0.0; 3], inertia: [0.0; 6] }] };
    assert!(one_joint_equivalent(&arm, &[two]).is_none());
}
