//! `coriolis_structure`: the model's C misses (or wrongly has) its skew-symmetric part; the
//! fixed column `(C_other − C) q̇` (no parameter) is the other formulation's difference.

use super::{Column, TermDesign};
use crate::prepare::dataset::FitData;

/// The fixed column of the other formulation of C.
pub(super) fn design(data: &[FitData]) -> TermDesign {
    let v = data.iter().flat_map(|d| d.coriolis_delta.iter().copied()).collect();
    TermDesign::fixed(Column::new(None, v))
}

/// The structure in words.
pub(super) fn describe() -> String {
    "the model's Coriolis matrix C misses (or wrongly has) its skew-symmetric part: the other formulation fits better".into()
}
