//! Bad URDFs in `models/bad/`: each must fail with the right [`Error`] variant, and its message
//! must name the file, the offending element (link or joint) and what was expected.

mod common;

use simgap_core::{Error, Model, UrdfOptions};

/// Loads `models/bad/<name>`, which must fail; returns the error and its message after checking
/// that the message names the file and says what was expected.
#[track_caller]
fn load_bad(name: &str) -> (Error, String) {
    let path = common::model_path(&format!("bad/{name}"));
    let err = match Model::from_urdf_file(&path) {
        Ok(m) => panic!("bad/{name} loaded as a {}-DOF model", m.dof()),
        Err(e) => e,
    };
    let message = err.to_string();
    assert!(message.contains(&format!("bad/{name}")), "message does not name the file: {message}");
    assert!(message.contains("expected"), "message does not say what was expected: {message}");
    (err, message)
}

/// Asserts that `message` mentions every one of `parts`.
#[track_caller]
fn assert_mentions(message: &str, parts: &[&str]) {
    for p in parts {
        assert!(message.contains(p), "message does not mention {p:?}: {message}");
    }
}

#[test]
fn malformed_xml_is_malformed_urdf_with_position() {
    let (err, msg) = load_bad("malformed_xml.urdf");
    assert!(matches!(err, Error::MalformedUrdf { .. }), "{err:?}");
    // the element left open and where the parser noticed
    assert_mentions(&msg, &["malformed URDF", "'link'", "13:1"]);
}

#[test]
fn joint_naming_missing_child_link_is_missing_link() {
    let (err, msg) = load_bad("missing_child_link.urdf");
    assert!(matches!(&err, Error::MissingLink { joint, role: "child", link, .. } if joint == "elbow" && link == "forearm"), "{err:?}");
    assert_mentions(&msg, &["joint 'elbow'", "child link 'forearm'", "not defined"]);
}

#[test]
fn joint_naming_missing_parent_link_is_missing_link() {
    let (err, msg) = load_bad("missing_parent_link.urdf");
    assert!(matches!(&err, Error::MissingLink { joint, role: "parent", link, .. } if joint == "elbow" && link == "upperarm"), "{err:?}");
    assert_mentions(&msg, &["joint 'elbow'", "parent link 'upperarm'", "not defined"]);
}

#[test]
fn duplicate_link_is_duplicate_link() {
    let (err, msg) = load_bad("duplicate_link.urdf");
    assert!(matches!(&err, Error::DuplicateLink { link, .. } if link == "upper"), "{err:?}");
    assert_mentions(&msg, &["link 'upper'", "more than once", "unique link names"]);
}

#[test]
fn duplicate_joint_is_duplicate_joint() {
    let (err, msg) = load_bad("duplicate_joint.urdf");
    assert!(matches!(&err, Error::DuplicateJoint { joint, .. } if joint == "shoulder"), "{err:?}");
    assert_mentions(&msg, &["joint 'shoulder'", "more than once", "unique joint names"]);
}

#[test]
fn link_with_two_parents_is_loop() {
    let (err, msg) = load_bad("loop_two_parents.urdf");
    assert!(matches!(&err, Error::Loop { link, .. } if link == "forearm"), "{err:?}");
    assert_mentions(&msg, &["link 'forearm'", "'elbow'", "'shortcut'", "expected a tree"]);
}

#[test]
fn closed_cycle_is_loop() {
    let (err, msg) = load_bad("loop_cycle.urdf");
    assert!(matches!(&err, Error::Loop { link, .. } if link == "a" || link == "b"), "{err:?}");
    assert_mentions(&msg, &["closed loop", "expected a tree"]);
    assert!(msg.contains("link 'a'") || msg.contains("link 'b'"), "{msg}");
}

#[test]
fn two_roots_is_roots() {
    let (err, msg) = load_bad("two_roots.urdf");
    assert!(matches!(&err, Error::Roots { found, .. } if found == &["base", "floating_box"]), "{err:?}");
    assert_mentions(&msg, &["\"base\"", "\"floating_box\"", "exactly one root link"]);
}

#[test]
fn only_fixed_joints_is_no_movable_joint() {
    let (err, msg) = load_bad("no_movable_joint.urdf");
    assert!(matches!(&err, Error::NoMovableJoint { root, .. } if root == "base"), "{err:?}");
    assert_mentions(&msg, &["root 'base'", "revolute, continuous or prismatic"]);
}

#[test]
fn floating_joint_is_unsupported_joint() {
    let (err, msg) = load_bad("floating_joint.urdf");
    assert!(matches!(&err, Error::UnsupportedJoint { name, kind, .. } if name == "free" && kind == "floating"), "{err:?}");
    assert_mentions(&msg, &["joint 'free'", "'floating'", "revolute, continuous, prismatic or fixed"]);
}

