//! Prediction: k-step-ahead prediction restarted from the measured state ([`kstep`]) and the
//! whole-run closed-loop re-simulation ([`resim`]) of logged runs, with and without effects.

pub(crate) mod kstep;
pub(crate) mod resim;

/// Most RK4 steps per sample a smoothed dry friction may ask for in a prediction or a
/// re-simulation: a band that would need more is integrated as the exact sign
/// ([`simgap_sim::unresolved_bands_exact`]).
pub(crate) const MAX_BAND_SUBSTEPS: usize = 16;
