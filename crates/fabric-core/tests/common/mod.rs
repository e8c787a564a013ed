//! The shared-data skip rule, one copy for every test support module (`fabric_support`,
//! `robot_support`, `scene_support` include it with `#[path = "../common/mod.rs"]`).
//!
//! The shared data lives at `<repo root>/../shared`, overridable by the environment variable
//! `GFCS_SHARED`. A test that needs it skips (printing why) when it is absent, unless `CI=true`: then the
//! test fails.
#![allow(dead_code)]

use std::path::PathBuf;

/// The shared data root: `$GFCS_SHARED`, else `<repo root>/../shared`. Not checked.
pub fn shared_root() -> PathBuf {
    std::env::var_os("GFCS_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")))
}

/// The shared data root ([`shared_root`]). `None` (test skipped, reason printed) when absent, unless
/// `CI=true`: then it panics, failing the test.
pub fn shared_dir() -> Option<PathBuf> {
    present(shared_root())
}

/// `<shared root>/<sub>`, under the same rule as [`shared_dir`] applied to that subdirectory.
pub fn shared_subdir(sub: &str) -> Option<PathBuf> {
    present(shared_root().join(sub))
}

/// `Some(dir)` when `dir` is a directory; else panics when `CI=true`, or prints why and returns `None`.
fn present(dir: PathBuf) -> Option<PathBuf> {
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!(
            "shared data directory {} is missing and CI=true",
            dir.display()
        );
    }
    eprintln!(
        "skipping: shared data directory {} not found (set GFCS_SHARED)",
        dir.display()
    );
    None
}
