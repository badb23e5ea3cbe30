//! Helpers shared by the tests that read the DFKI hardware logs.

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
