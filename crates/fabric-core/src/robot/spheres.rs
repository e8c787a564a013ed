//! Collision spheres: from URDF `<collision><sphere>` elements (see `urdf.rs`), an explicit list, or a
//! JSON sphere file:
//!
//! ```json
//! {"spheres": [{"link": "panda_link1", "center": [0.0, -0.05, -0.1], "radius": 0.08}, ...]}
//! ```
//!
//! Centres are in the link frame (m), radii in m and > 0. Other keys are ignored.

use std::path::Path;

use nalgebra::Vector3;
use serde_json::Value;

use super::model::Robot;
use crate::error::{FabricError, Result};

/// A sphere rigidly attached to a link, approximating the robot's volume for collision avoidance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionSphere {
    /// Link index (see [`Robot::link_names`]).
    pub link: usize,
    /// Centre in the link frame (m).
    pub center: Vector3<f64>,
    /// Radius (m), > 0.
    pub radius: f64,
}

impl Robot {
    /// Replace the collision spheres and recompute the self-collision pairs (keeping the SRDF-disabled
    /// link pairs). Errors: `Value` for a link index out of range, a non-finite centre, or a radius that is
    /// not finite and > 0.
    pub fn set_spheres(&mut self, spheres: Vec<CollisionSphere>) -> Result<()> {
        for (i, s) in spheres.iter().enumerate() {
            let what = || format!("sphere {i}");
            self.check_link_index(s.link, &what())?;
            if !s.center.iter().all(|v| v.is_finite()) {
                return Err(FabricError::Value {
                    what: what(),
                    message: "centre is not finite".into(),
                });
            }
            check_radius(s.radius, &what())?;
        }
        self.spheres = spheres;
        self.recompute_self_pairs();
        Ok(())
    }

    /// Read a JSON sphere file (format in the module docs). Errors: `Io`, and those of
    /// [`Robot::parse_sphere_json`].
    pub fn load_sphere_file(&self, path: &Path) -> Result<Vec<CollisionSphere>> {
        let source = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| FabricError::Io {
            path: source.clone(),
            message: e.to_string(),
        })?;
        self.parse_sphere_json(&text, &source)
    }

    /// Parse JSON sphere text (`source` names it in errors). Errors: `Format` for malformed JSON or a
    /// missing or mistyped field (the field is named, e.g. `spheres[3].center`), `MissingLink` for an
    /// unknown link, `Value` for a radius that is not finite and > 0.
    pub fn parse_sphere_json(&self, json: &str, source: &str) -> Result<Vec<CollisionSphere>> {
        let format = |field: &str, message: String| FabricError::Format {
            file: source.to_string(),
            field: field.to_string(),
            message,
        };
        let doc: Value =
            serde_json::from_str(json).map_err(|e| format("(document)", e.to_string()))?;
        let list = doc
            .get("spheres")
            .ok_or_else(|| format("spheres", "missing".into()))?
            .as_array()
            .ok_or_else(|| format("spheres", "expected an array".into()))?;
        let mut out = Vec::with_capacity(list.len());
        for (i, item) in list.iter().enumerate() {
            let field = |name: &str| format!("spheres[{i}].{name}");
            let get = |name: &str| {
                item.get(name)
                    .ok_or_else(|| format(&field(name), "missing".into()))
            };
            let link_name = get("link")?
                .as_str()
                .ok_or_else(|| format(&field("link"), "expected a string".into()))?;
            let link = self.link_index(link_name)?;
            let center = get("center")?
                .as_array()
                .filter(|a| a.len() == 3)
                .and_then(|a| {
                    let v: Option<Vec<f64>> = a.iter().map(Value::as_f64).collect();
                    v.map(|v| Vector3::new(v[0], v[1], v[2]))
                })
                .ok_or_else(|| format(&field("center"), "expected an array of 3 numbers".into()))?;
            let radius = get("radius")?
                .as_f64()
                .ok_or_else(|| format(&field("radius"), "expected a number".into()))?;
            check_radius(radius, &format!("{source}: {}", field("radius")))?;
            out.push(CollisionSphere {
                link,
                center,
                radius,
            });
        }
        Ok(out)
    }
}

fn check_radius(radius: f64, what: &str) -> Result<()> {
    if radius.is_finite() && radius > 0.0 {
        Ok(())
    } else {
        Err(FabricError::Value {
            what: what.to_string(),
            message: format!("radius {radius} must be finite and > 0"),
        })
    }
}
