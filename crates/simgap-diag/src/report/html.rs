//! A self-contained HTML report: the verdict, the tables of the [`Report`] and inline SVG plots
//! (measured, nominal and corrected trajectories of every held-out run, torque residual
//! against q̇, held-out shrink per candidate). No script, no external file.

use std::fmt::Write as _;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use simgap_sim::Run;

use crate::error::{Error, Result};
use crate::report::units::{kinds_of, Units};
use crate::report::verdict::ranked_selection;
pub use crate::report::verdict::{assess, Assessment};
use crate::report::Diagnosis;
use crate::report::Report;
use crate::vocabulary::effects::Param;
use simgap_core::Model;

/// Most points drawn per series (longer series are decimated evenly).
const MAX_POINTS: usize = 1500;

/// Writes the HTML report of `diagnosis` to `path` (one file, plots inline as SVG).
///
/// Without the model, inertial corrections are shown as absolute changes; [`write_html_for`]
/// shows them as percentages of the URDF values.
///
/// # Errors
/// [`Error::Write`] when a plot cannot be drawn or the file cannot be written.
pub fn write_html(diagnosis: &Diagnosis, path: &Path) -> Result<()> {
    write_html_for(diagnosis, None, path)
}

/// Writes the HTML report of `diagnosis` of `model` to `path`.
///
/// # Errors
/// [`Error::Write`] when a plot cannot be drawn or the file cannot be written.
pub fn write_html_for(diagnosis: &Diagnosis, model: Option<&Model>, path: &Path) -> Result<()> {
    write_html_linking(diagnosis, model, path, &[])
}

/// A file written beside the report (an exported model, its sidecar), linked from the page.
#[derive(Clone, Debug)]
pub struct LinkedFile {
    /// What it is, e.g. "corrected URDF (Pinocchio, Gazebo, Isaac)".
    pub what: String,
    /// Its address from the page: a relative path, or an absolute one.
    pub href: String,
}

/// Writes the HTML report of `diagnosis` of `model` to `path`, linking `files` (the corrected
/// model exported beside it).
///
/// # Errors
/// [`Error::Write`] when a plot cannot be drawn or the file cannot be written.
pub fn write_html_linking(diagnosis: &Diagnosis, model: Option<&Model>, path: &Path, files: &[LinkedFile]) -> Result<()> {
    let html = render_html_linking(diagnosis, model, files).map_err(|message| Error::Write { path: path.display().to_string(), message })?;
    std::fs::write(path, html).map_err(|e| Error::Write { path: path.display().to_string(), message: e.to_string() })
}

/// The HTML report of `diagnosis` as a string.
///
/// # Errors
/// A message when a plot cannot be drawn.
pub fn render_html(d: &Diagnosis) -> std::result::Result<String, String> {
    render_html_for(d, None)
}

/// The HTML report of `diagnosis` of `model` as a string.
///
/// # Errors
/// A message when a plot cannot be drawn.
pub fn render_html_for(d: &Diagnosis, model: Option<&Model>) -> std::result::Result<String, String> {
    render_html_linking(d, model, &[])
}

