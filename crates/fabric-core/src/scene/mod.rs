//! Obstacles and distance queries.
//!
//! A [`Scene`] holds [`Obstacle`]s (a [`Shape`] at a pose, with an optional linear velocity) behind a
//! parry BVH broadphase. For a point `p` (world = robot base frame; typically a robot collision-sphere
//! centre) it returns, per obstacle in range, the signed distance `d` (m, positive outside), the unit
//! gradient `∂d/∂p` and the Hessian `∂²d/∂p²` ([`DistanceSample`]): the task map and its curvature for
//! the distance-space repulsion of GF Sec. VII-A (2), pulled back with GF eq. 11-12, 16.
//!
//! * [`shape`]: [`Shape`], [`PointCloud`], [`Obstacle`].
//! * [`distance`]: closed-form distances for primitives, parry projections for meshes (formulas and
//!   singular cases documented there).
//! * `scene` (items re-exported here): [`Scene`] add / move / remove, [`Scene::advance`],
//!   [`Scene::query`], [`Scene::signed_distance`], [`Scene::shape_distance`].
//! * [`moveit`]: MoveIt PlanningScene / MotionPlanRequest YAML (MotionBenchMaker).
//! * [`meshio`]: OBJ / STL readers; [`collada`]: the COLLADA (`.dae`) reader.
//! * [`sampling`]: [`Scene::surface_points`] for the GFCS scene encoding (Sec. IV-B).

pub mod collada;
pub mod distance;
pub mod meshio;
pub mod moveit;
pub mod sampling;
#[allow(clippy::module_inception)]
mod scene;
pub mod shape;

pub use distance::{point_distance, DistanceSample, NearObstacle, SurfaceDistance};
pub use moveit::{MotionPlanRequest, OrientationGoal, PoseGoal, PLANNING_FRAMES};
pub use scene::{ObstacleId, Scene, LINEAR_SCAN_MAX};
pub use shape::{Obstacle, PointCloud, Shape};
