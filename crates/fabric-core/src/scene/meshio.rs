//! Small triangle-mesh readers (Wavefront OBJ, binary and ASCII STL; COLLADA in [`super::collada`]) and the
//! mesh builder that decides whether a mesh is solid.
//!
//! Units: whatever the file holds (URDF meshes are in metres; apply a URDF `scale` yourself with
//! `TriMesh::scaled`). Errors are [`FabricError::Mesh`] naming the file and the line (OBJ, ASCII STL) or
//! the triangle and byte offset (binary STL).

use std::collections::HashMap;
use std::path::Path;

use nalgebra::Point3;
use parry3d_f64::shape::{TriMesh, TriMeshFlags};

use crate::error::{FabricError, Result};

/// Vertices and triangles (indices into the vertices, counter-clockwise = outward by convention).
pub type MeshData = (Vec<Point3<f64>>, Vec<[u32; 3]>);

fn mesh_err(source: &str, message: impl Into<String>) -> FabricError {
    FabricError::Mesh {
        path: source.to_string(),
        message: message.into(),
    }
}

/// Load an `.obj`, `.stl` or `.dae` file (extension, case-insensitive) and build it with [`build_mesh`].
pub fn load_mesh(path: &Path) -> Result<TriMesh> {
    let source = path.display().to_string();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let bytes = std::fs::read(path).map_err(|e| mesh_err(&source, format!("cannot read: {e}")))?;
    let (vertices, triangles) = match ext.as_str() {
        "obj" => {
            let text = std::str::from_utf8(&bytes)
                .map_err(|e| mesh_err(&source, format!("not UTF-8 text: {e}")))?;
            parse_obj(text, &source)?
        }
        "stl" => parse_stl(&bytes, &source)?,
        "dae" => {
            let text = std::str::from_utf8(&bytes)
                .map_err(|e| mesh_err(&source, format!("not UTF-8 text: {e}")))?;
            super::collada::parse_dae(text, &source)?
        }
        _ => {
            return Err(mesh_err(
                &source,
                format!("unsupported mesh format '.{ext}' (supported: .obj, .stl, .dae)"),
            ))
        }
    };
    build_mesh(vertices, triangles, &source)
}

/// Parse Wavefront OBJ text: `v x y z [w]` and `f` lines (`i`, `i/t`, `i//n`, `i/t/n`, negative indices
/// relative to the vertices read so far); polygons are fan-triangulated; every other statement is
/// ignored. `source` names the file in errors ("line N: ...").
pub fn parse_obj(text: &str, source: &str) -> Result<MeshData> {
    let mut vertices: Vec<Point3<f64>> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Positive indices may be checked only at the end (some exporters write faces first).
    let mut pending: Vec<(usize, i64)> = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line_no = n + 1;
        let err = |m: String| mesh_err(source, format!("line {line_no}: {m}"));
        let line = raw.split('#').next().unwrap_or("");
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("v") => {
                let mut c = [0.0; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let t = tokens
                        .next()
                        .ok_or_else(|| err(format!("vertex needs 3 coordinates, got {k}")))?;
                    let v: f64 = t.parse().map_err(|_| err(format!("bad number '{t}'")))?;
                    if !v.is_finite() {
                        return Err(err(format!("non-finite coordinate '{t}'")));
                    }
                    *slot = v;
                }
                vertices.push(Point3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let mut idx = Vec::with_capacity(4);
                for t in tokens {
                    let first = t.split('/').next().unwrap_or("");
                    let i: i64 = first
                        .parse()
                        .map_err(|_| err(format!("bad vertex reference '{t}'")))?;
                    let resolved = match i {
                        0 => return Err(err("vertex index 0 (OBJ indices start at 1)".into())),
                        i if i > 0 => i - 1,
                        i => {
                            let r = vertices.len() as i64 + i;
                            if r < 0 {
                                return Err(err(format!(
                                    "relative index {i} with only {} vertices read",
                                    vertices.len()
                                )));
                            }
                            r
                        }
                    };
                    idx.push(resolved);
                }
                if idx.len() < 3 {
                    return Err(err(format!(
                        "face needs at least 3 vertices, got {}",
                        idx.len()
                    )));
                }
                for k in 1..idx.len() - 1 {
                    for &i in &[idx[0], idx[k], idx[k + 1]] {
                        pending.push((line_no, i));
                    }
                    let tri = [idx[0], idx[k], idx[k + 1]];
                    triangles.push(tri.map(|i| u32::try_from(i).unwrap_or(u32::MAX)));
                }
            }
            _ => {}
        }
    }
    for (line_no, i) in pending {
        if i as usize >= vertices.len() || i > u32::MAX as i64 - 1 {
            return Err(mesh_err(
                source,
                format!(
                    "line {line_no}: vertex index {} out of range ({} vertices)",
                    i + 1,
                    vertices.len()
                ),
            ));
        }
    }
    if triangles.is_empty() {
        return Err(mesh_err(source, "no faces"));
    }
    Ok((vertices, triangles))
}

