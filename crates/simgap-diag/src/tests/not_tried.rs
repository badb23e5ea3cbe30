//! The report names the families it did not try on the runs, with why and how to ask for them.

use crate::check::bench::{demo_specs, generate};
use crate::{diagnose, DiagnoseOptions};
use simgap_core::{Formulation, Model};

#[test]
fn the_report_names_the_families_it_did_not_try() {
    let model = Model::paper_arm();
    let (fit_specs, hold_specs) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, &[], s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<_> = fit_specs.iter().map(gen).collect();
    let hold: Vec<_> = hold_specs.iter().map(gen).collect();
    let skipped = |o: &DiagnoseOptions| {
        let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, o, &mut |_| {}).unwrap();
        d.report.notes.iter().filter(|n| n.starts_with("not tried:")).cloned().collect::<Vec<_>>()
    };
    // by default, directional friction is not tried on the arm's turning joints (and, on logs
    // that are no servo's, the load friction rising at rest is not named)
    let default = skipped(&DiagnoseOptions::default());
    assert_eq!(default.len(), 1, "{default:?}");
    assert!(default[0].contains("directional_friction") && default[0].contains("shoulder, elbow") && default[0].contains("--directional-friction"), "{}", default[0]);
    // asked for, it is tried, and nothing is named
    let asked = skipped(&DiagnoseOptions { directional_friction: true, ..DiagnoseOptions::default() });
    assert!(asked.is_empty(), "{asked:?}");
}
