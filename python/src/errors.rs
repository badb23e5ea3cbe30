//! The Python exception tree, and the one place where Rust errors become Python exceptions.
//!
//! ```text
//! SimgapError(Exception)
//! ├── UrdfError            every simgap_core::Error (unreadable file, bad URDF, invalid model)
//! ├── LogError             logs that cannot be read, written, or matched to the model by joint name
//! ├── DimensionError       also a ValueError: an array of the wrong shape
//! ├── DynamicsError        also a ValueError: dynamics undefined at this input
//! ├── SimulationError      a simulation that diverged, was interrupted or got bad parameters
//! └── FitError             identification / diagnosis that cannot proceed (no data, singular fit)
//! ```
//!
//! The classes are created once per interpreter with `type(name, bases, namespace)` so that
//! `DimensionError` and `DynamicsError` can also derive from `ValueError`.

use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

/// One class of the exception tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Simgap,
    Urdf,
    Log,
    Dimension,
    Dynamics,
    Simulation,
    Fit,
}

impl Kind {
    /// Every class, parents before children.
    pub(crate) const ALL: [Kind; 7] = [Kind::Simgap, Kind::Urdf, Kind::Log, Kind::Dimension, Kind::Dynamics, Kind::Simulation, Kind::Fit];

    fn index(self) -> usize {
        self as usize
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Kind::Simgap => "SimgapError",
            Kind::Urdf => "UrdfError",
            Kind::Log => "LogError",
            Kind::Dimension => "DimensionError",
            Kind::Dynamics => "DynamicsError",
            Kind::Simulation => "SimulationError",
            Kind::Fit => "FitError",
        }
    }

    fn doc(self) -> &'static str {
        match self {
            Kind::Simgap => "Base class of every error raised by simgap.",
            Kind::Urdf => "A URDF file that cannot be read or loaded, or an invalid model; the message names the file and the element.",
            Kind::Log => "A log (MCAP or CSV) that cannot be read or written, or whose joints do not match the model.",
            Kind::Dimension => "An array argument of the wrong shape; the message names the argument and says what was expected and what was found.",
            Kind::Dynamics => "The dynamics are undefined at this input: non-finite values where finite ones are needed, or a mass matrix that is not positive definite.",
            Kind::Simulation => "A simulation that diverged, was interrupted, or was given invalid parameters.",
            Kind::Fit => "An identification or diagnosis that cannot proceed (too little data, a singular problem).",
        }
    }

    /// The Python class, created on first use.
    pub(crate) fn type_object(self, py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
        static TYPES: [PyOnceLock<Py<PyType>>; 7] = [const { PyOnceLock::new() }; 7];
        let ty = TYPES[self.index()].get_or_try_init(py, || -> PyResult<Py<PyType>> {
            // the base classes
            let simgap = || Kind::Simgap.type_object(py).map(Bound::into_any);
            let bases = match self {
                Kind::Simgap => PyTuple::new(py, [py.get_type::<PyException>().into_any()])?,
                Kind::Dimension | Kind::Dynamics => PyTuple::new(py, [simgap()?, py.get_type::<PyValueError>().into_any()])?,
                _ => PyTuple::new(py, [simgap()?])?,
            };
            // type(name, bases, namespace)
            let namespace = PyDict::new(py);
            namespace.set_item("__module__", "simgap")?;
            namespace.set_item("__doc__", self.doc())?;
            let class = py.get_type::<PyType>().call1((self.name(), bases, namespace))?;
            Ok(class.cast_into::<PyType>()?.unbind())
        })?;
        Ok(ty.bind(py).clone())
    }

    /// An exception of this class with `message`.
    pub(crate) fn err(self, message: impl Into<String>) -> PyErr {
        let message = message.into();
        Python::attach(|py| match self.type_object(py) {
            Ok(ty) => PyErr::from_type(ty, message),
            Err(e) => e,
        })
    }
}

/// The class every `simgap_core::Error` maps to: all of them concern loading a model.
pub(crate) fn core_error_kind(e: &simgap_core::Error) -> Kind {
    use simgap_core::Error as E;
    match e {
        E::Io { .. }
        | E::MalformedUrdf { .. }
        | E::DuplicateLink { .. }
        | E::DuplicateJoint { .. }
        | E::MissingLink { .. }
        | E::Loop { .. }
        | E::Roots { .. }
        | E::NotSerial { .. }
        | E::UnknownTip { .. }
        | E::NoMovableJoint { .. }
        | E::UnsupportedJoint { .. }
        | E::ZeroAxis { .. }
        | E::NonFinite { .. }
        | E::NegativeMass { .. }
        | E::NonPhysicalInertia { .. }
        | E::Massless { .. }
        | E::InvalidModel(_) => Kind::Urdf,
        // variants added later are model errors too until mapped here
        _ => Kind::Urdf,
    }
}

/// Converts a `simgap_core::Error` to its Python exception; the message is the Rust one.
pub(crate) fn from_core(e: simgap_core::Error) -> PyErr {
    core_error_kind(&e).err(e.to_string())
}

/// The class of a `simgap_sim::Error`: logs are `LogError`, model errors keep their class, the
/// rest concerns a simulation.
pub(crate) fn sim_error_kind(e: &simgap_sim::Error) -> Kind {
    use simgap_sim::Error as E;
    match e {
        E::Log { .. } | E::Write { .. } | E::JointMismatch { .. } => Kind::Log,
        E::Diverged { .. } | E::Interrupted { .. } | E::Invalid { .. } => Kind::Simulation,
        E::Model(core) => core_error_kind(core),
        // variants added later concern a simulation until mapped here
        _ => Kind::Simulation,
    }
}

/// Converts a `simgap_sim::Error` to its Python exception; the message is the Rust one.
pub(crate) fn from_sim(e: simgap_sim::Error) -> PyErr {
    sim_error_kind(&e).err(e.to_string())
}

/// Converts a `simgap_log::Error` to its Python exception (`LogError`, or the class of the run
/// error it carries); the message is the Rust one.
pub(crate) fn from_log(e: simgap_log::Error) -> PyErr {
    match e {
        simgap_log::Error::Run(sim) => from_sim(sim),
        other => Kind::Log.err(other.to_string()),
    }
}

/// Adds every exception class to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    for kind in Kind::ALL {
        m.add(kind.name(), kind.type_object(m.py())?)?;
    }
    Ok(())
}

/// The class of a `simgap_diag::Error`: fits and missing inputs are `FitError`, logs and
/// reports that cannot be written are `LogError`, simulator and model errors keep their class.
pub(crate) fn diag_error_kind(e: &simgap_diag::Error) -> Kind {
    use simgap_diag::Error as E;
    match e {
        E::Fit(_) | E::Input(_) => Kind::Fit,
        E::Log { .. } | E::Write { .. } => Kind::Log,
        E::Sim(sim) => sim_error_kind(sim),
        E::Model(core) => core_error_kind(core),
        // variants added later concern the diagnosis until mapped here
        _ => Kind::Fit,
    }
}

/// Converts a `simgap_diag::Error` to its Python exception; the message is the Rust one.
pub(crate) fn from_diag(e: simgap_diag::Error) -> PyErr {
    diag_error_kind(&e).err(e.to_string())
}
