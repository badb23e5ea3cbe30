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
