//! The candidates: every effect of the vocabulary as one group of terms (scored alone by the
//! candidates stage, `pipeline/candidates.rs`, and on the held-out runs by the screen,
//! `pipeline/screen.rs`), and the selection's treatment of passive joints and of logs without
//! motion.

use simgap_sim::EffectKind;

use crate::select::{families, Context, Selection};
use crate::vocabulary::{Column, Term};

/// Removes torque gain, offset and saturation terms of passive joints (nothing drives them).
pub(crate) fn drop_passive_actuator_terms(terms: &mut Vec<Term>, passive: &[bool]) {
    terms.retain(|t| !(matches!(t, Term::Gain(_) | Term::Offset(_) | Term::Saturation { .. }) && t.joint().is_some_and(|j| passive[j])));
}

pub(crate) fn select_nothing(ctx: &Context<'_>) -> Selection {
    let (designs, _, f) = ctx.fit_terms(&[]);
    Selection { terms: vec![], nominal_cv_mse: f.cv_mse, fit: f, designs, log: vec![] }
}

/// Every effect of the vocabulary as one candidate: per-joint families on every joint (best
/// grid member per joint against the nominal residual), whole-robot ones once.
pub(crate) fn candidate_groups(ctx: &Context<'_>, resid: &Column) -> Vec<(&'static str, Vec<Term>)> {
    let mut groups: Vec<(&'static str, Vec<Term>)> = Vec::new();
    let fams = families(ctx.data);
    for f in &fams {
        let t = ctx.best_of(f, resid);
        let name = t.effect_name();
        match groups.iter_mut().find(|g| g.0 == name) {
            Some(g) => g.1.push(t),
            None => groups.push((name, vec![t])),
        }
    }
    if ctx.inertial_basis.ncols() > 0 {
        groups.push((EffectKind::InertialError.as_str(), vec![ctx.inertial_term()]));
    }
    groups
}
