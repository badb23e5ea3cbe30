//! Repeated elements, read as urdfdom reads them.
//!
//! urdfdom (and so Pinocchio, ROS and Gazebo) reads each of a joint's `<origin>`, `<parent>`,
//! `<child>`, `<axis>`, `<limit>`, `<dynamics>`, ... with `FirstChildElement`: a second one is
//! never looked at. Published URDFs carry such repeats (a fixed joint with two `<origin>` tags,
//! a link with two `<inertial>` blocks), and urdf-rs refuses them (`duplicate field 'origin'`).
//! This pass finds every element urdfdom would not read, says so in a warning naming the
//! element, its link or joint and its line, and blanks it out of the text: every byte of the
//! element becomes a space and its newlines stay, so lines and byte offsets are unchanged for
//! every later message. Elements urdfdom reads in any number (`<visual>`, `<collision>`) are
//! left alone.

/// The children urdfdom reads once (the first of their tag), by the tag of their parent.
/// A `<geometry>` reads its first child element, whatever its tag.
const READ_ONCE: [(&str, &[&str]); 6] = [
    ("joint", &["origin", "parent", "child", "axis", "limit", "dynamics", "calibration", "mimic", "safety_controller"]),
    ("link", &["inertial"]),
    ("inertial", &["origin", "mass", "inertia"]),
    ("visual", &["origin", "geometry", "material"]),
    ("collision", &["origin", "geometry"]),
    ("material", &["color", "texture"]),
];

/// The text without the elements urdfdom does not read (`None`: there are none, the text is
/// read as it is), and one warning per element left out.
pub(super) fn first_of_each(doc: &roxmltree::Document<'_>, text: &str, src: &str) -> (Option<String>, Vec<String>) {
    let mut ignored: Vec<(roxmltree::Node<'_, '_>, roxmltree::Node<'_, '_>)> = Vec::new();
    // the robot's links, joints and materials (not the <gazebo> or <transmission> blocks, which
    // urdfdom does not read as links or joints)
    for el in doc.root_element().children().filter(|n| n.is_element() && matches!(n.tag_name().name(), "link" | "joint" | "material")) {
        collect(el, &mut ignored);
    }
    if ignored.is_empty() {
        return (None, Vec::new());
    }
    let line = |n: &roxmltree::Node<'_, '_>| doc.text_pos_at(n.range().start).row;
    let warnings = ignored
        .iter()
        .map(|(first, again)| {
            format!(
                "{src}: line {}: {} has a second <{}> (the first is at line {}); the first is used and this one ignored, as urdfdom and Pinocchio do",
                line(again),
                owner(again),
                again.tag_name().name(),
                line(first),
            )
        })
        .collect();
    let mut ranges: Vec<std::ops::Range<usize>> = ignored.iter().map(|(_, again)| again.range()).collect();
    ranges.sort_by_key(|r| r.start);
    // every character of an ignored element becomes a space, its line breaks stay
    let mut out = String::with_capacity(text.len());
    let mut next = ranges.iter().peekable();
    for (pos, ch) in text.char_indices() {
        while next.peek().is_some_and(|r| r.end <= pos) {
            next.next();
        }
        let blank = next.peek().is_some_and(|r| r.start <= pos) && !matches!(ch, '\n' | '\r');
        out.push(if blank { ' ' } else { ch });
    }
    (Some(out), warnings)
}

/// Collects, below `el`, every element urdfdom does not read, paired with the one it reads
/// instead; descends only into elements that are read.
fn collect<'a, 'i>(el: roxmltree::Node<'a, 'i>, ignored: &mut Vec<(roxmltree::Node<'a, 'i>, roxmltree::Node<'a, 'i>)>) {
    let tag = el.tag_name().name();
    let once = READ_ONCE.iter().find(|(parent, _)| *parent == tag).map_or(&[][..], |(_, tags)| *tags);
    let mut first_of: Vec<roxmltree::Node<'a, 'i>> = Vec::new();
    for child in el.children().filter(|n| n.is_element()) {
        let child_tag = child.tag_name().name();
        let repeated_tag = once.contains(&child_tag);
        let first = if tag == "geometry" { first_of.first().copied() } else { first_of.iter().copied().find(|f| f.tag_name().name() == child_tag) };
        match first {
            Some(first) if repeated_tag || tag == "geometry" => ignored.push((first, child)),
            _ => {
                first_of.push(child);
                collect(child, ignored);
            }
        }
    }
}

/// Where an element sits, for a warning: `joint 'elbow'`, `<inertial> of link 'forearm'`,
/// `material 'grey'` (a material of the robot).
fn owner(el: &roxmltree::Node<'_, '_>) -> String {
    let mut path = Vec::new();
    let mut at = el.parent_element();
    while let Some(p) = at {
        let tag = p.tag_name().name();
        let robot_level = p.parent_element().is_some_and(|r| r.parent_element().is_none());
        if matches!(tag, "link" | "joint") || (robot_level && tag == "material") {
            path.push(p.attribute("name").map_or_else(|| format!("<{tag}>"), |n| format!("{tag} '{n}'")));
            break;
        }
        path.push(format!("<{tag}>"));
        at = p.parent_element().filter(|r| r.parent_element().is_some());
    }
    path.join(" of ")
}
