//! Loading a [`Model`] from URDF. This is the only file that names `urdf-rs`.
//!
//! Rules: revolute, continuous and prismatic joints are movable; fixed joints are merged into
//! their parent link; the chain runs from the unique root link to a tip link (by default the
//! end of the unique chain of movable joints); subtrees hanging off the chain (gripper fingers,
//! sensors) are merged rigidly at their zero position into the chain link they hang from, with
//! a warning when they contain movable joints. Mesh paths are never resolved. An element
//! repeated where urdfdom reads one (a joint's `<origin>`, a link's `<inertial>`, ...) is read
//! as urdfdom reads it, the first one, with a warning for each one left out
//! ([`duplicates`]).

mod duplicates;

use std::collections::{HashMap, HashSet};
use std::path::Path;

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::model::{check_inertia, Joint, JointKind, JointLimits, Model};
use crate::spatial::{SpatialInertia, Transform};

/// Options for [`Model::from_urdf_str_with`].
#[derive(Clone, Debug, Default)]
pub struct UrdfOptions {
    /// Tip link of the chain; `None` picks the end of the unique chain of movable joints.
    pub tip: Option<String>,
}

impl Model {
    /// Loads a model from a URDF file (chain from the root to the default tip).
    ///
    /// # Errors
    /// Any [`Error`] of the URDF family, naming the file and the offending element.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Model> {
        Self::from_urdf_file_with(path, &UrdfOptions::default())
    }

    /// Loads a model from a URDF file with options (e.g. a tip link).
    ///
    /// # Errors
    /// Any [`Error`] of the URDF family, naming the file and the offending element.
    pub fn from_urdf_file_with(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Model> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|cause| Error::Io { path: path.to_path_buf(), cause })?;
        from_urdf(&text, &path.display().to_string(), options)
    }

    /// Loads a model from URDF text.
    ///
    /// # Errors
    /// Any [`Error`] of the URDF family; the source is called `<string>`.
    pub fn from_urdf_str(text: &str) -> Result<Model> {
        from_urdf(text, "<string>", &UrdfOptions::default())
    }

    /// Loads a model from URDF text with options, naming the source `source_name` in errors.
    ///
    /// # Errors
    /// Any [`Error`] of the URDF family.
    pub fn from_urdf_str_with(text: &str, source_name: &str, options: &UrdfOptions) -> Result<Model> {
        from_urdf(text, source_name, options)
    }
}

struct RawJoint {
    name: String,
    kind: Option<JointKind>,
    parent: String,
    child: String,
    origin: Transform,
    axis: Vector3<f64>,
    limits: JointLimits,
}

/// The largest magnitude of a URDF's lengths, masses, inertias and axis components the loader
/// accepts: the joint-space terms are sums of products `mass · length²` (H, C) and `mass ·
/// length · g` (gravity), which stay below `1e300 < f64::MAX ≈ 1.8e308` when every factor is at
/// most `1e100`. A larger number is refused where it is written, not where it overflows.
pub const MAX_URDF_MAGNITUDE: f64 = 1e100;

/// Refuses a NaN or infinite value of `field` of `element`.
fn finite(src: &str, element: &str, field: &str, values: &[f64]) -> Result<()> {
    for &v in values {
        if !v.is_finite() {
            return Err(Error::NonFinite { source_name: src.into(), element: element.into(), field: field.into(), value: v });
        }
    }
    Ok(())
}

/// [`finite`], and refuses a value of magnitude above [`MAX_URDF_MAGNITUDE`].
fn bounded(src: &str, element: &str, field: &str, values: &[f64]) -> Result<()> {
    finite(src, element, field, values)?;
    match values.iter().find(|v| v.abs() > MAX_URDF_MAGNITUDE) {
        Some(&value) => Err(Error::TooLarge { source_name: src.into(), element: element.into(), field: field.into(), value, limit: MAX_URDF_MAGNITUDE }),
        None => Ok(()),
    }
}

fn malformed(src: &str, message: impl Into<String>) -> Error {
    Error::MalformedUrdf { source_name: src.into(), message: message.into() }
}

/// Deepest element nesting accepted. A URDF nests a handful of levels (robot > link > visual >
/// geometry > mesh); the XML readers recurse once per level, so a deeper document is refused
/// before it is parsed rather than overflowing the stack.
pub const MAX_NESTING_DEPTH: usize = 64;