/// The HTML report of `diagnosis` of `model` as a string, linking `files`.
///
/// # Errors
/// A message when a plot cannot be drawn.
pub fn render_html_linking(d: &Diagnosis, model: Option<&Model>, files: &[LinkedFile]) -> std::result::Result<String, String> {
    let r = &d.report;
    let mut h = String::new();
    let _ = write!(h, "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>simgap diagnosis: {}</title>\n<style>{}</style></head><body>\n", esc(&r.model), CSS);
    let _ = writeln!(h, "<h1>simgap diagnosis of <code>{}</code></h1>", esc(&r.model));
    let _ = writeln!(
        h,
        "<p class=\"meta\">simgap {} · C formulation: {} · joints: {} · fit logs: {} · held-out logs: {}</p>",
        esc(&r.simgap_version),
        esc(&r.formulation),
        esc(&r.joints.join(", ")),
        esc(&r.fit_logs.join(", ")),
        esc(&r.holdout_logs.join(", "))
    );
    let a = assess(r);
    let _ = writeln!(h, "<p class=\"verdict {}\" id=\"verdict\">{}</p>", a.class, esc(&a.text));
    // units by joint type: pooled figures, and each joint's own
    let kinds = kinds_of(&r.joint_types);
    let all = Units::of(&kinds);
    let joint_units = |j: usize| kinds.get(j).map_or_else(|| Units::of(&kinds), |k| Units::joint(*k));
    let units_of_name = |name: &str| r.joints.iter().position(|n| n == name).map_or_else(|| Units::of(&kinds), joint_units);
    if !r.notes.is_empty() {
        let _ = writeln!(h, "<ul class=\"notes\" id=\"notes\">");
        for n in &r.notes {
            let _ = writeln!(h, "<li>{}</li>", esc(n));
        }
        let _ = writeln!(h, "</ul>");
    }

    // how far: the headline figure first
    let kstep = &r.gap.kstep;
    let has_kstep = !kstep.horizons_s.is_empty();
    let headline_kstep = has_kstep && r.gap.headline == "k_step";
    let kstep_section = |h: &mut String| -> std::result::Result<(), String> {
        let _ = writeln!(h, "<h2 id=\"kstep\">How far: k-step prediction of held-out runs{}</h2>", if headline_kstep { " (headline)" } else { "" });
        let _ = writeln!(
            h,
            "<p class=\"meta\">Windows of each held-out run restart the model from the measured state and predict h seconds ahead; RMS position error at the window ends. Constant-velocity extrapolation is the floor a physical model must beat.</p>"
        );
        let _ = writeln!(
            h,
            "<table class=\"kstep\"><tr><th>horizon h [s]</th><th>constant velocity [{u}]</th><th>nominal [{u}]</th><th>selected effects [{u}]</th><th>after / before</th></tr>",
            u = all.position
        );
        for (i, hz) in kstep.horizons_s.iter().enumerate() {
            let get = |v: &Vec<f64>| v.get(i).copied().unwrap_or(f64::NAN);
            let (f, b, a) = (get(&kstep.floor), get(&kstep.before), get(&kstep.after));
            let _ = writeln!(h, "<tr><td>{hz}</td>{}{}{}{}</tr>", num(f), num(b), num(a), fixed(a / b, 3));
        }
        let _ = writeln!(h, "</table>");
        let _ = writeln!(h, "<figure class=\"kstep\">{}</figure>", kstep_svg(kstep, &all.position)?);
        Ok(())
    };
    if headline_kstep {
        kstep_section(&mut h)?;
    }
    let _ = writeln!(h, "<h2 id=\"closed-loop\">How far: held-out runs, closed loop (L², eq. 127){}</h2>", if r.gap.headline == "closed_loop" { " (headline)" } else { "" });
    if !r.gap.headline_reason.is_empty() {
        let _ = writeln!(h, "<p class=\"meta\">{}</p>", esc(&r.gap.headline_reason));
    }
    let _ = writeln!(h, "<table><tr><th></th><th>before [{u}]</th><th>after [{u}]</th><th>after / before</th></tr>", u = all.position);
    let _ = writeln!(h, "<tr><td>all held-out runs</td>{}{}{}</tr>", num(r.gap.holdout_l2_before), num(r.gap.holdout_l2_after), fixed(r.gap.ratio, 3));
    for (j, name) in r.joints.iter().enumerate() {
        let (b, a) = (r.gap.per_joint_before.get(j).copied().unwrap_or(f64::NAN), r.gap.per_joint_after.get(j).copied().unwrap_or(f64::NAN));
        let _ = writeln!(h, "<tr><td>joint {}</td>{}{}{}</tr>", esc(name), num(b), num(a), fixed(a / b, 3));
    }
    for (b, a) in r.gap.runs_before.iter().zip(&r.gap.runs_after) {
        let _ = writeln!(h, "<tr><td>run {} <small>({} → {})</small></td>{}{}{}</tr>", esc(&b.log), esc(&b.status), esc(&a.status), num(b.l2), num(a.l2), fixed(a.l2 / b.l2, 3));
    }
    let _ = writeln!(
        h,
        "<tr><td>fit runs (for reference)</td>{}{}{}</tr></table>",
        num(r.gap.fit_l2_before),
        num(r.gap.fit_l2_after),
        fixed(r.gap.fit_l2_after / r.gap.fit_l2_before, 3)
    );
    if has_kstep && !headline_kstep {
        kstep_section(&mut h)?;
    }

    // selected, ranked as the candidates are
    let _ = writeln!(h, "<h2 id=\"selected\">Selected effects</h2>");
    if r.selected_effects.is_empty() {
        let _ = writeln!(h, "<p>None: nothing significant remains, or the logs cannot tell.</p>");
    } else {
        let _ = writeln!(h, "<table class=\"selected\"><tr><th>effect</th><th>joints</th><th>parameters (± 95 %)</th></tr>");
        for e in &ranked_selection(r) {
            let cell = if e.effect == "inertial_error" { inertial_cell(&e.joints, &e.parameters, model) } else { params_cell(&e.parameters, Some(&e.uncertainty), Some(&e.units)) };
            let description = if e.description.is_empty() { String::new() } else { format!("<br><small>{}</small>", esc(&e.description)) };
            let _ = writeln!(h, "<tr><td><code>{}</code>{description}</td><td>{}</td><td>{cell}</td></tr>", esc(&e.effect), esc(&e.joints.join(", ")));
        }
        let _ = writeln!(h, "</table>");
    }
    if !r.alternatives.is_empty() {
        let _ = writeln!(h, "<h3 id=\"alternatives\">Alternatives these data cannot tell apart</h3><table class=\"alternatives\"><tr><th>effects</th><th>why</th></tr>");
        for alt in &r.alternatives {
            let _ = writeln!(h, "<tr><td><code>{}</code></td><td>{}</td></tr>", esc(&alt.effects.join(" + ")), esc(&alt.why));
        }
        let _ = writeln!(h, "</table>");
    }

    if !files.is_empty() {
        let _ = writeln!(h, "<h3 id=\"exported\">The corrected model, exported</h3><ul class=\"exported\">");
        for f in files {
            let _ = writeln!(h, "<li><a href=\"{}\">{}</a>: {}</li>", esc(&f.href), esc(&f.href), esc(&f.what));
        }
        let _ = writeln!(h, "</ul>");
    }

    // held-out trajectories with their error panels
    let _ = writeln!(h, "<h2 id=\"trajectories\">Held-out runs: measured, nominal and corrected simulation</h2>");
    let _ = writeln!(h, "<p class=\"meta\">Top: joint position; bottom: |q_measured − q_simulated| on a log axis, where the corrected simulation's success shows even when it lies on the measured curve.</p>");
    for (i, measured) in d.holdout.iter().enumerate() {
        let nominal = d.holdout_nominal.get(i).and_then(Option::as_ref);
        let corrected = d.holdout_corrected.get(i).and_then(Option::as_ref);
        let _ = writeln!(h, "<h3>{}</h3>", esc(&measured.source));
        for j in 0..measured.dof() {
            let svg = trajectory_svg(measured, nominal, corrected, j, !r.selected_effects.is_empty(), &joint_units(j).position)?;
            let _ = writeln!(h, "<figure class=\"trajectory\">{svg}</figure>");
        }
    }

    // where
    let _ = writeln!(h, "<h2 id=\"where\">Where: per joint (fit runs, nominal model)</h2>");
    let _ = writeln!(h, "<table><tr><th>joint</th><th>sim L²</th><th>share</th><th>torque residual L²</th></tr>");
    for j in &r.location.per_joint {
        let u = units_of_name(&j.joint);
        let _ = writeln!(h, "<tr><td>{}</td>{}{}{}</tr>", esc(&j.joint), num_in(j.sim_l2, &u.position), pct(j.share), num_in(j.torque_residual_l2, &u.effort));
    }
    let _ = writeln!(h, "</table>");
    if !r.location.worst_segments.is_empty() {
        let _ = writeln!(
            h,
            "<h3>Worst time segments</h3><table><tr><th>log</th><th>t since the log's start [s]</th><th>joint</th><th>phase</th><th>RMS error [{}]</th></tr>",
            all.position
        );
        for s in &r.location.worst_segments {
            let t0 = log_start(d, &s.log);
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{:.3}–{:.3}</td><td>{}</td><td>{}</td>{}</tr>",
                esc(&s.log),
                s.start - t0,
                s.end - t0,
                esc(&s.joint),
                esc(&s.phase),
                num(s.rms_error)
            );
        }
        let _ = writeln!(h, "</table>");
    }
    if !r.location.correlations.is_empty() {
        let keys: Vec<&String> = r.location.correlations.values().next().map(|m| m.keys().collect()).unwrap_or_default();
        let _ = write!(h, "<h3>Correlation of the torque residual with</h3><table><tr><th>joint</th>");
        for k in &keys {
            let _ = write!(h, "<th>{}</th>", esc(k));
        }
        let _ = writeln!(h, "</tr>");
        // joints in model order
        for joint in &r.joints {
            let Some(m) = r.location.correlations.get(joint) else { continue };
            let _ = write!(h, "<tr><td>{}</td>", esc(joint));
            for k in &keys {
                let _ = write!(h, "{}", fixed(m.get(*k).copied().unwrap_or(f64::NAN), 2));
            }
            let _ = writeln!(h, "</tr>");
        }
        let _ = writeln!(h, "</table>");
    }
    let _ = writeln!(h, "<h3>Torque residual against q̇ (fit runs)</h3>");
    for j in 0..r.joints.len() {
        let svg = residual_svg(d, j)?;
        let _ = writeln!(h, "<figure class=\"residual\">{svg}</figure>");
    }

    // which
    let _ = writeln!(h, "<h2 id=\"which\">Which: every candidate, fitted alone</h2>");
    let _ = writeln!(h, "<figure class=\"candidates\">{}</figure>", shrink_svg(r)?);
    let kstep_col = has_kstep && r.candidates.iter().any(|c| !c.holdout_kstep_after.is_empty());
    let last_h = kstep.horizons_s.last().copied().unwrap_or(f64::NAN);
    let _ = writeln!(
        h,
        "<table class=\"candidates\"><tr><th>rank</th><th>effect</th><th>joints</th><th>parameters</th><th>CV residual removed</th><th>held-out L² after [{u}]</th><th>after / before</th>{}<th>selected</th><th>reason</th></tr>",
        if kstep_col { format!("<th>{last_h} s prediction after / before</th>") } else { String::new() },
        u = all.position
    );
    for c in &r.candidates {
        let kcell = if kstep_col {
            let a = c.holdout_kstep_after.last().copied().unwrap_or(f64::NAN);
            fixed(a / kstep.before.last().copied().unwrap_or(f64::NAN), 3)
        } else {
            String::new()
        };
        let _ = writeln!(
            h,
            "<tr{}><td>{}</td><td><code>{}</code></td><td>{}</td><td>{}</td>{}{}{}{kcell}<td>{}</td><td>{}</td></tr>",
            if c.selected { " class=\"sel\"" } else { "" },
            c.rank,
            esc(&c.effect),
            esc(&c.joints.join(", ")),
            if c.effect == "inertial_error" { inertial_cell(&c.joints, &c.parameters, model) } else { params_cell(&c.parameters, Some(&c.uncertainty), Some(&c.units)) },
            pct(c.cv_residual_reduction),
            num(c.holdout_l2_after),
            fixed(c.holdout_ratio, 3),
            if c.selected { "yes" } else { "" },
            esc(&c.reason)
        );
    }
    let _ = writeln!(h, "</table>");
    if !r.selection_log.is_empty() {
        let _ = writeln!(h, "<h3>Stepwise selection</h3><table><tr><th>effect</th><th>joint</th><th>CV MSE</th><th>entered</th><th>reason</th></tr>");
        for s in &r.selection_log {
            let _ = writeln!(
                h,
                "<tr><td><code>{}</code></td><td>{}</td>{}<td>{}</td><td>{}</td></tr>",
                esc(&s.effect),
                esc(s.joint.as_deref().unwrap_or("")),
                num(s.cv_mse),
                if s.accepted { "yes" } else { "no" },
                esc(&s.reason)
            );
        }
        let _ = writeln!(h, "</table>");
    }
    if !r.verdict.is_empty() {
        let _ = writeln!(h, "<p class=\"meta\">The diagnosis's own summary: {}</p>", esc(&r.verdict));
    }
    let _ = writeln!(h, "<p class=\"meta\">Held-out runs are never used for fitting or selection. Nominal cross-validated torque MSE: {:.4e}.</p>", r.nominal_cv_mse);
    h.push_str("</body></html>\n");
    Ok(h)
}

