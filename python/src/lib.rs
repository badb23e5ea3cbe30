//! The `simgap._simgap` extension module: thin bindings over `simgap-core`, `simgap-sim` and
//! `simgap-diag`. `lib.rs` registers, `errors.rs` maps errors, `conv.rs` converts arrays, and
//! one file per exposed area holds the classes and functions.

mod conv;
mod diagnosis;
mod errors;
mod model;
mod sim;
mod vocabulary;
mod worker;

use pyo3::prelude::*;

/// Why your simulation disagrees with your robot: rigid-body dynamics, closed-loop simulation
/// and sim-to-real gap diagnosis.
#[pymodule]
fn _simgap(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<sim::PyRun>()?;
    m.add_class::<sim::PyL2Report>()?;
    m.add_function(wrap_pyfunction!(sim::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(sim::read_log, m)?)?;
    m.add_function(wrap_pyfunction!(sim::read_logs, m)?)?;
    m.add_function(wrap_pyfunction!(sim::lerobot_episodes, m)?)?;
    m.add_function(wrap_pyfunction!(sim::write_log, m)?)?;
    m.add_function(wrap_pyfunction!(sim::l2, m)?)?;
    m.add_function(wrap_pyfunction!(sim::l2_tracking, m)?)?;
    m.add_function(wrap_pyfunction!(sim::compare, m)?)?;
    m.add_class::<diagnosis::PyReport>()?;
    m.add_function(wrap_pyfunction!(diagnosis::diagnose, m)?)?;
    m.add("DIAGNOSE_SWITCHES", diagnosis::switch_table())?;
    m.add_function(wrap_pyfunction!(vocabulary::effect_vocabulary, m)?)?;
    Ok(())
}
