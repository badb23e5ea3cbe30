//! The exported URDF and MJCF hold the corrected model: the URDF loads back into exactly the
//! corrected bodies (fixed links merged as before), every other byte is kept, and what the
//! formats cannot hold is in the sidecar.

use std::collections::BTreeMap;

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::{gravity_torques, mass_matrix, Model, UrdfOptions, Workspace, ARM7_URDF, PAPER_ARM_URDF};
use simgap_diag::export::{export_mjcf, export_urdf, sidecar_path, ExportError, MjcfOptions};
use simgap_diag::{EffectReport, Param};
use simgap_sim::effects::apply_inertial_effects;
use simgap_sim::{Effect, LinkDelta};

fn effect(name: &str, joints: &[&str], params: &[(&str, Param)]) -> EffectReport {
    EffectReport {
        effect: name.parse().unwrap_or_else(|e| panic!("{e}")),
        joints: joints.iter().map(|s| s.to_string()).collect(),
        parameters: params.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
        uncertainty: BTreeMap::new(),
        units: params.iter().map(|(k, _)| (k.to_string(), unit(k).to_string())).collect(),
        description: String::new(),
    }
}

/// The units a report states (revolute joints).
fn unit(param: &str) -> &'static str {
    match param {
        "b" => "N·m·s/rad",
        "fc" | "fs" | "limit" | "offset" | "amplitude" => "N·m",
        "vs" | "w" => "rad/s",
        "ia" | "delta_inertia" => "kg·m²",
        "mass" | "delta_mass" => "kg",
        "com" | "delta_com" => "m",
        "delay" => "s",
        _ => "-",
    }
}

fn arm7() -> Model {
    Model::from_urdf_str_with(ARM7_URDF, "arm7.urdf", &UrdfOptions { tip: Some("panda_hand".into()) }).unwrap()
}

/// The effects of a diagnosis of the 7-DOF arm: an inertial correction of link 3 and of the
/// last body (panda_link7 with the flange, the hand and the locked fingers merged), a payload,
/// friction, rotor inertia, a gain and a delay.
fn arm7_effects() -> Vec<EffectReport> {
    vec![
        effect(
            "inertial_error",
            &["panda_joint3", "panda_joint7"],
            &[
                ("delta_mass", Param::PerJoint(vec![0.4, -0.3])),
                ("delta_com", Param::PerLink(vec![vec![0.01, -0.02, 0.005], vec![0.0, 0.004, -0.01]])),
                ("delta_inertia", Param::PerLink(vec![vec![0.002, 0.0005, 0.0, 0.001, -0.0003, 0.0015], vec![-0.001, 0.0, 0.0002, -0.0008, 0.0, 0.0005]])),
            ],
        ),
        effect("payload", &[], &[("mass", Param::Number(0.8)), ("com", Param::Vector(vec![0.02, -0.01, 0.15]))]),
        effect("viscous_friction", &["panda_joint1", "panda_joint4"], &[("b", Param::PerJoint(vec![0.5, 0.25]))]),
        effect("coulomb_friction", &["panda_joint4"], &[("fc", Param::PerJoint(vec![1.2])), ("w", Param::PerJoint(vec![0.02]))]),
        effect("armature", &["panda_joint2"], &[("ia", Param::PerJoint(vec![0.15]))]),
        effect("torque_gain", &["panda_joint5"], &[("k", Param::PerJoint(vec![0.9]))]),
        effect("time_delay", &[], &[("delay", Param::Number(0.005))]),
    ]
}

/// The same corrections as simulator effects, applied by the simulator's own function.
fn arm7_corrected(model: &Model) -> Model {
    let effects = [
        Effect::InertialError {
            deltas: vec![
                LinkDelta { joint: 2, mass: 0.4, com: [0.01, -0.02, 0.005], inertia: [0.002, 0.0005, 0.0, 0.001, -0.0003, 0.0015] },
                LinkDelta { joint: 6, mass: -0.3, com: [0.0, 0.004, -0.01], inertia: [-0.001, 0.0, 0.0002, -0.0008, 0.0, 0.0005] },
            ],
        },
        Effect::Payload { mass: 0.8, com: [0.02, -0.01, 0.15] },
    ];
    apply_inertial_effects(model, &effects).unwrap()
}