/// Builds the model in four phases: the document is checked and parsed, its links and joints
/// are read and validated, the chain from the root to the tip is found, and the chain's joints
/// and the inertias rigidly attached to them become the model.
fn from_urdf(text: &str, src: &str, options: &UrdfOptions) -> Result<Model> {
    let doc = parse(text, src)?;
    let link_inertia = read_links(src, &doc.robot)?;
    let (joints, world_welds) = read_joints(src, &doc.robot, &link_inertia)?;
    let chain = find_chain(src, &doc.robot, &joints, &link_inertia, options)?;
    build_model(src, &doc, &joints, &link_inertia, &chain, world_welds)
}

/// The parsed document: the robot as urdf-rs reads it, which links have an `<inertial>`, and
/// the warnings of the reading (repeated elements left out).
struct Document {
    robot: urdf_rs::Robot,
    has_inertial: HashMap<String, bool>,
    warnings: Vec<String>,
}

/// Line (1-based) of byte offset `pos` in `text`.
fn line_of(text: &str, pos: usize) -> u32 {
    let lines = text.as_bytes()[..pos.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1;
    u32::try_from(lines).unwrap_or(u32::MAX)
}

/// One lexical pass over the text before any parser sees it: the nesting depth (refused past
/// [`MAX_NESTING_DEPTH`]) and unexpanded xacro (`<xacro:...>` elements, `${...}` and `$(...)`
/// in attribute values), each named with its line. Malformed XML is left to the parser.
fn prescan(text: &str, src: &str) -> Result<()> {
    let b = text.as_bytes();
    let find = |from: usize, pat: &str| text.get(from..).and_then(|t| t.find(pat)).map(|k| from + k);
    let (mut i, mut depth, mut deepest) = (0usize, 0usize, 0usize);
    let mut first_too_deep: Option<usize> = None;
    while let Some(lt) = find(i, "<") {
        let rest = &text[lt..];
        // comments, CDATA, processing instructions and declarations do not nest
        let skip_to = |end: &str| find(lt, end).map_or(b.len(), |k| k + end.len());
        if rest.starts_with("<!--") {
            i = skip_to("-->");
            continue;
        }
        if rest.starts_with("<![CDATA[") {
            i = skip_to("]]>");
            continue;
        }
        if rest.starts_with("<?") {
            i = skip_to("?>");
            continue;
        }
        if rest.starts_with("<!") {
            // a DOCTYPE may hold an internal subset in brackets
            let mut k = lt + 2;
            let mut brackets = 0i32;
            while k < b.len() && !(b[k] == b'>' && brackets <= 0) {
                match b[k] {
                    b'[' => brackets += 1,
                    b']' => brackets -= 1,
                    _ => {}
                }
                k += 1;
            }
            i = k + 1;
            continue;
        }
        if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
            i = skip_to(">");
            continue;
        }
        // a start tag: its name, its attributes, and whether it closes itself
        let name_end = rest[1..].find(|c: char| c.is_whitespace() || c == '/' || c == '>').map_or(rest.len(), |k| k + 1);
        let name = &rest[1..name_end];
        if name.starts_with("xacro:") {
            return Err(Error::Xacro { source_name: src.into(), line: line_of(text, lt), element: name.into(), attribute: String::new(), value: String::new() });
        }
        let mut k = lt + name_end;
        let mut self_closing = false;
        while k < b.len() {
            match b[k] {
                b'>' => {
                    self_closing = k > 0 && b[k - 1] == b'/';
                    break;
                }
                q @ (b'"' | b'\'') => {
                    // an attribute value: look for xacro expressions in it
                    let end = text[k + 1..].find(q as char).map_or(b.len(), |e| k + 1 + e);
                    let value = &text[k + 1..end.min(b.len())];
                    if value.contains("${") || value.contains("$(") {
                        let before = text[lt + name_end..k].trim_end().trim_end_matches('=').trim_end();
                        let attribute = before.rsplit(|c: char| c.is_whitespace()).next().unwrap_or("").to_string();
                        return Err(Error::Xacro { source_name: src.into(), line: line_of(text, lt), element: name.into(), attribute, value: value.into() });
                    }
                    k = end + 1;
                    continue;
                }
                _ => {}
            }
            k += 1;
        }
        if !self_closing {
            depth += 1;
            if depth > MAX_NESTING_DEPTH && first_too_deep.is_none() {
                first_too_deep = Some(lt);
            }
            deepest = deepest.max(depth);
        }
        i = k + 1;
    }
    if let Some(pos) = first_too_deep {
        return Err(Error::TooDeep { source_name: src.into(), depth: deepest, limit: MAX_NESTING_DEPTH, line: line_of(text, pos) });
    }
    Ok(())
}

