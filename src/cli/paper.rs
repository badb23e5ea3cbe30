//! `simgap paper`: the seed paper's experiment (§5) under both formulations of C.
//!
//! PD control of the paper arm from rest at q = 0 to q_d = (π/4, π/2), Kp = diag(64.72, 32.36),
//! Kv = diag(48.54, 6.472), sampled at 2.5 ms, with the paper's encoders (1,024,000 counts/rev,
//! backward-difference velocity). Simulated for 3 s: the paper's plots end at 2–3 s and the
//! arm has settled by then.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context};
use plotters::prelude::*;
use simgap::core::{Formulation, Model};
use simgap::log::McapSink;
use simgap::sim::paper;
use simgap::sim::{l2_between, l2_tracking, simulate, MemorySink, Plant, Run, RunEnd, SimParams};

use super::diagnose::write_atomically;
use super::simulate::Tee;

/// Arguments of `simgap paper`.
#[derive(clap::Args)]
pub(crate) struct Args {
    /// Directory for the figure (paper.svg) and the two runs (MCAP); created if missing.
    #[arg(long, default_value = ".")]
    out_dir: PathBuf,
    /// Duration [s], 1.2 ≤ duration ≤ 600 (the zoom window lies at 1.07–1.115 s).
    #[arg(long, default_value_t = 3.0)]
    duration: f64,
}

/// Zoom window of the paper's detail plot [s].
const ZOOM: (f64, f64) = (1.070, 1.115);

fn simulate_paper(model: &Model, formulation: Formulation, duration: f64, out: Option<&Path>) -> anyhow::Result<Run> {
    let plant = Plant::new(model, formulation, &[])?;
    let mut pd = paper::controller();
    let reference = paper::reference();
    let params = SimParams { duration, sample_period: paper::SAMPLE_PERIOD, ..SimParams::default() };
    let mut memory = MemorySink::new();
    let end = match out {
        Some(path) => {
            let mut end = None;
            write_atomically(path, |tmp| {
                let mut file = McapSink::create(tmp)?;
                end = Some(simulate(&plant, &mut pd, &reference, &params, &mut Tee(&mut memory, &mut file), None)?);
                Ok(())
            })?;
            end.unwrap_or(RunEnd::Completed)
        }
        None => simulate(&plant, &mut pd, &reference, &params, &mut memory, None)?,
    };
    anyhow::ensure!(end == RunEnd::Completed, "the paper's experiment did not complete: {end:?}");
    Ok(memory.into_run())
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    super::check_range("duration", args.duration, 1.2, 600.0, "s")?;
    // Ctrl-C: the file being written is removed, finished files stay whole
    super::interrupt::install();
    let model = Model::paper_arm();
    std::fs::create_dir_all(&args.out_dir).with_context(|| format!("cannot create {}", args.out_dir.display()))?;
    let el = simulate_paper(&model, Formulation::EulerLagrange, args.duration, Some(&args.out_dir.join("paper_euler_lagrange.mcap")))?;
    let simple = simulate_paper(&model, Formulation::Simplified, args.duration, Some(&args.out_dir.join("paper_simplified.mcap")))?;

    // table: L² of the tracking error of each model, and of the difference between the models
    let names = &el.joints;
    println!("The paper's experiment (§5): PD from q = 0 to q_d = (π/4, π/2), T = 2.5 ms, {} s, paper encoders", args.duration);
    println!();
    println!("L² index (eq. 127) [rad]        {:>14} {:>14} {:>14}", names[0], names[1], "overall");
    for (label, run) in [("tracking error, Euler–Lagrange", &el), ("tracking error, simplified", &simple)] {
        let r = l2_tracking(run, None)?;
        println!("{label:<32}{:>14.8} {:>14.8} {:>14.8}", r.per_joint[0], r.per_joint[1], r.overall);
    }
    let diff = l2_between(&el, &simple, None)?;
    println!("{:<32}{:>14.3e} {:>14.3e} {:>14.3e}", "difference EL − simplified", diff.per_joint[0], diff.per_joint[1], diff.overall);
    println!("{:<32}{:>14.3e} {:>14.3e}", "max |difference|", diff.max_abs_per_joint[0], diff.max_abs_per_joint[1]);
    let zoom = l2_between(&el, &simple, Some(ZOOM))?;
    println!("{:<32}{:>14.3e} {:>14.3e} {:>14.3e}", format!("difference, t in {}–{} s", ZOOM.0, ZOOM.1), zoom.per_joint[0], zoom.per_joint[1], zoom.overall);

    let svg = args.out_dir.join("paper.svg");
    write_atomically(&svg, |tmp| plot(&el, &simple, tmp))?;
    println!();
    println!("wrote {}, {}, {}", svg.display(), args.out_dir.join("paper_euler_lagrange.mcap").display(), args.out_dir.join("paper_simplified.mcap").display());
    Ok(())
}

