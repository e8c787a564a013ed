//! Any text as an SRDF for the shipped Panda: `set_self_collision_from_srdf` returns the skipped link
//! names or an error, never panics or crashes.
#![no_main]

use std::sync::OnceLock;

use fabric_core::robot::Robot;
use libfuzzer_sys::fuzz_target;

fn panda() -> &'static Robot {
    static PANDA: OnceLock<Robot> = OnceLock::new();
    PANDA.get_or_init(Robot::panda)
}

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let mut robot = panda().clone();
        let _ = robot.set_self_collision_from_srdf(text, "<fuzz>");
    }
});
