//! The corrected URDF: the input text with the corrected links' `<inertial>` and the joints'
//! `<dynamics>` rewritten in place (by byte spans found with roxmltree), every other byte kept.

use nalgebra::{Matrix3, Vector3};
use simgap_core::{Model, SpatialInertia, Transform, UrdfOptions};

use super::effects::{joint_indices, Corrections};
use super::sidecar::{Format, Sidecar};
use super::{ExportError, ExportedFile};
use crate::EffectReport;
use simgap_sim::EffectKind;

/// The URDF `urdf_text` (read from `source_name`, named in errors) with the selected effects
/// written in, and its sidecar.
///
/// - `inertial_error` and `payload`: the `<inertial>` (mass [kg], origin = centre of mass [m]
///   and inertia about it [kg·m²], in the link's own frame) of every link whose body changes.
///   simgap's model merges links hanging by fixed joints into their parent's body; the
///   correction of a body is written into the link its movable joint moves (the one the report
///   names), so that loading the file merges back to exactly the corrected body. A payload is a
///   point mass on that link of the last joint.
/// - `viscous_friction`, `coulomb_friction`: `<dynamics damping="b" friction="fc"/>` of each
///   joint they act on [N·m·s/rad, N·m; prismatic N·s/m, N], replacing the joint's
///   `<dynamics>` (simgap's model ignores the URDF's `<dynamics>`: the diagnosed friction is
///   the whole friction).
/// - everything else goes to the sidecar (rotor inertia, torque gain, saturation, delay, …).
///
/// Names, visuals, collisions, comments and formatting outside the rewritten elements are kept
/// byte for byte. `model` must be the model loaded from this URDF (any tip on the same chain);
/// the result is checked by loading it again: its bodies equal the corrected model's.
///
/// # Errors
/// [`ExportError::Urdf`] when the text is not well-formed or is not the URDF `model` was
/// loaded from; [`ExportError::Effect`] for an effect that names an unknown joint or has a
/// parameter of the wrong shape, or a correction the link cannot hold (it would remove more
/// mass or inertia than the link has, the rest of its body being links merged by fixed
/// joints).
pub fn export_urdf(urdf_text: &str, source_name: &str, model: &Model, effects: &[EffectReport]) -> Result<ExportedFile, ExportError> {
    let urdf_err = |element: &str, message: String| ExportError::Urdf { source_name: source_name.into(), element: element.into(), message };

    // the input: well-formed, and the URDF the model came from
    let doc = roxmltree::Document::parse(urdf_text).map_err(|e| urdf_err("document", format!("not well-formed XML: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(urdf_err(&format!("<{}>", root.tag_name().name()), "root element; expected <robot>".into()));
    }
    let tip = model.joints().last().map(|j| j.link.clone());
    let nominal = Model::from_urdf_str_with(urdf_text, source_name, &UrdfOptions { tip: tip.clone() })
        .map_err(|e| urdf_err("robot", format!("does not load as the chain of the model diagnosed ({e}): not the URDF the model was loaded from")))?;
    check_same_chain(&nominal, model).map_err(|m| urdf_err("robot", m))?;

    // the corrections, and the edits that write them
    let corrections = Corrections::read(model, effects)?;
    let mut sidecar = Sidecar::new("urdf");
    let mut edits: Vec<Edit> = Vec::new();
    let link_el = |name: &str| root.children().find(|n| n.has_tag_name("link") && n.attribute("name") == Some(name));
    let joint_el = |name: &str| root.children().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(name));

    // inertials: each changed body's correction goes into its link
    for (i, joint) in model.joints().iter().enumerate() {
        if !corrections.changed[i] {
            continue;
        }
        let el = link_el(&joint.link).ok_or_else(|| urdf_err(&format!("link '{}'", joint.link), "not found; expected the link of joint's child".into()))?;
        let (old, rpy) = read_inertial(&el).map_err(|m| urdf_err(&format!("<inertial> of link '{}'", joint.link), m))?;
        let delta = difference(corrections.body(i), &joint.inertia);
        let new = add(&old, &delta);
        check_link(&new).map_err(|m| ExportError::Effect {
            effect: EffectKind::InertialError.to_string(),
            message: format!(
                "the corrected body of joint '{}' cannot be written into link '{}': {m} (the rest of the body is links merged by fixed joints, which keep their inertials)",
                joint.name, joint.link
            ),
        })?;
        edits.push(inertial_edit(urdf_text, &el, &new, rpy));
    }

    // dynamics: viscous and Coulomb friction
    let names = model.joint_names();
    for i in 0..model.dof() {
        let el = joint_el(names[i]).ok_or_else(|| urdf_err(&format!("joint '{}'", names[i]), "not found".into()))?;
        let dynamics = el.children().find(|n| n.has_tag_name("dynamics"));
        if corrections.viscous[i] == 0.0 && corrections.coulomb[i] == 0.0 {
            if let Some(d) = dynamics {
                let nonzero = ["damping", "friction"].iter().filter(|a| d.attribute(**a).and_then(|v| v.trim().parse::<f64>().ok()).is_some_and(|v| v != 0.0)).count();
                if nonzero > 0 {
                    sidecar
                        .notes
                        .push(format!("joint '{}' keeps its URDF <dynamics>, which simgap's model does not use: the file's joint friction there is not simgap's (none)", names[i]));
                }
            }
            continue;
        }
        let text = format!("<dynamics damping=\"{}\" friction=\"{}\"/>", num(corrections.viscous[i]), num(corrections.coulomb[i]));
        if let Some(d) = dynamics {
            let replaced: Vec<String> = ["damping", "friction"].iter().filter_map(|a| d.attribute(*a).map(|v| format!("{a}=\"{v}\""))).collect();
            if !replaced.is_empty() {
                sidecar.notes.push(format!("joint '{}': the URDF's <dynamics {}> is replaced by simgap's friction", names[i], replaced.join(" ")));
            }
            edits.push(Edit { range: d.range(), text });
        } else {
            edits.push(insert_child(urdf_text, &el, &text));
        }
    }

    // the sidecar: what the file holds and what it does not
    for e in effects {
        let links = || -> Result<String, ExportError> {
            let idx = if e.effect == EffectKind::Payload { vec![model.dof() - 1] } else { joint_indices(model, e)? };
            Ok(idx.iter().map(|&j| format!("'{}'", model.joints()[j].link)).collect::<Vec<_>>().join(", "))
        };
        match e.effect {
            EffectKind::InertialError | EffectKind::Payload => sidecar.hold(e, format!("<inertial> of link {}", links()?), ""),
            EffectKind::ViscousFriction => sidecar.hold(e, "<dynamics damping> of the joints", ""),
            EffectKind::CoulombFriction => sidecar.hold(
                e,
                "<dynamics friction> of the joints",
                "URDF friction is a constant dry friction whose law the simulator chooses; simgap simulated −fc·tanh(q̇/w) (w in the parameters, or 0.01 rad/s where the report gives none)",
            ),
            _ => sidecar.defer(e, Format::Urdf),
        }
    }

    let text = apply(urdf_text, edits);
    // the result loads and reproduces the corrected bodies
    let exported = Model::from_urdf_str_with(&text, source_name, &UrdfOptions { tip }).map_err(|e| urdf_err("exported URDF", format!("does not load: {e}")))?;
    for (k, j) in exported.joints().iter().enumerate() {
        if !same_inertia(&j.inertia, corrections.body(k)) {
            return Err(urdf_err(&format!("link '{}'", j.link), "the exported URDF does not reproduce the corrected body; this is a bug of the exporter".into()));
        }
    }
    Ok(ExportedFile { text, sidecar })
}

/// A replacement of the bytes `range` by `text`.
struct Edit {
    range: std::ops::Range<usize>,
    text: String,
}

/// Applies non-overlapping edits.
fn apply(text: &str, mut edits: Vec<Edit>) -> String {
    edits.sort_by_key(|e| e.range.start);
    let mut out = String::with_capacity(text.len() + 256);
    let mut at = 0;
    for e in edits {
        out.push_str(&text[at..e.range.start]);
        out.push_str(&e.text);
        at = e.range.end;
    }
    out.push_str(&text[at..]);
    out
}

/// A number as written: the shortest text that reads back to the same `f64`, with an exponent
/// for very small and very large magnitudes (`4.1e-19`, not eighteen zeros).
pub(super) fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if (1e-4..1e15).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The whitespace before the element on its line (its indentation).
fn indent_of(text: &str, node: &roxmltree::Node<'_, '_>) -> String {
    let start = node.range().start;
    let line_start = text[..start].rfind('\n').map_or(0, |k| k + 1);
    let lead = &text[line_start..start];
    if lead.chars().all(char::is_whitespace) {
        lead.to_string()
    } else {
        String::new()
    }
}

/// The indentation of an element's children (of its first child element, else one step of
/// two spaces more than the element).
fn child_indent(text: &str, node: &roxmltree::Node<'_, '_>) -> String {
    node.children().find(|c| c.is_element()).map(|c| indent_of(text, &c)).filter(|s| !s.is_empty()).unwrap_or_else(|| indent_of(text, node) + "  ")
}

/// Inserts `child` (its lines after the first already indented) as the last child of `el`, at
/// `el`'s child indentation; a self-closing element is opened.
fn insert_child(text: &str, el: &roxmltree::Node<'_, '_>, child: &str) -> Edit {
    let range = el.range();
    let inner = child_indent(text, el);
    if let Some(last) = el.children().rfind(|c| c.is_element()) {
        let at = last.range().end;
        return Edit { range: at..at, text: format!("\n{inner}{child}") };
    }
    let outer = indent_of(text, el);
    let body = &text[range.clone()];
    match body.rfind("</") {
        Some(k) => {
            let at = range.start + k;
            Edit { range: at..at, text: format!("\n{inner}{child}\n{outer}") }
        }
        None => {
            // `<link name="x"/>`: reopen it
            let open = body.trim_end_matches('>').trim_end_matches('/').trim_end();
            Edit { range, text: format!("{open}>\n{inner}{child}\n{outer}</{}>", el.tag_name().name()) }
        }
    }
}

/// The inertial element's replacement (or insertion) holding `inertia` (about the link frame
/// origin), written in the inertial frame rotated by `rpy` (the original's, kept).
fn inertial_edit(text: &str, link: &roxmltree::Node<'_, '_>, inertia: &SpatialInertia, rpy: Option<(String, Matrix3<f64>)>) -> Edit {
    let c = inertia.com();
    let ic = inertia.inertia_about_com();
    let (rpy_text, r0) = rpy.unwrap_or_else(|| ("0 0 0".into(), Matrix3::identity()));
    let i = r0.transpose() * ic * r0;
    let existing = link.children().find(|n| n.has_tag_name("inertial"));
    let outer = existing.as_ref().map(|n| indent_of(text, n)).unwrap_or_else(|| child_indent(text, link));
    let inner = existing.as_ref().map(|n| child_indent(text, n)).unwrap_or_else(|| format!("{outer}  "));
    let body = format!(
        "<inertial>\n{inner}<origin xyz=\"{} {} {}\" rpy=\"{rpy_text}\"/>\n{inner}<mass value=\"{}\"/>\n{inner}<inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n{outer}</inertial>",
        num(c.x),
        num(c.y),
        num(c.z),
        num(inertia.mass),
        num(i[(0, 0)]),
        num(0.5 * (i[(0, 1)] + i[(1, 0)])),
        num(0.5 * (i[(0, 2)] + i[(2, 0)])),
        num(i[(1, 1)]),
        num(0.5 * (i[(1, 2)] + i[(2, 1)])),
        num(i[(2, 2)]),
    );
    match existing {
        Some(n) => Edit { range: n.range(), text: body },
        None => insert_child(text, link, &body),
    }
}

/// The link's inertia about its frame origin from its `<inertial>` (zero when it has none),
/// and the inertial frame's `rpy` text and rotation when it states one.
#[allow(clippy::type_complexity)]
fn read_inertial(link: &roxmltree::Node<'_, '_>) -> Result<(SpatialInertia, Option<(String, Matrix3<f64>)>), String> {
    let Some(inertial) = link.children().find(|n| n.has_tag_name("inertial")) else { return Ok((SpatialInertia::ZERO, None)) };
    let numbers = |el: Option<roxmltree::Node<'_, '_>>, attr: &str, count: usize| -> Result<Vec<f64>, String> {
        let Some(v) = el.and_then(|e| e.attribute(attr)) else { return Ok(vec![0.0; count]) };
        let parts: Result<Vec<f64>, _> = v.split_whitespace().map(str::parse::<f64>).collect();
        match parts {
            Ok(p) if p.len() == count && p.iter().all(|x| x.is_finite()) => Ok(p),
            _ => Err(format!("{attr}=\"{v}\"; expected {count} finite number(s)")),
        }
    };
    let child = |tag: &str| inertial.children().find(|n| n.has_tag_name(tag));
    let origin = child("origin");
    let xyz = numbers(origin, "xyz", 3)?;
    let rpy = numbers(origin, "rpy", 3)?;
    let mass = numbers(child("mass"), "value", 1)?[0];
    let it = child("inertia");
    let get = |a: &str| numbers(it, a, 1).map(|v| v[0]);
    let (ixx, ixy, ixz, iyy, iyz, izz) = (get("ixx")?, get("ixy")?, get("ixz")?, get("iyy")?, get("iyz")?, get("izz")?);
    let frame = Transform::from_xyz_rpy([xyz[0], xyz[1], xyz[2]], [rpy[0], rpy[1], rpy[2]]);
    let ic = Matrix3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
    let inertia = SpatialInertia::from_com(mass, frame.translation, frame.rotation * ic * frame.rotation.transpose());
    let rpy_text = origin.and_then(|o| o.attribute("rpy")).map(|s| s.trim().to_string());
    Ok((inertia, rpy_text.map(|t| (t, frame.rotation))))
}

fn add(a: &SpatialInertia, b: &SpatialInertia) -> SpatialInertia {
    SpatialInertia { mass: a.mass + b.mass, first_moment: a.first_moment + b.first_moment, rotational: a.rotational + b.rotational }
}

fn difference(a: &SpatialInertia, b: &SpatialInertia) -> SpatialInertia {
    SpatialInertia { mass: a.mass - b.mass, first_moment: a.first_moment - b.first_moment, rotational: a.rotational - b.rotational }
}

/// A link a URDF can hold: mass > 0 and an inertia about the centre of mass that is positive
/// semi-definite and obeys the triangle inequality.
fn check_link(i: &SpatialInertia) -> Result<(), String> {
    if !(i.mass > 0.0) {
        return Err(format!("its mass would be {} kg; expected > 0", i.mass));
    }
    let ic = i.inertia_about_com();
    let scale = ic.abs().max().max(1e-300);
    let tol = 1e-9 * scale;
    let e = ic.symmetric_eigenvalues();
    let mut l = [e[0], e[1], e[2]];
    l.sort_by(f64::total_cmp);
    if l[0] < -tol {
        return Err(format!("its principal moments would be {:.6e}, {:.6e}, {:.6e} kg·m²; expected all >= 0", l[0], l[1], l[2]));
    }
    if l[0] + l[1] < l[2] - tol {
        return Err(format!("its principal moments would be {:.6e}, {:.6e}, {:.6e} kg·m², breaking the triangle inequality", l[0], l[1], l[2]));
    }
    Ok(())
}

/// Equal to 1e-9 of the larger value (mass, first moment, rotational inertia).
pub(super) fn same_inertia(a: &SpatialInertia, b: &SpatialInertia) -> bool {
    let scale = |x: f64, y: f64| 1e-9 * x.abs().max(y.abs()).max(1e-12);
    let v = |x: &Vector3<f64>, y: &Vector3<f64>| (x - y).amax() <= scale(x.amax(), y.amax());
    let m = |x: &Matrix3<f64>, y: &Matrix3<f64>| (x - y).amax() <= scale(x.amax(), y.amax());
    (a.mass - b.mass).abs() <= scale(a.mass, b.mass) && v(&a.first_moment, &b.first_moment) && m(&a.rotational, &b.rotational)
}

/// Whether the URDF's chain is the model's: the same joints (names, kinds) moving the same
/// links, with the same bodies.
fn check_same_chain(urdf: &Model, model: &Model) -> Result<(), String> {
    if urdf.joint_names() != model.joint_names() {
        return Err(format!("its chain has joints {:?}; the model diagnosed has {:?}: not the URDF the model was loaded from", urdf.joint_names(), model.joint_names()));
    }
    for (a, b) in urdf.joints().iter().zip(model.joints()) {
        if a.link != b.link || a.kind != b.kind || !same_inertia(&a.inertia, &b.inertia) {
            return Err(format!("joint '{}' (link '{}') differs from the model diagnosed: not the URDF the model was loaded from", a.name, a.link));
        }
    }
    Ok(())
}