/// Tick labels with as many decimals as a span of `span` needs for about five distinct ticks.
fn tick_decimals(span: f64) -> usize {
    if !(span.is_finite() && span > 0.0) {
        return 3;
    }
    ((-(span / 5.0).log10()).ceil().max(0.0) as usize).clamp(1, 8)
}

/// Joint 1 (shoulder) under both models over the whole run with the zoom window shaded, and
/// the zoom window: the Euler–Lagrange run solid, the simplified one dashed on top of it, so
/// where they coincide both stay visible.
fn plot(el: &Run, simple: &Run, path: &Path) -> anyhow::Result<()> {
    let e = |err: &dyn std::fmt::Debug| anyhow!("cannot draw {}: {err:?}", path.display());
    let root = SVGBackend::new(path, (900, 820)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (top, bottom) = root.split_vertically(410);
    let series = |run: &Run| -> Vec<(f64, f64)> { run.t.iter().zip(run.column(&run.q, 0)).map(|(t, q)| (*t, q)).collect() };
    let (a, b) = (series(el), series(simple));
    let t_end = *el.t.last().unwrap_or(&1.0);
    let zoom_color = RGBColor(255, 200, 60);
    for (area, (t0, t1), title) in [
        (&top, (0.0, t_end), "Joint 1 (shoulder): PD step response of the paper arm (shaded: the zoom window below)".to_string()),
        (&bottom, ZOOM, format!("Zoom: t = {:.3}–{:.3} s", ZOOM.0, ZOOM.1)),
    ] {
        let full = t0 == 0.0;
        let pts = |s: &[(f64, f64)]| -> Vec<(f64, f64)> { s.iter().copied().filter(|(t, _)| *t >= t0 - 1e-9 && *t <= t1 + 1e-9).collect() };
        let (pa, pb) = (pts(&a), pts(&b));
        let (mut lo, mut hi) = pa.iter().chain(&pb).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, q)| (lo.min(*q), hi.max(*q)));
        if full {
            hi = hi.max(paper::Q_DESIRED[0]);
        }
        let pad = ((hi - lo) * 0.08).max(1e-7);
        lo -= pad;
        hi += pad;
        let (x_dec, y_dec) = (tick_decimals(t1 - t0), tick_decimals(hi - lo));
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(85)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc("time since the start t [s]")
            .y_desc("shoulder position q₁ [rad]")
            .x_labels(8)
            .y_labels(6)
            .x_label_formatter(&|v| format!("{v:.x_dec$}"))
            .y_label_formatter(&|v| format!("{v:.y_dec$}"))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(|x| e(&x))?;
        if full {
            // the zoom window, shaded under the curves
            chart
                .draw_series(std::iter::once(Rectangle::new([(ZOOM.0, lo), (ZOOM.1, hi)], zoom_color.mix(0.35).filled())))
                .map_err(|x| e(&x))?
                .label(format!("zoom window {:.3}–{:.3} s", ZOOM.0, ZOOM.1))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], zoom_color.mix(0.35).filled()));
        }
        chart
            .draw_series(LineSeries::new(pa, BLUE.stroke_width(3)))
            .map_err(|x| e(&x))?
            .label("Euler–Lagrange C")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(3)));
        chart
            .draw_series(DashedLineSeries::new(pb, 6, 5, RED.stroke_width(2)))
            .map_err(|x| e(&x))?
            .label("simplified C = Ḣ/2 (dashed)")
            .legend(|(x, y)| plotters::element::DashedPathElement::new(vec![(x, y), (x + 20, y)], 6, 4, RED.stroke_width(2)));
        if full {
            chart
                .draw_series(LineSeries::new(vec![(t0, paper::Q_DESIRED[0]), (t1, paper::Q_DESIRED[0])], BLACK.mix(0.5)))
                .map_err(|x| e(&x))?
                .label("target q_d = π/4")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