/// The number attributes of URDF elements: (element, attribute, how many numbers).
const NUMBER_ATTRIBUTES: [(&str, &str, u8); 16] = [
    ("origin", "xyz", 3),
    ("origin", "rpy", 3),
    ("axis", "xyz", 3),
    ("mass", "value", 1),
    ("inertia", "ixx", 1),
    ("inertia", "ixy", 1),
    ("inertia", "ixz", 1),
    ("inertia", "iyy", 1),
    ("inertia", "iyz", 1),
    ("inertia", "izz", 1),
    ("limit", "lower", 1),
    ("limit", "upper", 1),
    ("limit", "effort", 1),
    ("limit", "velocity", 1),
    ("dynamics", "damping", 1),
    ("dynamics", "friction", 1),
];

/// An element named for a message: `<mass> of link 'forearm'`, `joint 'elbow'`.
fn described(el: &roxmltree::Node<'_, '_>) -> String {
    let tag = el.tag_name().name();
    if let (t @ ("link" | "joint"), Some(n)) = (tag, el.attribute("name")) {
        return format!("{t} '{n}'");
    }
    // name the element by the link or joint it belongs to
    let owner = el.ancestors().skip(1).find_map(|a| match (a.tag_name().name(), a.attribute("name")) {
        (t @ ("link" | "joint"), Some(n)) => Some(format!(" of {t} '{n}'")),
        _ => None,
    });
    format!("<{tag}>{}", owner.unwrap_or_default())
}

/// Checks every number attribute of links and joints, so that a bad one is named with its
/// element, attribute and line (urdf-rs says only "invalid float literal").
fn check_numbers(doc: &roxmltree::Document<'_>, src: &str) -> Result<()> {
    for el in doc.descendants().filter(|n| n.is_element()) {
        let tag = el.tag_name().name();
        for &(_, attr, count) in NUMBER_ATTRIBUTES.iter().filter(|(t, _, _)| *t == tag) {
            let Some(value) = el.attribute(attr) else { continue };
            let parts: Vec<&str> = value.split_whitespace().collect();
            if parts.len() != usize::from(count) || parts.iter().any(|p| p.parse::<f64>().is_err()) {
                return Err(Error::BadNumber {
                    source_name: src.into(),
                    line: doc.text_pos_at(el.range().start).row,
                    element: described(&el),
                    attribute: attr,
                    value: value.into(),
                    count,
                });
            }
        }
    }
    Ok(())
}

/// What urdfdom requires of an element, and urdf-rs refuses without naming the element
/// ("missing field `mass`").
struct Required {
    /// The element's tag.
    element: &'static str,
    /// The tag of the element it is required in (`robot` for the top level).
    within: &'static str,
    /// Children it must have.
    children: &'static [&'static str],
    /// Attributes it must have.
    attributes: &'static [&'static str],
    /// What is expected, for the message.
    expected: &'static str,
}

/// Every [`Required`] checked.
const REQUIRED: [Required; 5] = [
    Required {
        element: "inertial",
        within: "link",
        children: &["mass", "inertia"],
        attributes: &[],
        expected: "<mass value=\"...\"/> and <inertia ixx=... izz=.../> in every <inertial>",
    },
    Required { element: "mass", within: "inertial", children: &[], attributes: &["value"], expected: "<mass value=\"...\"/> (kg)" },
    Required {
        element: "inertia",
        within: "inertial",
        children: &[],
        attributes: &["ixx", "ixy", "ixz", "iyy", "iyz", "izz"],
        expected: "all of ixx, ixy, ixz, iyy, iyz and izz (kg·m²)",
    },
    Required { element: "joint", within: "robot", children: &[], attributes: &["type"], expected: "type=\"revolute\", \"continuous\", \"prismatic\" or \"fixed\"" },
    Required { element: "limit", within: "joint", children: &[], attributes: &["velocity"], expected: "velocity=\"...\" in every <limit> of a joint" },
];

