//! The fixture URDFs in `models/`: loaded, and checked against what can be worked out by hand.

mod common;

use common::{arm7_with_tip, model_path};
use nalgebra::{Matrix3, Vector3};
use simgap_core::*;

#[test]
fn pendulum_mass_matrix_gravity_and_energies_match_hand_formulas() {
    // m = 2 kg, l = 0.5 m, Iyy = 0.1 kg·m² about the centre of mass, joint 1 m above the base
    let model = Model::from_urdf_file(model_path("pendulum.urdf")).unwrap();
    assert_eq!(model.dof(), 1);
    assert_eq!(model.joint_names(), ["hinge"]);
    assert!(model.warnings().is_empty(), "{:?}", model.warnings());
    let (m, l, iyy, g0) = (2.0, 0.5, 0.1, 9.81);
    let mut ws = Workspace::new(&model);
    for k in 0..40 {
        let q = [-3.0 + 0.15 * k as f64];
        let qd = [1.7 - 0.1 * k as f64];
        let h = mass_matrix(&model, &mut ws, &q)[(0, 0)];
        assert!((h - (iyy + m * l * l)).abs() < 1e-12, "H = {h}, expected 0.6");
        let g = gravity_torques(&model, &mut ws, &q)[0];
        assert!((g - m * g0 * l * q[0].sin()).abs() < 1e-12, "g = {g}, expected 9.81 sin q");
        // U = m g z_com with z_com = 1 − l cos q
        let u = potential_energy(&model, &mut ws, &q);
        assert!((u - m * g0 * (1.0 - l * q[0].cos())).abs() < 1e-12, "U = {u}");
        let t = kinetic_energy(&model, &mut ws, &q, &qd);
        assert!((t - 0.5 * 0.6 * qd[0] * qd[0]).abs() < 1e-12, "T = {t}");
        for f in Formulation::ALL {
            assert!(coriolis_matrix(&model, &mut ws, &q, &qd, f)[(0, 0)].abs() < 1e-12, "a single joint has no Coriolis term");
        }
        // q̈ = (τ − g) / H
        let tau = [0.4 * k as f64 - 5.0];
        let qdd = forward_dynamics(&model, &mut ws, &q, &qd, &tau, Formulation::EulerLagrange)[0];
        assert!((qdd - (tau[0] - g) / 0.6).abs() < 1e-12);
    }
}

#[test]
fn non_unit_axis_is_normalised() {
    let scaled = Model::from_urdf_file(model_path("pendulum_nonunit_axis.urdf")).unwrap();
    let unit = Model::from_urdf_file(model_path("pendulum.urdf")).unwrap();
    assert_eq!(scaled.joints()[0].axis, Vector3::new(0.0, 1.0, 0.0), "axis (0, 3, 0) is stored as (0, 1, 0)");
    let (mut wa, mut wb) = (Workspace::new(&scaled), Workspace::new(&unit));
    for q in [-2.0, -0.4, 0.3, 1.9] {
        assert_eq!(mass_matrix(&scaled, &mut wa, &[q]), mass_matrix(&unit, &mut wb, &[q]));
        assert_eq!(gravity_torques(&scaled, &mut wa, &[q]), gravity_torques(&unit, &mut wb, &[q]));
    }
    // and an oblique one in code
    let j = Joint::new("j", JointKind::Revolute, Vector3::new(1.0, 2.0, 2.0), Transform::IDENTITY, "l", SpatialInertia::from_com(1.0, Vector3::x(), Matrix3::identity() * 0.01));
    let m = Model::new("m", "base", vec![j]).unwrap();
    assert!((m.joints()[0].axis - Vector3::new(1.0, 2.0, 2.0) / 3.0).norm() < 1e-15);
}

/// Link masses of arm7.urdf from panda_link1 to the fingers (the base never moves).
const ARM7_MASSES: [f64; 10] = [4.97, 0.646, 3.228, 3.587, 1.225, 1.666, 0.735, 0.73, 0.015, 0.015];

