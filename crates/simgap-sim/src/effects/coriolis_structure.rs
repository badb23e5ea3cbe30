//! The Coriolis structure ([`Effect::CoriolisStructure`]): the plant uses the other
//! formulation of C than the model under test. It has no parameter and adds no torque here;
//! the [`Plant`](crate::plant::Plant) switches the formulation.

use super::spelling::Spelling;
use super::{Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// The Coriolis structure (no parameter).
pub(super) struct CoriolisStructure;

impl Simulated for CoriolisStructure {
    fn kind(&self) -> EffectKind {
        EffectKind::CoriolisStructure
    }

    fn validate(&self, _dof: usize) -> Result<()> {
        Ok(())
    }

    fn joints_acted(&self) -> Vec<usize> {
        Vec::new()
    }
}

/// Reads nothing (the effect has no parameter).
pub(super) fn parse(_s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::CoriolisStructure)
}
