//! Rigid-body dynamics of serial manipulators loaded from URDF.
//!
//! # Conventions (written once; every function refers here)
//!
//! The equation of motion is
//!
//! ```text
//! H(q) q̈ + C(q, q̇) q̇ + g(q) = τ
//! ```
//!
//! in SI units (rad, m, s, kg, N·m, N), with `g(q) = ∂U/∂q` on the left-hand side: `g` is the
//! torque the actuators must supply to hold the robot still, and `U` the potential energy of
//! gravity. Gravity is the vector [`Model::gravity`] in the base frame (default `(0, 0, −9.81)`).
//! Joint vectors are ordered as [`Model::joint_names`] (chain order from root to tip).
//!
//! `C` comes in two [`Formulation`]s:
//! - **Euler–Lagrange**: Christoffel symbols of the first kind,
//!   `C_ij = Σ_k ½(∂H_ij/∂q_k + ∂H_ik/∂q_j − ∂H_jk/∂q_i) q̇_k`. Then `Ḣ = C + Cᵀ`, `Ḣ − 2C`
//!   is skew-symmetric and `C q̇` is the true Coriolis/centrifugal torque.
//! - **Simplified** (Sánchez-Sánchez & Arteaga-Pérez 2012): `C = Ḣ / 2`. Symmetric and
//!   energy-consistent, but its `C q̇` drops the skew-symmetric part of the true torque.
//!
//! H and g are the same in both. [`inverse_dynamics`] always uses the true torque.
//!
//! # Model and workspace
//!
//! A [`Model`] holds parameters only and never changes during evaluation; a [`Workspace`] holds
//! every temporary and what the algorithms derive from a model's parameters (the closed form
//! of a two-joint arm, generated on the first call that needs it), as Pinocchio's `Data`.
//! Each algorithm takes `(model, ws, q, qd, ...)` and comes as an allocating function and an
//! `_into` twin that writes into caller-owned buffers without allocating.
//!
//! ```
//! use simgap_core::{Model, Workspace, Formulation, dynamics_terms, coriolis_matrix, mass_matrix_derivative};
//!
//! let model = Model::paper_arm();
//! let mut ws = Workspace::new(&model);
//! let (q, qd) = ([0.3, -0.7], [1.2, 0.4]);
//! let terms = dynamics_terms(&model, &mut ws, &q, &qd, Formulation::EulerLagrange);
//! // h11 = 2.3515719820 + 0.167616 cos q2 (the paper's eq. 106)
//! assert!((terms.mass_matrix[(0, 0)] - (2.3515719820 + 0.167616 * (-0.7f64).cos())).abs() < 1e-9);
//! // Ḣ − 2C is skew-symmetric for the Euler–Lagrange C
//! let hdot = mass_matrix_derivative(&model, &mut ws, &q, &qd);
//! let n = &hdot - 2.0 * &terms.coriolis_matrix;
//! assert!((&n + n.transpose()).norm() < 1e-12);
//! // the simplified C is Ḣ / 2
//! let c_simple = coriolis_matrix(&model, &mut ws, &q, &qd, Formulation::Simplified);
//! assert!((c_simple - 0.5 * hdot).norm() < 1e-12);
//! ```
//!
//! # Batches
//!
//! The [`batch`] functions (`mass_matrix_batch`, `dynamics_terms_batch`, ...) evaluate many
//! states at once, several per SIMD register (AVX-512 or AVX2, picked at run time).
//!
//! References: R. Featherstone, *Rigid Body Dynamics Algorithms*, 2008; S. Echeandia and
//! P. M. Wensing, "Numerical methods to compute the Coriolis matrix and Christoffel symbols for
//! rigid-body systems", J. Comput. Nonlinear Dynam., 2021.

pub mod algorithms;
pub mod batch;
pub mod error;
pub mod formulation;
pub(crate) mod lanes;
pub mod model;
pub mod robots;
pub mod sincos;
pub mod spatial;
pub mod urdf;

pub use algorithms::aba::forward_dynamics_aba_into;
pub use algorithms::coriolis::{coriolis_matrix, coriolis_matrix_into, mass_matrix_derivative, mass_matrix_derivative_into};
pub use algorithms::crba::{mass_matrix, mass_matrix_into};
pub use algorithms::energy::{kinetic_energy, potential_energy};
pub use algorithms::forward_dynamics::{
    forward_dynamics, forward_dynamics_armature_into, forward_dynamics_crba_into, forward_dynamics_into, solve_spd_in_place, try_forward_dynamics_into, try_solve_spd_in_place,
    ABA_MIN_DOF,
};
pub use algorithms::kinematics::forward_kinematics;
pub use algorithms::regressor::{inertia_from_parameters, inertial_parameters, inverse_dynamics_regressor, inverse_dynamics_regressor_into, PARAMS_PER_LINK};
pub use algorithms::rnea::{
    bias_torques, bias_torques_into, coriolis_torques, coriolis_torques_into, gravity_torques, gravity_torques_into, inverse_dynamics, inverse_dynamics_into,
};
pub use algorithms::terms::{dynamics_terms, dynamics_terms_into, DynamicsTerms};
pub use algorithms::workspace::{self, Workspace};
pub use batch::{
    batch_lanes, bias_torques_batch, coriolis_matrix_batch, coriolis_torques_batch, dynamics_terms_batch, gravity_torques_batch, inverse_dynamics_batch, mass_matrix_batch,
    mass_matrix_derivative_batch,
};
pub use error::{Error, Result};
pub use formulation::Formulation;
pub use model::{Joint, JointKind, JointLimits, Model, STANDARD_GRAVITY};
pub use robots::{ARM7_URDF, PAPER_ARM_URDF, PENDULUM_URDF};
pub use spatial::{Force, Motion, SpatialInertia, Transform};
pub use urdf::UrdfOptions;
