//! The URDF joint graph: validation (names, parents, one root, no cycle, supported joint types), the
//! tree re-rooted at the base link (joints above the base are reversed), and the default end-effector.

use std::collections::HashMap;

use urdf_rs::JointType;

use crate::error::{FabricError, Result};

/// A `FabricError::Urdf` for the URDF named `source`.
pub(super) fn urdf_err(source: &str, message: impl Into<String>) -> FabricError {
    FabricError::Urdf {
        file: source.to_string(),
        message: message.into(),
    }
}

/// Revolute, continuous or prismatic (mimic joints included).
pub(super) fn is_movable(kind: &JointType) -> bool {
    matches!(
        kind,
        JointType::Revolute | JointType::Continuous | JointType::Prismatic
    )
}

/// The URDF type name of a joint of several degrees of freedom (floating, planar, spherical), `None` for
/// the others. MoveIt's default value of such a joint is the identity pose, and no gfcs planning group moves
/// it: the model holds it there, a fixed joint at its `<origin>` (a request whose start state moves it is
/// reported by `scene::MotionPlanRequest::ignored`).
pub(super) fn multi_dof_kind(kind: &JointType) -> Option<&'static str> {
    match kind {
        JointType::Floating => Some("floating"),
        JointType::Planar => Some("planar"),
        JointType::Spherical => Some("spherical"),
        _ => None,
    }
}

/// A revolute or prismatic joint whose `<limit>` (with a velocity > 0: a joint without `<limit>`, which
/// MoveIt's URDF parser refuses, is an error) gives one position (`lower == upper`, e.g. both absent, so
/// 0): MoveIt gives it a zero-width range, so no planner moves it. It is held at that position like any
/// locked joint.
pub(super) fn has_zero_range(joint: &urdf_rs::Joint) -> bool {
    matches!(joint.joint_type, JointType::Revolute | JointType::Prismatic)
        && joint.limit.velocity > 0.0
        && joint.limit.lower.is_finite()
        && joint.limit.lower == joint.limit.upper
}

/// A joint that moves: movable type and a range wider than one position ([`has_zero_range`]); mimic
/// joints included (they move with their source).
pub(super) fn moves(joint: &urdf_rs::Joint) -> bool {
    is_movable(&joint.joint_type) && !has_zero_range(joint)
}

/// A joint that moves on its own ([`moves`], not a mimic joint): what a planner can drive.
pub(super) fn moves_on_its_own(joint: &urdf_rs::Joint) -> bool {
    moves(joint) && joint.mimic.is_none()
}

/// The validated URDF graph: name lookups, parent joint of each link, child joints of each link.
pub(super) struct Graph<'a> {
    pub(super) urdf: &'a urdf_rs::Robot,
    pub(super) source: &'a str,
    pub(super) link_index: HashMap<&'a str, usize>,
    pub(super) joint_index: HashMap<&'a str, usize>,
    /// (URDF joint, parent link) of each URDF link.
    pub(super) parent: Vec<Option<(usize, usize)>>,
    /// (URDF joint, child link) of each URDF link, in document order.
    pub(super) children: Vec<Vec<(usize, usize)>>,
}