#[test]
fn arm7_with_tip_at_hand_is_seven_dof_with_fingers_merged() {
    let model = arm7_with_tip("panda_hand");
    assert_eq!(model.dof(), 7);
    assert_eq!(model.joint_names(), (1..=7).map(|i| format!("panda_joint{i}")).collect::<Vec<_>>());
    assert_eq!(model.base_link(), "panda_link0");
    // joint kinds and limits: joint 7 is continuous, without position limits
    let kinds: Vec<JointKind> = model.joints().iter().map(|j| j.kind).collect();
    assert_eq!(kinds[..6], [JointKind::Revolute; 6]);
    assert_eq!(kinds[6], JointKind::Continuous);
    let l7 = model.joints()[6].limits;
    assert!(l7.lower == f64::NEG_INFINITY && l7.upper == f64::INFINITY && l7.effort == 12.0, "{l7:?}");
    let l4 = model.joints()[3].limits;
    assert_eq!((l4.lower, l4.upper), (-3.0718, -0.0698));
    // every moving link's mass is there, fingers included
    let total: f64 = ARM7_MASSES.iter().sum();
    assert!((model.total_mass() - total).abs() < 1e-12, "total mass {} vs {total}", model.total_mass());
    // warnings: the fingers are locked, the flange has no <inertial>
    let w = model.warnings().join("\n");
    assert!(w.contains("panda_finger_joint1") && w.contains("panda_finger_joint2") && w.contains("locked"), "{w}");
    assert!(w.contains("panda_link8") && w.contains("no <inertial>"), "{w}");
    assert!(w.contains("arm7.urdf"), "warnings name the file: {w}");
}

#[test]
fn arm7_last_body_is_link7_plus_hand_plus_fingers_by_hand() {
    let model = arm7_with_tip("panda_hand");
    let x = |xyz: [f64; 3], rpy: [f64; 3]| Transform::from_xyz_rpy(xyz, rpy);
    let body = |m: f64, com: [f64; 3], rpy: [f64; 3], d: [f64; 3], off: [f64; 3]| {
        // URDF <inertial>: diagonal d plus off-diagonals (ixy, ixz, iyz), in a frame rotated by rpy
        let r = x([0.0; 3], rpy).rotation;
        let i = Matrix3::new(d[0], off[0], off[1], off[0], d[1], off[2], off[1], off[2], d[2]);
        SpatialInertia::from_com(m, Vector3::from(com), r * i * r.transpose())
    };
    let link7 = body(0.735, [0.0105, -0.0043, 0.0617], [0.0; 3], [0.0127, 0.0101, 0.0049], [-0.0004, -0.0012, -0.0007]);
    let hand = body(0.73, [0.0, 0.002, 0.03], [0.0; 3], [0.0025, 0.0005, 0.0023], [0.0; 3]);
    let finger = |y: f64| body(0.015, [0.0, y, 0.02], [0.0; 3], [2.4e-6, 2.4e-6, 1.0e-6], [0.0; 3]);
    // link7 → (fixed, z + 0.107) link8 → (fixed, yaw −π/4) hand → (prismatic at 0, z + 0.0584) fingers
    let to_hand = x([0.0, 0.0, 0.107], [0.0; 3]).compose(&x([0.0; 3], [0.0, 0.0, -std::f64::consts::FRAC_PI_4]));
    let to_fingers = to_hand.compose(&x([0.0, 0.0, 0.0584], [0.0; 3]));
    let mut expected = link7;
    expected += hand.transformed(&to_hand);
    expected += finger(0.01).transformed(&to_fingers);
    expected += finger(-0.01).transformed(&to_fingers);
    let got = &model.joints()[6].inertia;
    assert!((got.mass - expected.mass).abs() < 1e-12);
    assert!((got.first_moment - expected.first_moment).norm() < 1e-12, "{} vs {}", got.first_moment, expected.first_moment);
    assert!((got.rotational - expected.rotational).norm() < 1e-12, "{} vs {}", got.rotational, expected.rotational);
}

#[test]
fn arm7_inertial_rpy_rotates_the_inertia() {
    // panda_link3: diag(0.0372, 0.0361, 0.0108) in a frame rotated by rpy (0.1, 0.2, 0.3)
    let model = arm7_with_tip("panda_hand");
    let r = Transform::from_xyz_rpy([0.0; 3], [0.1, 0.2, 0.3]).rotation;
    let i = r * Matrix3::from_diagonal(&Vector3::new(0.0372, 0.0361, 0.0108)) * r.transpose();
    let expected = SpatialInertia::from_com(3.228, Vector3::new(0.0275, 0.0392, -0.0666), i);
    let got = &model.joints()[2].inertia;
    assert!((got.rotational - expected.rotational).norm() < 1e-14);
    assert!((got.inertia_about_com() - i).norm() < 1e-14);
    // the rotation matters: the unrotated diagonal differs
    assert!((got.inertia_about_com() - Matrix3::from_diagonal(&Vector3::new(0.0372, 0.0361, 0.0108))).norm() > 1e-3);
}

