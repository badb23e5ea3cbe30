//! The [`Workspace`]: every per-link temporary of the algorithms, allocated once per model, and
//! what the algorithms derive from a model's parameters (the closed form of a two-joint arm).

use nalgebra::{DMatrix, DVector};

use crate::algorithms::one_joint::OneJoint;
use crate::algorithms::soa::SoaWs;
use crate::algorithms::two_joint::TwoJoint;
use crate::model::Model;
use crate::spatial::{Force, InertiaRate, Motion, SpatialInertia, Transform};

/// Scratch space for the dynamics algorithms of one [`Model`].
///
/// Create one per thread with [`Workspace::new`]; algorithms taking `(model, ws, ...)` never
/// allocate. Its fields hold the results of the last pass (world-frame quantities about the
/// world origin) and may be read after a call, as Pinocchio's `Data`.
/// [`forward_dynamics`](crate::forward_dynamics) (articulated-body algorithm, two-joint closed
/// form) and [`dynamics_terms`](crate::dynamics_terms) of a two-joint arm leave them untouched,
/// except on their first call with a model, which generates the closed form by running the
/// general algorithms (and allocates). A workspace may serve several models with the same
/// number of joints: it regenerates the closed form when the model's parameters differ.
#[derive(Clone, Debug)]
pub struct Workspace {
    pub(crate) dof: usize,
    /// World pose of each joint frame (after the joint moved).
    pub poses: Vec<Transform>,
    /// Joint motion subspace `S_i` in world coordinates.
    pub subspaces: Vec<Motion>,
    /// Spatial velocity of each link `v_i` in world coordinates.
    pub velocities: Vec<Motion>,
    /// Time derivative of the world-frame subspace, `Ṡ_i = v_i × S_i`.
    pub subspace_rates: Vec<Motion>,
    /// Link inertia in world coordinates.
    pub inertias: Vec<SpatialInertia>,
    /// Composite inertia of the subtree of each link, world coordinates.
    pub composites: Vec<SpatialInertia>,
    /// Spatial momentum of the subtree of each link, world coordinates.
    pub momenta: Vec<Force>,
    /// Rate of the composite inertia of each subtree.
    pub composite_rates: Vec<InertiaRate>,
    /// Spatial accelerations (inverse dynamics).
    pub accelerations: Vec<Motion>,
    /// Spatial forces transmitted by each joint (inverse dynamics).
    pub forces: Vec<Force>,
    pub(crate) scratch_matrix: DMatrix<f64>,
    pub(crate) scratch_vector: DVector<f64>,
    /// One-lane scratch of the fast paths (small chains, articulated-body algorithm).
    pub(crate) lanes: SoaWs<1>,
    /// The closed form of the model of this revision ([`Model::revision`]), `None` inside when
    /// that model has none; filled by [`closed_forms`](crate::algorithms::closed_forms).
    pub(crate) closed_form: Slot<TwoJoint>,
    /// The one-joint closed form of the model of this revision, as `closed_form`.
    pub(crate) one_joint: Slot<OneJoint>,
}

/// A workspace's slot of one closed form: the model revision it was generated for, and the
/// form (`None` when that model has none).
pub(crate) type Slot<T> = Option<(u64, Option<T>)>;

impl Workspace {
    /// Allocates a workspace for `model`.
    #[must_use]
    pub fn new(model: &Model) -> Self {
        let n = model.dof();
        Workspace {
            dof: n,
            poses: vec![Transform::IDENTITY; n],
            subspaces: vec![Motion::ZERO; n],
            velocities: vec![Motion::ZERO; n],
            subspace_rates: vec![Motion::ZERO; n],
            inertias: vec![SpatialInertia::ZERO; n],
            composites: vec![SpatialInertia::ZERO; n],
            momenta: vec![Force::ZERO; n],
            composite_rates: vec![InertiaRate::default(); n],
            accelerations: vec![Motion::ZERO; n],
            forces: vec![Force::ZERO; n],
            scratch_matrix: DMatrix::zeros(n, n),
            scratch_vector: DVector::zeros(n),
            lanes: SoaWs::new(n),
            closed_form: None,
            one_joint: None,
        }
    }

    /// Number of degrees of freedom this workspace was made for.
    pub fn dof(&self) -> usize {
        self.dof
    }
}
