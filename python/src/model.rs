//! `simgap.Model`: a robot model and its dynamics terms, for one state or a batch of states.
//!
//! Every method takes joint vectors of shape `(dof,)` (one state) or `(N, dof)` (a batch, one
//! state per row) and returns `float64` arrays in C order: a matrix result has shape
//! `(dof, dof)` or `(N, dof, dof)` with row `i` = equation `i`; a vector result `(dof,)` or
//! `(N, dof)`. Batches release the GIL and run on all cores (rayon, one workspace per thread),
//! returning to Python between chunks of states to check for Ctrl-C (`KeyboardInterrupt`);
//! H, C, Ḣ, g, C q̇, bias torques, inverse dynamics and `dynamics_terms` go through
//! `simgap_core::batch`, several states per SIMD register.
//! The physics is entirely in `simgap_core`; this file only checks, converts and dispatches.

use std::borrow::Cow;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, RwLock};

use nalgebra::{DMatrix, Vector3};
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyFloat;
use rayon::prelude::*;

/// One block of a batch: its index and its slices of the three outputs.
type OutBlock<'a> = (usize, ((&'a mut [f64], &'a mut [f64]), &'a mut [f64]));
use simgap_core::{DynamicsTerms, Formulation, Model, UrdfOptions, Workspace};

use crate::conv::{joint_vectors, output, require_finite, to_array, vector3, ArrayArg, Batch};
use crate::errors::{from_core, Kind};

/// Per-thread scratch: the core workspace plus column-major result buffers.
struct Scratch {
    ws: Workspace,
    matrix: DMatrix<f64>,
    terms: DynamicsTerms,
}

impl Scratch {
    fn new(model: &Model) -> Self {
        let n = model.dof();
        Scratch { ws: Workspace::new(model), matrix: DMatrix::zeros(n, n), terms: DynamicsTerms::new(model) }
    }
}

/// Why one state could not be evaluated (only forward dynamics can fail).
struct StateError {
    state: usize,
    message: String,
}

/// Inputs of one state: up to three joint vectors (unused ones empty).
type Inputs<'a> = [&'a [f64]; 3];
/// Outputs of one state: up to three row-major buffers (unused ones empty).
type Outputs<'a> = [&'a mut [f64]; 3];

/// Writes the column-major `m` into `out` in row-major (C) order.
fn write_c_order(m: &DMatrix<f64>, out: &mut [f64]) {
    let n = m.nrows();
    for (j, col) in m.column_iter().enumerate() {
        for (i, x) in col.iter().enumerate() {
            out[i * n + j] = *x;
        }
    }
}

/// States per return to Python (Ctrl-C check): about 4·10⁵ dof² units of work.
fn states_per_check(dof: usize) -> usize {
    (400_000 / (dof * dof).max(1)).max(16)
}

