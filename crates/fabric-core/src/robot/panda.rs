//! The shipped Franka Emika Panda: `assets/panda.urdf` (kinematics and limits of the published Franka
//! model, no meshes), `assets/panda_spheres.json` (collision spheres) and `assets/panda.srdf` (disabled
//! self-collision pairs), embedded with `include_str!` so no file is needed at run time.

use super::model::{Robot, RobotOptions};

/// The shipped Panda URDF text (`assets/panda.urdf`): kinematics and limits, no collision elements.
pub const PANDA_URDF: &str = include_str!("../../assets/panda.urdf");
const PANDA_SPHERES: &str = include_str!("../../assets/panda_spheres.json");
/// The shipped Panda SRDF text (`assets/panda.srdf`): the self-collision link pairs it disables.
pub const PANDA_SRDF: &str = include_str!("../../assets/panda.srdf");

impl Robot {
    /// The shipped Panda: base `panda_link0`, end-effector `panda_hand` (the flange frame rotated by
    /// -π/4 about z; the tool centre point is the link `panda_hand_tcp`, 0.1034 m further along z),
    /// 7 active joints `panda_joint1..7`, fingers locked open at 0.04 m (`panda_finger_joint2` mimics
    /// `panda_finger_joint1`). Limits in rad and rad/s: the Franka datasheet values.
    pub fn panda() -> Robot {
        let opts = RobotOptions {
            base_link: Some("panda_link0".into()),
            ee_link: Some("panda_hand".into()),
            locked_positions: vec![("panda_finger_joint1".into(), 0.04)],
            ..RobotOptions::default()
        };
        // The assets are part of the crate and covered by tests: failing here is a build defect, not a
        // user error.
        let mut robot = Robot::from_urdf_str(PANDA_URDF, "assets/panda.urdf", &opts)
            .unwrap_or_else(|e| panic!("shipped Panda URDF: {e}"));
        let spheres = robot
            .parse_sphere_json(PANDA_SPHERES, "assets/panda_spheres.json")
            .unwrap_or_else(|e| panic!("shipped Panda spheres: {e}"));
        robot
            .set_spheres(spheres)
            .unwrap_or_else(|e| panic!("shipped Panda spheres: {e}"));
        robot
            .set_self_collision_from_srdf(PANDA_SRDF, "assets/panda.srdf")
            .unwrap_or_else(|e| panic!("shipped Panda SRDF: {e}"));
        robot
    }
}
