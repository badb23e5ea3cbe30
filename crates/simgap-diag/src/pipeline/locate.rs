//! The locate stage: where the gap lies, from the nominal model re-simulated in closed loop on
//! the fit runs ([`crate::locate`]).

use rayon::prelude::*;
use simgap_core::{Formulation, Model};
use simgap_sim::Run;

use crate::locate::{locate, Where};
use crate::prediction::resim::{self, RunGap};
use crate::prepare::Prepared;

/// What the locate stage found.
pub(crate) struct Located {
    /// Where the gap lies: joints, phases, residual correlations.
    pub(crate) location: Where,
    /// The nominal model's closed-loop gap on each fit run.
    pub(crate) fit_nominal: Vec<RunGap>,
}

/// The locate stage: the nominal model re-simulated in closed loop on every fit run, and where
/// the gap between simulation and logs lies.
pub(crate) fn locate_gap(model: &Model, formulation: Formulation, prep: &Prepared) -> Located {
    // the nominal closed loop on the fit runs
    let fit_nominal: Vec<(RunGap, Option<Run>)> = prep.fit_runs.par_iter().map(|r| resim::gap(model, formulation, &[], r)).collect();
    let nominal_sims: Vec<Option<Run>> = fit_nominal.iter().map(|g| g.1.clone()).collect();
    // where: joints, phases, residual correlations
    let location = locate(&prep.joints, &prep.data, &prep.fit_runs, &nominal_sims);
    Located { location, fit_nominal: fit_nominal.into_iter().map(|g| g.0).collect() }
}
