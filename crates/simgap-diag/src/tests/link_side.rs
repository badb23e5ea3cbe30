//! A 7-DOF arm whose joint torques are measured on the link side (after the gearbox), as torque
//! sensing arms log them: the logged effort already excludes the rotor, so no rotor inertia can
//! be found, while the sensors' biases (torque offsets) and the cables' spring must be. The recorder low-pass filters
//! its signals without phase (as an offline export does), and the fit runs repeat one trajectory.

use simgap_core::{Formulation, Model, UrdfOptions};
use simgap_sim::{ControllerKind, Effect};

use crate::check::bench::{gains_for, generate, random_fourier, RefSpec, RunSpec};
use crate::check::drives::filtered as recorded;
use crate::{diagnose, DiagnoseOptions};

#[test]
fn link_side_torque_sensing_finds_the_sensor_offsets_and_the_spring_and_no_rotor_inertia() {
    // the sensors' biases on four joints
    sensor_offsets_and_spring_found(&[0.8, 0.0, -0.7, 0.0, 0.6, 0.0, -0.9], 7);
}

#[test]
fn sensor_offsets_on_the_gravity_loaded_joints_are_offsets_not_an_inertial_correction() {
    // biases on the shoulder and elbow, which carry the arm's weight: over a motion of modest
    // range a shifted centre of mass mimics a constant torque there, and the parsimony of the
    // selection must prefer the offsets (a parameter each) to an inertial correction of every link
    sensor_offsets_and_spring_found(&[0.0, 0.9, 0.0, -0.7, 0.0, 0.0, 0.0], 11);
}

/// Diagnoses link-side runs of the 7-DOF arm with sensor `offsets`, viscous friction on every
/// joint and a cable spring on joint 6 (trajectories drawn from `seed`), and checks that the
/// offsets and the spring are found, with no rotor inertia and no inertial correction.
fn sensor_offsets_and_spring_found(offsets: &[f64], seed: u64) {
    let model = Model::from_urdf_str_with(simgap_core::ARM7_URDF, "arm7.urdf", &UrdfOptions { tip: Some("panda_hand".into()) }).unwrap();
    let n = model.dof();
    let period = 0.005;
    let offsets = offsets.to_vec();
    // cables along the wrist: a spring of 2 N·m/rad about q = 0.3 rad on joint 6
    let truth = vec![
        Effect::TorqueOffset { offset: offsets.clone() },
        Effect::ViscousFriction { b: vec![0.6, 0.6, 0.5, 0.5, 0.2, 0.2, 0.1] },
        Effect::JointSpring { k: vec![0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0], q0: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0] },
    ];
    let (kp, kv) = gains_for(&model, 2.0);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let trajectory = random_fourier(n, 0.5, &mut rng);
    let mut faster = random_fourier(n, 0.5, &mut rng);
    for f in faster.frequencies.iter_mut().flatten() {
        *f *= 1.5;
    }
    let spec = |name: &str, f: &simgap_sim::Fourier, duration: f64| RunSpec {
        name: name.into(),
        controller: ControllerKind::PdGravity,
        kp: kp.clone(),
        kv: kv.clone(),
        reference: RefSpec::Fourier(f.clone()),
        duration,
    };
    let run = |s: RunSpec| recorded(generate(&model, Formulation::EulerLagrange, &truth, &s, period, 1_048_576.0).unwrap(), 8.0, period);
    // two repeats of one trajectory to fit, a faster run held out
    let fit = vec![run(spec("repeat-1", &trajectory, 12.0)), run(spec("repeat-2", &trajectory, 12.0))];
    let hold = vec![run(spec("faster", &faster, 12.0))];
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    println!("{}", d.report.summary());
    for s in d.report.selection_log.iter().filter(|s| s.reason.starts_with("not a finding") || s.reason.contains("simpler")) {
        println!("plausibility: {} on {:?}: {}", s.effect, s.joint, s.reason);
    }
    let selected = |effect: &str| d.report.selected_effects.iter().find(|e| e.effect == effect);
    assert!(selected("armature").is_none(), "a link-side torque holds no rotor inertia: {:?}", selected("armature"));
    assert!(selected("inertial_error").is_none(), "the URDF's inertia is right: {:?}", selected("inertial_error"));
    // the recorder's filter is named, and its flattened torque peaks are not read as a limit
    assert!(selected("torque_saturation").is_none(), "a filter is no torque limit: {:?}", selected("torque_saturation"));
    let note = d.report.notes.iter().find(|n| n.contains("low-pass filtered")).unwrap_or_else(|| panic!("no note of the recorder's filter: {:?}", d.report.notes));
    assert!(note.contains("repeat-1") && note.contains("repeat-2") && note.contains("saturation"), "{note}");
    // every sensor bias found, within its interval
    let found = selected("torque_offset").unwrap_or_else(|| panic!("no torque offset selected: {:?}", d.report.selected_effects));
    let names = model.joint_names();
    for (j, o) in offsets.iter().enumerate().filter(|(_, o)| **o != 0.0) {
        let at = found.joints.iter().position(|x| x == names[j]).unwrap_or_else(|| panic!("no offset on {}: {found:?}", names[j]));
        let value = match found.parameters.get("offset") {
            Some(crate::vocabulary::Param::PerJoint(v)) => v[at],
            _ => panic!("{found:?}"),
        };
        assert!((value - o).abs() < 0.2 * o.abs(), "offset on {}: {value} against {o}", names[j]);
    }
    // the cables' spring found
    let spring = selected("joint_spring").unwrap_or_else(|| panic!("no joint spring selected: {:?}", d.report.selected_effects));
    assert_eq!(spring.joints, [names[5]], "{spring:?}");
    let k_found = match spring.parameters.get("k") {
        Some(crate::vocabulary::Param::PerJoint(v)) => v[0],
        _ => panic!("{spring:?}"),
    };
    assert!((k_found - 2.0).abs() < 0.3, "spring k = {k_found} against 2 N·m/rad");
    // the verdict is honest against constant-velocity extrapolation
    let k = &d.report.gap.kstep;
    if d.report.verdict.starts_with("the gap is explained") {
        for (a, f) in k.after.iter().zip(&k.floor) {
            assert!(*a <= 0.8 * f, "explained, yet {a} against the floor {f}");
        }
    }
}
