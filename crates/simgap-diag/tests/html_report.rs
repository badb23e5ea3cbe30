//! The HTML report as an engineer reads it: a conclusion that follows the report's numbers
//! (diverged and worse cases say so), every figure where it belongs, and the page as headless
//! Chromium renders it (skipped, with a message, when Chromium is not installed; failed then
//! when the environment variable `CI` is set, as the tests of the shared data do).

use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

use simgap_core::{Formulation, Model};
use simgap_diag::bench::{demo_effects, demo_specs, generate};
use simgap_diag::html::{assess, render_html_for};
use simgap_diag::{diagnose, DiagnoseOptions, Diagnosis};

/// The demo's diagnosis, once.
fn demo() -> &'static (Model, Diagnosis) {
    static DEMO: OnceLock<(Model, Diagnosis)> = OnceLock::new();
    DEMO.get_or_init(|| {
        let model = Model::paper_arm();
        let effects = demo_effects();
        let (fit, hold) = demo_specs(1);
        let gen = |s| generate(&model, Formulation::EulerLagrange, &effects, s, 0.0025, 1_024_000.0).unwrap();
        let fit: Vec<_> = fit.iter().map(gen).collect();
        let hold: Vec<_> = hold.iter().map(gen).collect();
        let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
        (model, d)
    })
}

fn count(html: &str, needle: &str) -> usize {
    html.matches(needle).count()
}

#[test]
fn conclusion_of_a_good_diagnosis_is_good_and_names_the_selection() {
    let (_, d) = demo();
    let a = assess(&d.report);
    assert_eq!(a.class, "good", "{}", a.text);
    assert!(a.text.contains("shrink") && a.text.contains("viscous_friction"), "{}", a.text);
}

#[test]
fn diverged_nominal_is_said_whatever_the_verdict_text() {
    let (_, d) = demo();
    let mut r = d.report.clone();
    r.verdict = "the gap is explained by everything".into();
    r.gap.runs_before[0].status = "diverged at t = 1.200 s on elbow".into();
    r.gap.holdout_l2_before = f64::INFINITY;
    let a = assess(&r);
    assert_eq!(a.class, "warn", "{}", a.text);
    assert!(a.text.contains("diverges") && a.text.contains("measures divergence"), "{}", a.text);
    assert!(!a.text.contains("explained"), "{}", a.text);
}

#[test]
fn diverged_correction_is_bad() {
    let (_, d) = demo();
    let mut r = d.report.clone();
    r.gap.runs_after[0].status = "diverged at t = 0.500 s on shoulder".into();
    let a = assess(&r);
    assert_eq!(a.class, "bad", "{}", a.text);
    assert!(a.text.contains("still diverges"), "{}", a.text);
}

#[test]
fn worse_after_is_bad() {
    let (_, d) = demo();
    let mut r = d.report.clone();
    r.gap.holdout_l2_after = 2.0 * r.gap.holdout_l2_before;
    r.gap.ratio = 2.0;
    let a = assess(&r);
    assert_eq!(a.class, "bad", "{}", a.text);
    assert!(a.text.contains("worse"), "{}", a.text);
}

#[test]
fn kstep_headline_decides_and_the_floor_is_checked() {
    let (_, d) = demo();
    let mut r = d.report.clone();
    r.gap.headline = "k_step".into();
    r.gap.kstep.horizons_s = vec![0.1, 0.5];
    r.gap.kstep.before = vec![0.01, 0.05];
    r.gap.kstep.after = vec![0.002, 0.01];
    r.gap.kstep.floor = vec![0.02, 0.2];
    let a = assess(&r);
    assert_eq!(a.class, "good", "{}", a.text);
    assert!(a.text.contains("0.5 s prediction"), "{}", a.text);
    r.gap.kstep.floor = vec![0.001, 0.005];
    let a = assess(&r);
    assert_eq!(a.class, "warn", "{}", a.text);
    assert!(a.text.contains("constant-velocity"), "{}", a.text);
}

