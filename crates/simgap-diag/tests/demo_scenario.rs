use simgap_core::{Formulation, Model};
use simgap_diag::bench::{demo_effects, demo_specs, generate};
use simgap_diag::{diagnose, DiagnoseOptions};

#[test]
fn demo_bench_robot_is_diagnosed_blind() {
    let model = Model::paper_arm();
    let effects = demo_effects();
    let (fit, hold) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, &effects, s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<_> = fit.iter().map(gen).collect();
    let hold: Vec<_> = hold.iter().map(gen).collect();
    let t = std::time::Instant::now();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    eprintln!("{}\n{:?}", d.report.summary(), t.elapsed());
    for s in &d.report.selection_log {
        eprintln!("{s:?}");
    }
}
