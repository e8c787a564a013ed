//! A COLLADA (`.dae`) triangle reader for collision meshes, as robot descriptions ship them (Kinova, Tiago,
//! Baxter's, most meshes exported from Blender).
//!
//! Read: every `<geometry>`'s `<mesh>` with its `<triangles>`, `<polylist>` and `<polygons>` (polygons
//! fan-triangulated; `<lines>` and other primitives ignored), placed by the `<node>` hierarchy of the scene's
//! visual scene (`<matrix>`, `<translate>`, `<rotate>` in degrees, `<scale>`, composed in document order;
//! `<instance_geometry>` and `<instance_node>` followed). A file without a visual scene yields every
//! geometry untransformed.
//!
//! Not applied: `<asset><unit>` and `<up_axis>`. MoveIt's mesh loader resets the root transform in which
//! its importer places both, and trimesh (which the validators in `tools/` use) ignores them too, so the
//! coordinates below the scene root are the mesh as every checker of the same URDF sees it.

use std::collections::HashMap;

use nalgebra::{Matrix4, Point3, Rotation3, Unit, Vector3};
use roxmltree::{Document, Node};

use super::meshio::MeshData;
use crate::error::{FabricError, Result};

/// Deepest `<node>` / `<instance_node>` nesting followed (a cycle of instance_nodes is an error).
const MAX_DEPTH: usize = 64;

fn err(source: &str, message: impl Into<String>) -> FabricError {
    FabricError::Mesh {
        path: source.to_string(),
        message: message.into(),
    }
}

/// Parse COLLADA text into vertices and triangles (see the module docs). `source` names the file in errors.
pub fn parse_dae(text: &str, source: &str) -> Result<MeshData> {
    let doc = Document::parse(text).map_err(|e| err(source, format!("not COLLADA XML: {e}")))?;
    let ids: HashMap<&str, Node> = doc
        .descendants()
        .filter_map(|n| n.attribute("id").map(|id| (id, n)))
        .collect();
    let mut geometries: HashMap<&str, MeshData> = HashMap::new();
    for g in doc.descendants().filter(|n| n.has_tag_name("geometry")) {
        if let (Some(id), Some(mesh)) = (g.attribute("id"), child(g, "mesh")) {
            geometries.insert(id, read_mesh(mesh, &ids, source)?);
        }
    }
    let mut out: MeshData = (Vec::new(), Vec::new());
    match visual_scene(&doc, &ids) {
        Some(scene) => {
            for node in scene.children().filter(|n| n.has_tag_name("node")) {
                place_node(
                    node,
                    &Matrix4::identity(),
                    &ids,
                    &geometries,
                    0,
                    source,
                    &mut out,
                )?;
            }
        }
        None => {
            let mut all: Vec<_> = geometries.iter().collect();
            all.sort_by_key(|(id, _)| *id);
            for (_, mesh) in all {
                append(mesh, &Matrix4::identity(), source, &mut out)?;
            }
        }
    }
    if out.1.is_empty() {
        return Err(err(
            source,
            "no triangles (no <triangles>, <polylist> or <polygons> in a placed geometry)",
        ));
    }
    Ok(out)
}

fn child<'a, 'i>(node: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|n| n.has_tag_name(tag))
}

/// The element a `#id` URL names.
fn target<'a, 'i>(url: Option<&str>, ids: &HashMap<&str, Node<'a, 'i>>) -> Option<Node<'a, 'i>> {
    url.and_then(|u| u.strip_prefix('#'))
        .and_then(|id| ids.get(id).copied())
}

fn numbers<T: std::str::FromStr>(node: Node, what: &str, source: &str) -> Result<Vec<T>> {
    node.text()
        .unwrap_or("")
        .split_whitespace()
        .map(|t| {
            t.parse()
                .map_err(|_| err(source, format!("<{what}>: bad number '{t}'")))
        })
        .collect()
}

/// The scene's `<instance_visual_scene>` target, else the first `<visual_scene>`.
fn visual_scene<'a, 'i>(
    doc: &'a Document<'i>,
    ids: &HashMap<&str, Node<'a, 'i>>,
) -> Option<Node<'a, 'i>> {
    doc.descendants()
        .find(|n| n.has_tag_name("instance_visual_scene"))
        .and_then(|n| target(n.attribute("url"), ids))
        .or_else(|| doc.descendants().find(|n| n.has_tag_name("visual_scene")))
}

