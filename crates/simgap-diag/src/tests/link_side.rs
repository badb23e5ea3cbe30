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
    let selected = |effect: &str| d.report.selected_effects.iter().find(|e| e.effect.as_str() == effect);
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

#[test]
fn a_rotor_inertia_is_not_tried_where_the_torque_is_measured_on_the_link_side() {
    // the paper's arm with a rotor inertia on its elbow and viscous friction: told that the
    // effort is the drive's, the diagnosis finds the rotor; told that it was measured on the link
    // side of the gearbox, it tries no rotor inertia (nor back-EMF), says so, and still finds the
    // friction
    let model = Model::from_urdf_str(simgap_core::PAPER_ARM_URDF).unwrap();
    let n = model.dof();
    let period = 0.002;
    let truth = vec![Effect::Armature { ia: vec![0.0, 0.05] }, Effect::ViscousFriction { b: vec![0.3, 0.2] }];
    let (kp, kv) = gains_for(&model, 3.0);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
    let runs: Vec<_> = (0..3)
        .map(|i| {
            let spec = RunSpec {
                name: format!("run-{i}"),
                controller: ControllerKind::PdGravity,
                kp: kp.clone(),
                kv: kv.clone(),
                reference: RefSpec::Fourier(random_fourier(n, 0.6, &mut rng)),
                duration: 8.0,
            };
            generate(&model, Formulation::EulerLagrange, &truth, &spec, period, 1_048_576.0).unwrap()
        })
        .collect();
    let (fit, hold) = runs.split_at(2);
    let names = |d: &crate::Diagnosis| d.report.selected_effects.iter().map(|e| e.effect.to_string()).collect::<Vec<_>>();
    let drive_side = diagnose(&model, Formulation::EulerLagrange, fit, hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    assert!(names(&drive_side).iter().any(|e| e == "armature"), "the drive's effort shows the rotor: {:?}", names(&drive_side));
    let mut options = DiagnoseOptions::default();
    options.prepare.link_side_torque = true;
    let link_side = diagnose(&model, Formulation::EulerLagrange, fit, hold, &options, &mut |_| {}).unwrap();
    println!("{}", link_side.report.summary());
    for e in ["armature", "back_emf"] {
        assert!(!names(&link_side).iter().any(|x| x == e), "{e} selected on link-side torque: {:?}", names(&link_side));
        assert!(!link_side.report.candidates.iter().any(|c| c.effect.as_str() == e), "{e} tried on link-side torque");
    }
    assert!(names(&link_side).iter().any(|e| e == "viscous_friction"), "{:?}", names(&link_side));
    assert!(link_side.report.notes.iter().any(|n| n.contains("link side of the gearbox")), "{:?}", link_side.report.notes);
    assert!(!link_side.report.notes.iter().any(|n| n.contains("the data show a rotor inertia")), "{:?}", link_side.report.notes);
}
