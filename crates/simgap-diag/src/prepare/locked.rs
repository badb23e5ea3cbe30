//! The model a diagnosis of some runs uses: joints the logs record but not as positions a model
//! can use (a LeRobot gripper range-normalised without its calibration, [`Run::left_out`]) are
//! locked at their zero position instead of making the diagnosis refuse the URDF.

use simgap_core::Model;
use simgap_sim::Run;

use crate::error::{Error, Result};

/// `model` with every joint locked at `q = 0` that no run logs and some run leaves out
/// ([`Model::with_joints_locked`]); `None` when nothing is to be locked. Call it before
/// [`diagnose`](crate::diagnose) or [`predict`](crate::predict) with the runs they will get,
/// and give them the model it returns.
///
/// A joint some runs log and others leave out is not locked (those runs are refused by the
/// diagnosis, naming the joint).
///
/// # Errors
/// [`Error::Input`] when locking leaves no joint, or no link with mass.
pub fn model_for_runs<'a>(model: &Model, runs: impl IntoIterator<Item = &'a Run>) -> Result<Option<Model>> {
    let runs: Vec<&Run> = runs.into_iter().collect();
    let lock: Vec<&str> =
        model.joint_names().into_iter().filter(|j| runs.iter().any(|r| r.left_out.iter().any(|l| l == j)) && !runs.iter().any(|r| r.joints.iter().any(|k| k == j))).collect();
    if lock.is_empty() {
        return Ok(None);
    }
    let reason = "the logs record them, but not as angles or positions the model can use (a LeRobot joint range-normalised without a calibration file)";
    model.with_joints_locked(&lock, reason).map(Some).map_err(|e| Error::Input(format!("cannot lock {lock:?}, which the logs do not give as positions: {e}")))
}