/// A batch kernel with one output: consecutive states' inputs, their outputs.
type BlockKernel = Box<dyn Fn(&Model, BlockInputs<'_>, &mut [f64]) + Sync>;

/// Below this many states a batch runs on the calling thread.
const PARALLEL_THRESHOLD: usize = 64;

/// Splits `buf` (`width` values per state) into consecutive blocks of `block` states.
fn blocks_of(buf: &mut [f64], width: usize, block: usize, count: usize) -> Vec<&mut [f64]> {
    if width == 0 {
        (0..count).map(|_| <&mut [f64]>::default()).collect()
    } else {
        buf.chunks_mut(block * width).collect()
    }
}

/// Evaluates `kernel` on every state of `batch`: the one-state path keeps the GIL and reuses the
/// model's cached scratch; batches release the GIL, run in parallel, and check for signals
/// between chunks. Returns one row-major buffer per output (`widths[o]` values per state).
fn evaluate<K>(py: Python<'_>, this: &PyModel, batch: Batch, inputs: &[Cow<'_, [f64]>], outputs: &[&Bound<'_, PyArrayDyn<f64>>], kernel: K) -> PyResult<()>
where
    K: Fn(&Model, &mut Scratch, Inputs<'_>, Outputs<'_>) -> Result<(), String> + Sync,
{
    let model = this.model();
    let n = model.dof();
    let input = |k: usize, a: usize| inputs.get(a).map_or(&[][..], |x| &x[k * n..(k + 1) * n]);
    let len = batch.len();
    // the outputs' row-major buffers and their widths per state (unused ones empty)
    // SAFETY: every output was created by the caller in this call and is not yet visible to
    // Python or borrowed elsewhere, so this is the only reference to its (contiguous) data.
    let mut bufs = outputs.iter().map(|o| unsafe { o.as_slice_mut() }.expect("a fresh array is contiguous"));
    let mut outs: [&mut [f64]; 3] = std::array::from_fn(|_| bufs.next().unwrap_or_default());
    let widths = outs.each_ref().map(|o| o.len().checked_div(len).unwrap_or(0));

    // one state: keep the GIL and the cached scratch
    if batch == Batch::Single {
        let mut cached = this.scratch.try_lock().ok();
        let mut scratch = cached.as_mut().and_then(|c| c.take()).unwrap_or_else(|| Scratch::new(&model));
        let [a, b, c] = &mut outs;
        kernel(&model, &mut scratch, [input(0, 0), input(0, 1), input(0, 2)], [a, b, c]).map_err(|m| Kind::Dynamics.err(m))?;
        if let Some(c) = cached.as_mut() {
            **c = Some(scratch);
        }
        return Ok(());
    }

    // a batch: chunks without the GIL, a signal check between chunks
    let chunk = states_per_check(n);
    let threads = rayon::current_num_threads().max(1);
    let mut start = 0;
    while start < len {
        let end = (start + chunk).min(len);
        let count = end - start;
        let [a, b, c] = &mut outs;
        let (a, b, c) = (&mut a[start * widths[0]..end * widths[0]], &mut b[start * widths[1]..end * widths[1]], &mut c[start * widths[2]..end * widths[2]]);
        let result = py.detach(|| -> Result<(), StateError> {
            let block = if count < PARALLEL_THRESHOLD { count } else { count.div_ceil(4 * threads).max(16) };
            let nblocks = count.div_ceil(block);
            let blocks: Vec<_> =
                blocks_of(a, widths[0], block, nblocks).into_iter().zip(blocks_of(b, widths[1], block, nblocks)).zip(blocks_of(c, widths[2], block, nblocks)).enumerate().collect();
            let run_block = |scratch: &mut Scratch, (i, ((a, b), c)): OutBlock<'_>| -> Result<(), StateError> {
                let first = start + i * block;
                let states = (a.len().checked_div(widths[0])).or(b.len().checked_div(widths[1])).or(c.len().checked_div(widths[2])).unwrap_or(0);
                for s in 0..states {
                    let k = first + s;
                    let outs = [&mut a[s * widths[0]..(s + 1) * widths[0]], &mut b[s * widths[1]..(s + 1) * widths[1]], &mut c[s * widths[2]..(s + 1) * widths[2]]];
                    kernel(&model, scratch, [input(k, 0), input(k, 1), input(k, 2)], outs).map_err(|message| StateError { state: k, message })?;
                }
                Ok(())
            };
            if nblocks <= 1 {
                let mut scratch = Scratch::new(&model);
                blocks.into_iter().try_for_each(|blk| run_block(&mut scratch, blk))
            } else {
                blocks.into_par_iter().try_for_each_init(|| Scratch::new(&model), run_block)
            }
        });
        result.map_err(|e| Kind::Dynamics.err(format!("state {}: {}", e.state, e.message)))?;
        py.check_signals()?;
        start = end;
    }
    Ok(())
}

/// Inputs of a block of states: up to three state-major slices (unused ones empty).
type BlockInputs<'a> = [&'a [f64]; 3];

