//! numpy in and out.
//!
//! Inputs: any array-like convertible to float64 (numpy arrays of any dtype, lists, tuples, scalars) is
//! copied into a C-contiguous `Vec<f64>` with its shape; the shape is checked first (`ShapeError` naming the
//! argument and the expected shape), then the values (`NonFiniteError` naming the argument).
//! Outputs: new float64 (or int64 / bool) numpy arrays, C-contiguous, row-major.
//!
//! Poses are 4 × 4 homogeneous matrices (rotation block orthonormal with det +1, last row [0, 0, 0, 1]) or a
//! pair (position (3,) in m, quaternion (4,) in [x, y, z, w] order, normalised here).

use fabric_core::error::check_finite;
use fabric_core::FabricError;
use nalgebra::{Isometry3, Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArrayDyn, PyArrayLike, PyArrayMethods,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};
use rayon::prelude::*;

use crate::errors::{error, internal, make};

/// Tolerance on ‖RᵀR − I‖∞, |det R − 1| and the last row of a 4 × 4 pose.
const POSE_TOL: f64 = 1e-6;

/// An input array copied to row-major float64.
#[derive(Debug, Clone)]
pub struct Input {
    /// Values in row-major (C) order.
    pub data: Vec<f64>,
    /// numpy shape.
    pub shape: Vec<usize>,
}

/// numpy notation of a shape: `(3,)`, `(2, 3)`, `()`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [] => "()".to_string(),
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// `ShapeError("{what}: expected shape {expected}, got {got}")`.
pub fn shape_error(what: &str, expected: &str, got: &[usize]) -> PyErr {
    error(FabricError::Shape {
        what: what.to_string(),
        expected: expected.to_string(),
        got: shape_text(got),
    })
}

/// Copy any array-like into a float64 [`Input`]; values are not checked (see [`finite`]).
pub fn array(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Input> {
    let arr = match obj.extract::<PyArrayLike<'_, f64, IxDyn, AllowTypeChange>>() {
        Ok(a) => a,
        Err(e) => {
            let py = obj.py();
            let message = format!("{what}: cannot convert to a float64 array: {}", e.value(py));
            return Err(make(py, "ShapeError", message));
        }
    };
    let shape = arr.shape().to_vec();
    let data: Vec<f64> = arr.as_array().iter().copied().collect();
    Ok(Input { data, shape })
}

/// `NonFiniteError` naming `what` when any value is NaN or infinite.
pub fn finite(what: &str, values: &[f64]) -> PyResult<()> {
    check_finite(what, values).map_err(error)
}