/// The first time stamp of the log named `log` (fit or held-out), 0 when unknown.
fn log_start(d: &Diagnosis, log: &str) -> f64 {
    d.fit_data.iter().map(|f| &f.raw).chain(&d.holdout).find(|r| r.source == log).and_then(|r| r.t.first().copied()).unwrap_or(0.0)
}

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
fn params_cell(
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
fn inertial_cell(joints: &[String], parameters: &std::collections::BTreeMap<String, Param>, model: Option<&Model>) -> String {
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

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1150px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:1em 0;font-size:90%}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}\
td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}tr.sel{background:#eef7ee}\
table.inertial{margin:0;font-size:100%}\
.verdict{font-size:120%;padding:.7em;border-left:6px solid #999;background:#f6f6f6}\
.verdict.good{border-color:#2a7;background:#f4faf6}.verdict.warn{border-color:#d90;background:#fff8e6}.verdict.bad{border-color:#c33;background:#fdf0f0}\
ul.notes{background:#fff8e6;border-left:6px solid #d90;padding:.5em 2em}.meta{color:#666;font-size:90%}\
figure{margin:.5em 0}svg{max-width:100%;height:auto}";

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

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{x:.4e}</td>")
    } else {
        format!("<td class=\"n\">{}</td>", if x.is_nan() { "–" } else { "∞ (diverged)" })
    }
}

/// A number cell with its unit.
fn num_in(x: f64, unit: &str) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{x:.4e} {}</td>", esc(unit))
    } else {
        num(x)
    }
}