/// Evaluates `kernel` (a `simgap_core::batch` function) on every state of a batch of `len`
/// states: the GIL released, blocks of states in parallel, a signal check between chunks.
/// Each call of `kernel` gets consecutive states' inputs and outputs, state after state.
fn evaluate_blocks<K>(py: Python<'_>, this: &PyModel, len: usize, inputs: &[Cow<'_, [f64]>], outputs: &[&Bound<'_, PyArrayDyn<f64>>], kernel: K) -> PyResult<()>
where
    K: Fn(&Model, BlockInputs<'_>, Outputs<'_>) + Sync,
{
    let model = this.model();
    let n = model.dof();
    let input = |a: usize, first: usize, end: usize| inputs.get(a).map_or(&[][..], |x| &x[first * n..end * n]);
    // SAFETY: as in `evaluate`: fresh, contiguous arrays not yet visible to Python.
    let mut bufs = outputs.iter().map(|o| unsafe { o.as_slice_mut() }.expect("a fresh array is contiguous"));
    let mut outs: [&mut [f64]; 3] = std::array::from_fn(|_| bufs.next().unwrap_or_default());
    let widths = outs.each_ref().map(|o| o.len().checked_div(len).unwrap_or(0));
    // chunks between signal checks, each split into blocks (whole SIMD registers) for the threads
    let chunk = states_per_check(n).next_multiple_of(BLOCK_STATES);
    let threads = rayon::current_num_threads().max(1);
    let mut start = 0;
    while start < len {
        let end = (start + chunk).min(len);
        let count = end - start;
        let [a, b, c] = &mut outs;
        let (a, b, c) = (&mut a[start * widths[0]..end * widths[0]], &mut b[start * widths[1]..end * widths[1]], &mut c[start * widths[2]..end * widths[2]]);
        py.detach(|| {
            let block = if count < PARALLEL_THRESHOLD || threads == 1 { count } else { count.div_ceil(4 * threads).next_multiple_of(BLOCK_STATES) };
            let nblocks = count.div_ceil(block);
            let blocks: Vec<_> =
                blocks_of(a, widths[0], block, nblocks).into_iter().zip(blocks_of(b, widths[1], block, nblocks)).zip(blocks_of(c, widths[2], block, nblocks)).enumerate().collect();
            let run_block = |(i, ((a, b), c)): OutBlock<'_>| {
                let first = start + i * block;
                let last = (first + block).min(end);
                kernel(&model, [input(0, first, last), input(1, first, last), input(2, first, last)], [a, b, c]);
            };
            if nblocks <= 1 {
                blocks.into_iter().for_each(run_block);
            } else {
                blocks.into_par_iter().for_each(run_block);
            }
        });
        py.check_signals()?;
        start = end;
    }
    Ok(())
}

/// States per parallel block are a multiple of this (the widest SIMD register holds 8).
const BLOCK_STATES: usize = 8;

/// Parses a formulation name.
pub(crate) fn formulation(name: &str) -> PyResult<Formulation> {
    match name {
        "euler_lagrange" | "euler-lagrange" => Ok(Formulation::EulerLagrange),
        "simplified" => Ok(Formulation::Simplified),
        other => Err(PyValueError::new_err(format!("formulation: expected 'euler_lagrange' or 'simplified', got '{other}'"))),
    }
}

/// A serial robot model (joint placements, axes, link inertias, gravity), loaded once from URDF.
///
/// Equation of motion, SI units: H(q) q̈ + C(q, q̇) q̇ + g(q) = τ, with g = ∂U/∂q on the left.
/// Joint vectors follow `joint_names`. Every dynamics method accepts one state, shape
/// `(dof,)`, or a batch, shape `(N, dof)`, of anything array-like, and returns C-ordered
/// float64 arrays (row i of a matrix = equation i); batches release the GIL, use all cores and
/// can be interrupted with Ctrl-C.
#[pyclass(module = "simgap._simgap", name = "Model", frozen)]
pub(crate) struct PyModel {
    /// Replaced (copy on write) when gravity is set, so running batches keep their copy.
    model: RwLock<Arc<Model>>,
    /// Scratch for one-state calls.
    scratch: Mutex<Option<Scratch>>,
    /// Degrees of freedom (fixed for the life of the object).
    dof: usize,
}

