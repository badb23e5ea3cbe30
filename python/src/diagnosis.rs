//! Binding of `simgap-diag` (`simgap.diagnose`): **not written yet**, so nothing is registered
//! from this file and `diagnose` is absent from `simgap.__all__` and from the stubs.
//!
//! What goes here (BRIEF §3.3, the Python face of `simgap diagnose`):
//! - `diagnose(model, fit, holdout, *, formulation="euler_lagrange", ...) -> dict`, calling
//!   `simgap_diag::diagnose(model, formulation, fit, holdout, options, progress)` on its own
//!   thread like `sim::simulate` (GIL released, Ctrl-C checked between progress reports), and
//!   returning the JSON report of §3.3 (`selected_effects`, `candidates`, `gap`, `where`) as
//!   Python objects, with the same keys as the CLI's `--json` output;
//! - error mapping in `errors.rs`: `simgap_diag::Error::{Fit, Input}` → `FitError`,
//!   `Log`/`Write` → `LogError`, `Sim(_)` → `errors::from_sim`, `Model(_)` → `errors::from_core`;
//! - stubs in `simgap/_simgap.pyi`, the export in `simgap/__init__.py`, and tests in
//!   `python/tests/test_diagnosis.py` (a known friction recovered from simulated runs, held-out
//!   L² reduced, `FitError` on a too-short log).