fn fixed(x: f64, digits: usize) -> String {
    if x.is_finite() {
        format!("<td class=\"n\">{x:.digits$}</td>")
    } else {
        "<td class=\"n\">–</td>".into()
    }
}

fn pct(x: f64) -> String {
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

/// Every `step`-th point so that at most [`MAX_POINTS`] remain.
fn decimate(points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let step = points.len().div_ceil(MAX_POINTS).max(1);
    points.into_iter().step_by(step).filter(|(x, y)| x.is_finite() && y.is_finite()).collect()
}

/// Range of values with a margin (never empty).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.06).max(1e-9 + 1e-6 * hi.abs().max(lo.abs()));
    (lo - pad, hi + pad)
}

fn draw_err<E: std::fmt::Debug>(e: E) -> String {
    format!("cannot draw a plot: {e:?}")
}

/// Renders one SVG plot into a string.
fn svg(size: (u32, u32), draw: impl FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> std::result::Result<(), String>) -> std::result::Result<String, String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        draw(&root)?;
        root.present().map_err(draw_err)?;
    }
    Ok(out)
}

/// Tick labels with as many decimals as a span of `span` needs for about five distinct ticks.
fn decimals(span: f64) -> usize {
    if !(span.is_finite() && span > 0.0) {
        return 3;
    }
    ((-(span / 5.0).log10()).ceil().max(0.0) as usize).clamp(1, 8)
}

