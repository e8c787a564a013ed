//! MotionBenchMaker survey of the reactive fabric alone (one command = the goal), for tuning gains:
//! per class, the number of problems reached within 0.01 rad in 7 s at dt = 0.01 s, the mean time, the
//! number of runs with negative obstacle / self clearance or a crossed joint limit, the peak speed and the
//! worst clearance. Ignored by default (≈ 1 s per 50 rollouts in release); run with
//!
//! ```text
//! cargo test -p fabric-core --release --test fabric_mbm_survey -- --ignored --nocapture
//! FABRIC_CFG=my.toml PER=50 cargo test ...     # a configuration file and problems per class
//! ```
//!
//! It fails if any evaluation errors or diverges (peak speed > 3 rad/s).

mod fabric_support;

use fabric_core::fabric::{Fabric, FabricConfig};
use fabric_support::*;

#[test]
#[ignore]
fn mbm_survey() {
    let Some(shared) = shared_dir() else { return };
    let robot = arc(mbm_panda(&shared));
    let cfg = match std::env::var("FABRIC_CFG") {
        Ok(p) => FabricConfig::from_file(std::path::Path::new(&p)).expect("FABRIC_CFG"),
        Err(_) => FabricConfig::default(),
    };
    let fabric = Fabric::new(robot.clone(), cfg).expect("fabric");
    let per: usize = std::env::var("PER")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(12)
        .clamp(1, 50);
    for class in [
        "table_pick",
        "table_under_pick",
        "box",
        "bookshelf_small",
        "bookshelf_tall",
        "bookshelf_thin",
        "cage",
    ] {
        let (mut reached, mut t, mut coll, mut selfc, mut jl, mut vmax, mut worst) =
            (0, 0.0, 0, 0, 0, 0.0f64, f64::INFINITY);
        for i in 1..=per {
            let (scene, start, goal) = mbm_problem(&shared, &robot, class, i);
            let r = euler_rollout(&fabric, &scene, &start, &goal, 0.01, 7.0, 0.01);
            assert!(r.ok, "{class} {i}: an evaluation failed");
            if let Some(tr) = r.reached {
                reached += 1;
                t += tr;
            }
            coll += (r.min_clearance < 0.0) as usize;
            selfc += (r.min_self_clearance < 0.0) as usize;
            jl += (r.min_joint_margin < 0.0) as usize;
            vmax = vmax.max(r.max_speed);
            worst = worst.min(r.min_clearance);
            assert!(r.max_speed < 3.0, "{class} {i}: peak speed {}", r.max_speed);
        }
        println!(
            "{class:18} reached {reached}/{per} mean t {:.2} coll {coll} selfcoll {selfc} jl {jl} vmax {vmax:.2} worst {worst:.4}",
            t / reached.max(1) as f64
        );
    }
}