#[test]
fn arm7_placements_compose_rpy_rotations() {
    // at q = 0 the Panda's flange (joint 7 frame) sits at x = 0.088, z = 0.333 + 0.316 + 0.384 − 0.0
    let model = arm7_with_tip("panda_hand");
    let mut ws = Workspace::new(&model);
    forward_kinematics(&model, &mut ws, &[0.0; 7]);
    let p7 = ws.poses[6].translation;
    assert!((p7 - Vector3::new(0.088, 0.0, 1.033)).norm() < 1e-12, "joint 7 at {p7}");
    // and its axis points down (the Panda's flange faces the floor at q = 0)
    let z7 = ws.poses[6].rotation * Vector3::z();
    assert!((z7 - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12, "joint 7 axis {z7}");
}

#[test]
fn arm7_tips_along_the_rigid_end_give_the_same_dynamics() {
    // tip panda_link7, panda_link8 or panda_hand: everything past joint 7 is rigid (fingers locked)
    let models: Vec<Model> = ["panda_link7", "panda_link8", "panda_hand"].iter().map(|t| arm7_with_tip(t)).collect();
    let mut ws = Workspace::new(&models[0]);
    for k in 0..10 {
        let q: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.37).sin() * 2.5).collect();
        let qd: Vec<f64> = (0..7).map(|i| ((k * 5 + i) as f64 * 0.91).cos() * 2.0).collect();
        let reference = dynamics_terms(&models[2], &mut ws, &q, &qd, Formulation::EulerLagrange);
        for m in &models[..2] {
            let t = dynamics_terms(m, &mut ws, &q, &qd, Formulation::EulerLagrange);
            assert!((&t.mass_matrix - &reference.mass_matrix).norm() < 1e-12);
            assert!((&t.coriolis_matrix - &reference.coriolis_matrix).norm() < 1e-12);
            assert!((&t.gravity_torques - &reference.gravity_torques).norm() < 1e-12);
        }
    }
}

#[test]
fn arm7_to_a_finger_is_eight_dof_and_agrees_with_the_merged_arm_at_zero_finger_position() {
    let arm = arm7_with_tip("panda_hand");
    let finger = arm7_with_tip("panda_leftfinger");
    assert_eq!(finger.dof(), 8);
    assert_eq!(finger.joints()[7].name, "panda_finger_joint1");
    assert_eq!(finger.joints()[7].kind, JointKind::Prismatic);
    assert!((finger.total_mass() - arm.total_mass()).abs() < 1e-12);
    let w = finger.warnings().join("\n");
    assert!(w.contains("panda_finger_joint2") && !w.contains("panda_finger_joint1"), "{w}");
    let (mut wa, mut wf) = (Workspace::new(&arm), Workspace::new(&finger));
    for k in 0..10 {
        let q: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.53).sin() * 2.5).collect();
        let q8: Vec<f64> = q.iter().copied().chain([0.0]).collect();
        let h7 = mass_matrix(&arm, &mut wa, &q);
        let h8 = mass_matrix(&finger, &mut wf, &q8);
        assert!((h8.view((0, 0), (7, 7)) - &h7).norm() < 1e-12, "H of the first 7 joints");
        // the finger's own entry is its mass (a prismatic joint carries the mass it moves)
        assert!((h8[(7, 7)] - 0.015).abs() < 1e-12, "H_88 = {}", h8[(7, 7)]);
        let g7 = gravity_torques(&arm, &mut wa, &q);
        let g8 = gravity_torques(&finger, &mut wf, &q8);
        assert!((g8.rows(0, 7) - &g7).norm() < 1e-12, "g of the first 7 joints");
    }
}

#[test]
fn continuous_joint_is_periodic_and_unwrapped() {
    let model = arm7_with_tip("panda_hand");
    let mut ws = Workspace::new(&model);
    let q = [0.3, -0.5, 0.2, -1.8, 0.4, 1.6, 0.7];
    let mut q_turned = q;
    q_turned[6] += 2.0 * std::f64::consts::PI;
    let (h, hq) = (mass_matrix(&model, &mut ws, &q), mass_matrix(&model, &mut ws, &q_turned));
    assert!((h - hq).norm() < 1e-12);
    let (g, gq) = (gravity_torques(&model, &mut ws, &q), gravity_torques(&model, &mut ws, &q_turned));
    assert!((g - gq).norm() < 1e-12);
}