/// The positions (x, y, z per vertex) of the `<source>` a `<vertices>` (or a source itself) names.
fn positions(node: Node, ids: &HashMap<&str, Node>, source: &str) -> Result<Vec<Point3<f64>>> {
    let src = if node.has_tag_name("vertices") {
        let input = node
            .children()
            .find(|n| n.has_tag_name("input") && n.attribute("semantic") == Some("POSITION"))
            .ok_or_else(|| err(source, "<vertices> without a POSITION input"))?;
        target(input.attribute("source"), ids)
            .ok_or_else(|| err(source, "POSITION input names no <source>"))?
    } else {
        node
    };
    let array = src
        .descendants()
        .find(|n| n.has_tag_name("float_array"))
        .ok_or_else(|| err(source, "position <source> without a <float_array>"))?;
    let values: Vec<f64> = numbers(array, "float_array", source)?;
    let stride = src
        .descendants()
        .find(|n| n.has_tag_name("accessor"))
        .and_then(|a| a.attribute("stride"))
        .and_then(|s| s.parse::<usize>().ok())
        .unwrap_or(3);
    if stride < 3 {
        return Err(err(
            source,
            format!("position accessor stride {stride} < 3"),
        ));
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(err(source, "non-finite vertex coordinate"));
    }
    Ok(values
        .chunks_exact(stride)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect())
}

/// One `<mesh>`: its vertices and the triangles of its polygon primitives.
fn read_mesh(mesh: Node, ids: &HashMap<&str, Node>, source: &str) -> Result<MeshData> {
    let mut vertices: Vec<Point3<f64>> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut offsets: HashMap<String, u32> = HashMap::new(); // position source id -> first vertex index
    for prim in mesh.children().filter(|n| {
        n.has_tag_name("triangles") || n.has_tag_name("polylist") || n.has_tag_name("polygons")
    }) {
        let inputs: Vec<Node> = prim
            .children()
            .filter(|n| n.has_tag_name("input"))
            .collect();
        let stride = 1 + inputs
            .iter()
            .filter_map(|i| i.attribute("offset").and_then(|o| o.parse::<usize>().ok()))
            .max()
            .unwrap_or(0);
        let Some(vertex) = inputs
            .iter()
            .find(|i| i.attribute("semantic") == Some("VERTEX"))
        else {
            continue; // a primitive without positions draws nothing
        };
        let offset: usize = vertex
            .attribute("offset")
            .and_then(|o| o.parse().ok())
            .unwrap_or(0);
        let key = vertex.attribute("source").unwrap_or("").to_string();
        let base = match offsets.get(&key) {
            Some(&b) => b,
            None => {
                let node = target(Some(&key), ids)
                    .ok_or_else(|| err(source, format!("VERTEX input names no element '{key}'")))?;
                let b =
                    u32::try_from(vertices.len()).map_err(|_| err(source, "too many vertices"))?;
                vertices.extend(positions(node, ids, source)?);
                offsets.insert(key, b);
                b
            }
        };
        let count =
            u32::try_from(vertices.len()).map_err(|_| err(source, "too many vertices"))? - base;
        let corner = |p: &[u32], k: usize| -> Result<u32> {
            let i = *p
                .get(k * stride + offset)
                .ok_or_else(|| err(source, "<p> ends inside a vertex"))?;
            if i >= count {
                return Err(err(
                    source,
                    format!("vertex index {i} out of range ({count} vertices)"),
                ));
            }
            Ok(base + i)
        };
        // polygons as (first corner, corner count) runs over one index list, fan-triangulated
        let mut fan = |p: &[u32], first: usize, n: usize| -> Result<()> {
            for k in 1..n.saturating_sub(1) {
                triangles.push([
                    corner(p, first)?,
                    corner(p, first + k)?,
                    corner(p, first + k + 1)?,
                ]);
            }
            Ok(())
        };
        if prim.has_tag_name("polygons") {
            for p in prim.children().filter(|n| n.has_tag_name("p")) {
                let p: Vec<u32> = numbers(p, "p", source)?;
                fan(&p, 0, p.len() / stride)?;
            }
            continue;
        }
        let p: Vec<u32> = match child(prim, "p") {
            Some(p) => numbers(p, "p", source)?,
            None => continue,
        };
        if prim.has_tag_name("triangles") {
            for t in 0..p.len() / (3 * stride) {
                fan(&p, 3 * t, 3)?;
            }
        } else {
            let counts: Vec<usize> = child(prim, "vcount")
                .map(|v| numbers(v, "vcount", source))
                .transpose()?
                .unwrap_or_default();
            let mut first = 0;
            for n in counts {
                fan(&p, first, n)?;
                first += n;
            }
        }
    }
    Ok((vertices, triangles))
}