/// Parse an STL file: binary when the size is `84 + 50·n` for the triangle count `n` in the header,
/// otherwise ASCII (`solid ... facet ... outer loop / vertex x y z ×3 / endloop ... endfacet ... endsolid`).
/// Vertices are not shared (3 per triangle); [`build_mesh`] merges duplicates.
pub fn parse_stl(bytes: &[u8], source: &str) -> Result<MeshData> {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        if n.checked_mul(50).and_then(|b| b.checked_add(84)) == Some(bytes.len()) {
            return parse_stl_binary(bytes, n, source);
        }
    }
    let text = std::str::from_utf8(bytes).map_err(|_| {
        mesh_err(
            source,
            "neither binary STL (size does not match the triangle count) nor ASCII STL",
        )
    })?;
    if !text.trim_start().starts_with("solid") {
        return Err(mesh_err(
            source,
            "neither binary STL (size does not match the triangle count) nor ASCII STL (no 'solid')",
        ));
    }
    parse_stl_ascii(text, source)
}

fn parse_stl_binary(bytes: &[u8], n: usize, source: &str) -> Result<MeshData> {
    if n == 0 {
        return Err(mesh_err(source, "binary STL with 0 triangles"));
    }
    let mut vertices = Vec::with_capacity(3 * n);
    let mut triangles = Vec::with_capacity(n);
    for t in 0..n {
        let off = 84 + 50 * t;
        for k in 0..3 {
            let base = off + 12 + 12 * k;
            let mut c = [0.0; 3];
            for (j, slot) in c.iter_mut().enumerate() {
                let b = base + 4 * j;
                let v = f32::from_le_bytes([bytes[b], bytes[b + 1], bytes[b + 2], bytes[b + 3]]);
                if !v.is_finite() {
                    return Err(mesh_err(
                        source,
                        format!("triangle {t} (byte offset {off}): non-finite vertex coordinate"),
                    ));
                }
                *slot = f64::from(v);
            }
            vertices.push(Point3::new(c[0], c[1], c[2]));
        }
        let i = u32::try_from(3 * t)
            .map_err(|_| mesh_err(source, format!("triangle {t}: too many vertices")))?;
        triangles.push([i, i + 1, i + 2]);
    }
    Ok((vertices, triangles))
}

fn parse_stl_ascii(text: &str, source: &str) -> Result<MeshData> {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut in_loop: Option<(usize, usize)> = None; // (line of `outer loop`, vertices read)
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let err = |m: String| mesh_err(source, format!("line {line_no}: {m}"));
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("outer") => {
                if in_loop.is_some() {
                    return Err(err("nested 'outer loop'".into()));
                }
                in_loop = Some((line_no, 0));
            }
            Some("vertex") => {
                let Some((_, count)) = in_loop.as_mut() else {
                    return Err(err("'vertex' outside 'outer loop'".into()));
                };
                let mut c = [0.0; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let t = tokens
                        .next()
                        .ok_or_else(|| err(format!("vertex needs 3 coordinates, got {k}")))?;
                    let v: f64 = t.parse().map_err(|_| err(format!("bad number '{t}'")))?;
                    if !v.is_finite() {
                        return Err(err(format!("non-finite coordinate '{t}'")));
                    }
                    *slot = v;
                }
                vertices.push(Point3::new(c[0], c[1], c[2]));
                *count += 1;
            }
            Some("endloop") => {
                let Some((start, count)) = in_loop.take() else {
                    return Err(err("'endloop' without 'outer loop'".into()));
                };
                if count != 3 {
                    return Err(err(format!(
                        "facet starting line {start} has {count} vertices, expected 3"
                    )));
                }
                let i = u32::try_from(vertices.len() - 3)
                    .map_err(|_| err("too many vertices".into()))?;
                triangles.push([i, i + 1, i + 2]);
            }
            _ => {}
        }
    }
    if let Some((start, _)) = in_loop {
        return Err(mesh_err(
            source,
            format!("line {start}: 'outer loop' never closed"),
        ));
    }
    if triangles.is_empty() {
        return Err(mesh_err(source, "no facets"));
    }
    Ok((vertices, triangles))
}