/// Checks the children and attributes of [`REQUIRED`], naming the element, its link or joint,
/// its line and what was expected.
fn check_required(doc: &roxmltree::Document<'_>, src: &str) -> Result<()> {
    for el in doc.descendants().filter(|n| n.is_element()) {
        let parent = el.parent_element().map(|p| p.tag_name().name());
        let Some(req) = REQUIRED.iter().find(|r| r.element == el.tag_name().name() && Some(r.within) == parent) else { continue };
        let missing_child = req.children.iter().find(|c| !el.children().any(|n| n.has_tag_name(**c))).map(|c| format!("<{c}>"));
        let missing = missing_child.or_else(|| req.attributes.iter().find(|a| el.attribute(**a).is_none()).map(|a| format!("{a} attribute")));
        if let Some(missing) = missing {
            let line = doc.text_pos_at(el.range().start).row;
            return Err(malformed(src, format!("line {line}: {} has no {missing}; expected {}", described(&el), req.expected)));
        }
    }
    Ok(())
}

/// Phase 1: the document is checked (nesting, xacro, well-formedness, the `<robot>` root),
/// the elements urdfdom would not read are left out with a warning each, the rest is checked
/// (names, references and numbers, each error naming its element) and parsed by urdf-rs.
fn parse(text: &str, src: &str) -> Result<Document> {
    prescan(text, src)?;
    // well-formedness first: roxmltree gives line numbers, and tells which links have <inertial>
    let original = roxmltree::Document::parse(text).map_err(|e| malformed(src, e.to_string()))?;
    let root_el = original.root_element();
    if root_el.tag_name().name() != "robot" {
        return Err(malformed(src, format!("root element is <{}>; expected <robot>", root_el.tag_name().name())));
    }
    // repeated elements: the first is read, as urdfdom reads it; lines stay where they were
    let (first_only, warnings) = duplicates::first_of_each(&original, text, src);
    let reparsed;
    let (text, doc) = match &first_only {
        Some(t) => {
            reparsed = roxmltree::Document::parse(t).map_err(|e| malformed(src, e.to_string()))?;
            (t.as_str(), &reparsed)
        }
        None => (text, &original),
    };
    let root_el = doc.root_element();
    let mut has_inertial: HashMap<String, bool> = HashMap::new();
    let mut seen_joints = HashSet::new();
    for el in root_el.children().filter(|n| n.is_element()) {
        let line = doc.text_pos_at(el.range().start).row;
        match el.tag_name().name() {
            "link" => {
                let name = el.attribute("name").ok_or_else(|| malformed(src, format!("<link> at line {line} has no name attribute")))?;
                let inertial = el.children().any(|c| c.has_tag_name("inertial"));
                if has_inertial.insert(name.to_string(), inertial).is_some() {
                    return Err(Error::DuplicateLink { source_name: src.into(), link: name.into() });
                }
            }
            "joint" => {
                let name = el.attribute("name").ok_or_else(|| malformed(src, format!("<joint> at line {line} has no name attribute")))?;
                if !seen_joints.insert(name.to_string()) {
                    return Err(Error::DuplicateJoint { source_name: src.into(), joint: name.into() });
                }
                for tag in ["parent", "child"] {
                    let ok = el.children().any(|c| c.has_tag_name(tag) && c.attribute("link").is_some());
                    if !ok {
                        return Err(malformed(src, format!("joint '{name}' (line {line}) has no <{tag} link=\"...\"/>")));
                    }
                }
            }
            _ => {}
        }
    }
    if has_inertial.is_empty() {
        return Err(Error::NoLinks { source_name: src.into() });
    }
    check_numbers(doc, src)?;
    check_required(doc, src)?;
    let robot = urdf_rs::read_from_string(text).map_err(|e| malformed(src, e.to_string()))?;
    Ok(Document { robot, has_inertial, warnings })
}