impl PyModel {
    fn new(model: Model) -> Self {
        PyModel { scratch: Mutex::new(Some(Scratch::new(&model))), dof: model.dof(), model: RwLock::new(Arc::new(model)) }
    }

    pub(crate) fn model(&self) -> Arc<Model> {
        self.model.read().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Evaluates a kernel with one matrix output per state; a batch goes through `batch`
    /// (a `simgap_core::batch` function on consecutive states).
    fn matrix_fn<'py, K, B>(&self, py: Python<'py>, args: &[(&str, &ArrayArg<'py>)], kernel: K, batch_kernel: B) -> PyResult<Bound<'py, PyAny>>
    where
        K: Fn(&Model, &mut Workspace, Inputs<'_>, &mut DMatrix<f64>) + Sync,
        B: Fn(&Model, BlockInputs<'_>, &mut [f64]) + Sync,
    {
        let n = self.dof;
        let (batch, data) = joint_vectors(n, args)?;
        let out = output(py, &batch.shape(&[n, n]));
        if let Batch::Many(len) = batch {
            evaluate_blocks(py, self, len, &data, &[&out], |m, i, [o, _, _]| batch_kernel(m, i, o))?;
            return Ok(out.into_any());
        }
        evaluate(py, self, batch, &data, &[&out], |m, s, i, [o, _, _]| {
            kernel(m, &mut s.ws, i, &mut s.matrix);
            write_c_order(&s.matrix, o);
            Ok(())
        })?;
        Ok(out.into_any())
    }

    /// Evaluates a kernel with one joint-vector output per state; a batch goes through
    /// `batch_kernel` when given (a `simgap_core::batch` function on consecutive states).
    fn vector_fn<'py, K>(&self, py: Python<'py>, args: &[(&str, &ArrayArg<'py>)], kernel: K, batch_kernel: Option<BlockKernel>) -> PyResult<Bound<'py, PyAny>>
    where
        K: Fn(&Model, &mut Workspace, Inputs<'_>, &mut [f64]) + Sync,
    {
        let n = self.dof;
        let (batch, data) = joint_vectors(n, args)?;
        let out = output(py, &batch.shape(&[n]));
        if let (Batch::Many(len), Some(batch_kernel)) = (batch, batch_kernel) {
            evaluate_blocks(py, self, len, &data, &[&out], |m, i, [o, _, _]| batch_kernel(m, i, o))?;
            return Ok(out.into_any());
        }
        evaluate(py, self, batch, &data, &[&out], |m, s, i, [o, _, _]| {
            kernel(m, &mut s.ws, i, o);
            Ok(())
        })?;
        Ok(out.into_any())
    }

    /// Evaluates a kernel with one number per state: a float for one state, shape `(N,)` for a batch.
    fn scalar_fn<'py, K>(&self, py: Python<'py>, args: &[(&str, &ArrayArg<'py>)], kernel: K) -> PyResult<Bound<'py, PyAny>>
    where
        K: Fn(&Model, &mut Workspace, Inputs<'_>) -> f64 + Sync,
    {
        let n = self.dof;
        let (batch, data) = joint_vectors(n, args)?;
        let out = output(py, &batch.shape(&[]));
        evaluate(py, self, batch, &data, &[&out], |m, s, i, [o, _, _]| {
            o[0] = kernel(m, &mut s.ws, i);
            Ok(())
        })?;
        Ok(match batch {
            Batch::Single => PyFloat::new(py, out.readonly().as_slice().expect("contiguous")[0]).into_any(),
            Batch::Many(_) => out.into_any(),
        })
    }
}

#[pymethods]
impl PyModel {
    /// Loads the serial chain of a URDF file, from its root link to `tip` (default: the end of
    /// the unique chain of movable joints). Fixed joints are merged into their parent link;
    /// subtrees off the chain (e.g. gripper fingers) are merged rigidly at their zero position,
    /// with a warning in `warnings`.
    ///
    /// Raises UrdfError (naming the file and the element) if the file cannot be read or loaded.
    #[staticmethod]
    #[pyo3(signature = (path, tip = None))]
    fn from_urdf(py: Python<'_>, path: PathBuf, tip: Option<String>) -> PyResult<Self> {
        let model = py.detach(|| Model::from_urdf_file_with(&path, &UrdfOptions { tip })).map_err(from_core)?;
        Ok(PyModel::new(model))
    }

    /// The seed paper's planar two-link arm (Table 2): vertical plane, q = 0 hanging down.
    #[staticmethod]
    fn paper_arm() -> Self {
        PyModel::new(Model::paper_arm())
    }

    /// Robot name (from the URDF).
    #[getter]
    fn name(&self) -> String {
        self.model().name().to_owned()
    }

    /// Number of degrees of freedom (movable joints of the chain).
    #[getter]
    fn dof(&self) -> usize {
        self.dof
    }

    /// Joint names in chain order, root to tip: the order of every joint vector.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.model().joint_names().into_iter().map(str::to_owned).collect()
    }

    /// Lower position limits [rad or m], shape (dof,); -inf for continuous joints.
    #[getter]
    fn lower_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.limits(py, |l| l.lower)
    }

    /// Upper position limits [rad or m], shape (dof,); +inf for continuous joints.
    #[getter]
    fn upper_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.limits(py, |l| l.upper)
    }

    /// Effort limits [N·m or N], shape (dof,).
    #[getter]
    fn effort_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.limits(py, |l| l.effort)
    }

    /// Velocity limits [rad/s or m/s], shape (dof,).
    #[getter]
    fn velocity_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.limits(py, |l| l.velocity)
    }

    /// Gravity acceleration in the base frame [m/s²], shape (3,); default (0, 0, -9.81).
    #[getter]
    fn get_gravity<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_array(py, self.model().gravity().as_slice().to_vec(), &[3]).into_any()
    }

    #[setter]
    fn set_gravity(&self, gravity: ArrayArg<'_>) -> PyResult<()> {
        let g = vector3("gravity", &gravity)?;
        if let Some(x) = g.iter().find(|x| !x.is_finite()) {
            return Err(Kind::Dynamics.err(format!("gravity: expected finite values, got {}", crate::conv::py_float(*x))));
        }
        let mut model = self.model.write().unwrap_or_else(|e| e.into_inner());
        Arc::make_mut(&mut model).set_gravity(Vector3::from(g));
        Ok(())
    }

    /// Warnings raised while loading (massless links, locked off-chain joints).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.model().warnings().to_vec()
    }

    fn __repr__(&self) -> String {
        let m = self.model();
        format!("Model(name={:?}, dof={}, joint_names={:?})", m.name(), m.dof(), m.joint_names())
    }

    /// Mass matrix H(q) (composite rigid body algorithm): symmetric positive definite.
    #[pyo3(signature = (q))]
    fn mass_matrix<'py>(&self, py: Python<'py>, q: ArrayArg<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.matrix_fn(py, &[("q", &q)], |m, ws, [q, _, _], out| simgap_core::mass_matrix_into(m, ws, q, out), |m, [q, _, _], out| simgap_core::mass_matrix_batch(m, q, out))
    }

    /// Coriolis matrix C(q, q̇) of the chosen formulation.
    #[pyo3(signature = (q, qd, formulation = "euler_lagrange"))]
    fn coriolis_matrix<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>, formulation: &str) -> PyResult<Bound<'py, PyAny>> {
        let f = self::formulation(formulation)?;
        self.matrix_fn(
            py,
            &[("q", &q), ("qd", &qd)],
            |m, ws, [q, qd, _], out| simgap_core::coriolis_matrix_into(m, ws, q, qd, f, out),
            |m, [q, qd, _], out| simgap_core::coriolis_matrix_batch(m, q, qd, f, out),
        )
    }

    /// Time derivative of the mass matrix, Ḣ(q, q̇) = Σ_k ∂H/∂q_k q̇_k.
    #[pyo3(signature = (q, qd))]
    fn mass_matrix_derivative<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.matrix_fn(
            py,
            &[("q", &q), ("qd", &qd)],
            |m, ws, [q, qd, _], out| simgap_core::mass_matrix_derivative_into(m, ws, q, qd, out),
            |m, [q, qd, _], out| simgap_core::mass_matrix_derivative_batch(m, q, qd, out),
        )
    }

