mod fabric_support;
use fabric_core::fabric::{Fabric, FabricConfig};
use fabric_support::*;

#[test]
#[ignore]
fn tune_mbm() {
    let Some(shared) = shared_dir() else { return };
    let robot = arc(mbm_panda(&shared));
    let cfg = match std::env::var("FABRIC_CFG") { Ok(p) => FabricConfig::from_file(std::path::Path::new(&p)).unwrap(), Err(_) => FabricConfig::default() };
    let fabric = Fabric::new(robot.clone(), cfg).unwrap();
    let per: usize = std::env::var("PER").ok().and_then(|s| s.parse().ok()).unwrap_or(5);
    for class in ["table_pick", "table_under_pick", "box", "bookshelf_small", "bookshelf_tall", "bookshelf_thin", "cage"] {
        let (mut reached, mut t, mut coll, mut selfc, mut jl, mut vmax, mut worst) = (0, 0.0, 0, 0, 0, 0.0f64, f64::INFINITY);
        for i in 1..=per {
            let (mut scene, start, goal) = mbm_problem(&shared, &robot, class, i);
            if std::env::var("EMPTY").is_ok() { scene = fabric_core::scene::Scene::new(); }
            let r = euler_rollout(&fabric, &scene, &start, &goal, 0.01, 7.0, 0.01);
            if let Some(tr) = r.reached { reached += 1; t += tr; }
            if r.min_clearance < 0.0 { coll += 1; }
            worst = worst.min(r.min_clearance);
            if r.min_self_clearance < 0.0 { selfc += 1; }
            if r.min_joint_margin < 0.0 { jl += 1; }
            vmax = vmax.max(r.max_speed);
            if std::env::var("VERBOSE").is_ok() {
                println!("{class} {i}: reached {:?} clear {:.3} self {:.3} jl {:.3} vmax {:.2} ok {} final err {:.3}", r.reached, r.min_clearance, r.min_self_clearance, r.min_joint_margin, r.max_speed, r.ok,
                    r.q.iter().zip(&goal).map(|(a,b)|(a-b)*(a-b)).sum::<f64>().sqrt());
            }
        }
        println!("{class:18} reached {reached}/{per} mean t {:.2} coll {coll} selfcoll {selfc} jl {jl} vmax {vmax:.2} worst {worst:.4}", t / reached.max(1) as f64);
    }
}

#[test]
#[ignore]
fn trace_one() {
    let Some(shared) = shared_dir() else { return };
    let robot = arc(mbm_panda(&shared));
    let cfg = match std::env::var("FABRIC_CFG") { Ok(p) => FabricConfig::from_file(std::path::Path::new(&p)).unwrap(), Err(_) => FabricConfig::default() };
    let fabric = Fabric::new(robot.clone(), cfg).unwrap();
    let class = std::env::var("CLASS").unwrap_or("box".into());
    let idx: usize = std::env::var("IDX").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let (mut scene, start, goal) = mbm_problem(&shared, &robot, &class, idx);
    if std::env::var("EMPTY").is_ok() { scene = fabric_core::scene::Scene::new(); }
    let mut ws = fabric_core::fabric::FabricWorkspace::new(&fabric);
    let n = start.len();
    let (mut q, mut qd, mut qdd) = (start.clone(), vec![0.0; n], vec![0.0; n]);
    println!("start {:?}\ngoal {:?}\nlower {:?}\nupper {:?}", start, goal, robot.lower(), robot.upper());
    for k in 0..700 {
        fabric.acceleration(&scene, &q, &qd, &goal, &mut ws, &mut qdd).unwrap();
        let d = fabric.diagnostics(&ws);
        let err = q.iter().zip(&goal).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
        if k % 20 == 0 || std::env::var("ALL").is_ok() {
            println!("t {:.2} err {:.3} v {:.3} |qdd| {:.2} eta {:.2} sb {:.2} aLe {:.2} aex0 {:.2} aexpsi {:.2} areg {:.2} clr {:.3} self {:.3} jl {:.3} leaves {}", k as f64 * 0.01, err, (2.0 * d.exec_energy).sqrt(), qdd.iter().map(|v| v*v).sum::<f64>().sqrt(), d.eta, d.s_beta, d.alpha_le, d.alpha_ex0, d.alpha_expsi, d.alpha_reg, d.min_clearance, d.min_self_clearance, d.min_joint_margin, d.leaves);
        }
        for i in 0..n { qd[i] += 0.01 * qdd[i]; q[i] += 0.01 * qd[i]; }
    }
    println!("final q {:?}", q);
}

#[test]
#[ignore]
fn closest_pairs() {
    let Some(shared) = shared_dir() else { return };
    let robot = mbm_panda(&shared);
    let mut kin = fabric_core::robot::KinematicsWorkspace::new(&robot);
    let (_, start, goal) = mbm_problem(&shared, &robot, "box", 1);
    for q in [start, goal] {
        robot.update_positions(&q, &mut kin).unwrap();
        let sp = robot.spheres();
        let mut v: Vec<(f64, usize, usize)> = robot.self_collision_pairs().iter().map(|&(a, b)| ((robot.sphere_center(&kin, a) - robot.sphere_center(&kin, b)).norm() - sp[a].radius - sp[b].radius, a, b)).collect();
        v.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        println!("pairs {} spheres {}", v.len(), sp.len());
        for (d, a, b) in v.iter().take(12) {
            println!("{d:.3} {} {} ({} {})", robot.link_names()[sp[*a].link], robot.link_names()[sp[*b].link], a, b);
        }
        let below = v.iter().filter(|x| x.0 < 0.15).count();
        println!("pairs within 0.15: {below}; within 0.05: {}", v.iter().filter(|x| x.0 < 0.05).count());
    }
}

#[test]
#[ignore]
fn goal_clearance() {
    let Some(shared) = shared_dir() else { return };
    let robot = mbm_panda(&shared);
    let mut kin = fabric_core::robot::KinematicsWorkspace::new(&robot);
    for class in ["table_pick", "table_under_pick", "box", "bookshelf_small", "bookshelf_tall", "bookshelf_thin", "cage"] {
        let mut v = vec![];
        for i in 1..=8 {
            let (scene, start, goal) = mbm_problem(&shared, &robot, class, i);
            let mut c = vec![];
            for q in [&start, &goal] {
                robot.update_positions(q, &mut kin).unwrap();
                let m = (0..robot.spheres().len()).map(|k| scene.signed_distance(&robot.sphere_center(&kin, k)).map(|s| s.distance - robot.spheres()[k].radius).unwrap_or(f64::INFINITY)).fold(f64::INFINITY, f64::min);
                c.push(m);
            }
            let jl = goal.iter().zip(robot.lower().iter().zip(robot.upper())).map(|(g, (l, u))| (g - l).min(u - g)).fold(f64::INFINITY, f64::min);
            v.push(format!("{:.3}/{:.3}/{:.3}", c[0], c[1], jl));
        }
        println!("{class:18} start/goal clearance, goal jl margin: {}", v.join(" "));
    }
}