fn rel(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).amax() / b.amax().max(1e-12)
}

#[test]
fn exported_urdf_has_the_corrected_mass_matrix_and_gravity_with_fixed_links_merged() {
    let model = arm7();
    let out = export_urdf(ARM7_URDF, "arm7.urdf", &model, &arm7_effects()).unwrap();
    let exported = Model::from_urdf_str_with(&out.text, "exported", &UrdfOptions { tip: Some("panda_hand".into()) }).unwrap();
    let corrected = arm7_corrected(&model);
    let nominal_h = {
        let mut ws = Workspace::new(&model);
        mass_matrix(&model, &mut ws, &[0.1; 7])
    };
    let (mut ws_e, mut ws_c) = (Workspace::new(&exported), Workspace::new(&corrected));
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut worst = 0.0f64;
    for _ in 0..100 {
        let q: Vec<f64> = (0..7).map(|_| rng.random_range(-3.0..3.0)).collect();
        let (he, hc) = (mass_matrix(&exported, &mut ws_e, &q), mass_matrix(&corrected, &mut ws_c, &q));
        let (ge, gc) = (gravity_torques(&exported, &mut ws_e, &q), gravity_torques(&corrected, &mut ws_c, &q));
        worst = worst.max(rel(&he, &hc)).max((ge - &gc).amax() / gc.amax().max(1e-12));
    }
    assert!(worst < 1e-12, "exported vs corrected H, g: relative {worst:e}");
    // the corrections changed something a wrong export would miss
    let mut ws = Workspace::new(&corrected);
    assert!(rel(&mass_matrix(&corrected, &mut ws, &[0.1; 7]), &nominal_h) > 1e-3);
    // the merged links keep their own inertials: the hand is still 0.73 kg, the corrections
    // went into panda_link7
    let doc = roxmltree::Document::parse(&out.text).unwrap();
    let mass_of = |link: &str| -> f64 {
        let l = doc.descendants().find(|n| n.has_tag_name("link") && n.attribute("name") == Some(link)).unwrap();
        l.descendants().find(|n| n.has_tag_name("mass")).and_then(|m| m.attribute("value")).unwrap().parse().unwrap()
    };
    assert_eq!(mass_of("panda_hand"), 0.73);
    assert!((mass_of("panda_link7") - (0.735 - 0.3 + 0.8)).abs() < 1e-12);
    assert!((mass_of("panda_link3") - (3.228 + 0.4)).abs() < 1e-12);
}