/// Build a parry mesh: check the data (finite vertices, indices in range, at least one triangle), merge
/// duplicate vertices and drop index-degenerate triangles. When the result is closed and consistently
/// oriented ([`is_closed`]) with a non-zero volume, it is oriented outward (triangles flipped if the
/// signed volume is negative) and built with `TriMeshFlags::ORIENTED`, so that distance queries are
/// signed (inside < 0); otherwise it is an open surface and distances are unsigned.
pub fn build_mesh(
    vertices: Vec<Point3<f64>>,
    triangles: Vec<[u32; 3]>,
    source: &str,
) -> Result<TriMesh> {
    if triangles.is_empty() {
        return Err(mesh_err(source, "no triangles"));
    }
    if u32::try_from(vertices.len()).is_err() {
        return Err(mesh_err(source, "too many vertices"));
    }
    if let Some(i) = vertices
        .iter()
        .position(|v| !v.coords.iter().all(|c| c.is_finite()))
    {
        return Err(mesh_err(source, format!("vertex {i} is not finite")));
    }
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= vertices.len()) {
            return Err(mesh_err(
                source,
                format!(
                    "triangle {t}: vertex index {i} out of range ({} vertices)",
                    vertices.len()
                ),
            ));
        }
    }
    let flags = TriMeshFlags::MERGE_DUPLICATE_VERTICES | TriMeshFlags::DELETE_DEGENERATE_TRIANGLES;
    let merged = TriMesh::with_flags(vertices, triangles, flags)
        .map_err(|e| mesh_err(source, format!("invalid mesh: {e:?}")))?;
    if merged.indices().is_empty() {
        return Err(mesh_err(source, "every triangle is degenerate"));
    }
    if !is_closed(merged.indices()) {
        return Ok(merged);
    }
    let vertices = merged.vertices().to_vec();
    let mut indices = merged.indices().to_vec();
    let volume = signed_volume(&vertices, &indices);
    let extent = merged.local_aabb().extents().max();
    if volume.abs() <= 1e-12 * extent.powi(3) {
        return Ok(merged);
    }
    if volume < 0.0 {
        for t in &mut indices {
            t.swap(1, 2);
        }
    }
    TriMesh::with_flags(vertices, indices, TriMeshFlags::ORIENTED)
        .map_err(|e| mesh_err(source, format!("invalid mesh: {e:?}")))
}

/// Whether the triangles form closed, consistently oriented surfaces: every directed edge `(a, b)`
/// occurs exactly once and its reverse `(b, a)` exactly once.
pub fn is_closed(triangles: &[[u32; 3]]) -> bool {
    let mut count: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
    for t in triangles {
        for k in 0..3 {
            *count.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    count
        .iter()
        .all(|(&(a, b), &c)| c == 1 && count.get(&(b, a)) == Some(&1))
}

/// Signed volume (divergence theorem): positive when the triangles are counter-clockwise seen from outside.
pub fn signed_volume(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .filter_map(|t| {
            let a = vertices.get(t[0] as usize)?.coords;
            let b = vertices.get(t[1] as usize)?.coords;
            let c = vertices.get(t[2] as usize)?.coords;
            Some(a.dot(&b.cross(&c)))
        })
        .sum::<f64>()
        / 6.0
}
