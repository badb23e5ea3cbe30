//! A self-contained HTML report: the verdict, the tables of the [`Report`] and inline SVG plots
//! (measured, nominal and corrected trajectories of every held-out run, torque residual
//! against q̇, held-out shrink per candidate). No script, no external file.

use std::fmt::Write as _;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use simgap_sim::Run;

use crate::effects::Param;
use crate::error::{Error, Result};
use crate::report::Report;
use crate::Diagnosis;

/// Most points drawn per series (longer series are decimated evenly).
const MAX_POINTS: usize = 1500;

/// Writes the HTML report of `diagnosis` to `path` (one file, plots inline as SVG).
///
/// # Errors
/// [`Error::Write`] when a plot cannot be drawn or the file cannot be written.
pub fn write_html(diagnosis: &Diagnosis, path: &Path) -> Result<()> {
    let html = render_html(diagnosis).map_err(|message| Error::Write { path: path.display().to_string(), message })?;
    std::fs::write(path, html).map_err(|e| Error::Write { path: path.display().to_string(), message: e.to_string() })
}

/// The HTML report of `diagnosis` as a string.
///
/// # Errors
/// A message when a plot cannot be drawn.
pub fn render_html(d: &Diagnosis) -> std::result::Result<String, String> {
    let r = &d.report;
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>simgap diagnosis: {}</title>\n<style>{}</style></head><body>\n",
        esc(&r.model),
        CSS
    );
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
    let _ = writeln!(h, "<p class=\"verdict\">{}</p>", esc(&r.verdict));

    // how far
    let _ = writeln!(h, "<h2>How far: held-out runs, closed loop (L², eq. 127)</h2>");
    let _ = writeln!(h, "<table><tr><th></th><th>before [rad]</th><th>after [rad]</th><th>after / before</th></tr>");
    let _ = writeln!(h, "<tr><td>all held-out runs</td>{}{}{}</tr>", num(r.gap.holdout_l2_before), num(r.gap.holdout_l2_after), fixed(r.gap.ratio, 3));
    for (j, name) in r.joints.iter().enumerate() {
        let (b, a) = (r.gap.per_joint_before.get(j).copied().unwrap_or(f64::NAN), r.gap.per_joint_after.get(j).copied().unwrap_or(f64::NAN));
        let _ = writeln!(h, "<tr><td>joint {}</td>{}{}{}</tr>", esc(name), num(b), num(a), fixed(a / b, 3));
    }
    for (b, a) in r.gap.runs_before.iter().zip(&r.gap.runs_after) {
        let _ = writeln!(h, "<tr><td>run {} <small>({} → {})</small></td>{}{}{}</tr>", esc(&b.log), esc(&b.status), esc(&a.status), num(b.l2), num(a.l2), fixed(a.l2 / b.l2, 3));
    }
    let _ = writeln!(h, "<tr><td>fit runs (for reference)</td>{}{}{}</tr></table>", num(r.gap.fit_l2_before), num(r.gap.fit_l2_after), fixed(r.gap.fit_l2_after / r.gap.fit_l2_before, 3));

    // selected
    let _ = writeln!(h, "<h2>Selected effects</h2>");
    if r.selected_effects.is_empty() {
        let _ = writeln!(h, "<p>None: nothing significant remains, or the logs cannot tell.</p>");
    } else {
        let _ = writeln!(h, "<table><tr><th>effect</th><th>joints</th><th>parameters (± 95 %)</th></tr>");
        for e in &r.selected_effects {
            let params: Vec<String> = e
                .parameters
                .iter()
                .map(|(k, v)| match e.uncertainty.get(k) {
                    Some(u) => format!("{} = {} ± {}", esc(k), esc(&fmt_param(v)), esc(&fmt_param(u))),
                    None => format!("{} = {}", esc(k), esc(&fmt_param(v))),
                })
                .collect();
            let _ = writeln!(h, "<tr><td><code>{}</code></td><td>{}</td><td>{}</td></tr>", esc(&e.effect), esc(&e.joints.join(", ")), params.join("<br>"));
        }
        let _ = writeln!(h, "</table>");
    }

    // held-out trajectories
    let _ = writeln!(h, "<h2>Held-out runs: measured, nominal and corrected simulation</h2>");
    for (i, measured) in d.holdout.iter().enumerate() {
        let nominal = d.holdout_nominal.get(i).and_then(Option::as_ref);
        let corrected = d.holdout_corrected.get(i).and_then(Option::as_ref);
        let _ = writeln!(h, "<h3>{}</h3>", esc(&measured.source));
        for j in 0..measured.dof() {
            let svg = trajectory_svg(measured, nominal, corrected, j)?;
            let _ = writeln!(h, "<figure>{svg}</figure>");
        }
    }

    // where
    let _ = writeln!(h, "<h2>Where: per joint (fit runs, nominal model)</h2>");
    let _ = writeln!(h, "<table><tr><th>joint</th><th>sim L² [rad]</th><th>share</th><th>torque residual L² [N·m]</th></tr>");
    for j in &r.location.per_joint {
        let _ = writeln!(h, "<tr><td>{}</td>{}{}{}</tr>", esc(&j.joint), num(j.sim_l2), pct(j.share), num(j.torque_residual_l2));
    }
    let _ = writeln!(h, "</table>");
    if !r.location.worst_segments.is_empty() {
        let _ = writeln!(h, "<h3>Worst time segments</h3><table><tr><th>log</th><th>t [s]</th><th>joint</th><th>phase</th><th>RMS error [rad]</th></tr>");
        for s in &r.location.worst_segments {
            let _ = writeln!(h, "<tr><td>{}</td><td>{:.3}–{:.3}</td><td>{}</td><td>{}</td>{}</tr>", esc(&s.log), s.start, s.end, esc(&s.joint), esc(&s.phase), num(s.rms_error));
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
        for (joint, m) in &r.location.correlations {
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
        let _ = writeln!(h, "<figure>{svg}</figure>");
    }

    // which
    let _ = writeln!(h, "<h2>Which: every candidate, fitted alone</h2>");
    let _ = writeln!(h, "<figure>{}</figure>", shrink_svg(r)?);
    let _ = writeln!(
        h,
        "<table><tr><th>rank</th><th>effect</th><th>joints</th><th>parameters</th><th>CV residual removed</th><th>held-out L² after [rad]</th><th>after / before</th><th>selected</th><th>reason</th></tr>"
    );
    for c in &r.candidates {
        let params: Vec<String> = c.parameters.iter().map(|(k, v)| format!("{} = {}", esc(k), esc(&fmt_param(v)))).collect();
        let _ = writeln!(
            h,
            "<tr{}><td>{}</td><td><code>{}</code></td><td>{}</td><td>{}</td>{}{}{}<td>{}</td><td>{}</td></tr>",
            if c.selected { " class=\"sel\"" } else { "" },
            c.rank,
            esc(&c.effect),
            esc(&c.joints.join(", ")),
            params.join("<br>"),
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
    let _ = writeln!(h, "<p class=\"meta\">Held-out runs are never used for fitting or selection. Nominal cross-validated torque MSE: {:.4e}.</p>", r.nominal_cv_mse);
    h.push_str("</body></html>\n");
    Ok(h)
}

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:1em 0;font-size:90%}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}\
td.n{text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}tr.sel{background:#eef7ee}\
.verdict{font-size:120%;padding:.7em;border-left:4px solid #2a7;background:#f4faf6}.meta{color:#666;font-size:90%}\
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
    let list = |v: &[f64]| v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ");
    match p {
        Param::Number(x) => format!("{x:.4}"),
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

fn trajectory_svg(measured: &Run, nominal: Option<&Run>, corrected: Option<&Run>, j: usize) -> std::result::Result<String, String> {
    let series = |r: &Run| decimate(r.t.iter().zip(r.column(&r.q, j)).map(|(t, q)| (*t, q)).collect());
    let m = series(measured);
    let n = nominal.map(series).unwrap_or_default();
    let c = corrected.map(series).unwrap_or_default();
    let (t0, t1) = (measured.t.first().copied().unwrap_or(0.0), measured.t.last().copied().unwrap_or(1.0).max(measured.t.first().copied().unwrap_or(0.0) + 1e-9));
    let (lo, hi) = range(m.iter().chain(&n).chain(&c).map(|p| p.1));
    let title = format!("joint {}: position", measured.joints[j]);
    svg((1000, 320), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(draw_err)?;
        chart.configure_mesh().x_desc("t [s]").y_desc("q [rad]").y_label_formatter(&|v| format!("{v:.3}")).draw().map_err(draw_err)?;
        for (pts, color, width, label) in [(m, BLACK, 2, "measured"), (n, RED, 1, "nominal model"), (c, BLUE, 1, "with selected effects")] {
            if pts.is_empty() {
                continue;
            }
            let style = color.stroke_width(width);
            chart.draw_series(LineSeries::new(pts, style)).map_err(draw_err)?.label(label).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
        chart.configure_series_labels().position(SeriesLabelPosition::UpperRight).background_style(WHITE.mix(0.85)).border_style(BLACK).draw().map_err(draw_err)?;
        Ok(())
    })
}

fn residual_svg(d: &Diagnosis, j: usize) -> std::result::Result<String, String> {
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
    let title = format!("joint {}: τ_cmd − (H q̈ + C q̇ + g) against q̇", d.report.joints.get(j).map_or("?", String::as_str));
    svg((1000, 320), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(draw_err)?;
        chart.configure_mesh().x_desc("q̇ [rad/s]").y_desc("residual [N·m]").draw().map_err(draw_err)?;
        chart.draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 2, BLUE.mix(0.4).filled()))).map_err(draw_err)?;
        Ok(())
    })
}

