//! The `gfcs` exception hierarchy and the one mapping from [`FabricError`] to Python exceptions.
//!
//! The classes live in `gfcs._core` and are re-exported by `gfcs.errors`. Several of them derive from two
//! bases (for instance `LinkError(GfcsError, KeyError)`), which `create_exception!` cannot express, so they
//! are defined once by a short Python snippet when the module is first imported and cached here.
//!
//! | FabricError variant            | Python exception                          |
//! |--------------------------------|-------------------------------------------|
//! | `Urdf`                         | `UrdfError(GfcsError)`                    |
//! | `MissingLink`, `MissingJoint`  | `LinkError(GfcsError, KeyError)`          |
//! | `Mesh`                         | `MeshError(GfcsError, OSError)`           |
//! | `Shape`                        | `ShapeError(GfcsError, ValueError)`       |
//! | `NonFinite`                    | `NonFiniteError(GfcsError, ValueError)`   |
//! | `Format`                       | `FormatError(GfcsError, ValueError)`      |
//! | `Value`                        | `InvalidValueError(GfcsError, ValueError)` (alias `ConfigError`) |
//! | `Io`                           | `IoError(GfcsError, OSError)`             |
//! | a Rust panic                   | `GfcsError("internal error: ...")`        |
//!
//! `GfcsWarning(UserWarning)` is defined alongside, for input accepted but not fully applied ([`warn`]).

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};

use fabric_core::FabricError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyType};

/// Python source of the hierarchy. `LinkError` restores `Exception.__str__` because `KeyError.__str__`
/// would wrap the message in quotes.
const DEFINITIONS: &std::ffi::CStr = c"
class GfcsError(Exception):
    '''Base class of every error raised by gfcs.'''

class UrdfError(GfcsError):
    '''A URDF that cannot be parsed or is inconsistent.'''

class LinkError(GfcsError, KeyError):
    '''A link or joint name that is not in the robot.'''
    def __str__(self):
        return Exception.__str__(self)

class MeshError(GfcsError, OSError):
    '''A mesh file that is missing or cannot be read.'''

class ShapeError(GfcsError, ValueError):
    '''An array of the wrong shape; the message names the argument and the expected shape.'''

class NonFiniteError(GfcsError, ValueError):
    '''An input that contains NaN or infinite values; the message names the argument.'''

class FormatError(GfcsError, ValueError):
    '''A malformed field in a data file (scene or request YAML, SRDF, sphere file, configuration).'''

class InvalidValueError(GfcsError, ValueError):
    '''A value outside its valid range (negative radius, zero time step, bad gain, ...).'''

ConfigError = InvalidValueError

class IoError(GfcsError, OSError):
    '''An I/O failure on a path.'''

class GfcsWarning(UserWarning):
    '''Input that gfcs accepts but does not fully apply (a MoveIt field, an SRDF entry for a link the
    robot lacks), or an argument it adjusts (a thread count above the cap).'''
";

/// Names of the classes defined by [`DEFINITIONS`], in the order of the fields of [`ErrorTypes`], plus the
/// alias `ConfigError`. Used to register them on the module.
pub const EXCEPTION_NAMES: [&str; 11] = [
    "GfcsError",
    "UrdfError",
    "LinkError",
    "MeshError",
    "ShapeError",
    "NonFiniteError",
    "FormatError",
    "InvalidValueError",
    "ConfigError",
    "IoError",
    "GfcsWarning",
];

/// The exception classes, created once per interpreter.
struct ErrorTypes {
    namespace: Py<PyDict>,
}

static TYPES: PyOnceLock<ErrorTypes> = PyOnceLock::new();

fn types(py: Python<'_>) -> PyResult<&ErrorTypes> {
    TYPES.get_or_try_init(py, || {
        let namespace = PyDict::new(py);
        namespace.set_item("__name__", "gfcs._core")?;
        py.run(DEFINITIONS, Some(&namespace), None)?;
        Ok(ErrorTypes {
            namespace: namespace.unbind(),
        })
    })
}

/// The exception class called `name` (one of [`EXCEPTION_NAMES`]).
pub fn exception_type<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyType>> {
    let namespace = types(py)?.namespace.bind(py);
    match namespace.get_item(name)? {
        Some(ty) => Ok(ty.cast_into::<PyType>()?),
        None => Err(pyo3::exceptions::PyRuntimeError::new_err(format!(
            "gfcs internal error: exception class {name} is not defined"
        ))),
    }
}

/// Add every exception class to the module `m`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    for name in EXCEPTION_NAMES {
        m.add(name, exception_type(m.py(), name)?)?;
    }
    Ok(())
}

