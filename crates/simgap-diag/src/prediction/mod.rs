//! Prediction: k-step-ahead prediction restarted from the measured state ([`kstep`]) and the
//! whole-run closed-loop re-simulation ([`resim`]) of logged runs, with and without effects.

pub(crate) mod kstep;
pub(crate) mod resim;
