//! Any text as a MoveIt planning scene and as a motion plan request: each reader returns its value or
//! an error, never panics or crashes.
#![no_main]

use fabric_core::scene::{moveit, Scene};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Scene::from_moveit_yaml_str(text, "<fuzz>", Some("panda_link0"));
        let _ = moveit::parse_request_str(text, "<fuzz>");
    }
});