impl<'a> Graph<'a> {
    /// Validate the joint graph of `urdf` (`source` names it in errors).
    pub(super) fn new(urdf: &'a urdf_rs::Robot, source: &'a str) -> Result<Self> {
        if urdf.links.is_empty() {
            return Err(urdf_err(source, "the robot has no <link>"));
        }
        let mut link_index = HashMap::new();
        for (i, l) in urdf.links.iter().enumerate() {
            if link_index.insert(l.name.as_str(), i).is_some() {
                return Err(urdf_err(
                    source,
                    format!("duplicate link name '{}'", l.name),
                ));
            }
        }
        let mut joint_index = HashMap::new();
        let mut parent = vec![None; urdf.links.len()];
        let mut children = vec![Vec::new(); urdf.links.len()];
        for (j, joint) in urdf.joints.iter().enumerate() {
            if joint_index.insert(joint.name.as_str(), j).is_some() {
                return Err(urdf_err(
                    source,
                    format!("duplicate joint name '{}'", joint.name),
                ));
            }
            let find = |name: &str| {
                link_index.get(name).copied().ok_or_else(|| {
                    urdf_err(
                        source,
                        format!("joint '{}' names unknown link '{name}'", joint.name),
                    )
                })
            };
            let (p, c) = (find(&joint.parent.link)?, find(&joint.child.link)?);
            if p == c {
                return Err(urdf_err(
                    source,
                    format!(
                        "joint '{}' connects link '{}' to itself",
                        joint.name, joint.parent.link
                    ),
                ));
            }
            if parent[c].is_some() {
                return Err(urdf_err(
                    source,
                    format!("link '{}' is the child of several joints", joint.child.link),
                ));
            }
            parent[c] = Some((j, p));
            children[p].push((j, c));
        }
        let roots: Vec<usize> = (0..urdf.links.len())
            .filter(|&l| parent[l].is_none())
            .collect();
        if roots.len() != 1 {
            let names: Vec<&str> = roots.iter().map(|&l| urdf.links[l].name.as_str()).collect();
            return Err(urdf_err(
                source,
                format!("expected one root link, found {}: {names:?}", roots.len()),
            ));
        }
        // Every link must hang below the root; a link that does not sits on a cycle.
        let mut seen = vec![false; urdf.links.len()];
        let mut stack = vec![roots[0]];
        while let Some(l) = stack.pop() {
            seen[l] = true;
            stack.extend(children[l].iter().map(|&(_, c)| c));
        }
        if let Some(l) = seen.iter().position(|s| !s) {
            return Err(urdf_err(
                source,
                format!("link '{}' is on a joint cycle", urdf.links[l].name),
            ));
        }
        Ok(Graph {
            urdf,
            source,
            link_index,
            joint_index,
            parent,
            children,
        })
    }

    /// The root link (the only link without a parent joint).
    pub(super) fn root(&self) -> usize {
        self.parent.iter().position(Option::is_none).unwrap_or(0)
    }

    /// URDF index of the joint `name`; `MissingJoint` naming `robot` otherwise.
    pub(super) fn joint(&self, name: &str, robot: &str) -> Result<usize> {
        self.joint_index
            .get(name)
            .copied()
            .ok_or_else(|| FabricError::MissingJoint {
                robot: robot.to_string(),
                joint: name.to_string(),
            })
    }
}

/// An edge of the re-rooted tree: (URDF joint, parent tree index, reversed).
pub(super) type Edge = (usize, usize, bool);

/// The tree re-rooted at the base link, in depth-first pre-order.
pub(super) struct Rooted {
    /// URDF link index of each tree link.
    pub(super) order: Vec<usize>,
    /// For each tree link but the base: (URDF joint, parent tree index, reversed).
    pub(super) edge: Vec<Option<Edge>>,
    /// Child tree links of each tree link.
    pub(super) children: Vec<Vec<usize>>,
}

/// Depth-first traversal from `base` over the undirected joint graph: joints met from child to parent
/// are marked reversed.
pub(super) fn reroot(g: &Graph, base: usize) -> Rooted {
    let n = g.urdf.links.len();
    let mut tree_index = vec![usize::MAX; n];
    let mut rooted = Rooted {
        order: Vec::with_capacity(n),
        edge: Vec::with_capacity(n),
        children: Vec::new(),
    };
    // (URDF link, incoming edge)
    let mut stack: Vec<(usize, Option<Edge>)> = vec![(base, None)];
    while let Some((l, edge)) = stack.pop() {
        tree_index[l] = rooted.order.len();
        rooted.order.push(l);
        rooted.edge.push(edge);
        let me = tree_index[l];
        let mut next: Vec<(usize, Option<Edge>)> = Vec::new();
        if let Some((j, p)) = g.parent[l] {
            if tree_index[p] == usize::MAX {
                next.push((p, Some((j, me, true))));
            }
        }
        for &(j, c) in &g.children[l] {
            if tree_index[c] == usize::MAX {
                next.push((c, Some((j, me, false))));
            }
        }
        stack.extend(next.into_iter().rev());
    }
    rooted.children = vec![Vec::new(); rooted.order.len()];
    for (i, e) in rooted.edge.iter().enumerate() {
        if let Some((_, p, _)) = e {
            rooted.children[*p].push(i);
        }
    }
    rooted
}

