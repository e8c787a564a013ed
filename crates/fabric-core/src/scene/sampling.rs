//! Points sampled on obstacle surfaces, for the point-set scene encoding of GFCS Sec. IV-B (the
//! environment `E` is represented by a point set `S` on object surfaces; the encoding takes, for each
//! reference lattice point, the distance to the nearest point of `S`).
//!
//! Sampling at spacing `h` (m): box faces get grids of step `<= h` (edges and corners once), cylinders
//! rings every `<= h` along the axis with points every `<= h` along each ring plus concentric rings on
//! the caps, spheres a Fibonacci lattice of `⌈4πR²/h²⌉` points, capsules rings on the core and latitude
//! rings on the hemispheres, meshes their vertices, points along every edge and a barycentric grid inside
//! every triangle, point clouds their points thinned to one per `h`-voxel, and half-spaces a square grid
//! of half width [`HALF_SPACE_PATCH`] around the obstacle origin (an infinite plane cannot be sampled).

use std::collections::HashSet;
use std::f64::consts::PI;

use nalgebra::{Point3, Vector3};
use parry3d_f64::shape::TriMesh;

use super::scene::Scene;
use super::shape::{PointCloud, Shape};

/// Half width (m) of the square patch of a half-space's boundary plane that is sampled.
pub const HALF_SPACE_PATCH: f64 = 1.0;

/// Smallest accepted spacing (m); smaller requests are raised to it to bound the number of points.
pub const MIN_SURFACE_SPACING: f64 = 1e-3;

/// Number of intervals of length `<= h` covering `len` (at least 1).
fn intervals(len: f64, h: f64) -> usize {
    ((len / h).ceil() as usize).max(1)
}

/// `n + 1` evenly spaced values from `-a` to `a`.
fn nodes(a: f64, n: usize) -> impl Iterator<Item = f64> {
    (0..=n).map(move |i| -a + 2.0 * a * i as f64 / n as f64)
}

/// Surface samples of `shape` in its own frame, appended to `out`. `h` must be > 0.
pub(crate) fn sample_local(shape: &Shape, h: f64, out: &mut Vec<Vector3<f64>>) {
    match shape {
        Shape::Sphere { radius } => sphere(*radius, h, out),
        Shape::Cuboid { half_extents } => cuboid(half_extents, h, out),
        Shape::Cylinder {
            half_height,
            radius,
        } => cylinder(*half_height, *radius, h, out),
        Shape::Capsule {
            half_height,
            radius,
        } => capsule(*half_height, *radius, h, out),
        Shape::HalfSpace => {
            let n = intervals(2.0 * HALF_SPACE_PATCH, h);
            for x in nodes(HALF_SPACE_PATCH, n) {
                for y in nodes(HALF_SPACE_PATCH, n) {
                    out.push(Vector3::new(x, y, 0.0));
                }
            }
        }
        Shape::TriMesh(m) => mesh(m, h, out),
        Shape::PointCloud(pc) => cloud(pc, h, out),
    }
}

/// Fibonacci lattice on a sphere of radius `r` centred at the origin.
fn sphere(r: f64, h: f64, out: &mut Vec<Vector3<f64>>) {
    let n = ((4.0 * PI * r * r / (h * h)).ceil() as usize).max(1);
    let golden = PI * (3.0 - 5f64.sqrt());
    for k in 0..n {
        let z = 1.0 - (2.0 * k as f64 + 1.0) / n as f64;
        let s = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * k as f64;
        out.push(Vector3::new(s * phi.cos(), s * phi.sin(), z) * r);
    }
}

/// Grids on the six faces; shared edges and corners appear once (z faces keep their borders, y faces
/// keep their x borders, x faces keep none).
fn cuboid(he: &Vector3<f64>, h: f64, out: &mut Vec<Vector3<f64>>) {
    let n = Vector3::from_fn(|i, _| intervals(2.0 * he[i], h));
    let axis_nodes = |i: usize, keep_ends: bool| -> Vec<f64> {
        let all: Vec<f64> = nodes(he[i], n[i]).collect();
        if keep_ends {
            all
        } else {
            all[1..all.len() - 1].to_vec()
        }
    };
    for s in [-1.0, 1.0] {
        for x in axis_nodes(0, true) {
            for y in axis_nodes(1, true) {
                out.push(Vector3::new(x, y, s * he.z));
            }
        }
        for x in axis_nodes(0, true) {
            for z in axis_nodes(2, false) {
                out.push(Vector3::new(x, s * he.y, z));
            }
        }
        for y in axis_nodes(1, false) {
            for z in axis_nodes(2, false) {
                out.push(Vector3::new(s * he.x, y, z));
            }
        }
    }
}

