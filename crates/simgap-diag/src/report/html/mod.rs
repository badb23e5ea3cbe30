//! A self-contained HTML report: the verdict, the tables of the [`Report`](crate::report::Report) and inline SVG plots
//! (measured, nominal and corrected trajectories of every held-out run, torque residual
//! against q̇, held-out shrink per candidate). No script, no external file.

mod cells;
mod plots;

use std::fmt::Write as _;
use std::path::Path;

use crate::error::{Error, Result};
use crate::report::units::{kinds_of, Units};
use crate::report::verdict::ranked_selection;
pub use crate::report::verdict::{assess, Assessment};
use crate::report::Diagnosis;
use simgap_core::Model;
use simgap_sim::EffectKind;

pub use cells::esc;
use cells::{fixed, inertial_cell, num, num_in, params_cell, pct};
use plots::{kstep_svg, residual_svg, shrink_svg, trajectory_svg};

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
            let cell = if e.effect == EffectKind::InertialError {
                inertial_cell(&e.joints, &e.parameters, model)
            } else {
                params_cell(&e.parameters, Some(&e.uncertainty), Some(&e.units))
            };
            let description = if e.description.is_empty() { String::new() } else { format!("<br><small>{}</small>", esc(&e.description)) };
            let _ = writeln!(h, "<tr><td><code>{}</code>{description}</td><td>{}</td><td>{cell}</td></tr>", esc(e.effect.as_str()), esc(&e.joints.join(", ")));
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
            esc(c.effect.as_str()),
            esc(&c.joints.join(", ")),
            if c.effect == EffectKind::InertialError { inertial_cell(&c.joints, &c.parameters, model) } else { params_cell(&c.parameters, Some(&c.uncertainty), Some(&c.units)) },
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
                esc(s.effect.as_str()),
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

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1150px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:1em 0;font-size:90%}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}\
td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}tr.sel{background:#eef7ee}\
table.inertial{margin:0;font-size:100%}\
.verdict{font-size:120%;padding:.7em;border-left:6px solid #999;background:#f6f6f6}\
.verdict.good{border-color:#2a7;background:#f4faf6}.verdict.warn{border-color:#d90;background:#fff8e6}.verdict.bad{border-color:#c33;background:#fdf0f0}\
ul.notes{background:#fff8e6;border-left:6px solid #d90;padding:.5em 2em}.meta{color:#666;font-size:90%}\
figure{margin:.5em 0}svg{max-width:100%;height:auto}";
