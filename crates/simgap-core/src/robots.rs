//! Built-in robots.

use nalgebra::{Matrix3, Vector3};

use crate::model::{Joint, JointKind, JointLimits, Model};
use crate::spatial::{SpatialInertia, Transform};

/// The seed paper's arm as URDF text (`models/paper_arm.urdf`).
pub const PAPER_ARM_URDF: &str = include_str!("../models/paper_arm.urdf");

/// Table 2 of Sánchez-Sánchez & Arteaga-Pérez (2012): the arm and its drives. The experiment
/// the paper runs on it (gains, set point, sample period) is `simgap_sim::paper`.
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

/// splitmix64 (Steele, Lea & Flood 2014): a tiny deterministic generator, so that
/// [`Model::random_chain`] needs no `rand` dependency.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        lo + (hi - lo) * unit
    }

    fn vector(&mut self, lo: f64, hi: f64) -> Vector3<f64> {
        Vector3::new(self.uniform(lo, hi), self.uniform(lo, hi), self.uniform(lo, hi))
    }

    /// A random unit vector (uniform on the sphere, by rejection from the cube).
    fn unit_vector(&mut self) -> Vector3<f64> {
        loop {
            let v = self.vector(-1.0, 1.0);
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }

    /// A random rotation from random roll, pitch and yaw.
    fn rotation(&mut self) -> Matrix3<f64> {
        let pi = std::f64::consts::PI;
        let rpy = [self.uniform(-pi, pi), self.uniform(-pi / 2.0, pi / 2.0), self.uniform(-pi, pi)];
        Transform::from_xyz_rpy([0.0; 3], rpy).rotation
    }
}

impl Model {
    /// A random serial chain of `n` joints, deterministic from `seed`; intended for tests,
    /// benchmarks and self-checks, not as a robot.
    ///
    /// Joints are a mix of revolute, continuous and prismatic (about one in four prismatic),
    /// with random unit axes; each placement has a random rotation (roll, pitch, yaw) and a
    /// translation of up to 0.5 m per coordinate; each link has a mass of 0.5–5 kg, a centre of
    /// mass up to 0.2 m from its frame, and a physical rotational inertia (the second moments of
    /// a random point-mass distribution, so positive definite and obeying the triangle
    /// inequality) in random principal axes. Gravity is [`STANDARD_GRAVITY`](crate::STANDARD_GRAVITY).
    /// Joint `i` is named `joint<i>` and moves link `link<i>`; the base is `base_link`.
    ///
    /// The random numbers come from splitmix64, so the same `(n, seed)` gives the same model on
    /// every platform and version of this crate's dependencies.
    ///
    /// # Panics
    /// If `n == 0`.
    #[must_use]
    pub fn random_chain(n: usize, seed: u64) -> Model {
        assert!(n > 0, "a random chain needs at least one joint");
        let mut rng = SplitMix64(seed);
        let pi = std::f64::consts::PI;
        let joints = (0..n)
            .map(|i| {
                // joint kind, axis and limits
                let kind = match rng.next_u64() % 8 {
                    0 | 1 => JointKind::Prismatic,
                    2 => JointKind::Continuous,
                    _ => JointKind::Revolute,
                };
                let axis = rng.unit_vector();
                let placement = Transform { rotation: rng.rotation(), translation: rng.vector(-0.5, 0.5) };
                // physical inertia: second moments (x, y, z) of a point-mass cloud, rotated
                let mass = rng.uniform(0.5, 5.0);
                let com = rng.vector(-0.2, 0.2);
                let s = rng.vector(0.001, 0.05) * mass;
                let principal = Matrix3::from_diagonal(&Vector3::new(s.y + s.z, s.x + s.z, s.x + s.y));
                let r = rng.rotation();
                let inertia = SpatialInertia::from_com(mass, com, r * principal * r.transpose());
                let mut joint = Joint::new(format!("joint{i}"), kind, axis, placement, format!("link{i}"), inertia);
                joint.limits = match kind {
                    JointKind::Revolute => JointLimits { lower: -pi, upper: pi, effort: 100.0, velocity: 10.0 },
                    JointKind::Continuous => JointLimits { effort: 100.0, velocity: 10.0, ..JointLimits::default() },
                    JointKind::Prismatic => JointLimits { lower: -1.0, upper: 1.0, effort: 500.0, velocity: 2.0 },
                };
                joint
            })
            .collect();
        Model::new(format!("random_chain_{n}_{seed}"), "base_link", joints).expect("a random chain is a valid model")
    }
}

/// The 1-link pendulum test model (`models/pendulum.urdf`).
pub const PENDULUM_URDF: &str = include_str!("../models/pendulum.urdf");

/// The 7-DOF Panda-like test arm (`models/arm7.urdf`); its gripper fingers branch off the hand,
/// so load it with tip `panda_hand`.
pub const ARM7_URDF: &str = include_str!("../models/arm7.urdf");