#[test]
fn exported_urdf_keeps_every_other_byte_and_writes_friction_into_dynamics() {
    let model = arm7();
    let out = export_urdf(ARM7_URDF, "arm7.urdf", &model, &arm7_effects()).unwrap();
    // the leading comment, untouched links and joints are byte for byte the input's
    let untouched = [
        "<!-- A 7-DOF arm shaped like the Franka Emika Panda",
        "<link name=\"panda_link2\">",
        "<origin xyz=\"-0.0031 -0.0287 0.0035\" rpy=\"0 0 0\"/>",
        "<link name=\"panda_link8\"/>",
    ];
    for s in untouched {
        assert!(out.text.contains(s), "lost: {s}");
    }
    let dropped_lines: Vec<&str> = ARM7_URDF.lines().filter(|l| !out.text.contains(l.trim())).collect();
    // only the rewritten inertials of links 3 and 7 differ
    assert!(dropped_lines.iter().all(|l| l.contains("<origin") || l.contains("<mass") || l.contains("<inertia ")), "{dropped_lines:?}");
    assert!(dropped_lines.len() <= 6, "{dropped_lines:?}");
    // the rotated inertial frame of link 3 keeps its rpy
    assert!(out.text.contains("rpy=\"0.1 0.2 0.3\""));
    // friction in <dynamics>: joint 1 viscous only, joint 4 both
    let doc = roxmltree::Document::parse(&out.text).unwrap();
    let dynamics = |joint: &str| -> Option<(f64, f64)> {
        let j = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(joint))?;
        let d = j.children().find(|n| n.has_tag_name("dynamics"))?;
        Some((d.attribute("damping")?.parse().ok()?, d.attribute("friction")?.parse().ok()?))
    };
    assert_eq!(dynamics("panda_joint1"), Some((0.5, 0.0)));
    assert_eq!(dynamics("panda_joint4"), Some((0.25, 1.2)));
    assert_eq!(dynamics("panda_joint2"), None);
    // the sidecar: armature, gain and delay are not in the URDF; the dry friction keeps its w
    let names: Vec<&str> = out.sidecar.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(names, ["armature", "torque_gain", "time_delay"]);
    assert!(out.sidecar.selected_effects.iter().all(|e| !e.apply.is_empty() && e.units.len() == e.parameters.len()));
    let coulomb = out.sidecar.held.iter().find(|h| h.effect.as_str() == "coulomb_friction").unwrap();
    assert_eq!(coulomb.parameters.get("w"), Some(&Param::PerJoint(vec![0.02])));
    let json: serde_json::Value = serde_json::from_str(&out.sidecar.to_json()).unwrap();
    assert_eq!(json["selected_effects"][2]["parameters"]["delay"], 0.005);
    assert_eq!(json["selected_effects"][2]["units"]["delay"], "s");
}

#[test]
fn payload_on_a_massless_last_link_gets_a_new_inertial() {
    // the pendulum's bob made massless: the payload becomes its only mass
    let urdf = "<?xml version=\"1.0\"?>\n<robot name=\"p\">\n  <link name=\"base\"/>\n  <joint name=\"j\" type=\"continuous\">\n    <parent link=\"base\"/>\n    <child link=\"a\"/>\n    <axis xyz=\"0 1 0\"/>\n  </joint>\n  <link name=\"a\">\n    <inertial>\n      <mass value=\"1\"/>\n      <origin xyz=\"0 0 -0.2\"/>\n      <inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>\n    </inertial>\n  </link>\n  <joint name=\"k\" type=\"revolute\">\n    <parent link=\"a\"/>\n    <child link=\"b\"/>\n    <origin xyz=\"0 0 -0.4\"/>\n    <axis xyz=\"0 1 0\"/>\n    <limit lower=\"-1\" upper=\"1\" effort=\"5\" velocity=\"3\"/>\n  </joint>\n  <link name=\"b\"/>\n</robot>\n";
    let model = Model::from_urdf_str(urdf).unwrap();
    let effects = [effect("payload", &[], &[("mass", Param::Number(0.5)), ("com", Param::Vector(vec![0.0, 0.0, -0.3]))])];
    let out = export_urdf(urdf, "p.urdf", &model, &effects).unwrap();
    assert!(out.text.contains("<link name=\"b\">\n    <inertial>"), "{}", out.text);
    let exported = Model::from_urdf_str(&out.text).unwrap();
    assert!((exported.joints()[1].inertia.mass - 0.5).abs() < 1e-15);
    assert!((exported.joints()[1].inertia.com().z + 0.3).abs() < 1e-15);
    // the MJCF of the same: a continuous joint and a real range
    let mjcf = export_mjcf(&model, &effects, &MjcfOptions::new(0.002)).unwrap();
    assert!(mjcf.text.contains("name=\"j\" type=\"hinge\" pos=\"0 0 0\" axis=\"0 1 0\" limited=\"false\""), "{}", mjcf.text);
    assert!(mjcf.text.contains("name=\"k\" type=\"hinge\" pos=\"0 0 0\" axis=\"0 1 0\" limited=\"true\" range=\"-1 1\""), "{}", mjcf.text);
    assert!(mjcf.text.contains("<inertial pos=\"0 0 -0.3\" mass=\"0.5\""), "{}", mjcf.text);
}