/// The class name for one core error variant (see the table in the module documentation).
fn class_name(err: &FabricError) -> &'static str {
    match err {
        FabricError::Urdf { .. } => "UrdfError",
        FabricError::MissingLink { .. } | FabricError::MissingJoint { .. } => "LinkError",
        FabricError::Mesh { .. } => "MeshError",
        FabricError::Shape { .. } => "ShapeError",
        FabricError::NonFinite { .. } => "NonFiniteError",
        FabricError::Format { .. } => "FormatError",
        FabricError::Value { .. } => "InvalidValueError",
        FabricError::Io { .. } => "IoError",
    }
}

/// A Python exception of class `name` (one of [`EXCEPTION_NAMES`]) with the message `message`.
pub fn make(py: Python<'_>, name: &str, message: String) -> PyErr {
    match exception_type(py, name) {
        Ok(ty) => PyErr::from_type(ty, (message,)),
        Err(e) => e,
    }
}

/// `GfcsError("internal error: {message}")`: a defect of gfcs itself, not of the input.
pub fn internal(py: Python<'_>, message: &str) -> PyErr {
    make(py, "GfcsError", format!("internal error: {message}"))
}

/// Issue `message` as a `gfcs.GfcsWarning`, attributed to the caller of the gfcs function (an error when
/// warnings are turned into errors).
pub fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    let category = exception_type(py, "GfcsWarning")?;
    let text = std::ffi::CString::new(message.replace('\0', " "))
        .map_err(|e| internal(py, &e.to_string()))?;
    PyErr::warn(py, category.as_any(), &text, 1)
}

/// Map one core error to its Python exception; the message is the core's `Display` text, which names the
/// culprit (file, link, joint, field or argument).
pub fn to_pyerr(py: Python<'_>, err: FabricError) -> PyErr {
    make(py, class_name(&err), err.to_string())
}

/// A `ShapeError`, `NonFiniteError`, ... raised by the bindings themselves: same mapping as the core's.
pub fn error(err: FabricError) -> PyErr {
    Python::attach(|py| to_pyerr(py, err))
}

/// Text of a panic payload.
fn panic_message(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".to_string()
    }
}

/// Turn a caught panic into `GfcsError("internal error: ...")`.
fn panic_to_pyerr(py: Python<'_>, payload: Box<dyn Any + Send>) -> PyErr {
    internal(py, &panic_message(payload.as_ref()))
}

/// Run `f` with the GIL held, turning a core error into its exception and a panic into `GfcsError`.
pub fn guarded<T>(py: Python<'_>, f: impl FnOnce() -> fabric_core::Result<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result.map_err(|e| to_pyerr(py, e)),
        Err(payload) => Err(panic_to_pyerr(py, payload)),
    }
}

/// Run the heavy computation `f` with the GIL released (other Python threads run meanwhile), turning a core
/// error into its exception and a panic into `GfcsError`.
pub fn detached<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> fabric_core::Result<T> + Send,
{
    match py.detach(move || catch_unwind(AssertUnwindSafe(f))) {
        Ok(result) => result.map_err(|e| to_pyerr(py, e)),
        Err(payload) => Err(panic_to_pyerr(py, payload)),
    }
}

/// For tests of the panic barrier: panics inside [`guarded`], which must surface as
/// `GfcsError("internal error: ...")` and never as pyo3's `PanicException`.
#[pyfunction]
pub fn _raise_internal_panic(py: Python<'_>) -> PyResult<()> {
    guarded(py, || -> fabric_core::Result<()> {
        panic!("deliberate panic for testing the panic barrier")
    })
}

/// Raise the exception that the core error variant `variant` maps to, with its message; for tests of the
/// mapping of every variant. `variant` is one of Urdf, MissingLink, MissingJoint, Mesh,
/// Shape, NonFinite, Format, Value, Io.
#[pyfunction]
pub fn _raise_core_error(variant: &str) -> PyResult<()> {
    let s = |x: &str| x.to_string();
    let err = match variant {
        "Urdf" => FabricError::Urdf {
            file: s("robot.urdf"),
            message: s("bad xml"),
        },
        "MissingLink" => FabricError::MissingLink {
            robot: s("r"),
            link: s("nolink"),
        },
        "MissingJoint" => FabricError::MissingJoint {
            robot: s("r"),
            joint: s("nojoint"),
        },
        "Mesh" => FabricError::Mesh {
            path: s("a.stl"),
            message: s("not found"),
        },
        "Shape" => FabricError::Shape {
            what: s("q"),
            expected: s("(7,)"),
            got: s("(3,)"),
        },
        "NonFinite" => FabricError::NonFinite { what: s("q") },
        "Format" => FabricError::Format {
            file: s("s.yaml"),
            field: s("radius"),
            message: s("not a number"),
        },
        "Value" => FabricError::Value {
            what: s("dt"),
            message: s("must be > 0"),
        },
        "Io" => FabricError::Io {
            path: s("x.yaml"),
            message: s("not found"),
        },
        other => {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "unknown variant '{other}'"
            )))
        }
    };
    Err(error(err))
}
