//! Kinematics benchmarks on the shipped Panda:
//! * one configuration: `update` (FK, velocities, bias accelerations) then every collision sphere's
//!   centre, Jacobian and J̇q̇ (target ≤ 2 µs), and the pieces alone;
//! * batch sphere centres over 10,000 configurations with 1 and 2 rayon threads.
//!
//! Run: `cargo bench -p fabric-core --bench kinematics`.

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use fabric_core::robot::{batch, KinematicsWorkspace, Robot, TaskPoint};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_q(robot: &Robot, rng: &mut ChaCha8Rng) -> Vec<f64> {
    robot
        .lower()
        .iter()
        .zip(robot.upper())
        .map(|(&l, &u)| rng.gen_range(l..u))
        .collect()
}

fn single_configuration(c: &mut Criterion) {
    let robot = Robot::panda();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let q = random_q(&robot, &mut rng);
    let qd: Vec<f64> = (0..robot.dof()).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut tp = TaskPoint::new(robot.dof());
    let n = robot.spheres().len();

    c.bench_function(
        &format!("panda update + {n} spheres (x, J, Jdot qdot)"),
        |b| {
            b.iter(|| {
                robot
                    .update(black_box(&q), black_box(&qd), &mut ws)
                    .unwrap();
                let mut acc = 0.0;
                for i in 0..n {
                    robot.sphere(&ws, i, &mut tp);
                    acc += tp.jac[(0, 0)] + tp.jdot_qdot.z;
                }
                black_box(acc)
            })
        },
    );
    c.bench_function("panda update", |b| {
        b.iter(|| {
            robot
                .update(black_box(&q), black_box(&qd), &mut ws)
                .unwrap()
        })
    });
    c.bench_function(
        &format!("panda update_positions + {n} sphere centres"),
        |b| {
            b.iter(|| {
                robot.update_positions(black_box(&q), &mut ws).unwrap();
                let mut acc = 0.0;
                for i in 0..n {
                    acc += robot.sphere_center(&ws, i).z;
                }
                black_box(acc)
            })
        },
    );
}

fn batch_sphere_centres(c: &mut Criterion) {
    let robot = Robot::panda();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let configs = 10_000;
    let qs: Vec<f64> = (0..configs)
        .flat_map(|_| random_q(&robot, &mut rng))
        .collect();
    let mut group = c.benchmark_group("batch sphere centres, 10000 configurations");
    group.sample_size(20);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        group.bench_with_input(BenchmarkId::new("threads", threads), &threads, |b, _| {
            b.iter(|| pool.install(|| batch::sphere_centers(&robot, black_box(&qs)).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, single_configuration, batch_sphere_centres);
criterion_main!(benches);