#[test]
fn planar_joint_is_unsupported_joint() {
    let (err, msg) = load_bad("planar_joint.urdf");
    assert!(matches!(&err, Error::UnsupportedJoint { name, kind, .. } if name == "slide" && kind == "planar"), "{err:?}");
    assert_mentions(&msg, &["joint 'slide'", "'planar'", "revolute, continuous, prismatic or fixed"]);
}

#[test]
fn zero_length_axis_is_zero_axis() {
    let (err, msg) = load_bad("zero_axis.urdf");
    assert!(matches!(&err, Error::ZeroAxis { joint, axis, .. } if joint == "elbow" && axis == &[0.0; 3]), "{err:?}");
    assert_mentions(&msg, &["joint 'elbow'", "zero-length axis", "non-zero direction"]);
}

#[test]
fn negative_mass_is_negative_mass() {
    let (err, msg) = load_bad("negative_mass.urdf");
    assert!(matches!(&err, Error::NegativeMass { link, mass, .. } if link == "forearm" && *mass == -1.5), "{err:?}");
    assert_mentions(&msg, &["link 'forearm'", "-1.5", "mass >= 0"]);
}

#[test]
fn negative_principal_moment_is_non_physical_inertia() {
    let (err, msg) = load_bad("inertia_not_positive_definite.urdf");
    assert!(matches!(&err, Error::NonPhysicalInertia { link, .. } if link == "forearm"), "{err:?}");
    assert_mentions(&msg, &["link 'forearm'", "-1.000000e-2", "positive semi-definite"]);
}

#[test]
fn triangle_inequality_violation_is_non_physical_inertia() {
    let (err, msg) = load_bad("inertia_triangle_inequality.urdf");
    assert!(matches!(&err, Error::NonPhysicalInertia { link, .. } if link == "forearm"), "{err:?}");
    assert_mentions(&msg, &["link 'forearm'", "5.000000e-2", "triangle inequality"]);
}

#[test]
fn nan_mass_is_non_finite() {
    let (err, msg) = load_bad("nan_mass.urdf");
    assert!(matches!(&err, Error::NonFinite { element, field, value, .. } if element == "link 'forearm'" && field == "inertial/mass" && value.is_nan()), "{err:?}");
    assert_mentions(&msg, &["link 'forearm'", "inertial/mass", "NaN", "finite number"]);
}

#[test]
fn infinite_origin_is_non_finite() {
    let (err, msg) = load_bad("infinite_origin.urdf");
    assert!(matches!(&err, Error::NonFinite { element, field, value, .. } if element == "joint 'elbow'" && field == "origin" && value.is_infinite()), "{err:?}");
    assert_mentions(&msg, &["joint 'elbow'", "origin", "inf", "finite number"]);
}

/// The paper arm fixture with `from` replaced by `to` (exactly once).
fn paper_arm_with(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(common::model_path("paper_arm.urdf")).unwrap();
    assert_eq!(text.matches(from).count(), 1, "{from:?} is not in the paper arm fixture exactly once");
    text.replacen(from, to, 1)
}