/// The transform of a `<node>`'s own transformation elements, composed in document order.
fn node_transform(node: Node, source: &str) -> Result<Matrix4<f64>> {
    let mut m = Matrix4::identity();
    for t in node.children().filter(|n| n.is_element()) {
        let tag = t.tag_name().name();
        let v: Vec<f64> = match tag {
            "matrix" | "translate" | "rotate" | "scale" => numbers(t, tag, source)?,
            _ => continue,
        };
        let need = match tag {
            "matrix" => 16,
            "rotate" => 4,
            _ => 3,
        };
        if v.len() != need || v.iter().any(|x| !x.is_finite()) {
            return Err(err(
                source,
                format!("<{tag}> needs {need} finite numbers, got {}", v.len()),
            ));
        }
        let step = match tag {
            "matrix" => Matrix4::from_row_slice(&v),
            "translate" => Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2])),
            "scale" => Matrix4::new_nonuniform_scaling(&Vector3::new(v[0], v[1], v[2])),
            _ => {
                let axis = Vector3::new(v[0], v[1], v[2]);
                match Unit::try_new(axis, 1e-12) {
                    Some(axis) => {
                        Rotation3::from_axis_angle(&axis, v[3].to_radians()).to_homogeneous()
                    }
                    None => Matrix4::identity(),
                }
            }
        };
        m *= step;
    }
    Ok(m)
}

fn place_node(
    node: Node,
    parent: &Matrix4<f64>,
    ids: &HashMap<&str, Node>,
    geometries: &HashMap<&str, MeshData>,
    depth: usize,
    source: &str,
    out: &mut MeshData,
) -> Result<()> {
    if depth > MAX_DEPTH {
        return Err(err(
            source,
            format!("<node> nesting deeper than {MAX_DEPTH} (an <instance_node> cycle?)"),
        ));
    }
    let m = parent * node_transform(node, source)?;
    for c in node.children().filter(|n| n.is_element()) {
        match c.tag_name().name() {
            "instance_geometry" => {
                let id = c
                    .attribute("url")
                    .and_then(|u| u.strip_prefix('#'))
                    .unwrap_or("");
                let mesh = geometries.get(id).ok_or_else(|| {
                    err(
                        source,
                        format!("<instance_geometry> names no geometry '{id}'"),
                    )
                })?;
                append(mesh, &m, source, out)?;
            }
            "instance_node" => {
                let n = target(c.attribute("url"), ids)
                    .ok_or_else(|| err(source, "<instance_node> names no node"))?;
                place_node(n, &m, ids, geometries, depth + 1, source, out)?;
            }
            "node" => place_node(c, &m, ids, geometries, depth + 1, source, out)?,
            _ => {}
        }
    }
    Ok(())
}

