//! Helpers shared by the tests: the DFKI hardware logs, and the paper's arm with hidden effects.

use std::path::{Path, PathBuf};

use simgap_sim::{ControllerKind, Experiment, Run};

/// The shared data folder next to the repository (`../shared/data`).
pub(crate) fn shared_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")
}

/// Labels `run` an open-loop replay of its logged torque, sampled every `period` seconds.
pub(crate) fn replay(run: &mut Run, period: f64) {
    let dof = run.dof();
    run.experiment = Some(Experiment {
        controller: ControllerKind::Replay,
        joints: run.joints.clone(),
        kp: vec![0.0; dof],
        kv: vec![0.0; dof],
        sample_period: period,
        extra: Default::default(),
    });
}

/// Whether the data folder `dir` a test needs is there. Without it the test is skipped with a
/// message, except in CI (the environment variable `CI` set), where a test that cannot see its
/// data must fail rather than pass silently.
pub(crate) fn have_data(test: &str, dir: &Path) -> bool {
    if dir.is_dir() {
        return true;
    }
    assert!(std::env::var_os("CI").is_none(), "{test}: the data it needs is not at {} (CI is set: a test without its data fails)", dir.display());
    println!("SKIPPED {test}: the data is not at {}", dir.display());
    false
}

/// The diagnosis of the paper's arm with `hidden` effects in its logs: the demo's fit and
/// held-out runs (seed 1), 2.5 ms samples, a 1,024,000-count encoder, default options.
pub(crate) fn paper_arm_diagnosed(hidden: &[simgap_sim::Effect]) -> crate::Diagnosis {
    use crate::check::bench::{demo_specs, generate};
    use simgap_core::{Formulation, Model};
    let model = Model::paper_arm();
    let (fit_specs, hold_specs) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, hidden, s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<_> = fit_specs.iter().map(gen).collect();
    let hold: Vec<_> = hold_specs.iter().map(gen).collect();
    crate::diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &crate::DiagnoseOptions::default(), &mut |_| {}).unwrap()
}