#[test]
fn page_has_every_figure_units_and_link_names() {
    let (model, d) = demo();
    let mut d = d.clone();
    d.report.alternatives.push(simgap_diag::Alternative { effects: vec!["torque_gain".into()], why: "the same dynamics".into() });
    d.report.notes.push("a note about the logs".into());
    d.report.gap.kstep.horizons_s = vec![0.1, 0.5];
    d.report.gap.kstep.before = vec![0.01, 0.05];
    d.report.gap.kstep.after = vec![0.002, 0.01];
    d.report.gap.kstep.floor = vec![0.02, 0.2];
    let html = render_html_for(&d, Some(model)).unwrap();
    let joints = model.dof();
    assert_eq!(count(&html, "<figure class=\"trajectory\">"), d.holdout.len() * joints);
    assert_eq!(count(&html, "<figure class=\"residual\">"), joints);
    assert_eq!(count(&html, "<figure class=\"candidates\">"), 1);
    assert_eq!(count(&html, "<figure class=\"kstep\">"), 1);
    assert_eq!(count(&html, "id=\"alternatives\""), 1);
    assert_eq!(count(&html, "<ul class=\"notes\""), 1);
    assert!(html.contains("N·m·s/rad") && html.contains("time since the log"), "units and time axes");
    assert!(!html.contains("NaN"), "no NaN on the page");
    // no k-step, alternatives or notes: their sections are absent
    let mut plain = demo().1.clone();
    plain.report.gap.kstep = Default::default();
    plain.report.alternatives.clear();
    plain.report.notes.clear();
    let html = render_html_for(&plain, Some(model)).unwrap();
    assert_eq!(count(&html, "<figure class=\"kstep\">") + count(&html, "id=\"alternatives\"") + count(&html, "<ul class=\"notes\""), 0);
}

/// The Chromium binary, if installed (Debian package `chromium`).
fn chromium() -> Option<PathBuf> {
    ["chromium", "chromium-browser", "google-chrome"].iter().find_map(|name| {
        let out = Command::new("which").arg(name).output().ok()?;
        out.status.success().then(|| PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()))
    })
}

#[test]
fn chromium_renders_the_page_with_every_figure() {
    let Some(chrome) = chromium() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "chromium_renders_the_page_with_every_figure: headless Chromium is not installed (CI is set: a test without its browser fails; `make browser` installs the Debian package chromium)"
        );
        println!("SKIPPED chromium_renders_the_page_with_every_figure: headless Chromium is not installed (`make browser`, or Debian: apt-get install chromium)");
        return;
    };
    let (model, d) = demo();
    let dir = std::env::temp_dir().join(format!("simgap-html-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let page = dir.join("report.html");
    simgap_diag::html::write_html_for(d, Some(model), &page).unwrap();
    let url = format!("file://{}", page.display());
    let base = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"];
    let profile = format!("--user-data-dir={}", dir.join("profile").display());
    // the DOM after rendering: the figures parsed as SVG, not as text
    let out = Command::new(&chrome).args(base).arg(&profile).args(["--dump-dom", &url]).output().unwrap();
    assert!(out.status.success(), "chromium failed: {}", String::from_utf8_lossy(&out.stderr));
    let dom = String::from_utf8_lossy(&out.stdout);
    let kstep = usize::from(!d.report.gap.kstep.horizons_s.is_empty());
    let figures = d.holdout.len() * model.dof() + model.dof() + 1 + kstep;
    assert_eq!(count(&dom, "<figure"), figures, "figures in the rendered page");
    assert_eq!(count(&dom, "<svg"), figures, "one SVG per figure");
    assert_eq!(count(&dom, "id=\"verdict\""), 1);
    assert_eq!(count(&dom, "<table"), count(&render_html_for(d, Some(model)).unwrap(), "<table"));
    // and a screenshot, as the README shows it
    let shot = dir.join("report.png");
    let out = Command::new(&chrome).args(base).arg(&profile).arg(format!("--screenshot={}", shot.display())).args(["--window-size=1200,2400", &url]).output().unwrap();
    assert!(out.status.success(), "chromium screenshot failed: {}", String::from_utf8_lossy(&out.stderr));
    let png = std::fs::read(&shot).unwrap();
    assert!(png.len() > 10_000 && png.starts_with(b"\x89PNG"), "screenshot of {} bytes", png.len());
    let _ = std::fs::remove_dir_all(&dir);
}
