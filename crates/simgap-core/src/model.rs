//! The immutable [`Model`]: joint placements, axes, link inertias and gravity of a serial chain.

use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::spatial::{SpatialInertia, Transform};

/// Kind of a movable joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum JointKind {
    /// Rotation about the axis, within position limits [rad].
    Revolute,
    /// Rotation about the axis without limits (one angle, not wrapped) [rad].
    Continuous,
    /// Translation along the axis [m].
    Prismatic,
}

impl JointKind {
    /// True for revolute and continuous joints.
    pub fn is_rotational(self) -> bool {
        !matches!(self, JointKind::Prismatic)
    }

    /// The URDF spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
        }
    }
}

/// Joint limits; absent limits are infinite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits {
    /// Lower position limit [rad or m].
    pub lower: f64,
    /// Upper position limit [rad or m].
    pub upper: f64,
    /// Actuator effort limit [N·m or N].
    pub effort: f64,
    /// Velocity limit [rad/s or m/s].
    pub velocity: f64,
}

impl Default for JointLimits {
    fn default() -> Self {
        JointLimits { lower: f64::NEG_INFINITY, upper: f64::INFINITY, effort: f64::INFINITY, velocity: f64::INFINITY }
    }
}

/// One movable joint and the link it moves.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Joint name (as in the URDF).
    pub name: String,
    /// Revolute, continuous or prismatic.
    pub kind: JointKind,
    /// Unit axis in the joint frame.
    pub axis: Vector3<f64>,
    /// Placement of the joint frame in the parent link frame at `q = 0`.
    pub placement: Transform,
    /// Limits (infinite where the URDF gives none).
    pub limits: JointLimits,
    /// Name of the child link (the frame the joint moves).
    pub link: String,
    /// Inertia of the child link, fixed descendants merged, about the joint frame origin.
    pub inertia: SpatialInertia,
}

impl Joint {
    /// A joint with default limits.
    pub fn new(name: impl Into<String>, kind: JointKind, axis: Vector3<f64>, placement: Transform, link: impl Into<String>, inertia: SpatialInertia) -> Self {
        Joint { name: name.into(), kind, axis, placement, limits: JointLimits::default(), link: link.into(), inertia }
    }
}

/// Precomputed pieces of the joint transform: `R(q) = a + cos q · b + sin q · d`
/// (Rodrigues' formula premultiplied by the placement rotation).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct JointCache {
    pub(crate) a: Matrix3<f64>,
    pub(crate) b: Matrix3<f64>,
    pub(crate) d: Matrix3<f64>,
    /// Placement rotation times axis (prismatic translation direction in the parent frame).
    pub(crate) placed_axis: Vector3<f64>,
}

/// A serial chain: the immutable parameters of every dynamics algorithm.
///
/// Built once (from URDF with [`Model::from_urdf_file`], or in code with [`Model::new`]) and
/// shared freely. It holds parameters only: all scratch space, and everything derived from the
/// parameters by running an algorithm (the closed form of a two-joint arm), lives in a
/// [`Workspace`](crate::Workspace), as Pinocchio splits `Model` and `Data`.
#[derive(Clone, Debug)]
pub struct Model {
    name: String,
    base_link: String,
    joints: Vec<Joint>,
    gravity: Vector3<f64>,
    cache: Vec<JointCache>,
    warnings: Vec<String>,
    /// See [`Model::revision`].
    revision: u64,
}

/// Equal parameters, names and warnings; the revision is not compared (two models built alike
/// are equal).
impl PartialEq for Model {
    fn eq(&self, other: &Self) -> bool {
        let Model { name, base_link, joints, gravity, cache, warnings, revision: _ } = self;
        *name == other.name && *base_link == other.base_link && *joints == other.joints && *gravity == other.gravity && *cache == other.cache && *warnings == other.warnings
    }
}

/// The next [`Model::revision`].
static NEXT_REVISION: AtomicU64 = AtomicU64::new(1);

fn next_revision() -> u64 {
    NEXT_REVISION.fetch_add(1, Ordering::Relaxed)
}

/// Standard gravity along −z [m/s²].
pub const STANDARD_GRAVITY: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

