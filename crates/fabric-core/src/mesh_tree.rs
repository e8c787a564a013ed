//! Exact distance between two triangle meshes by a simultaneous descent of two static box trees, with a
//! cutoff.
//!
//! parry's mesh-mesh distance walks the first mesh's tree against the *whole* second mesh's box and
//! runs a full query into the second mesh for every triangle in that box: between detailed meshes
//! that are near each other (a gripper next to a wrist, 40,000 triangles each) one query takes a
//! tenth of a second. [`MeshTree::distance`] descends both trees together instead (the bounding
//! volume test tree of collision libraries): a pair of nodes is split only while the gap between
//! their boxes is below both the smallest triangle distance found so far and the caller's cutoff, so
//! a query that only needs to know "farther than `cutoff`" visits the few node pairs within it.
//!
//! Frames: each tree holds its mesh's triangles in the mesh frame; a query takes both meshes' world
//! poses. Distances in metres between the triangle *surfaces* (0 when two triangles intersect), the
//! same quantity as `parry3d_f64::query::distance` between the two `TriMesh`es.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::{TriMesh, Triangle};

/// Slack (m) on box gaps before they prune a node pair: a gap and a triangle distance at the same
/// closest points differ by round-off.
const GAP_SLACK: f64 = 1e-9;

/// Triangles per leaf: small leaves prune better, large ones make shallower trees.
const LEAF_TRIANGLES: usize = 4;

/// A node of a [`MeshTree`]: an axis-aligned box (mesh frame) and either two children or a run of
/// triangles.
#[derive(Clone, Copy, Debug)]
struct Node {
    center: Vector3<f64>,
    half: Vector3<f64>,
    /// Leaf: first triangle of the run; inner node: index of the right child (the left one follows
    /// the node).
    index: u32,
    /// Leaf: number of triangles (≥ 1); inner node: 0.
    count: u32,
}

/// A static box tree over the triangles of one mesh, built once per mesh. Immutable, `Send + Sync`.
#[derive(Clone, Debug)]
pub struct MeshTree {
    nodes: Vec<Node>,
    /// The mesh's triangles (mesh frame, m), in the order of the leaves.
    triangles: Vec<Triangle>,
}

/// Scratch of [`MeshTree::distance`]: the stack of node pairs still to visit, reused across queries.
pub type MeshTreeStack = Vec<(u32, u32, f64)>;

/// Box of a set of points: (centre, half extents).
fn bounds<'a>(points: impl Iterator<Item = &'a Point3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in points {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    ((lo + hi) / 2.0, (hi - lo) / 2.0)
}

impl MeshTree {
    /// Build the tree of `mesh`: nodes split at the median triangle centroid along the longest axis of
    /// the centroids' box, down to [`LEAF_TRIANGLES`] triangles per leaf. `None` for a mesh without
    /// triangles.
    pub fn new(mesh: &TriMesh) -> Option<MeshTree> {
        let mut items: Vec<(Point3<f64>, Triangle)> = (0..mesh.num_triangles() as u32)
            .map(|i| {
                let t = mesh.triangle(i);
                (t.center(), t)
            })
            .collect();
        if items.is_empty() {
            return None;
        }
        let mut tree = MeshTree {
            nodes: Vec::with_capacity(2 * items.len() / LEAF_TRIANGLES + 1),
            triangles: Vec::with_capacity(items.len()),
        };
        tree.build(&mut items);
        Some(tree)
    }

