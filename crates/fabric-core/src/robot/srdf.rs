//! Self-collision pairs: SRDF `<disable_collisions link1= link2=>` (parsed with roxmltree) and the
//! sphere pairs that remain after removing pairs on one rigid body, on adjacent bodies and on disabled
//! link pairs.

use super::model::Robot;
use crate::error::{FabricError, Result};

impl Robot {
    /// Disable the self-collision link pairs listed by `<disable_collisions>` elements of an SRDF,
    /// replacing any earlier SRDF, and recompute [`Robot::self_collision_pairs`]. `source` names the text
    /// in errors.
    ///
    /// An entry naming a link the robot does not have is skipped, as MoveIt skips it (with a warning):
    /// SRDFs are often written for a larger model than the URDF at hand. Returns the names of those links,
    /// sorted and without repeats, for the caller to report.
    ///
    /// Errors: `Format` naming the file and the element (malformed XML or XML past the limits of
    /// [`crate::limits`], a root other than `<robot>`, a missing `link1`/`link2` attribute); the model is
    /// then unchanged.
    pub fn set_self_collision_from_srdf(
        &mut self,
        srdf_xml: &str,
        source: &str,
    ) -> Result<Vec<String>> {
        let err = |field: String, message: String| FabricError::Format {
            file: source.to_string(),
            field,
            message,
        };
        crate::limits::check_xml(srdf_xml).map_err(|m| err("(xml)".into(), m))?;
        let doc = roxmltree::Document::parse(srdf_xml).map_err(|e| {
            let parser = e.to_string();
            match crate::limits::xml_truncation(srdf_xml) {
                Some(why) => err("(xml)".into(), format!("{why} (parser: {parser})")),
                None => err("(xml)".into(), parser),
            }
        })?;
        let root = doc.root_element();
        if root.tag_name().name() != "robot" {
            return Err(err(
                "(root)".into(),
                format!("expected <robot>, found <{}>", root.tag_name().name()),
            ));
        }
        let mut disabled = Vec::new();
        let mut skipped = Vec::new();
        for (k, node) in root
            .children()
            .filter(|n| n.has_tag_name("disable_collisions"))
            .enumerate()
        {
            let line = doc.text_pos_at(node.range().start).row;
            let link = |attr: &str| -> Result<std::result::Result<usize, String>> {
                let field = format!("disable_collisions[{k}] (line {line}).{attr}");
                let name = node
                    .attribute(attr)
                    .ok_or_else(|| err(field, "missing attribute".into()))?;
                Ok(self.link_index(name).map_err(|_| name.to_string()))
            };
            match (link("link1")?, link("link2")?) {
                (Ok(a), Ok(b)) => disabled.push((a.min(b), a.max(b))),
                (a, b) => skipped.extend([a.err(), b.err()].into_iter().flatten()),
            }
        }
        skipped.sort_unstable();
        skipped.dedup();
        self.set_disabled(disabled);
        self.srdf = true;
        Ok(skipped)
    }

    /// Disable the self-collision checks between the named link pairs, in addition to those already
    /// disabled (an SRDF's `<disable_collisions>`), and recompute the sphere pairs.
    ///
    /// Errors: `Link` for an unknown link name; the model is then unchanged.
    pub fn disable_link_pairs(&mut self, pairs: &[(String, String)]) -> Result<()> {
        let mut disabled = self.disabled.clone();
        for (a, b) in pairs {
            let (a, b) = (self.link_index(a)?, self.link_index(b)?);
            disabled.push((a.min(b), a.max(b)));
        }
        self.set_disabled(disabled);
        Ok(())
    }

    /// The disabled link pairs (i < j), sorted without repeats, and the sphere pairs they leave.
    fn set_disabled(&mut self, mut disabled: Vec<(usize, usize)>) {
        disabled.sort_unstable();
        disabled.dedup();
        self.disabled = disabled;
        self.recompute_self_pairs();
    }

    /// Recompute the self-collision sphere pairs from the spheres, the rigid bodies, the adjacency of
    /// bodies (one movable joint between them) and the disabled link pairs.
    pub(crate) fn recompute_self_pairs(&mut self) {
        let n = self.link_names.len();
        // excluded[a * n + b]: spheres on links a and b are never checked against each other.
        let mut excluded = vec![false; n * n];
        let mut exclude = |a: usize, b: usize| {
            excluded[a * n + b] = true;
            excluded[b * n + a] = true;
        };
        for a in 0..n {
            for b in a..n {
                if self.bodies[a] == self.bodies[b] {
                    exclude(a, b);
                }
            }
        }
        // Adjacent bodies: a driven joint joins the parent's body to the child's body.
        for (child, joint) in self.joints.iter().enumerate() {
            let Some(j) = joint else { continue };
            if self.bodies[child] == self.bodies[j.parent] {
                continue;
            }
            let (pb, cb) = (self.bodies[j.parent], self.bodies[child]);
            for a in (0..n).filter(|&a| self.bodies[a] == pb) {
                for b in (0..n).filter(|&b| self.bodies[b] == cb) {
                    exclude(a, b);
                }
            }
        }
        for &(a, b) in &self.disabled {
            exclude(a, b);
        }
        let mut pairs = Vec::new();
        for (i, si) in self.spheres.iter().enumerate() {
            for (j, sj) in self.spheres.iter().enumerate().skip(i + 1) {
                if !excluded[si.link * n + sj.link] {
                    pairs.push((i, j));
                }
            }
        }
        self.self_pairs = pairs;
    }
}