impl Model {
    /// Builds a model from joints in chain order (joint `i+1`'s parent link is joint `i`'s child).
    ///
    /// Axes are normalised. Gravity defaults to [`STANDARD_GRAVITY`]; see [`Model::set_gravity`].
    ///
    /// # Errors
    /// [`Error::InvalidModel`] for an empty chain, a zero or non-finite axis, non-finite numbers,
    /// or a non-physical inertia; [`Error::Massless`] if every link is massless.
    pub fn new(name: impl Into<String>, base_link: impl Into<String>, mut joints: Vec<Joint>) -> Result<Self> {
        if joints.is_empty() {
            return Err(Error::InvalidModel("a model needs at least one movable joint".into()));
        }
        for j in &mut joints {
            let n = j.axis.norm();
            if !(n.is_finite() && n > 0.0) {
                return Err(Error::InvalidModel(format!("joint '{}' has axis {:?}; expected a finite non-zero direction", j.name, j.axis.as_slice())));
            }
            j.axis /= n;
            let finite = j.placement.rotation.iter().chain(j.placement.translation.iter()).all(|x| x.is_finite());
            if !finite {
                return Err(Error::InvalidModel(format!("joint '{}' has a non-finite placement", j.name)));
            }
            check_inertia("<code>", &j.link, &j.inertia).map_err(|e| Error::InvalidModel(e.to_string()))?;
        }
        if joints.iter().all(|j| j.inertia.mass == 0.0 && j.inertia.rotational == Matrix3::zeros()) {
            return Err(Error::Massless { source_name: "<code>".into(), links: joints.iter().map(|j| j.link.clone()).collect() });
        }
        let cache = joints.iter().map(JointCache::new).collect();
        Ok(Model { name: name.into(), base_link: base_link.into(), joints, gravity: STANDARD_GRAVITY, cache, warnings: Vec::new(), revision: next_revision() })
    }

    /// Robot name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Name of the root link (the world frame).
    pub fn base_link(&self) -> &str {
        &self.base_link
    }

    /// Number of degrees of freedom (movable joints).
    #[inline]
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The joints in chain order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Joint names in chain order (the order of every vector this crate takes or returns).
    pub fn joint_names(&self) -> Vec<&str> {
        self.joints.iter().map(|j| j.name.as_str()).collect()
    }

    /// Index of a joint by name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Gravity acceleration in the base frame [m/s²].
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }

    /// Sets gravity [m/s²] (default −9.81 along z).
    pub fn set_gravity(&mut self, gravity: Vector3<f64>) {
        self.gravity = gravity;
        self.revision = next_revision();
    }

    /// Replaces the inertia of the link moved by joint `index`.
    ///
    /// # Errors
    /// [`Error::InvalidModel`] when the inertia is not physical.
    ///
    /// # Panics
    /// If `index >= self.dof()`.
    pub fn set_link_inertia(&mut self, index: usize, inertia: SpatialInertia) -> Result<()> {
        check_inertia("<code>", &self.joints[index].link, &inertia).map_err(|e| Error::InvalidModel(e.to_string()))?;
        self.joints[index].inertia = inertia;
        self.revision = next_revision();
        Ok(())
    }

    /// Sets the limits of joint `index`.
    ///
    /// # Panics
    /// If `index >= self.dof()`.
    pub fn set_limits(&mut self, index: usize, limits: JointLimits) {
        self.joints[index].limits = limits;
    }

    /// Total mass of the chain [kg].
    pub fn total_mass(&self) -> f64 {
        self.joints.iter().map(|j| j.inertia.mass).sum()
    }

    /// Warnings raised while loading (massless links, locked off-chain joints).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    pub(crate) fn push_warning(&mut self, w: String) {
        self.warnings.push(w);
    }

    /// Identifies the parameters of this model within the process: a number drawn from a
    /// process-wide counter when the model is built and again whenever a parameter the
    /// dynamics depend on changes ([`Model::set_gravity`], [`Model::set_link_inertia`]); a
    /// clone keeps it. A [`Workspace`](crate::Workspace) keys what it derives from a model by it.
    #[inline]
    pub(crate) fn revision(&self) -> u64 {
        self.revision
    }

    /// The precomputed pieces of joint `i`'s transform.
    #[inline]
    pub(crate) fn joint_cache(&self, i: usize) -> &JointCache {
        &self.cache[i]
    }

    /// Transform from the parent link frame to joint `i`'s frame at position `qi`.
    #[inline]
    pub fn joint_transform(&self, i: usize, qi: f64) -> Transform {
        let j = &self.joints[i];
        let c = &self.cache[i];
        if j.kind.is_rotational() {
            let (s, co) = crate::sincos::sin_cos(qi);
            Transform { rotation: c.a + c.b * co + c.d * s, translation: j.placement.translation }
        } else {
            Transform { rotation: j.placement.rotation, translation: j.placement.translation + c.placed_axis * qi }
        }
    }

    /// The model with the joints `names` locked at `q = 0`: each one's link becomes part of
    /// the link before it (its inertia added there through the joint's placement; the first
    /// joint's link joins the fixed base), and the next joint's placement takes the locked
    /// joint's in front of its own, as the URDF loader locks joints off the chain. The
    /// dynamics of the result at `q` equal the full model's at `q` with zeros inserted for the
    /// locked joints, for every quantity of the remaining joints. `reason` ends the warning
    /// the new model adds (its other warnings are kept).
    ///
    /// # Errors
    /// [`Error::InvalidModel`] when a name is no joint of the model or every joint would be
    /// locked; [`Error::Massless`] when every remaining link is massless.
    pub fn with_joints_locked(&self, names: &[&str], reason: &str) -> Result<Model> {
        if let Some(n) = names.iter().find(|n| self.joint_index(n).is_none()) {
            return Err(Error::InvalidModel(format!("cannot lock joint '{n}': the model's joints are {:?}", self.joint_names())));
        }
        let mut joints: Vec<Joint> = Vec::new();
        // the placement a locked joint leaves to the next joint, from the last kept link
        let mut carried = Transform::IDENTITY;
        for j in &self.joints {
            let placement = carried.compose(&j.placement);
            if names.contains(&j.name.as_str()) {
                if let Some(prev) = joints.last_mut() {
                    prev.inertia += j.inertia.transformed(&placement);
                }
                carried = placement;
            } else {
                joints.push(Joint { placement, ..j.clone() });
                carried = Transform::IDENTITY;
            }
        }
        if joints.is_empty() {
            return Err(Error::InvalidModel(format!("cannot lock every joint of '{}' ({names:?})", self.name)));
        }
        let mut model = Model::new(self.name.clone(), self.base_link.clone(), joints)?;
        model.gravity = self.gravity;
        model.warnings = self.warnings.clone();
        model.warnings.push(format!("joints {names:?} are locked at their zero position: {reason}"));
        Ok(model)
    }
}