#[test]
fn mjcf_holds_joint_and_actuator_effects_and_leaves_the_rest_to_the_sidecar() {
    let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
    let effects = [
        effect("viscous_friction", &["shoulder", "elbow"], &[("b", Param::PerJoint(vec![2.288, 0.175]))]),
        effect("coulomb_friction", &["shoulder", "elbow"], &[("fc", Param::PerJoint(vec![7.17, 1.734]))]),
        effect("armature", &["elbow"], &[("ia", Param::PerJoint(vec![0.01]))]),
        effect("torque_gain", &["shoulder"], &[("k", Param::PerJoint(vec![0.95]))]),
        effect("torque_saturation", &["elbow"], &[("limit", Param::PerJoint(vec![15.0]))]),
        effect("stribeck_friction", &["elbow"], &[("fc", Param::PerJoint(vec![0.1])), ("fs", Param::PerJoint(vec![0.2])), ("vs", Param::PerJoint(vec![0.05]))]),
        effect("time_delay", &[], &[("delay", Param::Number(0.0025))]),
        effect("cogging", &["shoulder"], &[("amplitude", Param::PerJoint(vec![0.3])), ("periods_per_rev", Param::PerJoint(vec![12.0]))]),
    ];
    let out = export_mjcf(&model, &effects, &MjcfOptions::new(0.0025)).unwrap();
    let t = &out.text;
    assert!(t.contains("<option timestep=\"0.0025\" gravity=\"0 0 -9.81\" integrator=\"RK4\"/>"), "{t}");
    // ±π is the angle's convention: no range
    assert!(t.contains("name=\"shoulder\" type=\"hinge\" pos=\"0 0 0\" axis=\"0 1 0\" limited=\"false\" damping=\"2.288\" frictionloss=\"7.17\""), "{t}");
    assert!(t.contains("name=\"elbow\" type=\"hinge\" pos=\"0 0 0\" axis=\"0 1 0\" limited=\"false\" armature=\"0.01\" damping=\"0.175\" frictionloss=\"1.734\""), "{t}");
    assert!(t.contains("<body name=\"forearm\" pos=\"0 0 -0.45\" quat=\"1 0 0 0\">"), "{t}");
    assert!(t.contains("<motor name=\"shoulder_motor\" joint=\"shoulder\" gear=\"0.95\" ctrllimited=\"false\" forcelimited=\"false\"/>"), "{t}");
    assert!(t.contains("<motor name=\"elbow_motor\" joint=\"elbow\" gear=\"1\" ctrllimited=\"false\" forcelimited=\"true\" forcerange=\"-15 15\"/>"), "{t}");
    let deferred: Vec<&str> = out.sidecar.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(deferred, ["stribeck_friction", "time_delay", "cogging"]);
    assert_eq!(out.sidecar.held.len(), 5);
    // a document MuJoCo reads: well-formed XML
    roxmltree::Document::parse(t).unwrap();
}

#[test]
fn a_joint_spring_is_mjcf_stiffness_and_springref_and_a_urdf_sidecar_entry() {
    let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
    let effects = [effect("joint_spring", &["elbow"], &[("k", Param::PerJoint(vec![4.0])), ("q0", Param::PerJoint(vec![0.3]))])];
    let out = export_mjcf(&model, &effects, &MjcfOptions::new(0.0025)).unwrap();
    assert!(out.text.contains("stiffness=\"4\" springref=\"0.3\""), "{}", out.text);
    assert!(out.sidecar.selected_effects.is_empty() && out.sidecar.held.len() == 1, "{:?}", out.sidecar);
    roxmltree::Document::parse(&out.text).unwrap();
    let urdf = export_urdf(PAPER_ARM_URDF, "paper_arm.urdf", &model, &effects).unwrap();
    let deferred: Vec<&str> = urdf.sidecar.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(deferred, ["joint_spring"]);
    assert_eq!(urdf.sidecar.selected_effects[0].parameters["q0"], Param::PerJoint(vec![0.3]));
}

