//! One error type for the whole core. Every variant names its culprit (file, link, joint, field, shape)
//! so that the Python bindings can raise a precise exception (see `crates/fabric-py/src/errors.rs`).

use thiserror::Error;

/// Errors raised by `fabric-core`. The core never panics on user input: it returns one of these.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FabricError {
    /// A URDF could not be parsed or is inconsistent (`file` is the file name or `"<string>"`).
    #[error("URDF {file}: {message}")]
    Urdf { file: String, message: String },
    /// A link name that is not in the robot.
    #[error("no link named '{link}' in robot '{robot}'")]
    MissingLink { robot: String, link: String },
    /// A joint name that is not in the robot (or not active when an active joint is required).
    #[error("no joint named '{joint}' in robot '{robot}'")]
    MissingJoint { robot: String, joint: String },
    /// A mesh file that is missing or cannot be read.
    #[error("mesh '{path}': {message}")]
    Mesh { path: String, message: String },
    /// An array of the wrong shape.
    #[error("{what}: expected shape {expected}, got {got}")]
    Shape {
        what: String,
        expected: String,
        got: String,
    },
    /// NaN or infinite values in an input.
    #[error("{what} contains NaN or infinite values")]
    NonFinite { what: String },
    /// A malformed field in a data file (YAML scene or request, SRDF, sphere file, config).
    #[error("{file}: field '{field}': {message}")]
    Format {
        file: String,
        field: String,
        message: String,
    },
    /// A value outside its valid range (negative radius, zero time step, ...).
    #[error("invalid {what}: {message}")]
    Value { what: String, message: String },
    /// An I/O failure on a path.
    #[error("{path}: {message}")]
    Io { path: String, message: String },
}

/// Result alias used across the core.
pub type Result<T> = std::result::Result<T, FabricError>;

/// Return `Err(NonFinite)` when any value is NaN or infinite.
pub fn check_finite(what: &str, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(FabricError::NonFinite {
            what: what.to_string(),
        })
    }
}

/// The inputs of one policy evaluation (the fabric's or RMPflow's acceleration): `q`, `qd`, `command`
/// of length `dof` and finite, the output `qdd` of length `dof`.
pub fn check_policy_inputs(
    dof: usize,
    q: &[f64],
    qd: &[f64],
    command: &[f64],
    qdd: &[f64],
) -> Result<()> {
    check_len("q", q.len(), dof)?;
    check_len("qd", qd.len(), dof)?;
    check_len("command", command.len(), dof)?;
    check_len("qdd (output)", qdd.len(), dof)?;
    check_finite("q", q)?;
    check_finite("qd", qd)?;
    check_finite("command", command)
}

/// Return `Err(Shape)` unless `got == expected`.
pub fn check_len(what: &str, got: usize, expected: usize) -> Result<()> {
    if got == expected {
        Ok(())
    } else {
        Err(FabricError::Shape {
            what: what.to_string(),
            expected: format!("({expected},)"),
            got: format!("({got},)"),
        })
    }
}
