use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::scene::Scene;
use std::sync::Arc;
use std::time::Instant;
#[path = "../tests/fabric_support/mod.rs"]
mod fabric_support;
use fabric_support::{mbm_panda, mbm_problem, shared_root};
const OBS: [[f64; 3]; 10] = [
    [
        0.21913869971432698,
        -0.36834125797780753,
        0.13277881914895576,
    ],
    [0.17061724122748778, 0.3671944975743975, 0.5348999931723383],
    [-0.5189510070359056, 0.5810862757598185, 0.5331689761992734],
    [
        -0.32046097514018435,
        -0.12370044608374653,
        0.12265573691637038,
    ],
    [-0.6011467576006977, 0.2729990635098085, 0.6177516092594001],
    [
        0.30151476891350404,
        -0.17772572163343392,
        0.20807720401792898,
    ],
    [-0.0226634258691375, 0.6231805349584005, 0.8472348127649998],
    [0.15088004831951485, -0.2593420391885868, 0.413295200422529],
    [0.6244389632076677, -0.4365478503465925, 0.598549715748834],
    [-0.4170088912112766, 0.6023747692971262, 0.14685442784415548],
];
const START: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
const GOAL: [f64; 7] = [0.9, 0.3, 0.2, -1.6, -0.1, 1.9, 0.6];
fn states(
    fabric: &Fabric,
    scene: &Scene,
    start: &[f64],
    goal: &[f64],
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut ws = FabricWorkspace::new(fabric);
    let (mut q, mut qd, mut qdd) = (start.to_vec(), vec![0.0; 7], vec![0.0; 7]);
    let mut out = Vec::new();
    for k in 0..400 {
        if fabric
            .acceleration(scene, &q, &qd, goal, &mut ws, &mut qdd)
            .is_err()
        {
            break;
        }
        if k % 5 == 0 {
            out.push((q.clone(), qd.clone()));
        }
        for i in 0..7 {
            qd[i] += 0.01 * qdd[i];
            q[i] += 0.01 * qd[i];
        }
    }
    out
}
fn time(
    fabric: &Fabric,
    scene: &Scene,
    st: &[(Vec<f64>, Vec<f64>)],
    goal: &[f64],
    dump: &mut String,
) -> f64 {
    let mut ws = FabricWorkspace::for_rollouts(fabric);
    let mut qdd = vec![0.0; 7];
    for (q, qd) in st {
        fabric
            .acceleration(scene, q, qd, goal, &mut ws, &mut qdd)
            .unwrap();
        for v in &qdd {
            *dump += &format!("{:x} ", v.to_bits());
        }
        *dump += "\n";
    }
    let mut best = f64::INFINITY;
    for _ in 0..15 {
        let t = Instant::now();
        let reps = 50;
        for _ in 0..reps {
            for (q, qd) in st {
                fabric
                    .acceleration(scene, q, qd, goal, &mut ws, &mut qdd)
                    .unwrap();
            }
        }
        best = best.min(t.elapsed().as_secs_f64() / (reps * st.len()) as f64 * 1e6);
    }
    best
}
fn main() {
    let shared = shared_root();
    let robot = Arc::new(mbm_panda(&shared));
    let full = Fabric::new(robot.clone(), FabricConfig::default()).unwrap();
    let mut dump = String::new();
    let mut scene = Scene::new();
    for c in OBS {
        scene
            .add(fabric_core::scene::Obstacle::new(
                "s",
                fabric_core::scene::Shape::Sphere { radius: 0.05 },
                nalgebra::Isometry3::translation(c[0], c[1], c[2]),
            ))
            .unwrap();
    }
    let st = states(&full, &scene, &START, &GOAL);
    let a = time(&full, &scene, &st, &GOAL, &mut dump);
    let mut r81 = mbm_panda(&shared);
    let sp = r81
        .load_sphere_file(std::path::Path::new("/work/tmpex/mbm81.json"))
        .unwrap();
    r81.set_spheres(sp).unwrap();
    let f81 = Fabric::new(Arc::new(r81), FabricConfig::default()).unwrap();
    let st81 = states(&f81, &scene, &START, &GOAL);
    let a81 = time(&f81, &scene, &st81, &GOAL, &mut dump);
    print!("s81 {a81:.3} ");
    if std::env::var("ONLY81").is_ok() {
        println!();
        return;
    }
    let (cage, start, goal) = mbm_problem(&shared, &robot, "cage", 1);
    let st2 = states(&full, &cage, &start, &goal);
    let b = time(&full, &cage, &st2, &goal, &mut dump);
    let c = time(&full, &Scene::new(), &st2, &goal, &mut dump);
    println!("spheres10 {a:.3} cage {b:.3} free {c:.3}");
    std::fs::write(
        std::env::var("DUMP").unwrap_or("/tmp/dump.txt".into()),
        dump,
    )
    .unwrap();
}