/// The ignored elements of `paper_arm_repeated_elements.urdf`: (line, where, tag, line of the
/// element read instead).
const REPEATED: [(u32, &str, &str, u32); 14] = [
    (11, "material 'grey'", "color", 10),
    (16, "joint 'shoulder'", "parent", 15),
    (19, "joint 'shoulder'", "origin", 18),
    (21, "joint 'shoulder'", "axis", 20),
    (23, "joint 'shoulder'", "limit", 22),
    (28, "<inertial> of link 'upper_arm'", "origin", 27),
    (30, "<inertial> of link 'upper_arm'", "mass", 29),
    (32, "<inertial> of link 'upper_arm'", "inertia", 31),
    (34, "link 'upper_arm'", "inertial", 26),
    (42, "<geometry> of <visual> of link 'upper_arm'", "box", 41),
    (45, "<visual> of link 'upper_arm'", "material", 44),
    (52, "joint 'upper_arm_end'", "origin", 51),
    (67, "joint 'elbow'", "dynamics", 66),
    (77, "<collision> of link 'forearm'", "origin", 76),
];

/// Largest difference of H, both C and g between two models at a few states.
fn largest_difference(a: &Model, b: &Model) -> f64 {
    let (mut wa, mut wb) = (Workspace::new(a), Workspace::new(b));
    let mut worst: f64 = 0.0;
    for (q, qd) in [([0.3, -0.7], [1.2, 0.4]), ([2.0, 1.1], [-0.5, 3.0]), ([-1.4, 0.2], [0.0, -2.2])] {
        for f in Formulation::ALL {
            let (ta, tb) = (dynamics_terms(a, &mut wa, &q, &qd, f), dynamics_terms(b, &mut wb, &q, &qd, f));
            worst = worst
                .max((&ta.mass_matrix - &tb.mass_matrix).amax())
                .max((&ta.coriolis_matrix - &tb.coriolis_matrix).amax())
                .max((&ta.gravity_torques - &tb.gravity_torques).amax());
        }
    }
    worst
}

#[test]
fn repeated_elements_are_read_first_wins_as_urdfdom_with_a_warning_naming_each() {
    let model = Model::from_urdf_file(model_path("paper_arm_repeated_elements.urdf")).unwrap();
    let paper = Model::from_urdf_file(model_path("paper_arm.urdf")).unwrap();
    // read first-wins, the file is the paper's arm: chain, limits and every dynamics term
    assert_eq!(model.joint_names(), paper.joint_names());
    assert_eq!(model.joints()[0].axis, Vector3::y());
    assert_eq!(model.joints()[0].limits, paper.joints()[0].limits, "the first <limit> (effort 200 N·m) is read");
    let d = largest_difference(&model, &paper);
    assert!(d < 1e-12, "H, C or g differ from paper_arm.urdf by {d:e}");
    // one warning per ignored element, naming the file, the element, its link or joint and both lines
    let w = model.warnings();
    assert_eq!(w.len(), REPEATED.len(), "{w:#?}");
    for (line, owner, tag, first) in REPEATED {
        let needle = format!("line {line}: {owner} has a second <{tag}> (the first is at line {first}); the first is used");
        assert!(w.iter().any(|x| x.contains(&needle) && x.contains("paper_arm_repeated_elements.urdf")), "no warning {needle:?} in {w:#?}");
    }
}

