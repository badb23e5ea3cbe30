//! The columns of a linear least-squares problem and the bounds on their coefficients.

use std::sync::Arc;

use crate::lsq::inertial::InertialPrior;

/// A column of the design: per-joint (values per sample, on that joint's rows) or global
/// (values per sample and joint, row-major).
#[derive(Clone, Debug)]
pub(crate) struct Column {
    /// `Some(j)`: nonzero only on joint j's rows.
    pub joint: Option<usize>,
    /// Values: length = samples (per-joint) or samples × dof (global). Shared: a clone of a
    /// column (a design taken from the cache, a set refitted) copies no sample; change them
    /// with `Arc::make_mut`, which copies a shared column first.
    pub values: Arc<Vec<f64>>,
}

impl Column {
    /// A column of `values` on joint `joint`'s rows (`None`: a global column).
    pub(crate) fn new(joint: Option<usize>, values: Vec<f64>) -> Column {
        Column { joint, values: Arc::new(values) }
    }

    /// Sets the rows `rows` ((sample, joint) pairs, `dof` joints) to zero.
    pub(crate) fn zero_rows(&mut self, rows: &[(usize, usize)], dof: usize) {
        let joint = self.joint;
        let values = Arc::make_mut(&mut self.values);
        for &(s, j) in rows {
            match joint {
                Some(jj) if jj == j => values[s] = 0.0,
                Some(_) => {}
                None => values[s * dof + j] = 0.0,
            }
        }
    }

    /// Value at (sample, joint).
    #[inline]
    pub(crate) fn at(&self, s: usize, j: usize, dof: usize) -> f64 {
        match self.joint {
            Some(jj) => {
                if jj == j {
                    self.values[s]
                } else {
                    0.0
                }
            }
            None => self.values[s * dof + j],
        }
    }
}

/// The columns of a term: free columns (one per fitted parameter) and a fixed offset
/// (coefficient 1) subtracted from the residual, with the physical constraints on the
/// parameters.
#[derive(Clone, Debug, Default)]
pub(crate) struct TermDesign {
    /// Free columns.
    pub cols: Vec<Column>,
    /// Fixed part.
    pub offset: Option<Column>,
    /// Lower bound of each column's coefficient (empty: none).
    pub lo: Vec<f64>,
    /// Upper bound of each column's coefficient (empty: none).
    pub hi: Vec<f64>,
    /// The columns are a physically consistent inertial correction with this prior.
    pub inertial: Option<Arc<InertialPrior>>,
}

impl TermDesign {
    /// The index in θ of the first coefficient of the `i`-th of `designs` (θ lays out each
    /// design's columns in turn).
    pub(crate) fn first_column(designs: &[TermDesign], i: usize) -> usize {
        designs[..i].iter().map(|d| d.cols.len()).sum()
    }

    /// Columns without constraints.
    pub(crate) fn free(cols: Vec<Column>) -> TermDesign {
        TermDesign { cols, ..Default::default() }
    }

    /// Columns whose coefficients are at least `lo` each.
    pub(crate) fn at_least(cols: Vec<Column>, lo: f64) -> TermDesign {
        let k = cols.len();
        TermDesign { cols, lo: vec![lo; k], hi: vec![f64::INFINITY; k], ..Default::default() }
    }

    /// A fixed offset and no parameter.
    pub(crate) fn fixed(offset: Column) -> TermDesign {
        TermDesign { offset: Some(offset), ..Default::default() }
    }

    /// The design with the rows `rows` ((sample, joint) pairs of a problem of `dof` joints) set
    /// to zero in every column and in the offset (see [`crate::lsq::Problem::without_rows`]).
    pub(crate) fn without_rows(&self, rows: &[(usize, usize)], dof: usize) -> TermDesign {
        let mut d = self.clone();
        for c in d.cols.iter_mut().chain(d.offset.iter_mut()) {
            c.zero_rows(rows, dof);
        }
        d
    }
}
