//! Built-in robots.

use nalgebra::{Matrix3, Vector3};

use crate::model::{Joint, JointKind, JointLimits, Model};
use crate::spatial::{SpatialInertia, Transform};

/// The seed paper's arm as URDF text (`models/paper_arm.urdf`).
pub const PAPER_ARM_URDF: &str = include_str!("../models/paper_arm.urdf");

/// Table 2 of Sánchez-Sánchez & Arteaga-Pérez (2012).
pub mod paper_arm {
    /// Link lengths [m].
    pub const L1: f64 = 0.45;
    /// Link lengths [m].
    pub const L2: f64 = 0.45;
    /// Distance from joint to centre of mass [m].
    pub const LC1: f64 = 0.091;
    /// Distance from joint to centre of mass [m].
    pub const LC2: f64 = 0.048;
    /// Masses [kg].
    pub const M1: f64 = 23.902;
    /// Masses [kg].
    pub const M2: f64 = 3.88;
    /// Inertias about the centres of mass [kg·m²].
    pub const I1: f64 = 1.266;
    /// Inertias about the centres of mass [kg·m²].
    pub const I2: f64 = 0.093;
    /// Gravity [m/s²].
    pub const G: f64 = 9.81;
    /// Peak motor torques, shoulder and elbow [N·m].
    pub const TORQUE_LIMITS: [f64; 2] = [200.0, 15.0];
    /// Encoder counts per revolution.
    pub const COUNTS_PER_REV: f64 = 1_024_000.0;
    /// PD gains of the experiment (§5, Table 3).
    pub const KP: [f64; 2] = [64.72, 32.36];
    /// PD gains of the experiment (§5, Table 3).
    pub const KV: [f64; 2] = [48.54, 6.472];
    /// Desired position of the experiment [rad].
    pub const Q_DESIRED: [f64; 2] = [std::f64::consts::FRAC_PI_4, std::f64::consts::FRAC_PI_2];
    /// Controller sample period [s].
    pub const SAMPLE_PERIOD: f64 = 0.0025;
}

impl Model {
    /// The seed paper's 2-DOF vertical arm (Table 2), built in code; identical to loading
    /// [`PAPER_ARM_URDF`]. Joints `shoulder` and `elbow` rotate about y; q = 0 hangs down.
    #[must_use]
    pub fn paper_arm() -> Model {
        use paper_arm::*;
        let link = |m: f64, lc: f64, i: f64, izz: f64| SpatialInertia::from_com(m, Vector3::new(0.0, 0.0, -lc), Matrix3::from_diagonal(&Vector3::new(i, i, izz)));
        let limits = |effort: f64| JointLimits { lower: -std::f64::consts::PI, upper: std::f64::consts::PI, effort, velocity: 10.0 };
        let mut shoulder = Joint::new("shoulder", JointKind::Revolute, Vector3::y(), Transform::IDENTITY, "upper_arm", link(M1, LC1, I1, 0.05));
        shoulder.limits = limits(TORQUE_LIMITS[0]);
        let placement = Transform { rotation: Matrix3::identity(), translation: Vector3::new(0.0, 0.0, -L1) };
        let mut elbow = Joint::new("elbow", JointKind::Revolute, Vector3::y(), placement, "forearm", link(M2, LC2, I2, 0.01));
        elbow.limits = limits(TORQUE_LIMITS[1]);
        let mut model = Model::new("paper_arm", "base_link", vec![shoulder, elbow]).expect("the paper arm is a valid model");
        model.set_gravity(Vector3::new(0.0, 0.0, -G));
        model
    }
}