#[test]
fn repeated_elements_read_second_would_change_the_dynamics() {
    // each first element deleted from the text: the second is then the only one, and read
    let text = std::fs::read_to_string(model_path("paper_arm_repeated_elements.urdf")).unwrap();
    let first_wins = Model::from_urdf_str(&text).unwrap();
    let inertial = text.find("<inertial>").unwrap()..text.find("</inertial>").unwrap() + "</inertial>".len();
    let variants = [
        ("the fixed joint's <origin>", text.replacen(r#"<origin xyz="0 0 -0.45" rpy="0 0 0"/>"#, "", 1)),
        ("the shoulder's <axis>", text.replacen(r#"<axis xyz="0 1 0"/>"#, "", 1)),
        ("the upper arm's <mass>", text.replacen(r#"<mass value="23.902"/>"#, "", 1)),
        ("the upper arm's <inertia>", text.replacen(r#"<inertia ixx="1.266" ixy="0" ixz="0" iyy="1.266" iyz="0" izz="0.05"/>"#, "", 1)),
        ("the upper arm's first <inertial>", format!("{}{}", &text[..inertial.start], &text[inertial.end..])),
    ];
    for (what, edited) in variants {
        assert_ne!(edited, text, "{what}: not found in the fixture");
        let second_wins = Model::from_urdf_str(&edited).unwrap_or_else(|e| panic!("{what}: {e}"));
        let d = largest_difference(&first_wins, &second_wins);
        assert!(d > 1e-2, "reading the second instead of {what} changes H, C and g by only {d:e}");
    }
}

#[test]
fn repeated_elements_urdfdom_would_refuse_are_still_refused() {
    // the first <parent> has no link: urdfdom reads that one and refuses the joint
    let text = std::fs::read_to_string(model_path("paper_arm_repeated_elements.urdf")).unwrap();
    let edited = text.replacen(r#"<parent link="base_link"/>"#, "<parent/>", 1);
    let err = Model::from_urdf_str_with(&edited, "edited.urdf", &UrdfOptions::default()).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("edited.urdf") && msg.contains("joint 'shoulder'") && msg.contains("<parent link="), "{msg}");
    // a malformed number in an ignored element is never read, in the element read it is refused
    let ignored = text.replacen(r#"<mass value="1.0"/>"#, r#"<mass value="heavy"/>"#, 1);
    assert!(Model::from_urdf_str(&ignored).is_ok());
    let read = text.replacen(r#"<mass value="23.902"/>"#, r#"<mass value="heavy"/>"#, 1);
    let msg = Model::from_urdf_str(&read).unwrap_err().to_string();
    assert!(msg.contains("line 29") && msg.contains("<mass> of link 'upper_arm'") && msg.contains("expected a number"), "{msg}");
}

#[test]
fn a_locked_joint_gives_the_full_models_dynamics_at_its_zero() {
    // arm7 to the left finger has the finger on its chain (8 joints); locking it gives the
    // model to the hand, whose fingers the loader locks
    let to_finger = arm7_with_tip("panda_leftfinger");
    assert_eq!(to_finger.dof(), 8);
    let locked = to_finger.with_joints_locked(&["panda_finger_joint1"], "a test").unwrap();
    let to_hand = arm7_with_tip("panda_hand");
    assert_eq!(locked.joint_names(), to_hand.joint_names());
    assert!(locked.warnings().last().unwrap().contains("panda_finger_joint1"));
    let (mut ws_l, mut ws_h) = (Workspace::new(&locked), Workspace::new(&to_hand));
    // a joint in the middle: the full model's H and g with a zero inserted for it
    let middle = to_hand.with_joints_locked(&["panda_joint4"], "a test").unwrap();
    let mut ws_m = Workspace::new(&middle);
    for k in 0..20 {
        let q: Vec<f64> = (0..7).map(|i| (0.37 * (k * 7 + i) as f64).sin()).collect();
        let (h_l, h_h) = (mass_matrix(&locked, &mut ws_l, &q), mass_matrix(&to_hand, &mut ws_h, &q));
        assert!((h_l - &h_h).abs().max() < 1e-12, "mass matrix at {q:?}");
        let (g_l, g_h) = (gravity_torques(&locked, &mut ws_l, &q), gravity_torques(&to_hand, &mut ws_h, &q));
        assert!((g_l - &g_h).abs().max() < 1e-12, "gravity at {q:?}");
        let mut q0 = q.clone();
        q0[3] = 0.0;
        let (h_full, g_full) = (mass_matrix(&to_hand, &mut ws_h, &q0), gravity_torques(&to_hand, &mut ws_h, &q0));
        let q_m: Vec<f64> = q.iter().enumerate().filter(|(i, _)| *i != 3).map(|(_, v)| *v).collect();
        let (h_m, g_m) = (mass_matrix(&middle, &mut ws_m, &q_m), gravity_torques(&middle, &mut ws_m, &q_m));
        let keep = [0, 1, 2, 4, 5, 6];
        for (a, &i) in keep.iter().enumerate() {
            assert!((g_m[a] - g_full[i]).abs() < 1e-12, "gravity of joint {i}");
            for (b, &j) in keep.iter().enumerate() {
                assert!((h_m[(a, b)] - h_full[(i, j)]).abs() < 1e-12, "H[{i}, {j}]");
            }
        }
    }
    assert!(to_hand.with_joints_locked(&["no_such_joint"], "x").is_err());
}