    /// Coriolis and centrifugal torques C(q, q̇) q̇ of the chosen formulation.
    #[pyo3(signature = (q, qd, formulation = "euler_lagrange"))]
    fn coriolis_torques<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>, formulation: &str) -> PyResult<Bound<'py, PyAny>> {
        let f = self::formulation(formulation)?;
        let batch: BlockKernel = Box::new(move |m, [q, qd, _], out| simgap_core::coriolis_torques_batch(m, q, qd, f, out));
        self.vector_fn(py, &[("q", &q), ("qd", &qd)], |m, ws, [q, qd, _], out| simgap_core::coriolis_torques_into(m, ws, q, qd, f, out), Some(batch))
    }

    /// Gravity torques g(q) = ∂U/∂q; equivalent to inverse_dynamics(q, 0, 0).
    #[pyo3(signature = (q))]
    fn gravity_torques<'py>(&self, py: Python<'py>, q: ArrayArg<'py>) -> PyResult<Bound<'py, PyAny>> {
        let batch: BlockKernel = Box::new(|m, [q, _, _], out| simgap_core::gravity_torques_batch(m, q, out));
        self.vector_fn(py, &[("q", &q)], |m, ws, [q, _, _], out| simgap_core::gravity_torques_into(m, ws, q, out), Some(batch))
    }

    /// Joint torques τ = H q̈ + C q̇ + g (recursive Newton–Euler), with the true Coriolis torque.
    #[pyo3(signature = (q, qd, qdd))]
    fn inverse_dynamics<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>, qdd: ArrayArg<'py>) -> PyResult<Bound<'py, PyAny>> {
        let batch: BlockKernel = Box::new(|m, [q, qd, qdd], out| simgap_core::inverse_dynamics_batch(m, q, qd, qdd, out));
        self.vector_fn(py, &[("q", &q), ("qd", &qd), ("qdd", &qdd)], |m, ws, [q, qd, qdd], out| simgap_core::inverse_dynamics_into(m, ws, q, qd, qdd, out), Some(batch))
    }

    /// Bias torques C(q, q̇) q̇ + g(q) of the chosen formulation.
    #[pyo3(signature = (q, qd, formulation = "euler_lagrange"))]
    fn bias_torques<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>, formulation: &str) -> PyResult<Bound<'py, PyAny>> {
        let f = self::formulation(formulation)?;
        let batch: BlockKernel = Box::new(move |m, [q, qd, _], out| simgap_core::bias_torques_batch(m, q, qd, f, out));
        self.vector_fn(py, &[("q", &q), ("qd", &qd)], |m, ws, [q, qd, _], out| simgap_core::bias_torques_into(m, ws, q, qd, f, out), Some(batch))
    }

    /// Joint accelerations q̈ = H⁻¹ (τ − C q̇ − g) with the chosen formulation's C.
    ///
    /// Raises DynamicsError if an input is not finite or H is not positive definite.
    #[pyo3(signature = (q, qd, tau, formulation = "euler_lagrange"))]
    fn forward_dynamics<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>, tau: ArrayArg<'py>, formulation: &str) -> PyResult<Bound<'py, PyAny>> {
        let f = self::formulation(formulation)?;
        let n = self.dof;
        let (batch, data) = joint_vectors(n, &[("q", &q), ("qd", &qd), ("tau", &tau)])?;
        for (name, d) in ["q", "qd", "tau"].iter().zip(&data) {
            require_finite(name, d, n, batch)?;
        }
        let out = output(py, &batch.shape(&[n]));
        evaluate(py, self, batch, &data, &[&out], |m, s, [q, qd, tau], [o, _, _]| {
            // the only assertion left after the checks above is H positive definite
            catch_unwind(AssertUnwindSafe(|| simgap_core::forward_dynamics_into(m, &mut s.ws, q, qd, tau, f, o))).map_err(|_| {
                *s = Scratch::new(m);
                "the mass matrix is not positive definite (a massless link at the tip?)".to_owned()
            })
        })?;
        Ok(out.into_any())
    }

    /// Kinetic energy ½ q̇ᵀ H q̇ [J]: a float for one state, shape (N,) for a batch.
    #[pyo3(signature = (q, qd))]
    fn kinetic_energy<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.scalar_fn(py, &[("q", &q), ("qd", &qd)], |m, ws, [q, qd, _]| simgap_core::kinetic_energy(m, ws, q, qd))
    }

    /// Potential energy of gravity U(q) [J] (g = ∂U/∂q): a float for one state, shape (N,) for a batch.
    #[pyo3(signature = (q))]
    fn potential_energy<'py>(&self, py: Python<'py>, q: ArrayArg<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.scalar_fn(py, &[("q", &q)], |m, ws, [q, _, _]| simgap_core::potential_energy(m, ws, q))
    }

    /// H(q), C(q, q̇) and g(q) in one call, cheaper than three calls.
    #[pyo3(signature = (q, qd, formulation = "euler_lagrange"))]
    fn dynamics_terms<'py>(&self, py: Python<'py>, q: ArrayArg<'py>, qd: ArrayArg<'py>, formulation: &str) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let f = self::formulation(formulation)?;
        let n = self.dof;
        let (batch, data) = joint_vectors(n, &[("q", &q), ("qd", &qd)])?;
        let (mshape, vshape) = (batch.shape(&[n, n]), batch.shape(&[n]));
        let (h, c, g) = (output(py, &mshape), output(py, &mshape), output(py, &vshape));
        if let Batch::Many(len) = batch {
            evaluate_blocks(py, self, len, &data, &[&h, &c, &g], |m, [q, qd, _], [h, c, g]| simgap_core::dynamics_terms_batch(m, q, qd, f, h, c, g))?;
            return Ok((h.into_any(), c.into_any(), g.into_any()));
        }
        evaluate(py, self, batch, &data, &[&h, &c, &g], |m, s, [q, qd, _], [h, c, g]| {
            simgap_core::dynamics_terms_into(m, &mut s.ws, q, qd, f, &mut s.terms);
            write_c_order(&s.terms.mass_matrix, h);
            write_c_order(&s.terms.coriolis_matrix, c);
            g.copy_from_slice(s.terms.gravity_torques.as_slice());
            Ok(())
        })?;
        Ok((h.into_any(), c.into_any(), g.into_any()))
    }
}

impl PyModel {
    fn limits<'py>(&self, py: Python<'py>, f: impl Fn(&simgap_core::JointLimits) -> f64) -> Bound<'py, PyAny> {
        let v = self.model().joints().iter().map(|j| f(&j.limits)).collect();
        to_array(py, v, &[self.model().dof()]).into_any()
    }
}