/// A label on a log axis: 1e-3, 0.01, 0.1, 1, 10, …
fn log_label(v: f64) -> String {
    if (1e-2..1e3).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// Position of joint `j` (top) and the absolute error of each simulation (bottom, log axis),
/// against the time since the measured run's start; the legend sits outside the plot area.
fn trajectory_svg(measured: &Run, nominal: Option<&Run>, corrected: Option<&Run>, j: usize, has_correction: bool, unit: &str) -> std::result::Result<String, String> {
    let t0 = measured.t.first().copied().unwrap_or(0.0);
    let series = |r: &Run| decimate(r.t.iter().zip(r.column(&r.q, j)).map(|(t, q)| (*t - t0, q)).collect());
    let m = series(measured);
    let n = nominal.map(series).unwrap_or_default();
    let c = if has_correction { corrected.map(series).unwrap_or_default() } else { vec![] };
    let t1 = (measured.t.last().copied().unwrap_or(1.0) - t0).max(1e-9);
    let (lo, hi) = range(m.iter().chain(&n).chain(&c).map(|p| p.1));
    // |q_measured − q_sim| at the measured stamps (the simulations share them)
    let qm = measured.column(&measured.q, j);
    let error = |r: &Run| -> Vec<(f64, f64)> {
        let q = r.column(&r.q, j);
        decimate(r.t.iter().zip(&q).zip(&qm).map(|((t, a), b)| (*t - t0, (a - b).abs().max(1e-12))).collect())
    };
    let en = nominal.map(error).unwrap_or_default();
    let ec = if has_correction { corrected.map(error).unwrap_or_default() } else { vec![] };
    let (emin, emax) = en.iter().chain(&ec).map(|p| p.1).filter(|v| v.is_finite()).fold((f64::INFINITY, 0.0_f64), |(a, b), v| (a.min(v), b.max(v)));
    let (elo, ehi) = if emax > 0.0 { ((emin.max(emax * 1e-7)) / 2.0, emax * 2.0) } else { (1e-6, 1.0) };
    let joint = measured.joints[j].clone();
    let (xd, yd) = (decimals(t1), decimals(hi - lo));
    svg((1050, 470), |root| {
        let (plots, legend) = root.split_horizontally(860);
        let (top, bottom) = plots.split_vertically(270);
        let mut chart = ChartBuilder::on(&top)
            .caption(format!("joint {joint}: position"), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(75)
            .build_cartesian_2d(0.0..t1, lo..hi)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("time since the log's start [s]")
            .y_desc(format!("q [{unit}]"))
            .x_label_formatter(&|v| format!("{v:.xd$}"))
            .y_label_formatter(&|v| format!("{v:.yd$}"))
            .draw()
            .map_err(draw_err)?;
        chart.draw_series(LineSeries::new(m, RGBColor(120, 120, 120).stroke_width(4))).map_err(draw_err)?;
        if !n.is_empty() {
            chart.draw_series(LineSeries::new(n, RED.stroke_width(1))).map_err(draw_err)?;
        }
        if !c.is_empty() {
            chart.draw_series(DashedLineSeries::new(c, 6, 4, BLUE.stroke_width(2))).map_err(draw_err)?;
        }
        let mut err = ChartBuilder::on(&bottom).margin(8).x_label_area_size(38).y_label_area_size(75).build_cartesian_2d(0.0..t1, (elo..ehi).log_scale()).map_err(draw_err)?;
        err.configure_mesh()
            .light_line_style(WHITE)
            .x_desc("time since the log's start [s]")
            .y_desc(format!("|q_meas − q_sim| [{unit}]"))
            .x_label_formatter(&|v| format!("{v:.xd$}"))
            .y_label_formatter(&|v| log_label(*v))
            .y_labels(5)
            .draw()
            .map_err(draw_err)?;
        if !en.is_empty() {
            err.draw_series(LineSeries::new(en, RED.stroke_width(1))).map_err(draw_err)?;
        }
        if !ec.is_empty() {
            err.draw_series(LineSeries::new(ec, BLUE.stroke_width(1))).map_err(draw_err)?;
        }
        // the legend, outside the data
        let items: Vec<(&str, ShapeStyle, bool)> = [
            Some(("measured", RGBColor(120, 120, 120).stroke_width(4), false)),
            nominal.map(|_| ("nominal model", RED.stroke_width(1), false)),
            (has_correction && corrected.is_some()).then(|| ("with selected effects", BLUE.stroke_width(2), true)),
        ]
        .into_iter()
        .flatten()
        .collect();
        for (k, (label, style, dashed)) in items.into_iter().enumerate() {
            let y = 50 + 26 * k as i32;
            if dashed {
                legend.draw(&plotters::element::DashedPathElement::new(vec![(10, y), (45, y)], 6, 4, style)).map_err(draw_err)?;
            } else {
                legend.draw(&PathElement::new(vec![(10, y), (45, y)], style)).map_err(draw_err)?;
            }
            legend.draw(&Text::new(label.to_string(), (52, y - 7), ("sans-serif", 14).into_font())).map_err(draw_err)?;
        }
        Ok(())
    })
}

fn residual_svg(d: &Diagnosis, j: usize) -> std::result::Result<String, String> {
    let kinds = kinds_of(&d.report.joint_types);
    let u = kinds.get(j).map_or_else(|| Units::of(&kinds), |k| Units::joint(*k));
    let mut pts = Vec::new();
    for f in &d.fit_data {
        let n = f.dof;
        for k in 0..f.len() {
            pts.push((f.qd[k * n + j], f.residual[k * n + j]));
        }
    }
    let pts = decimate(pts);
    let (x0, x1) = range(pts.iter().map(|p| p.0));
    let (y0, y1) = range(pts.iter().map(|p| p.1));
    let (xd, yd) = (decimals(x1 - x0), decimals(y1 - y0));
    let title = format!("joint {}: τ_cmd − (H q̈ + C q̇ + g) against q̇", d.report.joints.get(j).map_or("?", String::as_str));
    svg((1000, 320), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(38)
            .y_label_area_size(75)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc(format!("q̇ [{}]", u.velocity))
            .y_desc(format!("residual [{}]", u.effort))
            .x_label_formatter(&|v| format!("{v:.xd$}"))
            .y_label_formatter(&|v| format!("{v:.yd$}"))
            .draw()
            .map_err(draw_err)?;
        chart.draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 2, BLUE.mix(0.4).filled()))).map_err(draw_err)?;
        Ok(())
    })
}

