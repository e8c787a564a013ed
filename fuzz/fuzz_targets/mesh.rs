//! Any bytes as an STL (binary or ASCII) and, when UTF-8, as an OBJ: each reader, and the mesh built
//! from what it returns, give a mesh or an error, never panic or crash.
#![no_main]

use fabric_core::scene::meshio::{build_mesh, parse_obj, parse_stl};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((vertices, triangles)) = parse_stl(data, "<fuzz>.stl") {
        let _ = build_mesh(vertices, triangles, "<fuzz>.stl");
    }
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok((vertices, triangles)) = parse_obj(text, "<fuzz>.obj") {
            let _ = build_mesh(vertices, triangles, "<fuzz>.obj");
        }
    }
});