impl JointCache {
    fn new(j: &Joint) -> Self {
        let r = &j.placement.rotation;
        let ax = &j.axis;
        let a = r * (ax * ax.transpose());
        JointCache { a, b: r - a, d: r * ax.cross_matrix(), placed_axis: r * ax }
    }
}

/// Checks that a link inertia is physical: finite, mass ≥ 0, rotational inertia about the
/// centre of mass symmetric positive semi-definite and obeying the triangle inequality.
pub(crate) fn check_inertia(source: &str, link: &str, inertia: &SpatialInertia) -> Result<()> {
    let all = std::iter::once(inertia.mass).chain(inertia.first_moment.iter().copied()).chain(inertia.rotational.iter().copied());
    for v in all {
        if !v.is_finite() {
            return Err(Error::NonFinite { source_name: source.into(), element: format!("link '{link}'"), field: "inertial".into(), value: v });
        }
    }
    if inertia.mass < 0.0 {
        return Err(Error::NegativeMass { source_name: source.into(), link: link.into(), mass: inertia.mass });
    }
    check_rotational_inertia(source, link, &inertia.inertia_about_com())
}

/// Checks a rotational inertia about the centre of mass.
pub(crate) fn check_rotational_inertia(source: &str, link: &str, i: &Matrix3<f64>) -> Result<()> {
    let scale = i.abs().max().max(1e-300);
    let tol = 1e-9 * scale;
    if (i - i.transpose()).abs().max() > tol {
        return Err(Error::NonPhysicalInertia { source_name: source.into(), link: link.into(), detail: "rotational inertia is not symmetric; expected a symmetric matrix".into() });
    }
    let eig = i.symmetric_eigenvalues();
    let (a, b, c) = (eig[0], eig[1], eig[2]);
    if a < -tol || b < -tol || c < -tol {
        return Err(Error::NonPhysicalInertia {
            source_name: source.into(),
            link: link.into(),
            detail: format!("principal moments {:.6e}, {:.6e}, {:.6e}; expected all >= 0 (positive semi-definite)", a, b, c),
        });
    }
    if a + b < c - tol || b + c < a - tol || a + c < b - tol {
        return Err(Error::NonPhysicalInertia {
            source_name: source.into(),
            link: link.into(),
            detail: format!("principal moments {:.6e}, {:.6e}, {:.6e} break the triangle inequality; expected each <= the sum of the other two", a, b, c),
        });
    }
    Ok(())
}