/// The k-step prediction error against the horizon (log axis): constant-velocity floor,
/// nominal, with the selected effects.
fn kstep_svg(k: &crate::report::KStep, unit: &str) -> std::result::Result<String, String> {
    let lines: Vec<(&str, &Vec<f64>, RGBColor)> =
        vec![("constant velocity (floor)", &k.floor, RGBColor(120, 120, 120)), ("nominal model", &k.before, RED), ("with selected effects", &k.after, BLUE)];
    let pts = |v: &Vec<f64>| -> Vec<(f64, f64)> { k.horizons_s.iter().zip(v).filter(|(h, e)| h.is_finite() && e.is_finite() && **e > 0.0).map(|(h, e)| (*h, *e)).collect() };
    let all: Vec<f64> = lines.iter().flat_map(|l| pts(l.1)).map(|p| p.1).collect();
    let (lo, hi) = all.iter().fold((f64::INFINITY, 0.0_f64), |(a, b), v| (a.min(*v), b.max(*v)));
    let (lo, hi) = if hi > 0.0 { (lo / 2.0, hi * 2.0) } else { (1e-6, 1.0) };
    let hmax = k.horizons_s.iter().copied().filter(|h| h.is_finite()).fold(0.0_f64, f64::max).max(1e-3) * 1.1;
    svg((1050, 300), |root| {
        let (plot, legend) = root.split_horizontally(860);
        let mut chart = ChartBuilder::on(&plot)
            .caption("held-out k-step prediction error against the horizon", ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(38)
            .y_label_area_size(75)
            .build_cartesian_2d(0.0..hmax, (lo..hi).log_scale())
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_desc("horizon h [s]")
            .y_desc(format!("RMS position error [{unit}]"))
            .x_label_formatter(&|v| format!("{v:.2}"))
            .y_label_formatter(&|v| log_label(*v))
            .draw()
            .map_err(draw_err)?;
        for (k2, (label, v, color)) in lines.iter().enumerate() {
            let p = pts(v);
            chart.draw_series(LineSeries::new(p.clone(), color.stroke_width(2))).map_err(draw_err)?;
            chart.draw_series(p.iter().map(|&q| Circle::new(q, 4, color.filled()))).map_err(draw_err)?;
            let y = 50 + 26 * k2 as i32;
            legend.draw(&PathElement::new(vec![(10, y), (45, y)], color.stroke_width(2))).map_err(draw_err)?;
            legend.draw(&Text::new(label.to_string(), (52, y - 7), ("sans-serif", 14).into_font())).map_err(draw_err)?;
        }
        Ok(())
    })
}

/// How a candidate fared on the held-out runs, for the chart.
#[derive(Clone, Copy, PartialEq)]
enum Outcome {
    Selected,
    Better,
    Worse,
    Diverged,
    NotSimulated,
}

/// Every candidate's held-out L² after / before on a log axis, as a bar from 1 (no change):
/// left is better, right is worse; diverged and not simulated candidates are drawn apart.
fn shrink_svg(r: &Report) -> std::result::Result<String, String> {
    let rows: Vec<(String, f64, Outcome)> = r
        .candidates
        .iter()
        .map(|c| {
            let ratio = c.holdout_ratio;
            let outcome = if c.holdout_l2_after.is_nan() || (ratio.is_nan() && !c.holdout_l2_after.is_infinite()) {
                Outcome::NotSimulated
            } else if c.holdout_l2_after.is_infinite() || ratio.is_infinite() {
                Outcome::Diverged
            } else if c.selected {
                Outcome::Selected
            } else if ratio > 1.0 {
                Outcome::Worse
            } else {
                Outcome::Better
            };
            let label = if c.joints.is_empty() || c.joints.len() > 3 { c.effect.clone() } else { format!("{} ({})", c.effect, c.joints.join(", ")) };
            (label, ratio, outcome)
        })
        .collect();
    let finite: Vec<f64> = rows.iter().map(|x| x.1).filter(|v| v.is_finite() && *v > 0.0).collect();
    let (mut lo, mut hi) = finite.iter().fold((1.0_f64, 1.0_f64), |(a, b), v| (a.min(*v), b.max(*v)));
    lo /= 1.6;
    hi *= 1.6;
    let n = rows.len().max(1);
    let height = (90 + 28 * n) as u32;
    svg((1050, height), |root| {
        let (plot, legend) = root.split_horizontally(860);
        let mut chart = ChartBuilder::on(&plot)
            .caption("held-out L² after / before, each candidate alone (log axis; 1 = no change)", ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(38)
            .y_label_area_size(10)
            .build_cartesian_2d((lo..hi).log_scale(), 0.0..n as f64)
            .map_err(draw_err)?;
        chart.configure_mesh().disable_y_mesh().light_line_style(WHITE).y_labels(0).x_desc("after / before").x_label_formatter(&|v| log_label(*v)).draw().map_err(draw_err)?;
        let color = |o: Outcome| match o {
            Outcome::Selected => RGBColor(40, 160, 90),
            Outcome::Better => RGBColor(90, 130, 200),
            Outcome::Worse => RGBColor(230, 140, 40),
            Outcome::Diverged => RGBColor(200, 40, 40),
            Outcome::NotSimulated => RGBColor(160, 160, 160),
        };
        for (k, (name, ratio, outcome)) in rows.iter().enumerate() {
            let y = n as f64 - k as f64;
            let (y0, y1) = (y - 0.8, y - 0.2);
            let col = color(*outcome);
            match outcome {
                Outcome::Selected | Outcome::Better | Outcome::Worse => {
                    let v = ratio.clamp(lo, hi);
                    let (a, b) = if v < 1.0 { (v, 1.0) } else { (1.0, v) };
                    chart.draw_series(std::iter::once(Rectangle::new([(a, y0), (b, y1)], col.mix(0.75).filled()))).map_err(draw_err)?;
                }
                // diverged: a red outline running to the right edge
                Outcome::Diverged => {
                    chart.draw_series(std::iter::once(Rectangle::new([(1.0, y0), (hi, y1)], col.stroke_width(2)))).map_err(draw_err)?;
                }
                // not simulated: a short grey outline at 1, no length claimed
                Outcome::NotSimulated => {
                    chart.draw_series(std::iter::once(Rectangle::new([(1.0 / 1.25, y0), (1.25, y1)], col.stroke_width(1)))).map_err(draw_err)?;
                }
            }
            let text = match outcome {
                Outcome::Diverged => format!("{name}: diverged"),
                Outcome::NotSimulated => format!("{name}: not simulated (fit not physical)"),
                _ => format!("{name}: {ratio:.3}"),
            };
            // labels on the empty side of 1
            let x = match outcome {
                Outcome::Selected | Outcome::Better => 1.05,
                _ => lo * 1.05,
            };
            chart.draw_series(std::iter::once(Text::new(text, (x, y - 0.28), ("sans-serif", 13).into_font()))).map_err(draw_err)?;
        }
        chart.draw_series(LineSeries::new(vec![(1.0, 0.0), (1.0, n as f64)], BLACK.stroke_width(1))).map_err(draw_err)?;
        for (k, (label, o)) in
            [("selected", Outcome::Selected), ("better", Outcome::Better), ("worse", Outcome::Worse), ("diverged", Outcome::Diverged), ("not simulated", Outcome::NotSimulated)]
                .into_iter()
                .enumerate()
        {
            let y = 50 + 24 * k as i32;
            let col = color(o);
            let style = if matches!(o, Outcome::Diverged | Outcome::NotSimulated) { col.stroke_width(2) } else { col.mix(0.75).filled() };
            legend.draw(&Rectangle::new([(10, y - 7), (40, y + 7)], style)).map_err(draw_err)?;
            legend.draw(&Text::new(label.to_string(), (48, y - 7), ("sans-serif", 14).into_font())).map_err(draw_err)?;
        }
        Ok(())
    })
}