/// Ring of radius `r` at height `z`, points `<= h` apart (at least 3).
fn ring(r: f64, z: f64, h: f64, out: &mut Vec<Vector3<f64>>) {
    let m = intervals(2.0 * PI * r, h).max(3);
    for k in 0..m {
        let a = 2.0 * PI * k as f64 / m as f64;
        out.push(Vector3::new(r * a.cos(), r * a.sin(), z));
    }
}

fn cylinder(hh: f64, r: f64, h: f64, out: &mut Vec<Vector3<f64>>) {
    for z in nodes(hh, intervals(2.0 * hh, h)) {
        ring(r, z, h, out);
    }
    let nr = intervals(r, h);
    for s in [-1.0, 1.0] {
        out.push(Vector3::new(0.0, 0.0, s * hh));
        for k in 1..nr {
            ring(r * k as f64 / nr as f64, s * hh, h, out);
        }
    }
}

fn capsule(hh: f64, r: f64, h: f64, out: &mut Vec<Vector3<f64>>) {
    if hh > 0.0 {
        for z in nodes(hh, intervals(2.0 * hh, h)) {
            ring(r, z, h, out);
        }
    } else {
        ring(r, 0.0, h, out);
    }
    let nt = intervals(0.5 * PI * r, h);
    for s in [-1.0, 1.0] {
        out.push(Vector3::new(0.0, 0.0, s * (hh + r)));
        for k in 1..nt {
            let theta = 0.5 * PI * k as f64 / nt as f64;
            ring(r * theta.sin(), s * (hh + r * theta.cos()), h, out);
        }
    }
}

/// Vertices, points along each edge (once per edge) and barycentric grids inside each triangle.
fn mesh(m: &TriMesh, h: f64, out: &mut Vec<Vector3<f64>>) {
    let v = m.vertices();
    out.extend(v.iter().map(|p| p.coords));
    let mut seen: HashSet<(u32, u32)> = HashSet::new();
    for t in m.indices() {
        for k in 0..3 {
            let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
            if !seen.insert((a, b)) {
                continue;
            }
            let (pa, pb) = (v[a as usize], v[b as usize]);
            let n = intervals((pb - pa).norm(), h);
            for i in 1..n {
                out.push(pa.coords.lerp(&pb.coords, i as f64 / n as f64));
            }
        }
        let (pa, pb, pc) = (v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
        let longest = (pb - pa).norm().max((pc - pb).norm()).max((pa - pc).norm());
        let n = intervals(longest, h);
        for i in 1..n {
            for j in 1..n - i {
                let (u, w) = (i as f64 / n as f64, j as f64 / n as f64);
                out.push(pa.coords * (1.0 - u - w) + pb.coords * u + pc.coords * w);
            }
        }
    }
}

/// The cloud's points, keeping the first point of every cubic voxel of side `h`.
fn cloud(pc: &PointCloud, h: f64, out: &mut Vec<Vector3<f64>>) {
    let mut voxels: HashSet<[i64; 3]> = HashSet::new();
    for p in pc.points() {
        if voxels.insert(voxel(p, h)) {
            out.push(p.coords);
        }
    }
}

fn voxel(p: &Point3<f64>, h: f64) -> [i64; 3] {
    [
        (p.x / h).floor() as i64,
        (p.y / h).floor() as i64,
        (p.z / h).floor() as i64,
    ]
}

impl Scene {
    /// Points (world frame, m) sampled on every obstacle surface at roughly `spacing` (m), obstacle by
    /// obstacle in increasing id order (see the module documentation of `scene::sampling` for each
    /// shape). A `spacing` that is not finite or not > 0 gives an empty vector; spacings below
    /// [`MIN_SURFACE_SPACING`] are raised to it.
    pub fn surface_points(&self, spacing: f64) -> Vec<Vector3<f64>> {
        let mut out = Vec::new();
        if !(spacing.is_finite() && spacing > 0.0) {
            return out;
        }
        let h = spacing.max(MIN_SURFACE_SPACING);
        let mut local = Vec::new();
        for (_, obstacle) in self.iter() {
            local.clear();
            sample_local(&obstacle.shape, h, &mut local);
            out.extend(
                local
                    .iter()
                    .map(|p| obstacle.pose * Point3::from(*p))
                    .map(|p| p.coords),
            );
        }
        out
    }
}