#[test]
fn an_encoder_offset_is_the_mjcf_joint_ref_with_its_range_shifted_and_a_urdf_sidecar_entry() {
    // the joint turns by qpos − ref = q_measured + offset: ref = −offset, and the limits (at the
    // true angle) are offset lower in qpos
    let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
    let effects = [effect("encoder_offset", &["elbow"], &[("offset", Param::PerJoint(vec![0.05]))])];
    let out = export_mjcf(&model, &effects, &MjcfOptions::new(0.0025)).unwrap();
    let doc = roxmltree::Document::parse(&out.text).unwrap();
    let elbow = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some("elbow")).unwrap();
    assert_eq!(elbow.attribute("ref"), Some("-0.05"), "{}", out.text);
    let limits = model.joints()[1].limits;
    if let Some(range) = elbow.attribute("range") {
        let r: Vec<f64> = range.split_whitespace().map(|x| x.parse().unwrap()).collect();
        assert!((r[0] - (limits.lower - 0.05)).abs() < 1e-9 && (r[1] - (limits.upper - 0.05)).abs() < 1e-9, "{range}");
    }
    let shoulder = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some("shoulder")).unwrap();
    assert_eq!(shoulder.attribute("ref"), None);
    assert!(out.sidecar.selected_effects.is_empty() && out.sidecar.held.len() == 1, "{:?}", out.sidecar);
    let urdf = export_urdf(PAPER_ARM_URDF, "paper_arm.urdf", &model, &effects).unwrap();
    let deferred: Vec<&str> = urdf.sidecar.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(deferred, ["encoder_offset"]);
}

#[test]
fn backlash_is_a_second_mjcf_joint_of_the_links_body_with_range_plus_minus_half_the_play() {
    // the drive's joint keeps the rotor's armature (and the motor); the play's joint, of the same
    // body and axis, lets the link turn ±w/2 from it
    let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
    let effects = [effect("armature", &["elbow"], &[("ia", Param::PerJoint(vec![0.4]))]), effect("backlash", &["elbow"], &[("width", Param::PerJoint(vec![0.03]))])];
    let out = export_mjcf(&model, &effects, &MjcfOptions::new(0.0025)).unwrap();
    let doc = roxmltree::Document::parse(&out.text).unwrap();
    let joint = |name: &str| doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(name));
    let (drive, play) = (joint("elbow").unwrap(), joint("elbow_backlash").unwrap());
    assert_eq!(drive.parent(), play.parent(), "{}", out.text);
    assert_eq!(drive.attribute("armature"), Some("0.4"));
    assert_eq!(play.attribute("axis"), drive.attribute("axis"));
    assert_eq!(play.attribute("range"), Some("-0.015 0.015"), "{}", out.text);
    assert!(joint("shoulder_backlash").is_none());
    let motor = doc.descendants().find(|n| n.has_tag_name("motor") && n.attribute("name") == Some("elbow_motor")).unwrap();
    assert_eq!(motor.attribute("joint"), Some("elbow"));
    assert_eq!(out.sidecar.held.len(), 2, "{:?}", out.sidecar);
    let urdf = export_urdf(PAPER_ARM_URDF, "paper_arm.urdf", &model, &effects).unwrap();
    let deferred: Vec<&str> = urdf.sidecar.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert!(deferred.contains(&"backlash"), "{deferred:?}");
}