/// Phase 2a: every link's inertia about its frame origin, validated.
fn read_links(src: &str, robot: &urdf_rs::Robot) -> Result<HashMap<String, SpatialInertia>> {
    let mut link_inertia: HashMap<String, SpatialInertia> = HashMap::new();
    for l in &robot.links {
        let el = format!("link '{}'", l.name);
        let i = &l.inertial;
        finite(src, &el, "inertial/origin", &[i.origin.xyz.0, i.origin.rpy.0].concat())?;
        bounded(src, &el, "inertial/origin", &i.origin.xyz.0)?;
        bounded(src, &el, "inertial/mass", &[i.mass.value])?;
        let it = &i.inertia;
        bounded(src, &el, "inertial/inertia", &[it.ixx, it.ixy, it.ixz, it.iyy, it.iyz, it.izz])?;
        if i.mass.value < 0.0 {
            return Err(Error::NegativeMass { source_name: src.into(), link: l.name.clone(), mass: i.mass.value });
        }
        let ic = Matrix3::new(it.ixx, it.ixy, it.ixz, it.ixy, it.iyy, it.iyz, it.ixz, it.iyz, it.izz);
        crate::model::check_rotational_inertia(src, &l.name, &ic)?;
        let frame = Transform::from_xyz_rpy(i.origin.xyz.0, i.origin.rpy.0);
        let rot_inertia = frame.rotation * ic * frame.rotation.transpose();
        let inertia = SpatialInertia::from_com(i.mass.value, frame.translation, rot_inertia);
        check_inertia(src, &l.name, &inertia)?;
        link_inertia.insert(l.name.clone(), inertia);
    }
    Ok(link_inertia)
}

/// Phase 2b: every joint's kind, links, placement, axis and limits, validated; fixed joints to
/// an undefined link (Gazebo's `world`) are dropped with a warning (second value).
fn read_joints(src: &str, robot: &urdf_rs::Robot, link_inertia: &HashMap<String, SpatialInertia>) -> Result<(Vec<RawJoint>, Vec<String>)> {
    let mut joints: Vec<RawJoint> = Vec::new();
    let mut world_welds: Vec<String> = Vec::new();
    for j in &robot.joints {
        let el = format!("joint '{}'", j.name);
        let kind = match j.joint_type {
            urdf_rs::JointType::Revolute => Some(JointKind::Revolute),
            urdf_rs::JointType::Continuous => Some(JointKind::Continuous),
            urdf_rs::JointType::Prismatic => Some(JointKind::Prismatic),
            urdf_rs::JointType::Fixed => None,
            ref other => return Err(Error::UnsupportedJoint { source_name: src.into(), name: j.name.clone(), kind: format!("{other:?}").to_lowercase() }),
        };
        // a fixed joint from an undefined link (Gazebo's `world`) welds the robot to the world
        // frame: the undefined link is the world and the joint is dropped
        if kind.is_none() && !link_inertia.contains_key(&j.parent.link) && link_inertia.contains_key(&j.child.link) {
            world_welds.push(format!("{src}: fixed joint '{}' attaches '{}' to undefined link '{}', taken as the world frame", j.name, j.child.link, j.parent.link));
            continue;
        }
        for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !link_inertia.contains_key(link) {
                return Err(Error::MissingLink { source_name: src.into(), joint: j.name.clone(), role, link: link.clone() });
            }
        }
        finite(src, &el, "origin", &[j.origin.xyz.0, j.origin.rpy.0].concat())?;
        bounded(src, &el, "origin", &j.origin.xyz.0)?;
        let axis = Vector3::from(j.axis.xyz.0);
        if kind.is_some() {
            bounded(src, &el, "axis", &j.axis.xyz.0)?;
            if axis.norm() == 0.0 {
                return Err(Error::ZeroAxis { source_name: src.into(), joint: j.name.clone(), axis: j.axis.xyz.0 });
            }
        }
        // limits: NaN anywhere, or an infinite effort or velocity, is refused
        let lim = &j.limit;
        let mut limits = JointLimits::default();
        for (field, v) in [("limit/lower", lim.lower), ("limit/upper", lim.upper)] {
            if v.is_nan() {
                return Err(Error::NonFinite { source_name: src.into(), element: el.clone(), field: field.into(), value: v });
            }
        }
        finite(src, &el, "limit/effort", &[lim.effort])?;
        finite(src, &el, "limit/velocity", &[lim.velocity])?;
        if matches!(kind, Some(JointKind::Revolute) | Some(JointKind::Prismatic)) && lim.lower < lim.upper {
            limits.lower = lim.lower;
            limits.upper = lim.upper;
        }
        if lim.effort > 0.0 {
            limits.effort = lim.effort;
        }
        if lim.velocity > 0.0 {
            limits.velocity = lim.velocity;
        }
        joints.push(RawJoint {
            name: j.name.clone(),
            kind,
            parent: j.parent.link.clone(),
            child: j.child.link.clone(),
            origin: Transform::from_xyz_rpy(j.origin.xyz.0, j.origin.rpy.0),
            axis: if axis.norm() > 0.0 { axis.normalize() } else { axis },
            limits,
        });
    }
    Ok((joints, world_welds))
}