/// A finite float, e.g. a time step or a radius given as a Python number or 0-d array.
pub fn scalar(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<f64> {
    let a = array(obj, what)?;
    if !a.shape.is_empty() {
        return Err(shape_error(what, "() (a number)", &a.shape));
    }
    finite(what, &a.data)?;
    Ok(a.data[0])
}

/// An integer argument `what` (a Python `int` or anything with `__index__`, not a `bool`) in `min..=max`:
/// `InvalidValueError` naming the argument otherwise (a negative index or thread count, a float, a value
/// too large for a machine integer).
pub fn integer(obj: &Bound<'_, PyAny>, what: &str, min: u64, max: u64) -> PyResult<u64> {
    let py = obj.py();
    let bad = |message: String| {
        error(FabricError::Value {
            what: what.to_string(),
            message,
        })
    };
    let range = || {
        if max == u64::MAX {
            format!("an integer >= {min}")
        } else {
            format!("an integer in [{min}, {max}]")
        }
    };
    let shown = || {
        obj.repr()
            .map(|r| r.to_string())
            .unwrap_or_else(|_| "?".into())
    };
    if obj.is_instance_of::<pyo3::types::PyBool>() {
        return Err(bad(format!("must be {}, got {}", range(), shown())));
    }
    let index = py
        .import("operator")?
        .getattr("index")?
        .call1((obj,))
        .map_err(|_| bad(format!("must be {}, got {}", range(), shown())))?;
    match index.extract::<u64>() {
        Ok(v) if (min..=max).contains(&v) => Ok(v),
        _ => Err(bad(format!("must be {}, got {}", range(), shown()))),
    }
}

/// [`integer`] as a `usize` (an index or a count).
pub fn index(obj: &Bound<'_, PyAny>, what: &str, min: usize) -> PyResult<usize> {
    let max = u64::try_from(usize::MAX).unwrap_or(u64::MAX);
    integer(obj, what, min as u64, max).map(|v| v as usize)
}

/// A `threads` argument: `None` (rayon's pool of one thread per core) or an integer >= 1. A count above
/// [`fabric_core::rollout::max_threads`] warns (`gfcs.GfcsWarning`) that it runs on that many.
pub fn threads(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<usize>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let n = index(obj, "threads", 1)?;
    let cap = fabric_core::rollout::max_threads();
    if n > cap {
        crate::errors::warn(
            obj.py(),
            &format!(
                "threads={n} exceeds 4 x the {} cores: running on {cap} threads",
                cap / 4
            ),
        )?;
    }
    Ok(Some(n))
}

/// The most worker threads a batch runs on (4 × the cores); a larger `threads` argument warns and is capped.
#[pyfunction]
pub fn max_threads() -> usize {
    fabric_core::rollout::max_threads()
}

/// Exactly shape (n,), finite.
pub fn vector(obj: &Bound<'_, PyAny>, what: &str, n: usize) -> PyResult<Vec<f64>> {
    // The common case, a contiguous float64 numpy vector, copied directly (without `array`'s array-like
    // conversion and borrow tracking); anything else goes through `array`.
    if let Ok(a) = obj.cast::<PyArray1<f64>>() {
        if let Ok(data) = a.to_vec() {
            if data.len() != n {
                return Err(shape_error(what, &format!("({n},)"), &[data.len()]));
            }
            finite(what, &data)?;
            return Ok(data);
        }
    }
    let a = array(obj, what)?;
    if a.shape != [n] {
        return Err(shape_error(what, &format!("({n},)"), &a.shape));
    }
    finite(what, &a.data)?;
    Ok(a.data)
}

/// [`vector`] of an optional argument: None (absent or Python `None`) stays None.
pub fn optional_vector(
    obj: Option<&Bound<'_, PyAny>>,
    what: &str,
    n: usize,
) -> PyResult<Option<Vec<f64>>> {
    obj.filter(|v| !v.is_none())
        .map(|v| vector(v, what, n))
        .transpose()
}

/// A finite 3-vector (shape (3,)).
pub fn vector3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vector3<f64>> {
    let v = vector(obj, what, 3)?;
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// Shape (n,) or (N, n), finite. Returns the row-major values and `None` for a single vector or `Some(N)`
/// for a batch.
pub fn vector_or_rows(
    obj: &Bound<'_, PyAny>,
    what: &str,
    n: usize,
) -> PyResult<(Vec<f64>, Option<usize>)> {
    let a = array(obj, what)?;
    let batch = match a.shape.as_slice() {
        [m] if *m == n => None,
        [rows, m] if *m == n => Some(*rows),
        _ => return Err(shape_error(what, &format!("({n},) or (N, {n})"), &a.shape)),
    };
    finite(what, &a.data)?;
    Ok((a.data, batch))
}

/// Shape (N, n) exactly (N may be 0), finite. Returns the row-major values and N.
pub fn rows(obj: &Bound<'_, PyAny>, what: &str, n: usize) -> PyResult<(Vec<f64>, usize)> {
    let a = array(obj, what)?;
    match a.shape.as_slice() {
        [r, m] if *m == n => {
            finite(what, &a.data)?;
            Ok((a.data, *r))
        }
        _ => Err(shape_error(what, &format!("(N, {n})"), &a.shape)),
    }
}

/// Shape (N, 3) (or (3,) for one point), finite, as points.
pub fn points(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<Vector3<f64>>, bool)> {
    let (data, batch) = vector_or_rows(obj, what, 3)?;
    let pts = data
        .chunks_exact(3)
        .map(|c| Vector3::new(c[0], c[1], c[2]))
        .collect();
    Ok((pts, batch.is_some()))
}

/// A pose from a 4 × 4 homogeneous matrix or a `(position (3,), quaternion xyzw (4,))` pair.
pub fn pose(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Isometry3<f64>> {
    let pair = if let Ok(t) = obj.cast::<PyTuple>() {
        (t.len() == 2).then(|| (t.get_item(0), t.get_item(1)))
    } else if let Ok(l) = obj.cast::<PyList>() {
        (l.len() == 2).then(|| (l.get_item(0), l.get_item(1)))
    } else {
        None
    };
    if let Some((p, q)) = pair {
        let position = vector3(&p?, &format!("{what} position"))?;
        let quat = vector(&q?, &format!("{what} quaternion [x, y, z, w]"), 4)?;
        return pose_from_parts(what, position, &quat);
    }
    let a = array(obj, what)?;
    if a.shape != [4, 4] {
        return Err(shape_error(
            what,
            "(4, 4) or a pair (position (3,), quaternion xyzw (4,))",
            &a.shape,
        ));
    }
    finite(what, &a.data)?;
    pose_from_matrix(what, &a.data).map_err(error)
}

/// Optional pose: `None` is the identity.
pub fn pose_or_identity(obj: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<Isometry3<f64>> {
    match obj {
        Some(o) if !o.is_none() => pose(o, what),
        _ => Ok(Isometry3::identity()),
    }
}

/// Isometry from a position and a quaternion [x, y, z, w] (normalised; zero is rejected).
pub fn pose_from_parts(
    what: &str,
    position: Vector3<f64>,
    xyzw: &[f64],
) -> PyResult<Isometry3<f64>> {
    let q = Quaternion::new(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
    let norm = q.norm();
    if norm < 1e-12 {
        return Err(error(FabricError::Value {
            what: format!("{what} quaternion"),
            message: "has zero norm".to_string(),
        }));
    }
    let rotation = UnitQuaternion::from_quaternion(q / norm);
    Ok(Isometry3::from_parts(
        Translation3::from(position),
        rotation,
    ))
}

/// Isometry from a row-major 4 × 4 homogeneous matrix; checks that it is a rigid transform.
pub fn pose_from_matrix(what: &str, m: &[f64]) -> fabric_core::Result<Isometry3<f64>> {
    let bad = |message: String| FabricError::Value {
        what: what.to_string(),
        message,
    };
    let bottom = [m[12], m[13], m[14], m[15]];
    if (bottom[0].abs().max(bottom[1].abs()).max(bottom[2].abs())) > POSE_TOL
        || (bottom[3] - 1.0).abs() > POSE_TOL
    {
        return Err(bad(format!(
            "last row must be [0, 0, 0, 1], got {bottom:?}"
        )));
    }
    let r = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let orth = (r.transpose() * r - Matrix3::identity()).amax();
    let det = r.determinant();
    if orth > POSE_TOL || (det - 1.0).abs() > POSE_TOL {
        return Err(bad(format!(
            "rotation block is not a rotation (|RᵀR − I| = {orth:.2e}, det = {det:.6})"
        )));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Isometry3::from_parts(
        Translation3::new(m[3], m[7], m[11]),
        rotation,
    ))
}

/// Row-major 4 × 4 homogeneous matrix of a pose, written to `out` (16 values).
pub fn write_pose(out: &mut [f64], pose: &Isometry3<f64>) {
    let h = pose.to_homogeneous();
    for i in 0..4 {
        for j in 0..4 {
            out[4 * i + j] = h[(i, j)];
        }
    }
}

/// Outputs of fewer values than this are flattened on the calling thread (see [`flatten_parallel`]).
const PARALLEL_MIN_VALUES: usize = 1 << 14;

/// `items` flattened into one row-major buffer of `width` values per item, `write` filling each item's
/// chunk, in parallel (rayon) from [`PARALLEL_MIN_VALUES`] values on. The buffer starts zeroed, which for a large one costs no pass over its pages
/// (they are mapped on first write, by the worker that fills them).
pub fn flatten_parallel<T: Sync>(
    items: &[T],
    width: usize,
    write: impl Fn(&T, &mut [f64]) + Sync,
) -> Vec<f64> {
    let mut data = vec![0.0; items.len() * width];
    if width == 0 {
        return data;
    }
    if data.len() < PARALLEL_MIN_VALUES {
        // small outputs are written on the calling thread: waking rayon's workers costs more
        for (out, item) in data.chunks_exact_mut(width).zip(items) {
            write(item, out);
        }
    } else {
        data.par_chunks_mut(width)
            .zip(items.par_iter())
            .for_each(|(out, item)| write(item, out));
    }
    data
}

/// A new float64 numpy array of shape `shape` holding `data` (row-major).
pub fn output<'py>(
    py: Python<'py>,
    data: Vec<f64>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    typed_output(py, data, shape)
}

/// A new numpy array of any element type (int64 indices, bool flags) of shape `shape` holding `data`.
pub fn typed_output<'py, T: numpy::Element>(
    py: Python<'py>,
    data: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let len = data.len();
    ArrayD::from_shape_vec(IxDyn(shape), data)
        .map(|a| a.into_pyarray(py))
        .map_err(|_| {
            internal(
                py,
                &format!("{len} values do not fill shape {}", shape_text(shape)),
            )
        })
}

/// A (3,) float64 array.
pub fn output_vec3<'py>(
    py: Python<'py>,
    v: &Vector3<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    output(py, vec![v.x, v.y, v.z], &[3])
}

/// A (3, 3) float64 array (row-major).
pub fn output_mat3<'py>(
    py: Python<'py>,
    m: &Matrix3<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut data = Vec::with_capacity(9);
    for i in 0..3 {
        for j in 0..3 {
            data.push(m[(i, j)]);
        }
    }
    output(py, data, &[3, 3])
}

/// A (4, 4) float64 array (homogeneous pose).
pub fn output_pose<'py>(
    py: Python<'py>,
    pose: &Isometry3<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut data = vec![0.0; 16];
    write_pose(&mut data, pose);
    output(py, data, &[4, 4])
}