#[test]
fn mjcf_body_frames_follow_the_urdf_joint_placements() {
    // panda_joint2 is rotated by rpy (−π/2, 0, 0): quat (cos(−π/4), sin(−π/4), 0, 0)
    let model = arm7();
    let out = export_mjcf(&model, &[], &MjcfOptions::new(0.001)).unwrap();
    let doc = roxmltree::Document::parse(&out.text).unwrap();
    let body = doc.descendants().find(|n| n.has_tag_name("body") && n.attribute("name") == Some("panda_link2")).unwrap();
    let quat: Vec<f64> = body.attribute("quat").unwrap().split(' ').map(|x| x.parse().unwrap()).collect();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let sign = quat[0].signum();
    for (a, b) in quat.iter().zip([h, -h, 0.0, 0.0]) {
        assert!((sign * a - b).abs() < 1e-12, "{quat:?}");
    }
    // the continuous joint 7 has no range, the limited joints theirs
    assert!(out.text.contains("name=\"panda_joint7\" type=\"hinge\" pos=\"0 0 0\" axis=\"0 0 1\" limited=\"false\""));
    assert!(out.text.contains("name=\"panda_joint4\" type=\"hinge\" pos=\"0 0 0\" axis=\"0 0 1\" limited=\"true\" range=\"-3.0718 -0.0698\""));
    // the last body holds the merged hand: its mass is link 7's, the hand's and the fingers'
    let last = doc.descendants().find(|n| n.has_tag_name("body") && n.attribute("name") == Some("panda_link7")).unwrap();
    let inertial = last.children().find(|n| n.has_tag_name("inertial")).unwrap();
    let mass: f64 = inertial.attribute("mass").unwrap().parse().unwrap();
    assert!((mass - (0.735 + 0.73 + 0.03)).abs() < 1e-12, "{mass}");
}

#[test]
fn bad_inputs_are_clear_errors() {
    let model = arm7();
    // an unknown joint
    let e = [effect("viscous_friction", &["elbow"], &[("b", Param::PerJoint(vec![0.1]))])];
    let err = export_urdf(ARM7_URDF, "arm7.urdf", &model, &e).unwrap_err().to_string();
    assert!(err.contains("viscous_friction") && err.contains("'elbow'") && err.contains("panda_joint1"), "{err}");
    // a parameter list of the wrong length
    let e = [effect("viscous_friction", &["panda_joint1", "panda_joint2"], &[("b", Param::PerJoint(vec![0.1]))])];
    let err = export_mjcf(&model, &e, &MjcfOptions::new(0.001)).unwrap_err().to_string();
    assert!(err.contains("1 values for 2 joints"), "{err}");
    // a correction that takes more mass from link 7 than it has (the hand keeps its own)
    let e = [effect(
        "inertial_error",
        &["panda_joint7"],
        &[("delta_mass", Param::PerJoint(vec![-1.0])), ("delta_com", Param::PerLink(vec![vec![0.0; 3]])), ("delta_inertia", Param::PerLink(vec![vec![0.0; 6]]))],
    )];
    let err = export_urdf(ARM7_URDF, "arm7.urdf", &model, &e).unwrap_err();
    assert!(matches!(err, ExportError::Effect { .. }), "{err}");
    let err = err.to_string();
    assert!(err.contains("panda_link7") && err.contains("mass would be"), "{err}");
    // a URDF that is not the model's
    let err = export_urdf(PAPER_ARM_URDF, "paper_arm.urdf", &model, &[]).unwrap_err().to_string();
    assert!(err.starts_with("paper_arm.urdf: robot:") && err.contains("not the URDF the model was loaded from"), "{err}");
    // not XML at all
    let err = export_urdf("<robot", "broken.urdf", &model, &[]).unwrap_err().to_string();
    assert!(err.starts_with("broken.urdf: document: not well-formed XML"), "{err}");
    // a bad time step
    let err = export_mjcf(&model, &[], &MjcfOptions::new(0.0)).unwrap_err().to_string();
    assert!(err.contains("timestep = 0 s"), "{err}");
    assert_eq!(sidecar_path(std::path::Path::new("out/corrected.xml")), std::path::Path::new("out/corrected.xml.effects.json"));
}