    /// Append the subtree of `items` (depth first, left child right after its parent).
    fn build(&mut self, items: &mut [(Point3<f64>, Triangle)]) {
        let (center, half) = bounds(items.iter().flat_map(|(_, t)| [&t.a, &t.b, &t.c]));
        let at = self.nodes.len();
        self.nodes.push(Node {
            center,
            half,
            index: self.triangles.len() as u32,
            count: items.len() as u32,
        });
        if items.len() <= LEAF_TRIANGLES {
            self.triangles.extend(items.iter().map(|(_, t)| *t));
            return;
        }
        let (_, spread) = bounds(items.iter().map(|(c, _)| c));
        let axis = spread.imax();
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |a, b| a.0[axis].total_cmp(&b.0[axis]));
        let (left, right) = items.split_at_mut(mid);
        self.build(left);
        self.nodes[at].index = self.nodes.len() as u32;
        self.nodes[at].count = 0;
        self.build(right);
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Distance (m) between the surfaces of the meshes of `self` at world pose `pose` and of `other`
    /// at `other_pose`, exact when it is at most `cutoff` (m; `f64::INFINITY` always measures), and
    /// `f64::INFINITY` otherwise; 0 when the surfaces touch or cross. `stack` is scratch (cleared).
    pub fn distance(
        &self,
        pose: &Isometry3<f64>,
        other: &MeshTree,
        other_pose: &Isometry3<f64>,
        cutoff: f64,
        stack: &mut MeshTreeStack,
    ) -> f64 {
        // Everything in this mesh's frame: `rel` places the other mesh's frame in it.
        let rel = pose.inv_mul(other_pose);
        let abs_rot: Matrix3<f64> = rel.rotation.to_rotation_matrix().matrix().abs();
        let gap = |a: &Node, b: &Node| {
            let center = rel * Point3::from(b.center);
            let half = abs_rot * b.half;
            let d = ((center.coords - a.center).abs() - a.half - half).sup(&Vector3::zeros());
            d.norm()
        };
        let mut best = cutoff;
        let mut found = false;
        stack.clear();
        stack.push((0, 0, gap(&self.nodes[0], &other.nodes[0])));
        while let Some((i, j, bound)) = stack.pop() {
            if bound - GAP_SLACK > best {
                continue;
            }
            let (a, b) = (&self.nodes[i as usize], &other.nodes[j as usize]);
            if a.count > 0 && b.count > 0 {
                if let Some(d) = self.leaf_distance(a, other, b, &rel, best) {
                    (best, found) = (d, true);
                    if d <= 0.0 {
                        return 0.0;
                    }
                }
                continue;
            }
            // Split the node that is not a leaf, or the larger one.
            let split_a =
                b.count > 0 || (a.count == 0 && a.half.norm_squared() >= b.half.norm_squared());
            let children = if split_a {
                let (l, r) = (i + 1, a.index);
                [
                    (l, j, gap(&self.nodes[l as usize], b)),
                    (r, j, gap(&self.nodes[r as usize], b)),
                ]
            } else {
                let (l, r) = (j + 1, b.index);
                [
                    (i, l, gap(a, &other.nodes[l as usize])),
                    (i, r, gap(a, &other.nodes[r as usize])),
                ]
            };
            // The nearer pair is visited first (pushed last).
            let [near, far] = if children[0].2 <= children[1].2 {
                children
            } else {
                [children[1], children[0]]
            };
            for c in [far, near] {
                if c.2 - GAP_SLACK <= best {
                    stack.push(c);
                }
            }
        }
        if found {
            best
        } else {
            f64::INFINITY
        }
    }

    /// The triangles of leaf `n`.
    fn leaf(&self, n: &Node) -> &[Triangle] {
        let start = n.index as usize;
        &self.triangles[start..start + n.count as usize]
    }

