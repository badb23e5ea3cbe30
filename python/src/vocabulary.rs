//! `effect_vocabulary()`: the effect names, their parameters, units by joint type and neutral
//! values, read from `simgap_sim::EffectKind` (the one list of names).

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use simgap_core::JointKind;
use simgap_sim::EffectKind;

/// effect_vocabulary() -> list[dict]
/// --
///
/// Every effect of the vocabulary, in the documented order, as
/// ``{"name": str, "whole_robot": bool, "parameters": [{"name": str, "quantity": str,
/// "unit": {"revolute": str,
/// "prismatic": str}, "neutral": float | None, "estimated": bool}]}``. ``neutral`` is the value
/// at which the effect is absent (``None`` where there is none, e.g. a period count);
/// ``estimated`` is false for values searched on a grid and for counts, which carry no interval.
#[pyfunction]
pub(crate) fn effect_vocabulary(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let out = PyList::empty(py);
    for kind in EffectKind::ALL {
        let params = PyList::empty(py);
        for spec in kind.parameters() {
            let unit = PyDict::new(py);
            unit.set_item("revolute", spec.quantity.unit(JointKind::Revolute))?;
            unit.set_item("prismatic", spec.quantity.unit(JointKind::Prismatic))?;
            let p = PyDict::new(py);
            p.set_item("name", spec.name)?;
            p.set_item("quantity", spec.quantity.name())?;
            p.set_item("unit", unit)?;
            p.set_item("neutral", spec.neutral)?;
            p.set_item("estimated", spec.estimated)?;
            params.append(p)?;
        }
        let e = PyDict::new(py);
        e.set_item("name", kind.as_str())?;
        e.set_item("whole_robot", kind.whole_robot())?;
        e.set_item("parameters", params)?;
        out.append(e)?;
    }
    Ok(out)
}