/// The chain from the root to the tip.
struct Chain {
    root: String,
    tip: String,
    /// Joint indices from the root to the tip.
    path: Vec<usize>,
    /// The joints leaving each link.
    children: HashMap<String, Vec<usize>>,
}

/// Does the subtree below `link` contain a movable joint?
fn has_movable(link: &str, children: &HashMap<String, Vec<usize>>, joints: &[RawJoint]) -> bool {
    children.get(link).is_some_and(|ks| ks.iter().any(|&k| joints[k].kind.is_some() || has_movable(&joints[k].child, children, joints)))
}

/// Phase 3: the topology (one parent per link, a single root, no loops) and the chain from the
/// root to the tip (given, or the end of the unique movable chain).
fn find_chain(src: &str, robot: &urdf_rs::Robot, joints: &[RawJoint], link_inertia: &HashMap<String, SpatialInertia>, options: &UrdfOptions) -> Result<Chain> {
    // one parent per link
    let mut parent_joint: HashMap<&str, usize> = HashMap::new();
    for (k, j) in joints.iter().enumerate() {
        if let Some(prev) = parent_joint.insert(j.child.as_str(), k) {
            return Err(Error::Loop { source_name: src.into(), link: j.child.clone(), detail: format!("is the child of two joints ('{}' and '{}')", joints[prev].name, j.name) });
        }
    }
    // a single root
    let mut roots: Vec<String> = robot.links.iter().filter(|l| !parent_joint.contains_key(l.name.as_str())).map(|l| l.name.clone()).collect();
    if roots.is_empty() {
        let link = joints.first().map(|j| j.child.clone()).unwrap_or_default();
        return Err(Error::Loop { source_name: src.into(), link, detail: "lies on a closed loop (every link is some joint's child, so no root link exists)".into() });
    }
    if roots.len() > 1 {
        // a link on a loop is unreachable from the root; a disconnected link is another root
        roots.sort();
        return Err(Error::Roots { source_name: src.into(), found: roots });
    }
    let root = roots.pop().unwrap_or_default();
    let mut children: HashMap<String, Vec<usize>> = HashMap::new();
    for (k, j) in joints.iter().enumerate() {
        children.entry(j.parent.clone()).or_default().push(k);
    }
    // every link must be reachable from the root (otherwise it is on a loop)
    let mut reached = HashSet::new();
    let mut stack = vec![root.as_str()];
    while let Some(l) = stack.pop() {
        if !reached.insert(l) {
            continue;
        }
        for &k in children.get(l).map(|v| v.as_slice()).unwrap_or(&[]) {
            stack.push(joints[k].child.as_str());
        }
    }
    if let Some(l) = robot.links.iter().find(|l| !reached.contains(l.name.as_str())) {
        return Err(Error::Loop { source_name: src.into(), link: l.name.clone(), detail: "lies on a closed loop unreachable from the root".into() });
    }

    // the tip: given, or the end of the unique movable chain
    let tip = match &options.tip {
        Some(t) => {
            if !link_inertia.contains_key(t) {
                return Err(Error::UnknownTip { source_name: src.into(), tip: t.clone() });
            }
            t.clone()
        }
        None => {
            let mut link = root.clone();
            loop {
                let ks: Vec<usize> = children
                    .get(link.as_str())
                    .map(|v| v.iter().copied().filter(|&k| joints[k].kind.is_some() || has_movable(&joints[k].child, &children, joints)).collect())
                    .unwrap_or_default();
                match ks.len() {
                    0 => break,
                    1 => link = joints[ks[0]].child.clone(),
                    _ => return Err(Error::NotSerial { source_name: src.into(), link, children: ks.iter().map(|&k| joints[k].child.clone()).collect() }),
                }
            }
            link
        }
    };

    // the path root -> tip, as joint indices
    let mut path = Vec::new();
    let mut link = tip.as_str();
    while let Some(&k) = parent_joint.get(link) {
        path.push(k);
        link = joints[k].parent.as_str();
    }
    path.reverse();
    if !path.iter().any(|&k| joints[k].kind.is_some()) {
        return Err(Error::NoMovableJoint { source_name: src.into(), root: root.clone(), tip: tip.clone() });
    }
    Ok(Chain { root, tip, path, children })
}

