//! One file per algorithm. Every function takes `(model, ws, q, qd[, qdd])`; see the crate root
//! for the equation of motion and the conventions.

pub mod aba;
pub(crate) mod closed_forms;
pub mod coriolis;
pub mod crba;
pub mod energy;
pub mod forward_dynamics;
pub mod kinematics;
pub mod regressor;
pub mod rnea;
pub(crate) mod soa;
pub mod terms;
pub(crate) mod two_joint;
