//! A time delay of the whole robot's command, `τ_applied(t) = τ_cmd(t − delay)` [s]
//! ([`Effect::TimeDelay`]); the simulator's delay line applies it.

use super::spelling::Spelling;
use super::{invalid, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A time delay's parameter.
pub(super) struct TimeDelay {
    /// Delay [s], `>= 0`.
    pub(super) delay: f64,
}

impl Simulated for TimeDelay {
    fn kind(&self) -> EffectKind {
        EffectKind::TimeDelay
    }

    fn validate(&self, _dof: usize) -> Result<()> {
        let delay = self.delay;
        if !(delay.is_finite() && delay >= 0.0) {
            return Err(invalid(self.kind().as_str(), format!("delay = {delay}; expected a finite number >= 0 [s]")));
        }
        Ok(())
    }

    fn joints_acted(&self) -> Vec<usize> {
        Vec::new()
    }

    fn delay(&self) -> f64 {
        self.delay
    }
}

/// Reads `delay` (one number, seconds).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::TimeDelay { delay: s.scalar("delay")? })
}