/// Joints that move on their own (not mimic joints) a branch needs below a branching link for the default
/// end-effector walk to take it as an arm ([`default_ee`]): not a wheel, a pan-tilt head, a gripper.
const ARM_JOINTS: usize = 3;
/// The least length of an arm branch (the longest sum of joint-origin lengths down it) against the path
/// from the base to the branching link: a hand's fingers (a few centimetres after a metre of arm) are no
/// arm however many joints they have.
const ARM_LENGTH: f64 = 0.25;

/// Default end-effector: follow the only child, or the only child subtree holding a joint that moves
/// ([`moves`]: not one of zero range), or, where several do, the longest arm among them (at least
/// [`ARM_JOINTS`] joints that move on their own, at least [`ARM_LENGTH`] times as long as the path to the
/// branching link: a mobile manipulator's arm beside its wheels and head; the first of two equal arms);
/// with explicit active joints, start below the deepest one and follow single children on joints that do
/// not move only.
pub(super) fn default_ee(g: &Graph, t: &Rooted, active: Option<&[usize]>) -> usize {
    let n = t.order.len();
    let movable_edge = |i: usize| t.edge[i].is_some_and(|(j, _, _)| moves(&g.urdf.joints[j]));
    let mut current = 0;
    if let Some(active) = active {
        let depth = |mut i: usize| {
            let mut d = 0;
            while let Some((_, p, _)) = t.edge[i] {
                i = p;
                d += 1;
            }
            d
        };
        let deepest = (0..n)
            .filter(|&i| t.edge[i].is_some_and(|(j, _, _)| active.contains(&j)))
            .max_by_key(|&i| depth(i));
        current = deepest.unwrap_or(0);
        while let [only] = t.children[current][..] {
            if movable_edge(only) {
                break;
            }
            current = only;
        }
        return current;
    }
    // has_movable[i]: a movable joint at or below link i's parent joint; free[i]: the joints at or below it
    // that move on their own (mimic joints follow another); offset[i]: the length (m) of link i's parent
    // joint origin; reach[i]: the longest sum of joint-origin lengths from link i down its subtree, from[i]:
    // from the base to link i
    let mut has_movable = vec![false; n];
    let mut free = vec![0usize; n];
    let mut offset = vec![0.0; n];
    let mut reach = vec![0.0_f64; n];
    let mut from = vec![0.0; n];
    for i in 0..n {
        if let Some((j, p, _)) = t.edge[i] {
            let xyz = &g.urdf.joints[j].origin.xyz;
            offset[i] = (xyz[0] * xyz[0] + xyz[1] * xyz[1] + xyz[2] * xyz[2]).sqrt();
            from[i] = from[p] + offset[i];
        }
    }
    for i in (0..n).rev() {
        has_movable[i] |= movable_edge(i);
        free[i] +=
            usize::from(t.edge[i].is_some_and(|(j, _, _)| moves_on_its_own(&g.urdf.joints[j])));
        if let Some((_, p, _)) = t.edge[i] {
            has_movable[p] |= has_movable[i];
            free[p] += free[i];
            reach[p] = reach[p].max(offset[i] + reach[i]);
        }
    }
    // the length of the branch from link b's parent joint down; an arm below a branching link b: at least
    // ARM_JOINTS joints that move on their own, and as long as ARM_LENGTH times the path from the base to b
    // (a hand's fingers are short against the arm before them)
    let length = |c: usize| offset[c] + reach[c];
    let arm = |b: usize, c: usize| free[c] >= ARM_JOINTS && length(c) >= ARM_LENGTH * from[b];
    loop {
        let kids = &t.children[current];
        let next = match kids[..] {
            [] => None,
            [only] => Some(only),
            _ => match kids.iter().filter(|&&c| has_movable[c]).collect::<Vec<_>>()[..] {
                [&only] => Some(only),
                // several moving branches: the longest arm among them (the first of equals, e.g. one of
                // two arms); no arm: stop here (a hand between its fingers)
                ref moving => moving
                    .iter()
                    .map(|&&c| c)
                    .filter(|&c| arm(current, c))
                    .fold(None, |best: Option<usize>, c| match best {
                        Some(b) if length(b) >= length(c) => Some(b),
                        _ => Some(c),
                    }),
            },
        };
        match next {
            Some(c) => current = c,
            None => return current,
        }
    }
}