    /// Smallest triangle distance between two leaves (`rel` places `other`'s frame in this one's)
    /// when it is at most `limit`.
    fn leaf_distance(
        &self,
        a: &Node,
        other: &MeshTree,
        b: &Node,
        rel: &Isometry3<f64>,
        limit: f64,
    ) -> Option<f64> {
        let (ta, tb) = (self.leaf(a), other.leaf(b));
        let identity = Isometry3::identity();
        let mut best: Option<f64> = None;
        for t in ta {
            for u in tb {
                if let Ok(d) = query::distance(&identity, t, rel, u) {
                    let d = d.max(0.0);
                    if d <= best.unwrap_or(limit) {
                        best = Some(d);
                    }
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use parry3d_f64::shape::TriMesh;

    /// A closed bumpy sphere of radius about `r` (m): a UV sphere whose radius varies with the angles,
    /// so that it is not convex.
    fn bumpy_sphere(r: f64, rings: u32, sectors: u32) -> TriMesh {
        let mut vertices = vec![Point3::new(0.0, 0.0, r), Point3::new(0.0, 0.0, -r)];
        for i in 1..rings {
            let theta = std::f64::consts::PI * i as f64 / rings as f64;
            for j in 0..sectors {
                let phi = 2.0 * std::f64::consts::PI * j as f64 / sectors as f64;
                let rr = r * (1.0 + 0.25 * (3.0 * phi).sin() * (2.0 * theta).sin());
                vertices.push(Point3::new(
                    rr * theta.sin() * phi.cos(),
                    rr * theta.sin() * phi.sin(),
                    rr * theta.cos(),
                ));
            }
        }
        let at = |i: u32, j: u32| 2 + (i - 1) * sectors + (j % sectors);
        let mut indices = Vec::new();
        for j in 0..sectors {
            indices.push([0, at(1, j), at(1, j + 1)]);
            indices.push([1, at(rings - 1, j + 1), at(rings - 1, j)]);
        }
        for i in 1..rings - 1 {
            for j in 0..sectors {
                indices.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                indices.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        TriMesh::new(vertices, indices).unwrap()
    }

    fn pose(t: [f64; 3], axis_angle: [f64; 3]) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_scaled_axis(Vector3::from(axis_angle)),
        )
    }

    /// Against parry's own mesh-mesh distance on poses from far apart to interpenetrating.
    #[test]
    fn equals_parry_mesh_distance() {
        let (m1, m2) = (bumpy_sphere(0.1, 12, 16), bumpy_sphere(0.07, 9, 13));
        let (t1, t2) = (MeshTree::new(&m1).unwrap(), MeshTree::new(&m2).unwrap());
        assert_eq!(t1.num_triangles(), m1.num_triangles());
        let mut stack = MeshTreeStack::new();
        let mut touching = 0;
        for k in 0..60 {
            let s = k as f64;
            let p1 = pose([0.01 * s.sin(), 0.0, 0.02], [0.3 * s, 0.1, -0.2 * s.cos()]);
            let p2 = pose(
                [0.12 + 0.2 * (0.37 * s).cos(), 0.05 * s.sin(), 0.0],
                [0.5, -0.7 * s.sin(), 0.2 * s],
            );
            let want = query::distance(&p1, &m1, &p2, &m2).unwrap().max(0.0);
            let got = t1.distance(&p1, &t2, &p2, f64::INFINITY, &mut stack);
            assert!(
                (got - want).abs() <= 1e-9,
                "pose {k}: tree {got} vs parry {want}"
            );
            // The other way round, and with a cutoff above and below the distance.
            let back = t2.distance(&p2, &t1, &p1, f64::INFINITY, &mut stack);
            assert!(
                (back - want).abs() <= 1e-9,
                "pose {k} swapped: {back} vs {want}"
            );
            let at = t1.distance(&p1, &t2, &p2, got, &mut stack);
            assert_eq!(at, got, "pose {k}: cutoff at the distance");
            let above = t1.distance(&p1, &t2, &p2, want + 1e-3, &mut stack);
            assert!((above - want).abs() <= 1e-9);
            if want > 1e-3 {
                let below = t1.distance(&p1, &t2, &p2, want - 1e-3, &mut stack);
                assert_eq!(below, f64::INFINITY);
            }
            if want == 0.0 {
                touching += 1;
            }
        }
        assert!(touching > 3 && touching < 57, "{touching} touching poses");
    }

    /// Two unit-spaced parallel triangles: the distance is the closed-form gap.
    #[test]
    fn parallel_triangles_closed_form() {
        let tri = |z: f64| {
            TriMesh::new(
                vec![
                    Point3::new(0.0, 0.0, z),
                    Point3::new(1.0, 0.0, z),
                    Point3::new(0.0, 1.0, z),
                ],
                vec![[0, 1, 2]],
            )
            .unwrap()
        };
        let (a, b) = (tri(0.0), tri(0.0));
        let (ta, tb) = (MeshTree::new(&a).unwrap(), MeshTree::new(&b).unwrap());
        let mut stack = MeshTreeStack::new();
        let up = pose([0.2, 0.1, 0.35], [0.0, 0.0, 0.0]);
        let d = ta.distance(&Isometry3::identity(), &tb, &up, f64::INFINITY, &mut stack);
        assert!((d - 0.35).abs() < 1e-12, "{d}");
        assert_eq!(
            ta.distance(&Isometry3::identity(), &tb, &up, 0.3, &mut stack),
            f64::INFINITY
        );
    }
}
