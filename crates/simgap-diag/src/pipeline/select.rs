//! The select stage: forward stepwise selection on the torque residual ([`crate::select`]).

use crate::options::SelectOptions;
use crate::prepare::Prepared;
use crate::select::screen::{drop_passive_actuator_terms, select_nothing};
use crate::select::{select, Context, Selection};

/// The select stage: every effect of the vocabulary a family of candidate terms, fitted by
/// bounded least squares and compared by block cross-validation; a forward stepwise selection
/// proposes a set (none when the fit runs do not move). Actuator terms of passive joints leave.
pub(crate) fn select_on_residual(ctx: &Context<'_>, prep: &Prepared, options: &SelectOptions) -> Selection {
    // stepwise on the torque residual
    let mut selection = if prep.moving { select(ctx, options) } else { select_nothing(ctx) };
    // nothing drives a passive joint
    drop_passive_actuator_terms(&mut selection.terms, &prep.passive);
    selection
}
