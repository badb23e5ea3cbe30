//! Units of a report's figures by joint type: positions in rad or m, velocities in rad/s or m/s,
//! efforts in N·m or N. A figure pooled over joints of both types is stated in both units.

use simgap_core::JointKind;
use simgap_sim::Quantity;

/// The units of positions, velocities and efforts over a set of joints.
#[derive(Clone, Debug, PartialEq)]
pub struct Units {
    /// rad, m, or "rad or m" for a mix.
    pub position: String,
    /// rad/s, m/s, or both.
    pub velocity: String,
    /// N·m, N, or both.
    pub effort: String,
}

impl Units {
    /// The units of figures pooled over joints of types `kinds`.
    pub fn of(kinds: &[JointKind]) -> Units {
        let pooled = |q: Quantity| {
            let rotational = kinds.is_empty() || kinds.iter().any(|k| k.is_rotational());
            let linear = kinds.iter().any(|k| !k.is_rotational());
            match (rotational, linear) {
                (true, true) => format!("{} or {}", q.unit(JointKind::Revolute), q.unit(JointKind::Prismatic)),
                (false, true) => q.unit(JointKind::Prismatic).to_string(),
                _ => q.unit(JointKind::Revolute).to_string(),
            }
        };
        Units { position: pooled(Quantity::Position), velocity: pooled(Quantity::Velocity), effort: pooled(Quantity::Effort) }
    }

    /// The units of one joint of type `kind`.
    pub(crate) fn joint(kind: JointKind) -> Units {
        Units::of(&[kind])
    }

    /// The units of joints given by their URDF type names (`revolute`, `continuous`,
    /// `prismatic`, as the report's `joint_types` holds them).
    pub(crate) fn of_types(types: &[String]) -> Units {
        Units::of(&kinds_of(types))
    }
}

/// Joint kinds from URDF type names (anything but `prismatic` turns).
pub(crate) fn kinds_of(types: &[String]) -> Vec<JointKind> {
    types.iter().map(|t| if t == "prismatic" { JointKind::Prismatic } else { JointKind::Revolute }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_follow_the_joint_type() {
        assert_eq!(Units::of(&[JointKind::Revolute]).position, "rad");
        assert_eq!(Units::of(&[JointKind::Prismatic]).effort, "N");
        assert_eq!(Units::of(&[JointKind::Prismatic, JointKind::Prismatic]).velocity, "m/s");
        assert_eq!(Units::of(&[JointKind::Continuous, JointKind::Prismatic]).position, "rad or m");
    }
}
