//! The `simgap._simgap` extension module: thin bindings over `simgap-core` (and, as they land,
//! `simgap-sim` and `simgap-diag`). `lib.rs` registers, `errors.rs` maps errors, `conv.rs`
//! converts arrays, and one file per exposed area holds the classes and functions.

mod conv;
mod errors;
mod model;

use pyo3::prelude::*;

/// Why your simulation disagrees with your robot: rigid-body dynamics, closed-loop simulation
/// and sim-to-real gap diagnosis.
#[pymodule]
fn _simgap(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<model::PyModel>()?;
    Ok(())
}
