//! OBJ and STL readers, the solid/open decision of `build_mesh`, and error messages naming file and line.

mod scene_support;

use std::path::PathBuf;

use fabric_core::scene::meshio::{
    build_mesh, is_closed, load_mesh, parse_obj, parse_stl, signed_volume,
};
use fabric_core::FabricError;
use nalgebra::{Isometry3, Point3};
use parry3d_f64::query::PointQuery;
use scene_support::{fine_cube, shared_dir, UNIT_CUBE_OBJ};

/// A folder of test files, one per test (tests run in parallel), removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("gfcs_scene_meshio_{}_{test}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn file(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn mesh_message(r: Result<impl std::fmt::Debug, FabricError>) -> (String, String) {
    match r {
        Err(FabricError::Mesh { path, message }) => (path, message),
        other => panic!("expected a Mesh error, got {other:?}"),
    }
}

fn ascii_stl(v: &[Point3<f64>], t: &[[u32; 3]]) -> String {
    let mut s = String::from("solid cube\n");
    for tri in t {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for &i in tri {
            let p = v[i as usize];
            s.push_str(&format!("      vertex {} {} {}\n", p.x, p.y, p.z));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid cube\n");
    s
}

fn binary_stl(v: &[Point3<f64>], t: &[[u32; 3]]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(t.len() as u32).to_le_bytes());
    for tri in t {
        b.extend_from_slice(&[0u8; 12]);
        for &i in tri {
            for c in v[i as usize].coords.iter() {
                b.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

#[test]
fn obj_statements_and_index_forms() {
    let text = "# comment\nmtllib x.mtl\no thing\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n\
                usemtl m\ns off\nf 1/1/1 2/2/1 3//1 4 # a quad\nf -4 -2 -1\n";
    let (v, t) = parse_obj(text, "q.obj").unwrap();
    assert_eq!(v.len(), 4);
    assert_eq!(v[1], Point3::new(1.0, 0.0, 0.0));
    assert_eq!(t, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
}

#[test]
fn obj_errors_name_file_and_line() {
    let cases = [
        ("v 0 0 0\nv 1 0 zero\n", "line 2"),
        ("v 0 0 0\nv 1 0\n", "line 2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 0 1 2\n", "line 5"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3"),
        ("v 0 0 0\nf -3 -2 -1\n", "line 2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x/1\n", "line 4"),
        ("v 0 0 nan\n", "line 1"),
    ];
    for (text, line) in cases {
        let (path, message) = mesh_message(parse_obj(text, "bad.obj"));
        assert_eq!(path, "bad.obj");
        assert!(
            message.starts_with(line),
            "{message:?} should start with {line}"
        );
    }
    let (_, message) = mesh_message(parse_obj("v 0 0 0\n", "none.obj"));
    assert!(message.contains("no faces"));
}

#[test]
fn stl_ascii_and_binary_give_the_same_solid_as_obj() {
    let (v, t) = parse_obj(UNIT_CUBE_OBJ, "cube.obj").unwrap();
    let obj = build_mesh(v.clone(), t.clone(), "cube.obj").unwrap();
    let tmp = TempDir::new("stl_obj");
    let a = load_mesh(&tmp.file("cube_ascii.stl", ascii_stl(&v, &t).as_bytes())).unwrap();
    let b = load_mesh(&tmp.file("cube_binary.STL", &binary_stl(&v, &t))).unwrap();
    let o = load_mesh(&tmp.file("cube.obj", UNIT_CUBE_OBJ.as_bytes())).unwrap();
    for m in [&obj, &a, &b, &o] {
        // STL duplicates vertices per triangle: merged back to the 8 corners, closed, solid.
        assert_eq!(m.vertices().len(), 8);
        assert_eq!(m.indices().len(), 12);
        assert!(is_closed(m.indices()));
        assert!(m.pseudo_normals_if_oriented().is_some());
        assert!((signed_volume(m.vertices(), m.indices()) - 1.0).abs() < 1e-12);
        assert!(m.contains_point(&Isometry3::identity(), &Point3::new(0.1, 0.2, 0.3)));
        assert!(!m.contains_point(&Isometry3::identity(), &Point3::new(0.1, 0.2, 0.6)));
        let proj = m.project_point(&Isometry3::identity(), &Point3::new(0.1, 0.2, 0.3), false);
        assert!((proj.point.z - 0.5).abs() < 1e-12);
    }
}

#[test]
fn stl_errors() {
    let (v, t) = parse_obj(UNIT_CUBE_OBJ, "cube.obj").unwrap();
    let mut bin = binary_stl(&v, &t);
    bin.truncate(bin.len() - 10);
    let (path, message) = mesh_message(parse_stl(&bin, "cut.stl"));
    assert_eq!(path, "cut.stl");
    assert!(message.contains("neither binary"), "{message}");
    let bad = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n";
    let (_, message) = mesh_message(parse_stl(bad.as_bytes(), "two.stl"));
    assert!(message.starts_with("line 6"), "{message}");
    let bad = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 q\n";
    let (_, message) = mesh_message(parse_stl(bad.as_bytes(), "num.stl"));
    assert!(message.starts_with("line 5"), "{message}");
    let mut nan = binary_stl(&v, &t);
    nan[84 + 50 * 3 + 12..84 + 50 * 3 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    let (_, message) = mesh_message(parse_stl(&nan, "nan.stl"));
    assert!(message.contains("triangle 3"), "{message}");
}

#[test]
fn build_mesh_orients_closed_meshes_and_leaves_open_ones_unsigned() {
    // Inward-facing cube: flipped to outward.
    let (v, t) = fine_cube(0.5, 2);
    let inward: Vec<[u32; 3]> = t.iter().map(|f| [f[0], f[2], f[1]]).collect();
    let m = build_mesh(v.clone(), inward, "inward").unwrap();
    assert!(m.pseudo_normals_if_oriented().is_some());
    assert!(signed_volume(m.vertices(), m.indices()) > 0.99);
    assert!(m.contains_point(&Isometry3::identity(), &Point3::new(0.0, 0.0, 0.2)));
    // One face removed: open, unsigned.
    let open: Vec<[u32; 3]> = t[2..].to_vec();
    let m = build_mesh(v.clone(), open.clone(), "open").unwrap();
    assert!(!is_closed(&open));
    assert!(m.pseudo_normals_if_oriented().is_none());
    // Inconsistent orientation (one triangle flipped): not closed-and-oriented.
    let mut flipped = t.clone();
    flipped[0].swap(1, 2);
    assert!(!is_closed(&flipped));
    // Bad data.
    let (_, message) = mesh_message(build_mesh(v.clone(), vec![[0, 1, 999]], "idx"));
    assert!(message.contains("out of range"), "{message}");
    let mut nan = v.clone();
    nan[3] = Point3::new(f64::NAN, 0.0, 0.0);
    let (_, message) = mesh_message(build_mesh(nan, t.clone(), "nan"));
    assert!(message.contains("vertex 3"), "{message}");
    assert!(build_mesh(v, vec![], "empty").is_err());
}

#[test]
fn load_mesh_errors() {
    let tmp = TempDir::new("errors");
    let (path, message) = mesh_message(load_mesh(&tmp.file("m.ply", b"ply")));
    assert!(path.ends_with("m.ply"));
    assert!(
        message.contains("unsupported mesh format '.ply' (supported: .obj, .stl, .dae)"),
        "{message}"
    );
    let (path, message) = mesh_message(load_mesh(&tmp.file("m.dae", b"<xml/>")));
    assert!(path.ends_with("m.dae"));
    assert!(message.contains("no triangles"), "{message}");
    let (path, _) = mesh_message(load_mesh(std::path::Path::new("/nonexistent/dir/mesh.obj")));
    assert_eq!(path, "/nonexistent/dir/mesh.obj");
    let (path, message) = mesh_message(load_mesh(&tmp.file("broken.obj", b"v 0 0 0\nf 1 2 3\n")));
    assert!(path.ends_with("broken.obj"));
    assert!(message.starts_with("line 2"), "{message}");
}

#[test]
fn panda_collision_meshes_load() {
    let Some(dir) = shared_dir("robots/mbm_panda/meshes/collision") else {
        return;
    };
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("obj") {
            continue;
        }
        let m = load_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(!m.indices().is_empty());
        let aabb = m.local_aabb();
        let size = aabb.maxs - aabb.mins;
        // Panda links are a few centimetres to a few decimetres across (metres in the files).
        assert!(
            size.max() > 0.02 && size.max() < 0.5,
            "{}: {size:?}",
            path.display()
        );
        n += 1;
    }
    assert!(n >= 9, "{n} meshes");
}
