//! One file per algorithm. Every function takes `(model, ws, q, qd[, qdd])`; see the crate root
//! for the equation of motion and the conventions. The [`Workspace`](workspace::Workspace) they
//! write in lives here too: it holds their scratch (the SoA lanes, the two-joint closed forms).

pub mod aba;
pub(crate) mod closed_forms;
pub mod coriolis;
pub mod crba;
pub mod energy;
pub mod forward_dynamics;
pub mod kinematics;
pub(crate) mod one_joint;
pub mod regressor;
pub mod rnea;
pub(crate) mod soa;
pub mod terms;
pub(crate) mod two_joint;
pub mod workspace;
