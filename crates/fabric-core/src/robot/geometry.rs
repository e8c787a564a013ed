//! URDF `<collision>` geometry kept for mesh-based validation, and mesh path resolution.
//!
//! `package://pkg/rest` and relative mesh paths are resolved here rather than with urdf-rs' helper, which
//! needs a ROS installation (see `DESIGN.md`, version facts). A missing mesh file is not an error at load
//! time: the resolved path is stored with `exists = false`.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Vector3};

/// Shape of one URDF `<collision>` element, in its element frame (sizes in m).
#[derive(Clone, Debug, PartialEq)]
pub enum GeometryKind {
    /// A mesh file, in its own units scaled per axis.
    Mesh {
        /// Resolved path (see [`RobotOptions::mesh_dir`](super::RobotOptions::mesh_dir)).
        path: PathBuf,
        /// Per-axis scale (URDF `scale`, default 1 1 1).
        scale: Vector3<f64>,
        /// Whether the file existed at load time.
        exists: bool,
    },
    /// A box centred on the frame origin.
    Box {
        /// Full edge lengths along x, y, z (m).
        size: Vector3<f64>,
    },
    /// A cylinder along local z, centred on the origin.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Full length (m).
        length: f64,
    },
    /// A capsule along local z, centred on the origin.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Full length of the cylinder part (m).
        length: f64,
    },
    /// A sphere centred on the origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
}

/// One URDF `<collision>` element: the link it belongs to, its pose in the link frame, and its shape.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkGeometry {
    /// Link index (see [`Robot::link_names`](super::Robot::link_names)).
    pub link: usize,
    /// Pose of the geometry frame in the link frame (URDF `<origin>`, rpy fixed-axis).
    pub origin: Isometry3<f64>,
    /// Shape.
    pub kind: GeometryKind,
}

/// Resolve a URDF mesh file name. `package://pkg/rest` tries `<dir>/pkg/rest`, `<dir>/rest` and
/// `<dir>/../rest`; `file://path` and other paths are taken relative to `dir` unless absolute. The first
/// existing candidate wins; when none exists the first candidate is returned with `false`.
/// `dir` is the mesh directory (or the URDF file's directory); `None` means the current directory.
pub(crate) fn resolve_mesh_path(filename: &str, dir: Option<&Path>) -> (PathBuf, bool) {
    let base = dir.map(Path::to_path_buf).unwrap_or_default();
    let mut candidates: Vec<PathBuf> = Vec::with_capacity(3);
    if let Some(rest) = filename.strip_prefix("package://") {
        let (pkg, tail) = rest.split_once('/').unwrap_or((rest, ""));
        candidates.push(base.join(pkg).join(tail));
        if !tail.is_empty() {
            candidates.push(base.join(tail));
            if let Some(parent) = dir.and_then(Path::parent) {
                candidates.push(parent.join(tail));
            }
        }
    } else {
        let plain = filename.strip_prefix("file://").unwrap_or(filename);
        let p = Path::new(plain);
        candidates.push(if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        });
    }
    match candidates.iter().find(|c| c.is_file()) {
        Some(found) => (found.clone(), true),
        None => (candidates.swap_remove(0), false),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn package_paths_try_package_then_plain_then_parent() {
        let dir = std::env::temp_dir().join(format!("gfcs_mesh_{}", std::process::id()));
        let sub = dir.join("urdf");
        std::fs::create_dir_all(sub.join("pkg/meshes")).unwrap();
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::write(dir.join("meshes/a.obj"), "").unwrap();
        std::fs::write(sub.join("pkg/meshes/b.obj"), "").unwrap();

        // <dir>/pkg/rest
        let (p, ok) = resolve_mesh_path("package://pkg/meshes/b.obj", Some(&sub));
        assert!(ok);
        assert_eq!(p, sub.join("pkg/meshes/b.obj"));
        // <dir>/../rest
        let (p, ok) = resolve_mesh_path("package://other/meshes/a.obj", Some(&sub));
        assert!(ok);
        assert_eq!(p, dir.join("meshes/a.obj"));
        // <dir>/rest
        let (p, ok) = resolve_mesh_path("package://other/meshes/a.obj", Some(&dir));
        assert!(ok);
        assert_eq!(p, dir.join("meshes/a.obj"));
        // missing: first candidate, flagged
        let (p, ok) = resolve_mesh_path("package://pkg/none.obj", Some(&dir));
        assert!(!ok);
        assert_eq!(p, dir.join("pkg/none.obj"));
        // relative and file://
        let (p, ok) = resolve_mesh_path("meshes/a.obj", Some(&dir));
        assert!(ok);
        assert_eq!(p, dir.join("meshes/a.obj"));
        let abs = dir.join("meshes/a.obj");
        let (p, ok) = resolve_mesh_path(&format!("file://{}", abs.display()), None);
        assert!(ok);
        assert_eq!(p, abs);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