#[test]
fn overflowing_number_is_refused_naming_the_element_that_holds_it() {
    // the elbow's origin 1e300 m is finite, but its square times a mass overflows H in the
    // shoulder's row: the error names the elbow, where the number is written
    let elbow = r#"<origin xyz="0 0 -0.45" rpy="0 0 0"/>"#;
    for (from, to, element, field) in [
        (elbow, r#"<origin xyz="1e300 0 0" rpy="0 0 0"/>"#, "joint 'elbow'", "origin"),
        (r#"<origin xyz="0 0 -0.048" rpy="0 0 0"/>"#, r#"<origin xyz="0 0 -1e300" rpy="0 0 0"/>"#, "link 'forearm'", "inertial/origin"),
    ] {
        let (err, msg) = load_text(&paper_arm_with(from, to));
        assert!(matches!(&err, Error::TooLarge { element: e, field: f, value, .. } if e == element && f == field && value.abs() == 1e300), "{err:?}");
        assert_mentions(&msg, &[element, field, "1e300", "at most 1e100", "overflow"]);
        assert!(!msg.contains("shoulder"), "{msg}");
    }
}

#[test]
fn whole_massless_chain_is_massless() {
    let (err, msg) = load_bad("massless_chain.urdf");
    assert!(matches!(&err, Error::Massless { links, .. } if links == &["upper", "forearm"]), "{err:?}");
    assert_mentions(&msg, &["\"upper\"", "\"forearm\"", "massless", "mass > 0"]);
}

#[test]
fn every_bad_fixture_is_tested() {
    // a new file in models/bad/ needs a test above
    let mut names: Vec<String> = std::fs::read_dir(common::model_path("bad")).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    let source = include_str!("urdf_errors.rs");
    for name in names {
        assert!(source.contains(&format!("load_bad(\"{name}\")")), "models/bad/{name} has no test");
    }
}

#[test]
fn missing_file_is_io_naming_the_path() {
    let path = common::model_path("bad/does_not_exist.urdf");
    let err = Model::from_urdf_file(&path).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert_mentions(&err.to_string(), &["does_not_exist.urdf", "cannot read file"]);
}

#[test]
fn unknown_tip_is_unknown_tip() {
    let options = UrdfOptions { tip: Some("panda_link99".into()) };
    let err = Model::from_urdf_file_with(common::model_path("arm7.urdf"), &options).unwrap_err();
    assert!(matches!(&err, Error::UnknownTip { tip, .. } if tip == "panda_link99"), "{err:?}");
    assert_mentions(&err.to_string(), &["arm7.urdf", "tip link 'panda_link99'", "not defined"]);
}

#[test]
fn branching_arm_without_tip_is_not_serial() {
    let err = Model::from_urdf_file(common::model_path("arm7.urdf")).unwrap_err();
    assert!(matches!(&err, Error::NotSerial { link, children, .. } if link == "panda_hand" && children == &["panda_leftfinger", "panda_rightfinger"]), "{err:?}");
    assert_mentions(&err.to_string(), &["arm7.urdf", "link 'panda_hand'", "panda_leftfinger", "panda_rightfinger", "choose a tip link"]);
}

#[test]
fn joint_without_parent_element_is_malformed_urdf() {
    let text = r#"<robot name="r"><link name="a"/><link name="b"/>
        <joint name="j" type="revolute"><child link="b"/><axis xyz="0 0 1"/></joint></robot>"#;
    let err = Model::from_urdf_str_with(text, "inline.urdf", &UrdfOptions::default()).unwrap_err();
    assert!(matches!(err, Error::MalformedUrdf { .. }), "{err:?}");
    assert_mentions(&err.to_string(), &["inline.urdf", "joint 'j'", "<parent link="]);
}

#[test]
fn root_element_other_than_robot_is_malformed_urdf() {
    let err = Model::from_urdf_str("<model name=\"x\"/>").unwrap_err();
    assert!(matches!(err, Error::MalformedUrdf { .. }), "{err:?}");
    assert_mentions(&err.to_string(), &["<string>", "<model>", "expected <robot>"]);
}

/// The pendulum fixture with `from` replaced by `to` (exactly once).
fn pendulum_with(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(common::model_path("pendulum.urdf")).unwrap();
    assert_eq!(text.matches(from).count(), 1, "{from:?} is not in the pendulum fixture exactly once");
    text.replacen(from, to, 1)
}

#[track_caller]
fn load_text(text: &str) -> (Error, String) {
    let err = match Model::from_urdf_str_with(text, "inline.urdf", &UrdfOptions::default()) {
        Ok(m) => panic!("loaded as a {}-DOF model", m.dof()),
        Err(e) => e,
    };
    let message = err.to_string();
    assert_mentions(&message, &["inline.urdf", "expected"]);
    (err, message)
}

#[test]
fn deep_nesting_is_refused_before_parsing_naming_the_depth() {
    // ~15,000 levels (≈ 105 KB): the XML readers would recurse once per level and overflow the stack
    let depth = 15_000;
    let text = format!("<robot name=\"r\"><link name=\"a\">{}{}</link></robot>", "<x>".repeat(depth), "</x>".repeat(depth));
    // on a small stack, as a Python or worker thread has: the check itself must not recurse
    let (err, msg) = std::thread::Builder::new().stack_size(256 * 1024).spawn(move || load_text(&text)).unwrap().join().unwrap();
    assert!(matches!(&err, Error::TooDeep { depth: d, line: 1, .. } if *d == depth + 2), "{err:?}");
    assert_mentions(&msg, &["nest 15002 levels deep", "more than 64"]);
}

#[test]
fn nesting_within_the_limit_loads() {
    let inner = format!("{}{}", "<x>".repeat(50), "</x>".repeat(50));
    let text = pendulum_with("<link name=\"base_link\"/>", &format!("<link name=\"base_link\">{inner}</link>"));
    assert_eq!(Model::from_urdf_str(&text).unwrap().dof(), 1);
}

#[test]
fn unexpanded_xacro_expression_names_element_and_attribute() {
    let text = pendulum_with("<mass value=\"2.0\"/>", "<mass value=\"${m_bob}\"/>");
    let (err, msg) = load_text(&text);
    assert!(matches!(&err, Error::Xacro { element, attribute, value, line: 20, .. } if element == "mass" && attribute == "value" && value == "${m_bob}"), "{err:?}");
    assert_mentions(&msg, &["line 20", "<mass>", "value=\"${m_bob}\"", "run xacro first"]);
}

#[test]
fn unexpanded_xacro_substitution_args_are_named() {
    let text = pendulum_with("<axis xyz=\"0 1 0\"/>", "<axis xyz='$(arg axis)'/>");
    let (err, msg) = load_text(&text);
    assert!(matches!(&err, Error::Xacro { element, attribute, .. } if element == "axis" && attribute == "xyz"), "{err:?}");
    assert_mentions(&msg, &["<axis>", "xyz=\"$(arg axis)\"", "run xacro first"]);
}

#[test]
fn xacro_element_is_named() {
    let text = pendulum_with("<link name=\"base_link\"/>", "<link name=\"base_link\"/>\n  <xacro:property name=\"m\" value=\"2\"/>");
    let (err, msg) = load_text(&text);
    assert!(matches!(&err, Error::Xacro { element, attribute, .. } if element == "xacro:property" && attribute.is_empty()), "{err:?}");
    assert_mentions(&msg, &["<xacro:property>", "unexpanded xacro element", "run xacro first"]);
}

#[test]
fn robot_without_links_says_so() {
    let (err, msg) = load_text("<robot name=\"empty\"></robot>");
    assert!(matches!(err, Error::NoLinks { .. }), "{err:?}");
    assert_mentions(&msg, &["<robot> has no <link>", "at least one link"]);
    assert!(!msg.contains("closed loop"), "{msg}");
}

#[test]
fn nan_effort_limit_is_refused_naming_the_joint() {
    let text = pendulum_with("effort=\"20\"", "effort=\"NaN\"");
    let (err, msg) = load_text(&text);
    assert!(matches!(&err, Error::NonFinite { element, field, .. } if element == "joint 'hinge'" && field == "limit/effort"), "{err:?}");
    assert_mentions(&msg, &["joint 'hinge'", "limit/effort", "finite"]);
}

#[test]
fn infinite_velocity_limit_is_refused_naming_the_joint() {
    let text = pendulum_with("velocity=\"10\"", "velocity=\"inf\"");
    let (err, msg) = load_text(&text);
    assert!(matches!(&err, Error::NonFinite { element, field, .. } if element == "joint 'hinge'" && field == "limit/velocity"), "{err:?}");
    assert_mentions(&msg, &["joint 'hinge'", "limit/velocity"]);
}

#[test]
fn number_that_is_not_a_number_names_element_attribute_and_owner() {
    let text = pendulum_with("<mass value=\"2.0\"/>", "<mass value=\"two\"/>");
    let (err, msg) = load_text(&text);
    assert!(matches!(&err, Error::BadNumber { element, attribute, line: 20, .. } if element == "<mass> of link 'bob'" && *attribute == "value"), "{err:?}");
    assert_mentions(&msg, &["line 20", "<mass> of link 'bob'", "value=\"two\"", "expected a number"]);
    let text = pendulum_with("<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 1\"/>");
    let (_, msg) = load_text(&text);
    assert_mentions(&msg, &["<axis> of joint 'hinge'", "xyz=\"0 1\"", "expected 3 numbers"]);
}

#[test]
fn missing_required_element_or_attribute_names_the_element_its_owner_its_line_and_what_was_expected() {
    // what urdfdom refuses and urdf-rs reported only as "missing field `mass`"
    let cases: [(&str, &str, &[&str]); 6] = [
        ("<mass value=\"2.0\"/>", "", &["line 18", "<inertial> of link 'bob' has no <mass>", "expected <mass value="]),
        ("<inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.1\" iyz=\"0\" izz=\"0.02\"/>", "", &["line 18", "<inertial> of link 'bob' has no <inertia>", "and <inertia ixx="]),
        ("<mass value=\"2.0\"/>", "<mass/>", &["line 20", "<mass> of link 'bob' has no value attribute", "expected"]),
        ("ixz=\"0\" ", "", &["line 21", "<inertia> of link 'bob' has no ixz attribute", "ixx, ixy, ixz, iyy, iyz and izz"]),
        ("<joint name=\"hinge\" type=\"revolute\">", "<joint name=\"hinge\">", &["line 10", "joint 'hinge' has no type attribute", "revolute"]),
        (" velocity=\"10\"", "", &["line 15", "<limit> of joint 'hinge' has no velocity attribute", "expected"]),
    ];
    for (from, to, parts) in cases {
        let (err, msg) = load_text(&pendulum_with(from, to));
        assert!(matches!(err, Error::MalformedUrdf { .. }), "{err:?}");
        assert_mentions(&msg, parts);
    }
}
