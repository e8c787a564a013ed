//! Any text as a URDF: `Robot::from_urdf_str` returns a robot or an error, never panics or crashes.
#![no_main]

use fabric_core::robot::{Robot, RobotOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Robot::from_urdf_str(text, "<fuzz>", &RobotOptions::default());
    }
});
