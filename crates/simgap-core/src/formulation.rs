//! The two Coriolis matrices a model is evaluated with (see the crate root): the Christoffel
//! (Euler–Lagrange) one and the seed paper's simplified `C = Ḣ / 2`.

/// Which Coriolis matrix: see the crate root.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Formulation {
    /// Christoffel symbols of the first kind: `Ḣ − 2C` skew-symmetric, `C q̇` the true
    /// Coriolis/centrifugal torque.
    #[default]
    EulerLagrange,
    /// The seed paper's `C = Ḣ / 2` (Sánchez-Sánchez & Arteaga-Pérez 2012, eqs. 24–32):
    /// symmetric, energy-consistent, but `C q̇` lacks the skew-symmetric part.
    Simplified,
}

impl Formulation {
    /// Both formulations, Euler–Lagrange first.
    pub const ALL: [Formulation; 2] = [Formulation::EulerLagrange, Formulation::Simplified];

    /// The CLI / JSON spelling: `euler-lagrange` or `simplified`.
    pub fn as_str(self) -> &'static str {
        match self {
            Formulation::EulerLagrange => "euler-lagrange",
            Formulation::Simplified => "simplified",
        }
    }

    /// The other formulation.
    pub fn other(self) -> Formulation {
        match self {
            Formulation::EulerLagrange => Formulation::Simplified,
            Formulation::Simplified => Formulation::EulerLagrange,
        }
    }
}

impl std::fmt::Display for Formulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Formulation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().replace('_', "-").as_str() {
            "euler-lagrange" | "el" | "lagrange" => Ok(Formulation::EulerLagrange),
            "simplified" | "simple" | "paper" => Ok(Formulation::Simplified),
            other => Err(format!("unknown formulation '{other}'; expected euler-lagrange or simplified")),
        }
    }
}
