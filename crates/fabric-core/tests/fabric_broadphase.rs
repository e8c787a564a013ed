//! The culling of the fabric's collision leaves (self-collision link pairs and sphere runs, one scene query
//! per link, bounds from the link's bounding sphere) never drops a leaf: on random configurations the
//! number of leaves and the minimum clearances reported by `Fabric::diagnostics` equal a brute force over
//! every self-collision pair and every (sphere, obstacle) pair, for the shipped Panda in a box scene and,
//! when the shared data is present, for the MotionBenchMaker Panda in MotionBenchMaker scenes.

mod fabric_support;

use std::sync::Arc;

use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::{KinematicsWorkspace, Robot};
use fabric_core::scene::{point_distance, Scene};
use fabric_support::{box_scene, mbm_panda, mbm_problem, shared_dir};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Leaves and minimum clearances of one configuration by brute force, with the engine's rules: a
/// self-collision pair is within reach when ‖c_a − c_b‖ < r_a + r_b + margin + influence, a (sphere,
/// obstacle) pair when d(c) < r + margin + influence (the clearance minimum also takes d = r + reach).
struct Brute {
    leaves: usize,
    min_clearance: f64,
    min_self_clearance: f64,
}

fn brute_force(robot: &Robot, cfg: &FabricConfig, scene: &Scene, q: &[f64]) -> Brute {
    let mut kin = KinematicsWorkspace::new(robot);
    robot.update(q, &vec![0.0; q.len()], &mut kin).unwrap();
    let spheres = robot.spheres();
    let centers: Vec<_> = (0..spheres.len())
        .map(|k| robot.sphere_center(&kin, k))
        .collect();
    let mut out = Brute {
        leaves: 0,
        min_clearance: f64::INFINITY,
        min_self_clearance: f64::INFINITY,
    };
    let sc = &cfg.self_collision;
    let reach = sc.margin + sc.influence;
    for &(a, b) in robot.self_collision_pairs() {
        let (ra, rb) = (spheres[a].radius, spheres[b].radius);
        let d2 = (centers[a] - centers[b]).norm_squared();
        let far = ra + rb + reach;
        if d2 < far * far {
            out.leaves += 1;
            out.min_self_clearance = out.min_self_clearance.min(d2.sqrt() - ra - rb);
        }
    }
    let ob = &cfg.obstacles;
    let reach = ob.margin + ob.influence;
    for (k, c) in centers.iter().enumerate() {
        let r = spheres[k].radius;
        for (_, o) in scene.iter() {
            if let Some(s) = point_distance(&o.shape, &o.pose, c, f64::INFINITY) {
                if s.distance <= r + reach {
                    out.min_clearance = out.min_clearance.min(s.distance - r);
                }
                if s.distance - r - ob.margin < ob.influence {
                    out.leaves += 1;
                }
            }
        }
    }
    out
}

/// Random configurations within the joint limits, and near the `start` configuration (where the robot
/// is close to the obstacles), with random velocities; checks leaves and clearances against the brute
/// force and returns the number of configurations with at least one obstacle leaf.
fn check(robot: Robot, scene: &Scene, start: &[f64], seed: u64, samples: usize) -> usize {
    let mut cfg = FabricConfig::default();
    cfg.joint_limits.enabled = false; // every leaf is then a collision leaf
                                      // fixed reaches (not the defaults), with margins, so that many leaves exist
    (cfg.obstacles.margin, cfg.obstacles.influence) = (0.02, 0.3);
    (cfg.self_collision.margin, cfg.self_collision.influence) = (0.01, 0.1);
    let fabric = Fabric::new(Arc::new(robot), cfg.clone()).unwrap();
    let robot = fabric.robot().clone();
    let mut ws = FabricWorkspace::new(&fabric);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = robot.dof();
    let mut qdd = vec![0.0; n];
    let mut near_obstacles = 0;
    for i in 0..samples {
        let q: Vec<f64> = (0..n)
            .map(|j| {
                let (lo, hi) = (robot.lower()[j], robot.upper()[j]);
                if i % 2 == 0 {
                    rng.gen_range(lo..hi)
                } else {
                    (start[j] + rng.gen_range(-0.4..0.4)).clamp(lo, hi)
                }
            })
            .collect();
        let qd: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        if fabric
            .acceleration(scene, &q, &qd, start, &mut ws, &mut qdd)
            .is_err()
        {
            // deep self-penetration can make the root metric singular; the culling is then moot
            continue;
        }
        let d = fabric.diagnostics(&ws);
        let b = brute_force(&robot, &cfg, scene, &q);
        assert_eq!(d.leaves, b.leaves, "leaves at q = {q:?}");
        assert_eq!(d.min_self_clearance, b.min_self_clearance, "q = {q:?}");
        assert_eq!(d.min_clearance, b.min_clearance, "q = {q:?}");
        near_obstacles += b.min_clearance.is_finite() as usize;
    }
    near_obstacles
}

#[test]
fn shipped_panda_culling_matches_brute_force() {
    let start = [0.45, 0.35, 0.19, -1.9, -0.1, 2.3, 0.8];
    let near = check(Robot::panda(), &box_scene(), &start, 7, 400);
    assert!(near > 100, "only {near} configurations near the box");
    // free space: self-collision culling alone
    check(Robot::panda(), &Scene::new(), &start, 8, 200);
}

#[test]
fn motionbenchmaker_panda_culling_matches_brute_force() {
    let Some(shared) = shared_dir() else { return };
    let robot = mbm_panda(&shared);
    for (class, index) in [("cage", 1), ("box", 2), ("bookshelf_small", 3)] {
        let (scene, start, _) = mbm_problem(&shared, &robot, class, index);
        let near = check(robot.clone(), &scene, &start, index as u64, 600);
        assert!(
            near > 60,
            "{class} {index}: only {near} configurations near obstacles"
        );
    }
}