fn append(mesh: &MeshData, m: &Matrix4<f64>, source: &str, out: &mut MeshData) -> Result<()> {
    let base = u32::try_from(out.0.len()).map_err(|_| err(source, "too many vertices"))?;
    out.0.extend(mesh.0.iter().map(|p| m.transform_point(p)));
    out.1.extend(
        mesh.1
            .iter()
            .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube [0, 1]³ as 8 positions; `body` holds the primitives, `scene` the visual scene.
    fn dae(body: &str, scene: &str) -> String {
        format!(
            r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="0.001"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries><geometry id="cube"><mesh>
    <source id="pos"><float_array id="pos-array" count="24">0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1</float_array>
      <technique_common><accessor source="#pos-array" count="8" stride="3"/></technique_common></source>
    <source id="nrm"><float_array id="nrm-array" count="3">0 0 1</float_array></source>
    <vertices id="verts"><input semantic="POSITION" source="#pos"/></vertices>
    {body}
  </mesh></geometry></library_geometries>
  <library_nodes><node id="shared"><translate>0 0 5</translate><instance_geometry url="#cube"/></node></library_nodes>
  {scene}
</COLLADA>"##
        )
    }

    const TRIANGLES: &str = r##"<triangles count="12"><input semantic="VERTEX" source="#verts" offset="0"/>
      <input semantic="NORMAL" source="#nrm" offset="1"/>
      <p>0 0 2 0 1 0  0 0 3 0 2 0  4 0 5 0 6 0  4 0 6 0 7 0  0 0 1 0 5 0  0 0 5 0 4 0
         1 0 2 0 6 0  1 0 6 0 5 0  2 0 3 0 7 0  2 0 7 0 6 0  3 0 0 0 4 0  3 0 4 0 7 0</p></triangles>"##;

    #[test]
    fn triangles_with_interleaved_inputs_and_no_scene_are_read_untransformed() {
        let (v, t) = parse_dae(&dae(TRIANGLES, ""), "cube.dae").unwrap();
        assert_eq!(v.len(), 8);
        assert_eq!(t.len(), 12);
        assert_eq!(t[0], [0, 2, 1]);
        // units and up axis are not applied (the coordinates below the root, as MoveIt and trimesh read them)
        assert!(v
            .iter()
            .all(|p| p.coords.iter().all(|&c| c == 0.0 || c == 1.0)));
    }

    #[test]
    fn polylists_and_polygons_are_fan_triangulated() {
        let poly = r##"<polylist count="2"><input semantic="VERTEX" source="#verts" offset="0"/>
          <vcount>4 3</vcount><p>0 1 2 3 4 5 6</p></polylist>
          <polygons count="1"><input semantic="VERTEX" source="#verts" offset="0"/><p>4 5 6 7</p></polygons>"##;
        let (_, t) = parse_dae(&dae(poly, ""), "poly.dae").unwrap();
        assert_eq!(
            t,
            vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 5, 6], [4, 6, 7]]
        );
    }

    #[test]
    fn nodes_place_geometry_with_their_transforms_in_document_order() {
        let scene = r##"<library_visual_scenes><visual_scene id="s">
          <node><matrix>1 0 0 10 0 1 0 0 0 0 1 0 0 0 0 1</matrix>
            <node><rotate>0 0 1 90</rotate><scale>2 2 2</scale><instance_geometry url="#cube"/></node>
            <instance_node url="#shared"/></node>
          </visual_scene></library_visual_scenes><scene><instance_visual_scene url="#s"/></scene>"##;
        let (v, t) = parse_dae(&dae(TRIANGLES, scene), "placed.dae").unwrap();
        assert_eq!((v.len(), t.len()), (16, 24));
        // first instance: scale 2, then rotate 90° about z, then translate x by 10: (1, 0, 0) -> (10, 2, 0)
        let p = v[1];
        assert!((p - Point3::new(10.0, 2.0, 0.0)).norm() < 1e-12, "{p}");
        // the library node: translate z by 5 under the x offset: (1, 1, 1) -> (11, 1, 6)
        assert!((v[8 + 6] - Point3::new(11.0, 1.0, 6.0)).norm() < 1e-12);
        assert_eq!(t[12], [8, 10, 9]);
    }

    #[test]
    fn bad_files_name_the_problem() {
        let msg = |text: &str| parse_dae(text, "bad.dae").unwrap_err().to_string();
        assert!(msg("<not xml").contains("not COLLADA XML"));
        assert!(msg(&dae("", "")).contains("no triangles"));
        let out_of_range = TRIANGLES.replace("0 0 2 0 1 0", "0 0 9 0 1 0");
        assert!(msg(&dae(&out_of_range, "")).contains("vertex index 9 out of range (8 vertices)"));
        assert!(msg(&dae(&TRIANGLES.replace("0 0 2 0", "0 0 x 0"), "")).contains("bad number 'x'"));
        let cycle = r##"<library_visual_scenes><visual_scene id="s"><node id="a"><instance_node url="#a"/></node>
          </visual_scene></library_visual_scenes>"##;
        assert!(msg(&dae(TRIANGLES, cycle)).contains("nesting deeper"));
    }
}
