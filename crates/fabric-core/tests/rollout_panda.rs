use std::sync::Arc;
use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::Robot;
use fabric_core::scene::Scene;
use fabric_core::rollout::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn explore() {
    let robot = Arc::new(Robot::panda());
    let fabric = Fabric::new(robot.clone(), FabricConfig::default()).unwrap();
    let scene = Scene::new();
    let mut ws = FabricWorkspace::new(&fabric);
    let ready = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let goal = [0.5, -0.3, 0.3, -1.8, 0.2, 1.9, 0.5];
    let o = RolloutOptions { record: true, ..Default::default() };
    let t0 = std::time::Instant::now();
    let r = rollout(&fabric, &scene, &ready, &[0.0; 7], &goal, &o, &mut ws).unwrap();
    println!("{:?} t*={} steps={} el={:?} q={:?}", r.reason, r.t_star, r.steps, t0.elapsed(), r.q);
    fabric.acceleration(&scene, &ready, &[0.0;7], &ready, &mut ws, &mut [0.0;7]).unwrap();
    println!("{:?}", fabric.diagnostics(&ws));
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (lo, up) = (robot.lower().to_vec(), robot.upper().to_vec());
    for trial in 0..10 {
        let q0: Vec<f64> = (0..7).map(|i| rng.gen_range(lo[i]..up[i])).collect();
        let qd0: Vec<f64> = (0..7).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let cmd: Vec<f64> = (0..7).map(|i| rng.gen_range(lo[i]-0.3..up[i]+0.3)).collect();
        let o = RolloutOptions { record: true, t_max: 10.0, ..Default::default() };
        let r = rollout(&fabric, &scene, &q0, &qd0, &cmd, &o, &mut ws).unwrap();
        let tr = r.trajectory.unwrap();
        let mut worst = f64::INFINITY;
        for k in 0..tr.len() { for i in 0..7 { let q = tr.q[k*7+i]; worst = worst.min(q-lo[i]).min(up[i]-q);} }
        println!("trial {trial} {:?} t*={} worst margin {worst:.4}", r.reason, r.t_star);
    }
}
