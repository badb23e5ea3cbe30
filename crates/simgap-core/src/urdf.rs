//! Loading a [`Model`] from URDF. This is the only file that names `urdf-rs`.
//!
//! Rules: revolute, continuous and prismatic joints are movable; fixed joints are merged into
//! their parent link; the chain runs from the unique root link to a tip link (by default the
//! end of the unique chain of movable joints); subtrees hanging off the chain (gripper fingers,
//! sensors) are merged rigidly at their zero position into the chain link they hang from, with
//! a warning when they contain movable joints. Mesh paths are never resolved.

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

fn finite(src: &str, element: &str, field: &str, values: &[f64]) -> Result<()> {
    for &v in values {
        if !v.is_finite() {
            return Err(Error::NonFinite { source_name: src.into(), element: element.into(), field: field.into(), value: v });
        }
    }
    Ok(())
}

fn malformed(src: &str, message: impl Into<String>) -> Error {
    Error::MalformedUrdf { source_name: src.into(), message: message.into() }
}

fn from_urdf(text: &str, src: &str, options: &UrdfOptions) -> Result<Model> {
    // well-formedness first: roxmltree gives line numbers, and tells which links have <inertial>
    let doc = roxmltree::Document::parse(text).map_err(|e| malformed(src, e.to_string()))?;
    let root_el = doc.root_element();
    if root_el.tag_name().name() != "robot" {
        return Err(malformed(src, format!("root element is <{}>; expected <robot>", root_el.tag_name().name())));
    }
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

    let robot = urdf_rs::read_from_string(text).map_err(|e| malformed(src, e.to_string()))?;

    // links: inertia about the link frame origin, validated
    let mut link_inertia: HashMap<String, SpatialInertia> = HashMap::new();
    for l in &robot.links {
        let el = format!("link '{}'", l.name);
        let i = &l.inertial;
        finite(src, &el, "inertial/origin", &[i.origin.xyz.0, i.origin.rpy.0].concat())?;
        finite(src, &el, "inertial/mass", &[i.mass.value])?;
        let it = &i.inertia;
        finite(src, &el, "inertial/inertia", &[it.ixx, it.ixy, it.ixz, it.iyy, it.iyz, it.izz])?;
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

    // joints: kinds, references, numbers
    let mut joints: Vec<RawJoint> = Vec::new();
    let mut world_welds: Vec<String> = Vec::new();
    for j in &robot.joints {
        let el = format!("joint '{}'", j.name);
        let kind = match j.joint_type {
            urdf_rs::JointType::Revolute => Some(JointKind::Revolute),
            urdf_rs::JointType::Continuous => Some(JointKind::Continuous),
            urdf_rs::JointType::Prismatic => Some(JointKind::Prismatic),
            urdf_rs::JointType::Fixed => None,
            ref other => {
                return Err(Error::UnsupportedJoint { source_name: src.into(), name: j.name.clone(), kind: format!("{other:?}").to_lowercase() })
            }
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
        let axis = Vector3::from(j.axis.xyz.0);
        if kind.is_some() {
            finite(src, &el, "axis", &j.axis.xyz.0)?;
            if axis.norm() == 0.0 {
                return Err(Error::ZeroAxis { source_name: src.into(), joint: j.name.clone(), axis: j.axis.xyz.0 });
            }
        }
        let lim = &j.limit;
        let mut limits = JointLimits::default();
        if matches!(kind, Some(JointKind::Revolute) | Some(JointKind::Prismatic)) {
            for (field, v) in [("limit/lower", lim.lower), ("limit/upper", lim.upper)] {
                if v.is_nan() {
                    return Err(Error::NonFinite { source_name: src.into(), element: el.clone(), field: field.into(), value: v });
                }
            }
            if lim.lower < lim.upper {
                limits.lower = lim.lower;
                limits.upper = lim.upper;
            }
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

    // topology: one parent per link, a single root, no loops
    let mut parent_joint: HashMap<&str, usize> = HashMap::new();
    for (k, j) in joints.iter().enumerate() {
        if let Some(prev) = parent_joint.insert(j.child.as_str(), k) {
            return Err(Error::Loop {
                source_name: src.into(),
                link: j.child.clone(),
                detail: format!("is the child of two joints ('{}' and '{}')", joints[prev].name, j.name),
            });
        }
    }
    let mut roots: Vec<String> = robot.links.iter().filter(|l| !parent_joint.contains_key(l.name.as_str())).map(|l| l.name.clone()).collect();
    if roots.is_empty() {
        let link = joints.first().map(|j| j.child.clone()).unwrap_or_default();
        return Err(Error::Loop { source_name: src.into(), link, detail: "lies on a closed loop (no root link exists)".into() });
    }
    if roots.len() > 1 {
        // a link on a loop is unreachable from the root; a disconnected link is another root
        roots.sort();
        return Err(Error::Roots { source_name: src.into(), found: roots });
    }
    let root = roots.pop().unwrap();
    let mut children: HashMap<&str, Vec<usize>> = HashMap::new();
    for (k, j) in joints.iter().enumerate() {
        children.entry(j.parent.as_str()).or_default().push(k);
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

    // does the subtree below a link contain a movable joint?
    fn has_movable(link: &str, children: &HashMap<&str, Vec<usize>>, joints: &[RawJoint]) -> bool {
        children.get(link).is_some_and(|ks| ks.iter().any(|&k| joints[k].kind.is_some() || has_movable(&joints[k].child, children, joints)))
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
                    .map(|v| v.iter().copied().filter(|&k| joints[k].kind.is_some() || has_movable(&joints[k].child, &children, &joints)).collect())
                    .unwrap_or_default();
                match ks.len() {
                    0 => break,
                    1 => link = joints[ks[0]].child.clone(),
                    _ => {
                        return Err(Error::NotSerial {
                            source_name: src.into(),
                            link,
                            children: ks.iter().map(|&k| joints[k].child.clone()).collect(),
                        })
                    }
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
    let on_path: HashSet<usize> = path.iter().copied().collect();
    let movable: Vec<usize> = path.iter().copied().filter(|&k| joints[k].kind.is_some()).collect();
    if movable.is_empty() {
        return Err(Error::NoMovableJoint { source_name: src.into(), root: root.clone(), tip: tip.clone() });
    }

    // inertia of everything rigidly attached to `link` (off-path subtrees locked at q = 0)
    fn rigid_subtree(
        link: &str,
        children: &HashMap<&str, Vec<usize>>,
        joints: &[RawJoint],
        on_path: &HashSet<usize>,
        link_inertia: &HashMap<String, SpatialInertia>,
        locked: &mut Vec<String>,
    ) -> SpatialInertia {
        let mut total = link_inertia[link];
        for &k in children.get(link).map(|v| v.as_slice()).unwrap_or(&[]) {
            if on_path.contains(&k) {
                continue;
            }
            if joints[k].kind.is_some() {
                locked.push(joints[k].name.clone());
            }
            let sub = rigid_subtree(&joints[k].child, children, joints, on_path, link_inertia, locked);
            total += sub.transformed(&joints[k].origin);
        }
        total
    }

    // walk the path: fixed joints fold into the next placement and into the current body
    let mut locked = Vec::new();
    let mut out: Vec<Joint> = Vec::new();
    let mut placement = Transform::IDENTITY; // from the current body frame to the current link frame
    let mut body: Option<usize> = None; // index in `out` of the body being accumulated
    let mut current_link = root.as_str();
    let visit_link = |link: &str, placement: &Transform, body: Option<usize>, out: &mut Vec<Joint>, locked: &mut Vec<String>| {
        let inertia = rigid_subtree(link, &children, &joints, &on_path, &link_inertia, locked).transformed(placement);
        // links before the first movable joint are the fixed base: their inertia does not enter
        if let Some(b) = body {
            out[b].inertia += inertia;
        }
    };
    visit_link(current_link, &placement, body, &mut out, &mut locked);
    for &k in &path {
        let j = &joints[k];
        debug_assert_eq!(j.parent, current_link);
        placement = placement.compose(&j.origin);
        if let Some(kind) = j.kind {
            out.push(Joint {
                name: j.name.clone(),
                kind,
                axis: j.axis,
                placement,
                limits: j.limits,
                link: j.child.clone(),
                inertia: SpatialInertia::ZERO,
            });
            body = Some(out.len() - 1);
            placement = Transform::IDENTITY;
        }
        current_link = j.child.as_str();
        visit_link(current_link, &placement, body, &mut out, &mut locked);
    }
    let mut warnings = world_welds;
    if !locked.is_empty() {
        warnings.push(format!("{src}: joints {locked:?} are off the chain to '{tip}' and are locked at their zero position"));
    }
    let massless: Vec<&str> = path
        .iter()
        .map(|&k| joints[k].child.as_str())
        .filter(|l| !has_inertial.get(*l).copied().unwrap_or(false))
        .collect();
    if out.iter().all(|j| j.inertia.mass == 0.0 && j.inertia.rotational == Matrix3::zeros()) {
        return Err(Error::Massless { source_name: src.into(), links: path.iter().map(|&k| joints[k].child.clone()).collect() });
    }
    if !massless.is_empty() {
        warnings.push(format!("{src}: links {massless:?} have no <inertial> and are treated as massless"));
    }
    let name = if robot.name.is_empty() { "robot".to_string() } else { robot.name.clone() };
    let mut model = Model::new(name, root, out).map_err(|e| match e {
        Error::InvalidModel(m) => malformed(src, m),
        other => other,
    })?;
    for w in warnings {
        log::warn!("{w}");
        model.push_warning(w);
    }
    Ok(model)
}
