//! Distance queries for 60 points (one Panda's worth of collision spheres) around a MotionBenchMaker-like
//! scene: `Scene::signed_distance` (minimum over obstacles, with gradient and Hessian) and
//! `Scene::query` (every obstacle within an influence radius). The scene is built in code (a table, a
//! shelf of boxes and a few cylinders); when the shared MotionBenchMaker data is present
//! (`<repo>/../shared/mbm` or `$GFCS_SHARED/mbm`), one real scene of each of a few classes is measured too.
//!
//! Run: `cargo bench -p fabric-core --bench distance`.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use fabric_core::scene::{DistanceSample, Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Influence radius used for `query` (m), of the order of a fabric repulsion range.
const INFLUENCE: f64 = 0.2;

fn pose(x: f64, y: f64, z: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

/// A table with a bookshelf and cans, like MotionBenchMaker's `table_pick` / `bookshelf_*` classes.
fn synthetic_scene() -> Scene {
    let mut s = Scene::new();
    let mut add = |name: &str, shape: Shape, p: Isometry3<f64>| {
        s.add(Obstacle::new(name, shape, p))
            .expect("valid obstacle");
    };
    let boxed = |x: f64, y: f64, z: f64| Shape::cuboid_from_size(Vector3::new(x, y, z));
    add("table", boxed(0.8, 1.2, 0.04), pose(0.7, 0.0, -0.02, 0.1));
    add("back", boxed(0.04, 0.8, 0.8), pose(1.0, 0.0, 0.4, 0.1));
    add("left", boxed(0.35, 0.04, 0.8), pose(0.83, -0.4, 0.4, 0.1));
    add("right", boxed(0.35, 0.04, 0.8), pose(0.83, 0.4, 0.4, 0.1));
    for (k, z) in [0.25, 0.5, 0.78].iter().enumerate() {
        add(
            &format!("shelf{k}"),
            boxed(0.35, 0.8, 0.02),
            pose(0.83, 0.0, *z, 0.1),
        );
    }
    for (k, (x, y)) in [(0.5, -0.3), (0.55, 0.2), (0.45, 0.35), (0.8, -0.15)]
        .iter()
        .enumerate()
    {
        add(
            &format!("can{k}"),
            Shape::Cylinder {
                half_height: 0.07,
                radius: 0.03,
            },
            pose(*x, *y, 0.07, 0.0),
        );
    }
    s
}

/// 60 points spread over the scene's bounding box enlarged by 0.1 m (where robot spheres would be).
fn points_around(scene: &Scene, seed: u64) -> Vec<Vector3<f64>> {
    let mut lo = Point3::new(f64::MAX, f64::MAX, f64::MAX);
    let mut hi = Point3::new(f64::MIN, f64::MIN, f64::MIN);
    for id in scene.ids() {
        if let Some(a) = scene.aabb(id) {
            lo = lo.inf(&a.mins);
            hi = hi.sup(&a.maxs);
        }
    }
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    (0..60)
        .map(|_| Vector3::from_fn(|i, _| r.gen_range(lo[i] - 0.1..hi[i] + 0.1)))
        .collect()
}

fn bench_scene(c: &mut Criterion, label: &str, scene: &Scene) {
    let points = points_around(scene, 7);
    c.bench_function(&format!("{label}: signed_distance x60"), |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for p in &points {
                if let Some(s) = scene.signed_distance(black_box(p)) {
                    acc += s.distance + s.gradient.x + s.hessian[(0, 0)];
                }
            }
            acc
        })
    });
    let mut out: Vec<DistanceSample> = Vec::with_capacity(64);
    c.bench_function(&format!("{label}: query({INFLUENCE} m) x60"), |b| {
        b.iter(|| {
            let mut n = 0;
            for p in &points {
                out.clear();
                scene.query(black_box(p), INFLUENCE, &mut out);
                n += out.len();
            }
            n
        })
    });
}

fn shared_mbm() -> Option<PathBuf> {
    let root = std::env::var("GFCS_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|_| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")));
    let dir = root.join("mbm");
    dir.is_dir().then_some(dir)
}

fn distance(c: &mut Criterion) {
    bench_scene(c, "synthetic", &synthetic_scene());
    match shared_mbm() {
        Some(dir) => {
            for class in ["bookshelf_small", "box", "table_pick"] {
                let path = dir.join(class).join("scene0001.yaml");
                match Scene::from_moveit_yaml_file(&path, None) {
                    Ok(scene) => bench_scene(c, &format!("mbm {class}/scene0001"), &scene),
                    Err(e) => eprintln!("skipping {}: {e}", path.display()),
                }
            }
        }
        None => eprintln!("shared MotionBenchMaker data not found: real scenes skipped"),
    }
}

criterion_group!(benches, distance);
criterion_main!(benches);
