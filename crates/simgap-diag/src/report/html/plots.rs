//! The report's inline SVG plots, drawn by plotters: held-out trajectories with their error
//! panels ([`trajectory_svg`]), the torque residual against q̇ ([`residual_svg`]), the k-step
//! error against the horizon ([`kstep_svg`]) and every candidate's held-out shrink
//! ([`shrink_svg`]).

use plotters::coord::Shift;
use plotters::prelude::*;
use simgap_sim::Run;

use crate::report::units::{kinds_of, Units};
use crate::report::Diagnosis;
use crate::report::Report;

/// Most points drawn per series (longer series are decimated evenly).
const MAX_POINTS: usize = 1500;

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
pub(super) fn trajectory_svg(measured: &Run, nominal: Option<&Run>, corrected: Option<&Run>, j: usize, has_correction: bool, unit: &str) -> std::result::Result<String, String> {
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

pub(super) fn residual_svg(d: &Diagnosis, j: usize) -> std::result::Result<String, String> {
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
pub(super) fn kstep_svg(k: &crate::report::KStep, unit: &str) -> std::result::Result<String, String> {
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
pub(super) fn shrink_svg(r: &Report) -> std::result::Result<String, String> {
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
            let label = if c.joints.is_empty() || c.joints.len() > 3 { c.effect.to_string() } else { format!("{} ({})", c.effect, c.joints.join(", ")) };
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
