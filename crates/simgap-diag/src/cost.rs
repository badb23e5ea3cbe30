//! What diagnoses cost, counted process-wide: the candidate sets scored by cross-validated
//! k-step prediction and the RK4 steps the k-step predictions integrated. `simgap diagnose
//! --timings` prints them per stage beside the wall time; several diagnoses running at once in
//! one process (a fleet on threads) add to the same counters.

use std::sync::atomic::{AtomicU64, Ordering};

static SETS_SCORED: AtomicU64 = AtomicU64::new(0);
static STEPS: AtomicU64 = AtomicU64::new(0);

/// The counters at one moment: read before and after a piece of work, the difference is its
/// cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    /// Candidate sets scored by cross-validated k-step prediction of the fit runs (a set already
    /// scored is remembered and not counted again).
    pub sets_scored: u64,
    /// RK4 steps integrated by k-step predictions (each is four evaluations of the plant's
    /// forward dynamics).
    pub steps: u64,
}

/// The counters now.
pub fn cost() -> Cost {
    Cost { sets_scored: SETS_SCORED.load(Ordering::Relaxed), steps: STEPS.load(Ordering::Relaxed) }
}

impl std::ops::Sub for Cost {
    type Output = Cost;
    fn sub(self, before: Cost) -> Cost {
        Cost { sets_scored: self.sets_scored.saturating_sub(before.sets_scored), steps: self.steps.saturating_sub(before.steps) }
    }
}

/// One more set scored.
pub(crate) fn add_set() {
    SETS_SCORED.fetch_add(1, Ordering::Relaxed);
}

/// `steps` more RK4 steps integrated.
pub(crate) fn add_steps(steps: u64) {
    STEPS.fetch_add(steps, Ordering::Relaxed);
}