#[test]
fn urdf_dynamics_are_replaced_by_the_diagnosed_friction_and_kept_elsewhere_with_a_note() {
    let urdf = PAPER_ARM_URDF
        .replace(
            "<limit lower=\"-3.14159265358979\" upper=\"3.14159265358979\" effort=\"200\" velocity=\"10\"/>",
            "<limit lower=\"-3.14159265358979\" upper=\"3.14159265358979\" effort=\"200\" velocity=\"10\"/>\n    <dynamics damping=\"0.3\" friction=\"0.1\"/>",
        )
        .replace(
            "<limit lower=\"-3.14159265358979\" upper=\"3.14159265358979\" effort=\"15\" velocity=\"10\"/>",
            "<limit lower=\"-3.14159265358979\" upper=\"3.14159265358979\" effort=\"15\" velocity=\"10\"/>\n    <dynamics damping=\"0.05\"/>",
        );
    let model = Model::from_urdf_str(&urdf).unwrap();
    let effects = [effect("viscous_friction", &["shoulder"], &[("b", Param::PerJoint(vec![2.5]))])];
    let out = export_urdf(&urdf, "arm.urdf", &model, &effects).unwrap();
    assert!(out.text.contains("<dynamics damping=\"2.5\" friction=\"0\"/>"), "{}", out.text);
    assert!(out.text.contains("<dynamics damping=\"0.05\"/>"), "{}", out.text);
    assert_eq!(out.text.matches("<dynamics").count(), 2);
    assert!(out.sidecar.notes.iter().any(|n| n.contains("'shoulder'") && n.contains("damping=\"0.3\" friction=\"0.1\"") && n.contains("replaced")), "{:?}", out.sidecar.notes);
    assert!(out.sidecar.notes.iter().any(|n| n.contains("'elbow' keeps its URDF <dynamics>")), "{:?}", out.sidecar.notes);
    // no inertial changed: the rest of the file is the input
    let expected = urdf.replace("<dynamics damping=\"0.3\" friction=\"0.1\"/>", "<dynamics damping=\"2.5\" friction=\"0\"/>");
    assert_eq!(out.text, expected);
}