fn shrink_svg(r: &Report) -> std::result::Result<String, String> {
    let rows: Vec<(String, f64, bool)> = r.candidates.iter().map(|c| (c.effect.clone(), c.holdout_ratio, c.selected)).collect();
    let finite_max = rows.iter().map(|x| x.1).filter(|v| v.is_finite()).fold(1.0_f64, f64::max);
    let xmax = finite_max.min(3.0) * 1.05;
    let n = rows.len().max(1);
    let height = (60 + 26 * n) as u32;
    svg((1000, height), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption("held-out L² after / before, each candidate alone (1 = no change; selected in green)", ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(10)
            .build_cartesian_2d(0.0..xmax, 0.0..n as f64)
            .map_err(draw_err)?;
        chart.configure_mesh().disable_y_mesh().y_labels(0).x_desc("after / before").draw().map_err(draw_err)?;
        chart
            .draw_series(rows.iter().enumerate().map(|(k, (_, ratio, selected))| {
                let y = n as f64 - k as f64;
                let v = if ratio.is_finite() { ratio.min(xmax) } else { xmax };
                let color = if *selected { GREEN.mix(0.8) } else if ratio.is_finite() { BLUE.mix(0.5) } else { RED.mix(0.5) };
                Rectangle::new([(0.0, y - 0.8), (v, y - 0.2)], color.filled())
            }))
            .map_err(draw_err)?;
        // labels next to the bars: effect and ratio
        chart
            .draw_series(rows.iter().enumerate().map(|(k, (name, ratio, _))| {
                let y = n as f64 - k as f64 - 0.5;
                let v = if ratio.is_finite() { ratio.min(xmax) } else { 0.0 };
                let text = if ratio.is_finite() { format!("{name}  {ratio:.3}") } else { format!("{name}  (diverged or not simulated)") };
                let x = if v > 0.6 * xmax { 0.01 * xmax } else { v + 0.01 * xmax };
                Text::new(text, (x, y + 0.2), ("sans-serif", 13).into_font())
            }))
            .map_err(draw_err)?;
        chart.draw_series(LineSeries::new(vec![(1.0, 0.0), (1.0, n as f64)], BLACK.stroke_width(1))).map_err(draw_err)?;
        Ok(())
    })
}
