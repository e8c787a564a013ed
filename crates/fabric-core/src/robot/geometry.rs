//! URDF `<collision>` geometry kept for mesh-based validation, and mesh path resolution.
//!
//! `package://pkg/rest` and relative mesh paths are resolved here rather than with urdf-rs' helper, which
//! needs a ROS installation (see `DESIGN.md`, version facts). A missing mesh file is not an error at load
//! time: the resolved path is stored with `exists = false`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

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
/// `<dir>/../rest`, then, as ROS resolves a package by the name in its `package.xml` rather than by its
/// folder's name (`moveit_resources_fanuc_description` lives in `fanuc_description/`), `<p>/rest` for the
/// folder `<p>` of the `package.xml` naming `pkg` below `dir` or below a root of `ROS_PACKAGE_PATH`
/// ([`find_package`]); `file://path` and other paths are taken relative to `dir` unless absolute. The
/// first existing candidate wins; when none exists the first candidate is returned with `false`.
/// `dir` is the mesh directory (or the URDF file's directory); `None` means the current directory.
pub(crate) fn resolve_mesh_path(filename: &str, dir: Option<&Path>) -> (PathBuf, bool) {
    let ros_roots: Vec<PathBuf> = std::env::var_os("ROS_PACKAGE_PATH")
        .map(|v| std::env::split_paths(&v).collect())
        .unwrap_or_default();
    resolve_mesh_path_in(filename, dir, &ros_roots)
}

/// [`resolve_mesh_path`] with the package roots `ros_roots` in place of `ROS_PACKAGE_PATH`'s.
fn resolve_mesh_path_in(
    filename: &str,
    dir: Option<&Path>,
    ros_roots: &[PathBuf],
) -> (PathBuf, bool) {
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
    if let Some(found) = candidates.iter().find(|c| c.is_file()) {
        return (found.clone(), true);
    }
    if let Some((pkg, tail)) = filename
        .strip_prefix("package://")
        .and_then(|rest| rest.split_once('/'))
    {
        let roots = dir
            .map(Path::to_path_buf)
            .into_iter()
            .chain(ros_roots.iter().cloned());
        for root in roots {
            if let Some(found) = find_package(&root, pkg).map(|p| p.join(tail)) {
                if found.is_file() {
                    return (found, true);
                }
            }
        }
    }
    (candidates.swap_remove(0), false)
}

/// Folders below `root` searched for `package.xml` files (a ROS workspace: `src/<group>/<package>/`).
const PACKAGE_SEARCH_DEPTH: usize = 4;

/// The folder of the `package.xml` whose `<name>` is `pkg`, at most [`PACKAGE_SEARCH_DEPTH`] folders below
/// `root` (hidden folders skipped; the first found in sorted order). Each root is scanned once per process.
pub(crate) fn find_package(root: &Path, pkg: &str) -> Option<PathBuf> {
    static SCANNED: OnceLock<Mutex<HashMap<PathBuf, HashMap<String, PathBuf>>>> = OnceLock::new();
    let mut scanned = SCANNED
        .get_or_init(|| Mutex::new(HashMap::new()))
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let packages = scanned.entry(root.to_path_buf()).or_insert_with(|| {
        let mut found = HashMap::new();
        scan_packages(root, PACKAGE_SEARCH_DEPTH, &mut found);
        found
    });
    packages.get(pkg).cloned()
}

fn scan_packages(dir: &Path, depth: usize, found: &mut HashMap<String, PathBuf>) {
    if let Ok(text) = std::fs::read_to_string(dir.join("package.xml")) {
        if let Some(name) = package_name(&text) {
            found.entry(name).or_insert_with(|| dir.to_path_buf());
        }
    }
    if depth == 0 {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut subdirs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .filter(|p| {
            !p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'))
        })
        .collect();
    subdirs.sort();
    for sub in subdirs {
        scan_packages(&sub, depth - 1, found);
    }
}

/// The text of the first `<name>` element of a `package.xml`, trimmed.
fn package_name(xml: &str) -> Option<String> {
    let start = xml.find("<name>")? + "<name>".len();
    let end = start + xml[start..].find("</name>")?;
    let name = xml[start..end].trim();
    (!name.is_empty()).then(|| name.to_string())
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

    /// A package found by the name in its package.xml, below the mesh directory (a ROS workspace whose
    /// folder names differ from the package names) or below a ROS_PACKAGE_PATH root; hidden folders and
    /// packages deeper than the search depth are not found.
    #[test]
    fn package_paths_find_the_package_xml_naming_the_package() {
        let dir = std::env::temp_dir().join(format!("gfcs_pkgxml_{}", std::process::id()));
        let pkg = dir.join("ws/src/fanuc_description");
        std::fs::create_dir_all(pkg.join("meshes")).unwrap();
        std::fs::write(
            pkg.join("package.xml"),
            "<package format=\"3\">\n  <name> moveit_resources_fanuc_description </name>\n</package>",
        )
        .unwrap();
        std::fs::write(pkg.join("meshes/link.stl"), "").unwrap();
        let hidden = dir.join("ws/.hidden/other");
        std::fs::create_dir_all(&hidden).unwrap();
        std::fs::write(
            hidden.join("package.xml"),
            "<package><name>other</name></package>",
        )
        .unwrap();
        std::fs::write(hidden.join("a.stl"), "").unwrap();
        let uri = "package://moveit_resources_fanuc_description/meshes/link.stl";
        let (p, ok) = resolve_mesh_path_in(uri, Some(&dir), &[]);
        assert!(ok);
        assert_eq!(p, pkg.join("meshes/link.stl"));
        // from a ROS_PACKAGE_PATH root when the mesh directory holds no such package
        let elsewhere = dir.join("urdf");
        std::fs::create_dir_all(&elsewhere).unwrap();
        let (p, ok) = resolve_mesh_path_in(uri, Some(&elsewhere), &[dir.join("ws")]);
        assert!(ok);
        assert_eq!(p, pkg.join("meshes/link.stl"));
        let (p, ok) = resolve_mesh_path_in(uri, Some(&elsewhere), &[]);
        assert!(!ok);
        assert_eq!(
            p,
            elsewhere.join("moveit_resources_fanuc_description/meshes/link.stl")
        );
        let (_, ok) = resolve_mesh_path_in("package://other/a.stl", Some(&dir), &[]);
        assert!(!ok, "hidden folders are not searched");
        assert_eq!(package_name("<name></name>"), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