#[test]
fn passive_joints_and_the_sample_period_come_from_the_logs() {
    use simgap_diag::export::{passive_joints, sample_period_of};
    let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
    // logs name the joints in another order than the model; the elbow is never commanded
    let mut a = simgap_sim::Run::new(vec!["elbow".into(), "shoulder".into()]);
    a.t = vec![10.0, 10.002, 10.004, 10.0061];
    a.tau = vec![0.0, 1.0, 0.0, -2.0, 0.0, 0.5, 0.0, 0.1];
    let mut b = a.clone();
    b.tau = vec![0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(passive_joints(&model, &[a.clone(), b.clone()]), ["elbow"]);
    // a run that commands the elbow once makes it driven
    b.tau[6] = 1e-3;
    assert!(passive_joints(&model, &[a.clone(), b]).is_empty());
    assert!(passive_joints(&model, &[]).is_empty());
    // the median stamp spacing, unless an experiment states the period
    assert!((sample_period_of(std::slice::from_ref(&a)).unwrap() - 0.002).abs() < 1e-12);
    let map: BTreeMap<String, String> = [("controller", "replay"), ("joints", "shoulder,elbow"), ("kp", "0,0"), ("kv", "0,0"), ("sample_period", "0.0025")]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    a.experiment = Some(simgap_sim::experiment_from_map(&map).unwrap());
    assert_eq!(sample_period_of(&[a]), Some(0.0025));
    assert_eq!(sample_period_of(&[simgap_sim::Run::new(vec!["elbow".into()])]), None);
}

#[test]
fn servo_joints_are_mujoco_position_actuators_with_the_motor_law_in_kp_kv_and_forcerange() {
    use simgap_diag::export::ServoActuators;
    use simgap_diag::{EffectiveConstants, ServoReport};
    use simgap_sim::{ControllerKind, Experiment, Run};
    let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
    // a servo log whose experiment lists the joints in another order than the model
    let extra = BTreeMap::from([("duty_gain".to_string(), "3,2".to_string()), ("max_duty".to_string(), "0.5,1".to_string()), ("supply_voltage".to_string(), "12".to_string())]);
    let mut run = Run::new(vec!["elbow".into(), "shoulder".into()]);
    run.source = "servo.csv".into();
    run.experiment = Some(Experiment { controller: ControllerKind::Servo, joints: vec!["elbow".into(), "shoulder".into()], kp: vec![], kv: vec![], sample_period: 0.002, extra });
    // the report's servo key, also in another order: the effective constants are used
    let report = ServoReport {
        joints: vec!["elbow".into(), "shoulder".into()],
        kt: vec![1.0, 1.0],
        r: vec![1.0, 1.0],
        source: "fitted".into(),
        effective: EffectiveConstants { kt: vec![0.25, 0.5], r: vec![4.0, 2.0] },
    };
    let servo = ServoActuators::of(&model, &report, &[run]).unwrap().expect("a servo log");
    assert_eq!(servo.joints, ["shoulder", "elbow"]);
    // shoulder: kt/R = 0.25, kp = 0.25·12·2, kv = 0.5²/2, force = 0.25·12·1;
    // elbow: kt/R = 0.0625, kp = 0.0625·12·3, kv = 0.25²/4, force = 0.0625·12·0.5
    assert_eq!((servo.kp(0), servo.kv(0), servo.force_limit(0)), (6.0, 0.125, 3.0));
    assert_eq!((servo.kp(1), servo.kv(1), servo.force_limit(1)), (2.25, 0.015625, 0.375));
    let effects =
        [effect("back_emf", &["shoulder", "elbow"], &[("kb", Param::PerJoint(vec![0.01, 0.02]))]), effect("viscous_friction", &["elbow"], &[("b", Param::PerJoint(vec![0.3]))])];
    let out = export_mjcf(&model, &effects, &MjcfOptions { servo: Some(servo), ..MjcfOptions::new(0.002) }).unwrap();
    let t = &out.text;
    assert!(t.contains("<position name=\"shoulder_servo\" joint=\"shoulder\" kp=\"6\" kv=\"0.125\" ctrllimited=\"false\" forcelimited=\"true\" forcerange=\"-3 3\"/>"), "{t}");
    assert!(
        t.contains("<position name=\"elbow_servo\" joint=\"elbow\" kp=\"2.25\" kv=\"0.015625\" ctrllimited=\"false\" forcelimited=\"true\" forcerange=\"-0.375 0.375\"/>"),
        "{t}"
    );
    assert!(!t.contains("<motor"), "a servo joint has no torque motor: {t}");
    assert!(t.contains("damping=\"0.3\""), "joint effects stay on the joints: {t}");
    // the back-EMF is in kv (folded into the effective constants), the friction on the joint
    assert!(out.sidecar.selected_effects.is_empty(), "{:?}", out.sidecar.selected_effects);
    assert!(out.sidecar.held.iter().any(|h| h.effect.as_str() == "back_emf" && h.written_as.contains("kv")), "{:?}", out.sidecar.held);
    let notes = out.sidecar.notes.join("\n");
    assert!(notes.contains("position actuators") && notes.contains("V = 12 V (supply_voltage of servo.csv)"), "{notes}");
    assert!(notes.contains("duty and torque are proportional at zero speed") && notes.contains("(kt²/R)·|q̇|"), "the approximation is stated: {notes}");
    assert!(notes.contains("torque enable"), "{notes}");
    roxmltree::Document::parse(t).unwrap();
}