/// Inertia of everything rigidly attached to `link` (off-path subtrees locked at q = 0); the
/// movable joints locked are pushed to `locked`.
fn rigid_subtree(
    link: &str,
    chain: &Chain,
    joints: &[RawJoint],
    on_path: &HashSet<usize>,
    link_inertia: &HashMap<String, SpatialInertia>,
    locked: &mut Vec<String>,
) -> SpatialInertia {
    let mut total = link_inertia[link];
    for &k in chain.children.get(link).map(|v| v.as_slice()).unwrap_or(&[]) {
        if on_path.contains(&k) {
            continue;
        }
        if joints[k].kind.is_some() {
            locked.push(joints[k].name.clone());
        }
        let sub = rigid_subtree(&joints[k].child, chain, joints, on_path, link_inertia, locked);
        total += sub.transformed(&joints[k].origin);
    }
    total
}

/// Phase 4: the chain's movable joints with their placements, and the inertia of each body
/// (fixed joints folded into the next placement and into the current body).
fn build_model(src: &str, doc: &Document, joints: &[RawJoint], link_inertia: &HashMap<String, SpatialInertia>, chain: &Chain, world_welds: Vec<String>) -> Result<Model> {
    let on_path: HashSet<usize> = chain.path.iter().copied().collect();
    let mut locked = Vec::new();
    let mut out: Vec<Joint> = Vec::new();
    let mut placement = Transform::IDENTITY; // from the current body frame to the current link frame
    let mut body: Option<usize> = None; // index in `out` of the body being accumulated
    let mut visit_link = |link: &str, placement: &Transform, body: Option<usize>, out: &mut Vec<Joint>| {
        let inertia = rigid_subtree(link, chain, joints, &on_path, link_inertia, &mut locked).transformed(placement);
        // links before the first movable joint are the fixed base: their inertia does not enter
        if let Some(b) = body {
            out[b].inertia += inertia;
        }
    };
    visit_link(&chain.root, &placement, body, &mut out);
    for &k in &chain.path {
        let j = &joints[k];
        placement = placement.compose(&j.origin);
        if let Some(kind) = j.kind {
            out.push(Joint { name: j.name.clone(), kind, axis: j.axis, placement, limits: j.limits, link: j.child.clone(), inertia: SpatialInertia::ZERO });
            body = Some(out.len() - 1);
            placement = Transform::IDENTITY;
        }
        visit_link(&j.child, &placement, body, &mut out);
    }
    let mut warnings = doc.warnings.clone();
    warnings.extend(world_welds);
    if !locked.is_empty() {
        warnings.push(format!("{src}: joints {locked:?} are off the chain to '{}' and are locked at their zero position", chain.tip));
    }
    if out.iter().all(|j| j.inertia.mass == 0.0 && j.inertia.rotational == Matrix3::zeros()) {
        return Err(Error::Massless { source_name: src.into(), links: chain.path.iter().map(|&k| joints[k].child.clone()).collect() });
    }
    let massless: Vec<&str> = chain.path.iter().map(|&k| joints[k].child.as_str()).filter(|l| !doc.has_inertial.get(*l).copied().unwrap_or(false)).collect();
    if !massless.is_empty() {
        warnings.push(format!("{src}: links {massless:?} have no <inertial> and are treated as massless"));
    }
    let name = if doc.robot.name.is_empty() { "robot".to_string() } else { doc.robot.name.clone() };
    let mut model = Model::new(name, chain.root.clone(), out).map_err(|e| match e {
        Error::InvalidModel(m) => malformed(src, m),
        other => other,
    })?;
    for w in warnings {
        log::warn!("{w}");
        model.push_warning(w);
    }
    Ok(model)
}
