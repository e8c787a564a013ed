//! Helpers shared by the `scene_*` integration tests: the shared-data location (skip rule), random poses
//! and finite-difference derivatives of a scalar field.
#![allow(dead_code)]

#[path = "../common/mod.rs"]
mod common;

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// `<repo root>/../shared/<sub>` (or `$GFCS_SHARED/<sub>`), by the skip rule of `tests/common`: `None`
/// (after printing why) when absent and `CI` is not `"true"`; panics when absent and `CI == "true"`.
#[allow(unused_imports)] // not every test crate that includes this module calls it
pub use common::shared_subdir as shared_dir;

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub fn vec_in(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> Vector3<f64> {
    Vector3::new(
        rng.gen_range(lo..hi),
        rng.gen_range(lo..hi),
        rng.gen_range(lo..hi),
    )
}

/// A uniformly random rotation with a translation in `[-t, t]^3`.
pub fn random_pose(rng: &mut ChaCha8Rng, t: f64) -> Isometry3<f64> {
    let axis = vec_in(rng, -1.0, 1.0);
    let angle = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
    let rot = UnitQuaternion::new(axis.normalize() * angle);
    let tr = vec_in(rng, -t, t);
    Isometry3::from_parts(Translation3::from(tr), rot)
}

/// Central-difference gradient of `f` at `p` with step `h`.
pub fn fd_gradient(f: &dyn Fn(&Vector3<f64>) -> f64, p: &Vector3<f64>, h: f64) -> Vector3<f64> {
    Vector3::from_fn(|i, _| {
        let mut e = Vector3::zeros();
        e[i] = h;
        (f(&(p + e)) - f(&(p - e))) / (2.0 * h)
    })
}

/// Second-difference Hessian of `f` at `p` with step `h` (uses only values of `f`).
pub fn fd_hessian(f: &dyn Fn(&Vector3<f64>) -> f64, p: &Vector3<f64>, h: f64) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| {
        let mut ei = Vector3::zeros();
        ei[i] = h;
        let mut ej = Vector3::zeros();
        ej[j] = h;
        if i == j {
            (f(&(p + ei)) - 2.0 * f(p) + f(&(p - ei))) / (h * h)
        } else {
            (f(&(p + ei + ej)) - f(&(p + ei - ej)) - f(&(p - ei + ej)) + f(&(p - ei - ej)))
                / (4.0 * h * h)
        }
    })
}

/// Text of a unit cube OBJ centred at the origin (half extent 0.5), outward counter-clockwise faces.
pub const UNIT_CUBE_OBJ: &str = "# unit cube
v -0.5 -0.5 -0.5
v  0.5 -0.5 -0.5
v  0.5  0.5 -0.5
v -0.5  0.5 -0.5
v -0.5 -0.5  0.5
v  0.5 -0.5  0.5
v  0.5  0.5  0.5
v -0.5  0.5  0.5
f 1 4 3
f 1 3 2
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
";

/// A cube of half extent `a` whose faces are each split into an `n × n` grid of quads (2 triangles
/// each), outward counter-clockwise: vertices on edges and inside faces, coplanar diagonals.
pub fn fine_cube(a: f64, n: usize) -> (Vec<nalgebra::Point3<f64>>, Vec<[u32; 3]>) {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    // For each face: outward normal axis k, sign s; tangent axes (u, v) with u × v = s e_k.
    for k in 0..3 {
        for s in [-1.0, 1.0] {
            let (mut iu, mut iv) = ((k + 1) % 3, (k + 2) % 3);
            if s < 0.0 {
                std::mem::swap(&mut iu, &mut iv);
            }
            let base = vertices.len() as u32;
            for i in 0..=n {
                for j in 0..=n {
                    let mut p = nalgebra::Point3::origin();
                    p[k] = s * a;
                    p[iu] = -a + 2.0 * a * i as f64 / n as f64;
                    p[iv] = -a + 2.0 * a * j as f64 / n as f64;
                    vertices.push(p);
                }
            }
            let id = |i: usize, j: usize| base + (i * (n + 1) + j) as u32;
            for i in 0..n {
                for j in 0..n {
                    triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                    triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                }
            }
        }
    }
    (vertices, triangles)
}
