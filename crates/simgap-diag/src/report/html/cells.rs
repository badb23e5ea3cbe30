//! The report's table cells: numbers with their units, parameters with their 95 % intervals,
//! the inertial correction per link ([`inertial_cell`]), and HTML escaping ([`esc`]).

use std::fmt::Write as _;

use crate::vocabulary::effects::Param;
use simgap_core::Model;

/// A number with its unit (no unit for `-`).
fn with_unit(v: &str, unit: Option<&str>) -> String {
    match unit {
        Some(u) if !u.is_empty() && u != "-" => format!("{v} {u}"),
        _ => v.to_string(),
    }
}

/// Is any value of an uncertainty finite?
fn any_finite(p: &Param) -> bool {
    match p {
        Param::Number(x) => x.is_finite(),
        Param::PerJoint(v) | Param::Vector(v) => v.iter().any(|x| x.is_finite()),
        Param::PerLink(v) => v.iter().flatten().any(|x| x.is_finite()),
    }
}

/// Parameters as `name = value ± u unit`, one per line; units from `units` or the vocabulary.
pub(super) fn params_cell(
    params: &std::collections::BTreeMap<String, Param>,
    unc: Option<&std::collections::BTreeMap<String, Param>>,
    units: Option<&std::collections::BTreeMap<String, String>>,
) -> String {
    params
        .iter()
        .map(|(k, v)| {
            let unit = units.and_then(|u| u.get(k)).map(String::as_str).unwrap_or("-");
            let value = match unc.and_then(|u| u.get(k)).filter(|u| any_finite(u)) {
                Some(u) => format!("{} ± {}", fmt_param(v), fmt_param(u)),
                None => fmt_param(v),
            };
            format!("{} = {}", esc(k), esc(&with_unit(&value, Some(unit))))
        })
        .collect::<Vec<_>>()
        .join("<br>")
}

/// The inertial correction per link by name: mass, centre of mass and inertia about it, as
/// percentages of the URDF values when the model is known.
pub(super) fn inertial_cell(joints: &[String], parameters: &std::collections::BTreeMap<String, Param>, model: Option<&Model>) -> String {
    let per_joint = |k: &str| match parameters.get(k) {
        Some(Param::PerJoint(v)) => v.clone(),
        _ => vec![],
    };
    let per_link = |k: &str| match parameters.get(k) {
        Some(Param::PerLink(v)) => v.clone(),
        _ => vec![],
    };
    let (dm, dc, di) = (per_joint("delta_mass"), per_link("delta_com"), per_link("delta_inertia"));
    let mut rows = String::from(
        "<table class=\"inertial\"><tr><th>link</th><th>mass</th><th>centre of mass moved [mm]</th><th>inertia about the centre of mass (xx, yy, zz; xy, xz, yz)</th></tr>",
    );
    for (i, joint) in joints.iter().enumerate() {
        let urdf = model.and_then(|m| m.joints().iter().find(|j| &j.name == joint));
        let link = urdf.map_or_else(|| format!("link of joint {joint}"), |j| j.link.clone());
        let m = dm.get(i).copied().unwrap_or(f64::NAN);
        let mass = match urdf {
            Some(j) if j.inertia.mass > 0.0 => format!("{:.4} → {:.4} kg ({:+.1} %)", j.inertia.mass, j.inertia.mass + m, 100.0 * m / j.inertia.mass),
            _ => format!("{m:+.4} kg"),
        };
        let c = dc.get(i).cloned().unwrap_or_default();
        let com = if c.len() == 3 { format!("({:+.1}, {:+.1}, {:+.1})", 1e3 * c[0], 1e3 * c[1], 1e3 * c[2]) } else { "–".into() };
        // delta_inertia is [xx, xy, xz, yy, yz, zz] about the centre of mass
        let d = di.get(i).cloned().unwrap_or_default();
        let inertia = if d.len() == 6 {
            let (dd, off) = ([d[0], d[3], d[5]], [d[1], d[2], d[4]]);
            match urdf {
                Some(j) if j.inertia.mass > 0.0 => {
                    let ic = j.inertia.inertia_about_com();
                    let diag = [ic[(0, 0)], ic[(1, 1)], ic[(2, 2)]];
                    let scale = (diag[0] + diag[1] + diag[2]) / 3.0;
                    let rel = |x: f64, of: f64| if of.abs() > 1e-12 { format!("{:+.0} %", 100.0 * x / of) } else { format!("{x:+.2e} kg·m²") };
                    format!(
                        "{}, {}, {}; {}, {}, {} <small>(off-diagonal: % of the mean principal moment)</small>",
                        rel(dd[0], diag[0]),
                        rel(dd[1], diag[1]),
                        rel(dd[2], diag[2]),
                        rel(off[0], scale),
                        rel(off[1], scale),
                        rel(off[2], scale)
                    )
                }
                _ => format!("{:+.2e}, {:+.2e}, {:+.2e}; {:+.2e}, {:+.2e}, {:+.2e} kg·m²", dd[0], dd[1], dd[2], off[0], off[1], off[2]),
            }
        } else {
            "–".into()
        };
        let _ = write!(
            rows,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&link),
            esc(&mass),
            esc(&com),
            esc(&inertia).replace("&lt;small&gt;", "<small>").replace("&lt;/small&gt;", "</small>")
        );
    }
    rows.push_str("</table>");
    if let Some(Param::Number(n)) = parameters.get("identifiable_directions") {
        let _ = write!(rows, "<small>{n} identifiable directions of the inertial parameters</small>");
    }
    rows
}

/// HTML-escapes text.
pub fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

pub(super) fn num(x: f64) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{x:.4e}</td>")
    } else {
        format!("<td class=\"n\">{}</td>", if x.is_nan() { "–" } else { "∞ (diverged)" })
    }
}

/// A number cell with its unit.
pub(super) fn num_in(x: f64, unit: &str) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{x:.4e} {}</td>", esc(unit))
    } else {
        num(x)
    }
}

pub(super) fn fixed(x: f64, digits: usize) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{x:.digits$}</td>")
    } else {
        "<td class=\"n\">–</td>".into()
    }
}

pub(super) fn pct(x: f64) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{:.1} %</td>", 100.0 * x)
    } else {
        "<td class=\"n\">–</td>".into()
    }
}

fn fmt_param(p: &Param) -> String {
    let one = |x: &f64| if x.is_finite() { format!("{x:.4}") } else { "–".to_string() };
    let list = |v: &[f64]| v.iter().map(one).collect::<Vec<_>>().join(", ");
    match p {
        Param::Number(x) => one(x),
        Param::PerJoint(v) | Param::Vector(v) => format!("[{}]", list(v)),
        Param::PerLink(v) => v.iter().map(|l| format!("[{}]", list(l))).collect::<Vec<_>>().join(" "),
    }
}
