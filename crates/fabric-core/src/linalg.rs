//! Small dense kernels written out by hand where nalgebra's generic products are slower in hot loops.

use nalgebra::{Matrix3, Vector3};

/// `r v` for a 3 × 3 matrix `r` (e.g. a rotation taking a link-frame vector to the world frame).
#[inline(always)]
pub(crate) fn rotate(r: &Matrix3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        r.m11 * v.x + r.m12 * v.y + r.m13 * v.z,
        r.m21 * v.x + r.m22 * v.y + r.m23 * v.z,
        r.m31 * v.x + r.m32 * v.y + r.m33 * v.z,
    )
}
