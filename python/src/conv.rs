//! Arrays across the boundary: anything array-like in, C-ordered `float64` numpy arrays out.
//!
//! Inputs are received as [`ArrayArg`] (numpy's `asarray(x, dtype=float64)`: lists, tuples, int
//! arrays and Fortran-ordered arrays are all accepted), their shapes are checked against the
//! model's degrees of freedom, and they are viewed (or, if not C-contiguous, copied) as flat
//! row-major slices. Outputs are built from row-major `Vec<f64>`s without copying.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::PathBuf;

use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{AllowTypeChange, IntoPyArray, PyArrayDyn, PyArrayLikeDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use simgap_sim::run::experiment_from_map;
use simgap_sim::Experiment;

use crate::errors::Kind;

/// An array-like argument converted to `float64` by numpy.
pub(crate) type ArrayArg<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;

/// One state (`shape == (dof,)`) or a batch of `N` states (`shape == (N, dof)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Batch {
    /// A single state: outputs drop the leading axis.
    Single,
    /// `N` states, one per row.
    Many(usize),
}

impl Batch {
    /// Number of states.
    pub(crate) fn len(self) -> usize {
        match self {
            Batch::Single => 1,
            Batch::Many(n) => n,
        }
    }

    /// Output shape: the batch axis (if any) followed by `per_state`.
    pub(crate) fn shape(self, per_state: &[usize]) -> Vec<usize> {
        match self {
            Batch::Single => per_state.to_vec(),
            Batch::Many(n) => std::iter::once(n).chain(per_state.iter().copied()).collect(),
        }
    }
}

fn shape_str(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// The flat row-major data of `arr`, borrowed when it is C-contiguous, copied otherwise.
pub(crate) fn row_major<'a>(arr: &'a ArrayArg<'_>) -> Cow<'a, [f64]> {
    // `as_slice` also succeeds on Fortran-contiguous arrays, whose memory order is not ours
    match arr.as_slice() {
        Ok(s) if arr.is_c_contiguous() => Cow::Borrowed(s),
        _ => Cow::Owned(arr.as_array().iter().copied().collect()),
    }
}

/// Checks that every argument holds joint vectors of length `dof`, all with the shape of the
/// first one, and returns the batch and the flat data in argument order.
///
/// # Errors
/// `DimensionError` naming the argument: "q: expected 2, got 3 (shape (3,))".
pub(crate) fn joint_vectors<'a>(dof: usize, args: &[(&str, &'a ArrayArg<'_>)]) -> PyResult<(Batch, Vec<Cow<'a, [f64]>>)> {
    let (first_name, first) = args[0];
    let shape = first.shape().to_vec();
    let batch = match shape.as_slice() {
        [n] if *n == dof => Batch::Single,
        [n] => return Err(Kind::Dimension.err(format!("{first_name}: expected {dof}, got {n} (shape {}; one state has one value per joint)", shape_str(&shape)))),
        [b, n] if *n == dof => Batch::Many(*b),
        [_, n] => return Err(Kind::Dimension.err(format!("{first_name}: expected {dof}, got {n} (shape {}; a batch has shape (N, {dof}), one row per state)", shape_str(&shape)))),
        _ => return Err(Kind::Dimension.err(format!("{first_name}: expected shape ({dof},) or (N, {dof}), got {} ({} dimensions)", shape_str(&shape), shape.len()))),
    };
    for (name, arr) in &args[1..] {
        let s = arr.shape();
        if s != shape.as_slice() {
            let message = match (s, batch) {
                ([n], Batch::Single) | ([_, n], Batch::Many(_)) if *n != dof => {
                    format!("{name}: expected {dof}, got {n} (shape {}; {first_name} has shape {})", shape_str(s), shape_str(&shape))
                }
                _ => format!("{name}: expected shape {} like {first_name}, got {}", shape_str(&shape), shape_str(s)),
            };
            return Err(Kind::Dimension.err(message));
        }
    }
    Ok((batch, args.iter().map(|(_, a)| row_major(a)).collect()))
}

/// Checks that `data` (an argument of shape `(N, dof)` or `(dof,)`, flattened) is all finite.
///
/// # Errors
/// `DynamicsError` naming the argument and the first offending entry.
pub(crate) fn require_finite(name: &str, data: &[f64], dof: usize, batch: Batch) -> PyResult<()> {
    match data.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(k) => {
            let at = match batch {
                Batch::Single => format!("[{k}]"),
                Batch::Many(_) => format!("[{}, {}]", k / dof, k % dof),
            };
            Err(Kind::Dynamics.err(format!("{name}: expected finite values, got {} at {name}{at}", py_float(data[k]))))
        }
    }
}

/// `x` as Python prints it (`nan`, `inf`, `-inf`, `1.5`).
pub(crate) fn py_float(x: f64) -> String {
    match x {
        x if x.is_nan() => "nan".to_owned(),
        f64::INFINITY => "inf".to_owned(),
        f64::NEG_INFINITY => "-inf".to_owned(),
        x => format!("{x:?}"),
    }
}

/// A C-ordered `float64` array of `shape` that takes ownership of `data` (row-major).
pub(crate) fn to_array<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> Bound<'py, PyArrayDyn<f64>> {
    ArrayD::from_shape_vec(IxDyn(shape), data).expect("output length matches its shape").into_pyarray(py)
}

/// A zeroed C-ordered `float64` output array of `shape`, allocated by numpy.
///
/// Batch results are written straight into it: numpy's allocator asks for huge pages on large
/// arrays, which makes filling 100 000 mass matrices several times cheaper than a `Vec` would.
pub(crate) fn output<'py>(py: Python<'py>, shape: &[usize]) -> Bound<'py, PyArrayDyn<f64>> {
    PyArrayDyn::zeros(py, IxDyn(shape), false)
}

/// A 3-vector argument (e.g. gravity).
///
/// # Errors
/// `DimensionError` unless the shape is `(3,)`.
pub(crate) fn vector3(name: &str, arr: &ArrayArg<'_>) -> PyResult<[f64; 3]> {
    match (arr.shape(), row_major(arr).as_ref()) {
        ([3], [x, y, z]) => Ok([*x, *y, *z]),
        (s, _) => Err(Kind::Dimension.err(format!("{name}: expected 3, got {} (shape {}; expected shape (3,))", s.iter().product::<usize>(), shape_str(s)))),
    }
}

/// The name of `obj`'s type, for error messages.
pub(crate) fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "an unknown type".into())
}

/// The `experiment` argument: a `simgap.experiment` metadata dict (values converted with
/// `str`), or the path of an experiment JSON file (as the CLI's `--experiment`).
pub(crate) fn experiment_arg(arg: &Bound<'_, PyAny>) -> PyResult<Experiment> {
    if let Ok(dict) = arg.cast::<PyDict>() {
        let mut map = BTreeMap::new();
        for (k, v) in dict.iter() {
            map.insert(k.str()?.to_string(), v.str()?.to_string());
        }
        return experiment_from_map(&map).map_err(|m| Kind::Log.err(format!("experiment: {m}")));
    }
    let path: PathBuf = arg
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("experiment: expected a dict of simgap.experiment metadata or the path of an experiment file, got {}", type_name(arg))))?;
    simgap_log::experiment::read_experiment_file(&path).map_err(crate::errors::from_log)
}
