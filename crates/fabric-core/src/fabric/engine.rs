//! The robot fabric (GF Sec. V, VII-A): [`Fabric`] (read-only model: robot, gains, components) and
//! [`FabricWorkspace`] (per-thread scratch), with [`Fabric::acceleration`] evaluating the policy
//! q̈ = f(q, q̇; q_g) of GFCS eq. 1.
//!
//! One evaluation builds the transform tree at the root (GF Sec. V, eq. 15-17; see [`root`](super::root)):
//!
//! 1. joint attraction to the command q_g on x = q − q_g (VII-A1);
//! 2. optional end-effector position and axis attraction towards the end-effector pose at q_g (VII-A3,
//!    App. G), or towards explicit [`EeTargets`];
//! 3. joint-limit barriers, x = q − q_low − margin and q_up − margin − q (VII-A2);
//! 4. self-collision barriers for the robot's sphere pairs closer than the influence radius;
//! 5. obstacle barriers for every (robot sphere, obstacle) pair within the influence radius, the
//!    samples of [`Scene::query`] (task maps in [`leaves`](super::leaves));
//!
//! then resolves π̃ = −M̃⁻¹f̃ (Cholesky), energizes it (eq. 7), forces and damps it with speed control
//! (eq. 40-46). [`Mode::Unbent`](super::config::Mode::Unbent) drops the geometries (classical Lagrangian system, GF Sec. VI).
//!
//! Culling (exact: it only skips pairs the per-pair tests would reject, and keeps the order of the
//! leaves, so the result is the same to the bit as without it). Each link's spheres have a bounding
//! sphere. Self-collision pairs are grouped by link pair and, within one, by first sphere: a link pair
//! whose bounding spheres are out of reach is skipped whole, then each first sphere against the other
//! link's bounding sphere, then the pairs themselves. Obstacles: one distance-only broadphase query
//! per link at its bounding centre, a 1-Lipschitz bound per sphere, then one exact sample (gradient,
//! Hessian) per (sphere, obstacle) pair left, fetched by storage position (no id lookup).
//!
//! Sphere Jacobians are computed only for spheres that own at least one leaf, and an obstacle leaf's
//! J̇q̇ only when its barrier's metric is nonzero (the root uses it multiplied by that metric; a leaf
//! moving away has none). Nothing allocates per call once the workspace exists (the scene queries append
//! into reused buffers).

use std::sync::Arc;

use nalgebra::Vector3;

use super::components::{Attractor, Barrier, BarrierEval};
use super::config::{FabricConfig, GoalSpace};
use super::energy::{ConstantMass, TanhMass};
use super::leaves::{obstacle_leaf, obstacle_value, self_collision_leaf, LeafState};
use super::root::RootSystem;
use super::speed::EeMotion;
use crate::error::{check_finite, check_len, check_policy_inputs, FabricError, Result};
use crate::robot::{CollisionSphere, KinematicsWorkspace, Robot, TaskPoint};
use crate::scene::distance::NearObstacle;
use crate::scene::Scene;

/// End-effector targets in the world (base) frame: the position of the end-effector link origin (m) and
/// its three unit axes (columns of its rotation), as used by the VII-A3 / App. G attractors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EeTargets {
    /// Target position p_d (m).
    pub position: Vector3<f64>,
    /// Target unit axes R_d e_x, R_d e_y, R_d e_z.
    pub axes: [Vector3<f64>; 3],
}

/// Quantities of the last evaluation (see [`Fabric::diagnostics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diagnostics {
    /// Fabric energy L̃_e = ½ q̇ᵀ M̃ q̇ (the summed Finsler energies).
    pub energy: f64,
    /// Execution energy L_ex = ½ ‖q̇‖² (rad²/s²).
    pub exec_energy: f64,
    /// Total forcing potential ψ (the Lyapunov function is L̃_e + ψ, GF Thm IV.4); NaN when the
    /// workspace does not accumulate it ([`FabricWorkspace::set_potential`]).
    pub potential: f64,
    /// Minimum over (robot sphere, obstacle) pairs within the obstacle influence radius (plus margin) of
    /// d(c) − r (m, negative in collision); +∞ when no sphere is that close to any obstacle.
    pub min_clearance: f64,
    /// Minimum over self-collision sphere pairs within the self-collision influence radius (plus the
    /// widest pair margin) of ‖c_a − c_b‖ − r_a − r_b (m); +∞ when no pair is that close.
    pub min_self_clearance: f64,
    /// Minimum over joints of min(q − q_low, q_up − q) (rad or m), without margin; +∞ without limits.
    pub min_joint_margin: f64,
    /// α_Le: energization coefficient of π̃ w.r.t. L̃_e (eq. 7); 0 when unbent.
    pub alpha_le: f64,
    /// α_ex^0 (eq. 41).
    pub alpha_ex0: f64,
    /// α_ex^ψ (eq. 42).
    pub alpha_expsi: f64,
    /// η (eq. 46).
    pub eta: f64,
    /// s_β (eq. 45).
    pub s_beta: f64,
    /// β_reg (eq. 44), or s_β B + B̲ with speed control disabled.
    pub beta: f64,
    /// α_boost.
    pub alpha_boost: f64,
    /// α_reg, the coefficient of q̇ in eq. 40.
    pub alpha_reg: f64,
    /// Number of barrier leaves (joint limits + self-collision + obstacles) in the tree.
    pub leaves: usize,
}

impl Default for Diagnostics {
    fn default() -> Self {
        Diagnostics {
            energy: 0.0,
            exec_energy: 0.0,
            potential: 0.0,
            min_clearance: f64::INFINITY,
            min_self_clearance: f64::INFINITY,
            min_joint_margin: f64::INFINITY,
            alpha_le: 0.0,
            alpha_ex0: 0.0,
            alpha_expsi: 0.0,
            eta: 0.0,
            s_beta: 0.0,
            beta: 0.0,
            alpha_boost: 0.0,
            alpha_reg: 0.0,
            leaves: 0,
        }
    }
}

/// The collision spheres of one link and a sphere bounding them all (link frame), used to cull obstacle
/// queries and self-collision pairs: an obstacle within distance δ of a sphere is within R + δ of the
/// bounding centre, and two spheres of links A and B are at least ‖C_A − C_B‖ − R_A − R_B apart.
#[derive(Clone, Debug)]
struct SphereGroup {
    link: usize,
    center: Vector3<f64>,
    radius: f64,
    spheres: Vec<usize>,
}

fn sphere_groups(robot: &Robot) -> Vec<SphereGroup> {
    let mut groups: Vec<SphereGroup> = Vec::new();
    // group_of_link[l]: the group of link l, in order of first appearance (a direct index keeps this
    // linear in spheres and links)
    let mut group_of_link = vec![usize::MAX; robot.link_names().len()];
    for (k, s) in robot.spheres().iter().enumerate() {
        match group_of_link[s.link] {
            usize::MAX => {
                group_of_link[s.link] = groups.len();
                groups.push(SphereGroup {
                    link: s.link,
                    center: Vector3::zeros(),
                    radius: 0.0,
                    spheres: vec![k],
                });
            }
            g => groups[g].spheres.push(k),
        }
    }
    for g in &mut groups {
        let sp = robot.spheres();
        g.center = g
            .spheres
            .iter()
            .map(|&k| sp[k].center)
            .sum::<Vector3<f64>>()
            / g.spheres.len() as f64;
        g.radius = g
            .spheres
            .iter()
            .map(|&k| (sp[k].center - g.center).norm() + sp[k].radius)
            .fold(0.0, f64::max);
    }
    groups
}

/// Slack (m) added to the culling distances (self-collision bounding spheres, obstacle Lipschitz bounds),
/// far above the round-off of those bounds, so that culling never drops a pair the exact test keeps.
const CULL_SLACK: f64 = 1e-9;

/// Self-collision sphere pairs consecutive in `Robot::self_collision_pairs` that share their first sphere
/// and the link group of their second: `pairs` indexes [`SelfPairs::pairs`].
#[derive(Clone, Debug)]
struct PairRun {
    /// The common first sphere.
    sphere: usize,
    /// The link group (index into `Fabric::groups`) of every second sphere.
    other: usize,
    pairs: std::ops::Range<usize>,
}

/// The runs whose spheres lie on two given link groups: `runs` indexes [`SelfPairs::runs`].
#[derive(Clone, Debug)]
struct LinkPair {
    a: usize,
    b: usize,
    runs: std::ops::Range<usize>,
}

/// Broadphase of the self-collision sphere pairs: pairs grouped by the link groups of their two spheres,
/// in two levels of bounding-sphere tests (link group against link group, then first sphere against the
/// other link group), so that most pairs are never looked at. Exact: see [`SelfPairs::collect`].
#[derive(Clone, Debug)]
struct SelfPairs {
    links: Vec<LinkPair>,
    runs: Vec<PairRun>,
    /// (index in `Robot::self_collision_pairs`, first sphere, second sphere), ordered by link pair
    /// (group indices), then as in `Robot::self_collision_pairs`.
    pairs: Vec<(u32, usize, usize)>,
}

impl SelfPairs {
    fn new(robot: &Robot, groups: &[SphereGroup]) -> SelfPairs {
        let mut group_of = vec![usize::MAX; robot.spheres().len()];
        for (gi, g) in groups.iter().enumerate() {
            for &k in &g.spheres {
                group_of[k] = gi;
            }
        }
        // the pairs sorted by link pair, each link pair's in their original order: one sort, with no
        // allocation per link pair (a robot of n one-sphere links has ~n²/2 link pairs)
        let mut sorted: Vec<((u32, u32), u32)> = robot
            .self_collision_pairs()
            .iter()
            .enumerate()
            .map(|(index, &(a, b))| {
                let (ga, gb) = (group_of[a] as u32, group_of[b] as u32);
                ((ga.min(gb), ga.max(gb)), index as u32)
            })
            .collect();
        sorted.sort_unstable();
        let all = robot.self_collision_pairs();
        let mut out = SelfPairs {
            links: Vec::new(),
            runs: Vec::new(),
            pairs: Vec::with_capacity(all.len()),
        };
        for same_link_pair in sorted.chunk_by(|x, y| x.0 == y.0) {
            let (a, b) = same_link_pair[0].0;
            let first_run = out.runs.len();
            for &(_, index) in same_link_pair {
                let (first, second) = all[index as usize];
                let other = group_of[second];
                let i = out.pairs.len();
                let extends = out.runs.len() > first_run
                    && matches!(out.runs.last(), Some(r) if r.sphere == first && r.other == other);
                match out.runs.last_mut() {
                    Some(r) if extends => r.pairs.end = i + 1,
                    _ => out.runs.push(PairRun {
                        sphere: first,
                        other,
                        pairs: i..i + 1,
                    }),
                }
                out.pairs.push((index, first, second));
            }
            out.links.push(LinkPair {
                a: a as usize,
                b: b as usize,
                runs: first_run..out.runs.len(),
            });
        }
        out
    }

    /// Append to `out` (index, ‖c_a − c_b‖²) of every pair with ‖c_a − c_b‖ < r_a + r_b + `reach` (the
    /// exact test of the unculled loop), sorted by index. `centers` (world sphere centres) and
    /// `group_centers` (world bounding-sphere centres of `groups`) are those of one configuration.
    ///
    /// Exact because a group whose bounding sphere (C, R) contains every sphere (c, r) of its link
    /// (‖c − C‖ + r ≤ R) gives ‖c_a − c_b‖ − r_a − r_b ≥ ‖c_a − C_B‖ − r_a − R_B ≥ ‖C_A − C_B‖ − R_A − R_B:
    /// a run or link pair is skipped only when that bound is ≥ `reach` + [`CULL_SLACK`].
    fn collect(
        &self,
        groups: &[SphereGroup],
        spheres: &[CollisionSphere],
        centers: &[Vector3<f64>],
        group_centers: &[Vector3<f64>],
        reach: f64,
        out: &mut Vec<(u32, f64)>,
    ) {
        let reach_slack = reach + CULL_SLACK;
        for lp in &self.links {
            let far = groups[lp.a].radius + groups[lp.b].radius + reach_slack;
            if (group_centers[lp.a] - group_centers[lp.b]).norm_squared() >= far * far {
                continue;
            }
            for run in &self.runs[lp.runs.clone()] {
                let (c, r) = (centers[run.sphere], spheres[run.sphere].radius);
                let far = r + groups[run.other].radius + reach_slack;
                if (c - group_centers[run.other]).norm_squared() >= far * far {
                    continue;
                }
                for &(index, _, b) in &self.pairs[run.pairs.clone()] {
                    let far = r + spheres[b].radius + reach;
                    let d2 = (c - centers[b]).norm_squared();
                    if d2 < far * far {
                        out.push((index, d2));
                    }
                }
            }
        }
        out.sort_unstable_by_key(|&(index, _)| index);
    }
}

/// A geometric fabric for one robot: the model shared by every thread (`Send + Sync`).
#[derive(Clone, Debug)]
pub struct Fabric {
    robot: Arc<Robot>,
    groups: Vec<SphereGroup>,
    self_pairs: SelfPairs,
    config: FabricConfig,
    joint: Attractor<ConstantMass>,
    ee_position: Attractor<TanhMass>,
    ee_axis: Attractor<TanhMass>,
    joint_limits: Barrier,
    self_collision: Barrier,
    obstacles: Barrier,
    /// Per-sphere obstacle margins (m), replacing `config.obstacles.margin` for each robot sphere; None:
    /// the configured margin for all. See [`Fabric::with_obstacle_margins`].
    obstacle_margins: Option<Arc<[f64]>>,
    /// The largest obstacle margin of any sphere (m), for the culling bounds: set with the margins.
    widest_obstacle_margin: f64,
    /// Per-pair self-collision margins (m), replacing `config.self_collision.margin` for each pair of
    /// [`Robot::self_collision_pairs`]; None: the configured margin for all. See
    /// [`Fabric::with_self_margins`].
    self_margins: Option<Arc<[f64]>>,
    /// The largest self-collision margin of any pair (m), for the culling bounds: set with the margins.
    widest_self_margin: f64,
    /// Per-joint scales s_i (> 0) of the joint attractor's task space x = S (q − q_g); None: S = I (the
    /// paper's x = q − q_g). See [`Fabric::with_joint_scales`].
    joint_scales: Option<Arc<[f64]>>,
}

/// Per-thread scratch of a [`Fabric`]; create once with [`FabricWorkspace::new`] and reuse.
#[derive(Clone, Debug)]
pub struct FabricWorkspace {
    kin: KinematicsWorkspace,
    target_kin: KinematicsWorkspace,
    target_command: Vec<f64>,
    targets: Option<EeTargets>,
    root: RootSystem,
    centers: Vec<Vector3<f64>>,
    group_centers: Vec<Vector3<f64>>,
    /// Self-collision pairs within reach: (index in `Robot::self_collision_pairs`, squared distance).
    active_pairs: Vec<(u32, f64)>,
    spheres: Vec<TaskPoint>,
    sphere_ready: Vec<bool>,
    near: Vec<NearObstacle>,
    task: TaskPoint,
    jrow: Vec<f64>,
    x: Vec<f64>,
    scratch: Vec<f64>,
    xi: Vec<f64>,
    f: Vec<f64>,
    grad: Vec<f64>,
    diag: Diagnostics,
    with_potential: bool,
}

impl FabricWorkspace {
    /// Scratch sized for `fabric`'s robot (dof, links, spheres).
    pub fn new(fabric: &Fabric) -> Self {
        let robot = &fabric.robot;
        let n = robot.dof();
        let s = robot.spheres().len();
        FabricWorkspace {
            kin: KinematicsWorkspace::new(robot),
            target_kin: KinematicsWorkspace::new(robot),
            target_command: vec![f64::NAN; n],
            targets: None,
            root: RootSystem::new(n),
            centers: vec![Vector3::zeros(); s],
            group_centers: vec![Vector3::zeros(); fabric.groups.len()],
            active_pairs: Vec::with_capacity(fabric.self_pairs.pairs.len()),
            spheres: (0..s).map(|_| TaskPoint::new(n)).collect(),
            sphere_ready: vec![false; s],
            near: Vec::with_capacity(16),
            task: TaskPoint::new(n),
            jrow: vec![0.0; n],
            x: vec![0.0; n],
            scratch: vec![0.0; n.max(3)],
            xi: vec![0.0; n.max(3)],
            f: vec![0.0; n.max(3)],
            grad: vec![0.0; n.max(3)],
            diag: Diagnostics::default(),
            with_potential: true,
        }
    }

    /// Scratch for rollouts: [`FabricWorkspace::new`] with the potential off ([`set_potential`]).
    ///
    /// [`set_potential`]: FabricWorkspace::set_potential
    pub fn for_rollouts(fabric: &Fabric) -> Self {
        let mut ws = FabricWorkspace::new(fabric);
        ws.set_potential(false);
        ws
    }

    /// Whether evaluations accumulate the forcing potential ψ into [`Diagnostics::potential`] (default
    /// true). ψ only reports energy: q̈ depends on its gradient alone, and the soft-plus of every barrier
    /// leaf's ψ cost ~7 % of a fabric step, so rollouts turn it off (`Diagnostics::potential` is then
    /// NaN). q̈ is identical bit for bit either way.
    pub fn set_potential(&mut self, on: bool) {
        self.with_potential = on;
    }

    /// The root system of the last evaluation: M̃, ξ̃, f̃, ∂ψ, π̃ and M̃⁻¹∂ψ (for analysis and tests).
    pub fn root(&self) -> &RootSystem {
        &self.root
    }

    /// The kinematics of the last evaluation.
    pub fn kinematics(&self) -> &KinematicsWorkspace {
        &self.kin
    }
}

impl Fabric {
    /// Build a fabric for `robot` with `config` (validated; `Err(Format)` naming the bad field).
    pub fn new(robot: Arc<Robot>, config: FabricConfig) -> Result<Fabric> {
        config.validate()?;
        let n = robot.dof();
        let groups = sphere_groups(&robot);
        let self_pairs = SelfPairs::new(&robot, &groups);
        Ok(Fabric {
            joint: Attractor::joint(&config.joint_attraction, n),
            ee_position: Attractor::end_effector(&config.ee_position, 3),
            ee_axis: Attractor::end_effector(&config.ee_orientation, 3),
            joint_limits: Barrier::from_config(&config.joint_limits),
            self_collision: Barrier::from_config(&config.self_collision),
            obstacles: Barrier::from_config(&config.obstacles),
            obstacle_margins: None,
            widest_obstacle_margin: config.obstacles.margin,
            self_margins: None,
            widest_self_margin: config.self_collision.margin,
            joint_scales: None,
            groups,
            self_pairs,
            robot,
            config,
        })
    }

    /// This fabric with an obstacle margin per robot sphere (m, in the order of [`Robot::spheres`]),
    /// replacing `config.obstacles.margin` in the obstacle barrier x = d(c) − r − margin; None restores the
    /// configured margin. A margin may be negative (down to, not including, −r): the barrier then lets that
    /// sphere sink into obstacles by up to −margin, e.g. for a goal at which conservative spheres overlap an
    /// obstacle that the robot's meshes clear (`gfcs.optimize.solve`'s goal-contact retry).
    ///
    /// Errors: `Shape` unless there is one margin per sphere, `NonFinite` for NaN or ±inf, `Value` naming
    /// the sphere and its link for a margin ≤ −radius.
    pub fn with_obstacle_margins(mut self, margins: Option<Vec<f64>>) -> Result<Fabric> {
        if let Some(m) = &margins {
            let spheres = self.robot.spheres();
            check_len("obstacle_margins", m.len(), spheres.len())?;
            check_finite("obstacle_margins", m)?;
            for (k, (&mk, sphere)) in m.iter().zip(spheres).enumerate() {
                if mk <= -sphere.radius {
                    return Err(FabricError::Value {
                        what: format!("obstacle_margins[{k}]"),
                        message: format!(
                            "{mk} m is at or below minus the radius ({} m) of sphere {k} on link '{}'",
                            sphere.radius,
                            self.robot.link_names()[sphere.link]
                        ),
                    });
                }
            }
        }
        self.widest_obstacle_margin = margins.as_ref().map_or(self.config.obstacles.margin, |m| {
            m.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
        });
        self.obstacle_margins = margins.map(Arc::from);
        Ok(self)
    }

    /// This fabric with a self-collision margin per sphere pair (m, in the order of
    /// [`Robot::self_collision_pairs`]), replacing `config.self_collision.margin` in the pair's barrier
    /// x = ‖c_a − c_b‖ − r_a − r_b − margin; None restores the configured margin. A wider margin keeps two
    /// links apart by more than their spheres, e.g. where the robot's meshes stick out of its spheres
    /// (`gfcs.planning.policies.SelfCover`); a negative one (down to, not including, −(r_a + r_b)) lets the
    /// pair's spheres overlap by up to −margin.
    ///
    /// Errors: `Shape` unless there is one margin per pair, `NonFinite` for NaN or ±inf, `Value` naming
    /// the pair's spheres and links for a margin ≤ −(r_a + r_b).
    pub fn with_self_margins(mut self, margins: Option<Vec<f64>>) -> Result<Fabric> {
        if let Some(m) = &margins {
            let (spheres, pairs) = (self.robot.spheres(), self.robot.self_collision_pairs());
            check_len("self_margins", m.len(), pairs.len())?;
            check_finite("self_margins", m)?;
            for (k, (&mk, &(a, b))) in m.iter().zip(pairs).enumerate() {
                let radii = spheres[a].radius + spheres[b].radius;
                if mk <= -radii {
                    let links = self.robot.link_names();
                    return Err(FabricError::Value {
                        what: format!("self_margins[{k}]"),
                        message: format!(
                            "{mk} m is at or below minus the radii ({radii} m) of spheres {a} and {b} on \
                             links '{}' and '{}'",
                            links[spheres[a].link], links[spheres[b].link]
                        ),
                    });
                }
            }
        }
        self.widest_self_margin = margins
            .as_ref()
            .map_or(self.config.self_collision.margin, |m| {
                m.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
            });
        self.self_margins = margins.map(Arc::from);
        Ok(self)
    }

    /// The per-pair self-collision margins (m) set by [`Fabric::with_self_margins`], if any.
    pub fn self_margins(&self) -> Option<&[f64]> {
        self.self_margins.as_deref()
    }

    /// This fabric with the joint attractor (GF VII-A1) on the scaled task space x = S (q − q_g),
    /// S = diag(`scales`) (one per joint, > 0, units of x per rad or per m): J = S, so the attractor adds
    /// M̃ += m S², and ξ, f and ∂ψ of x pulled back through S. With s_i = v_ref / v_i (joint velocity
    /// limits v_i) x measures each joint's error in time at its speed limit, and a slow joint (a lift
    /// moving 0.1 m/s beside arm joints moving 2 rad/s) is as heavy in M̃ as its slowness: barriers then
    /// deflect the motion with the fast joints instead of shifting the slow one. The other leaves are
    /// task-space fabrics and do not depend on the root coordinates. None restores S = I.
    ///
    /// Errors: `Shape` unless there is one scale per joint, `NonFinite` for NaN or ±inf, `Value` naming
    /// the joint for a scale ≤ 0.
    pub fn with_joint_scales(mut self, scales: Option<Vec<f64>>) -> Result<Fabric> {
        if let Some(s) = &scales {
            check_len("joint_scales", s.len(), self.robot.dof())?;
            check_finite("joint_scales", s)?;
            if let Some(i) = s.iter().position(|&v| v <= 0.0) {
                return Err(FabricError::Value {
                    what: format!("joint_scales[{i}]"),
                    message: format!(
                        "{} is not positive (joint '{}')",
                        s[i],
                        self.robot.joint_names()[i]
                    ),
                });
            }
        }
        self.joint_scales = scales.map(Arc::from);
        Ok(self)
    }

    /// The joint attractor's per-joint scales set by [`Fabric::with_joint_scales`], if any.
    pub fn joint_scales(&self) -> Option<&[f64]> {
        self.joint_scales.as_deref()
    }

    /// The per-sphere obstacle margins (m) set by [`Fabric::with_obstacle_margins`], if any.
    pub fn obstacle_margins(&self) -> Option<&[f64]> {
        self.obstacle_margins.as_deref()
    }

    /// The robot model.
    pub fn robot(&self) -> &Arc<Robot> {
        &self.robot
    }

    /// The configuration.
    pub fn config(&self) -> &FabricConfig {
        &self.config
    }

    /// Checks that the fabric can see `scene`'s obstacles: the obstacle barrier (GF Sec. VII-A) acts on
    /// the robot's collision spheres only, so an enabled barrier on a robot without spheres would ignore
    /// every obstacle. Errors (`FabricError::Value`) for such a robot in a non-empty scene; the engine's
    /// per-step calls do not repeat this check.
    pub fn check_scene(&self, scene: &Scene) -> Result<()> {
        if self.config.obstacles.enabled && !scene.is_empty() && self.robot.spheres().is_empty() {
            return Err(FabricError::Value {
                what: "scene".into(),
                message: format!(
                    "robot '{}' has no collision spheres, so the fabric cannot avoid the scene's {} \
                     obstacles (its URDF collision elements are meshes or boxes, or none): give it \
                     spheres (gfcs.sphere_fit.with_fitted_spheres(robot) fits them to its collision \
                     geometry; or a spherized URDF, Robot.from_urdf(..., spheres=FILE), --spheres FILE), \
                     or disable obstacles in the fabric config",
                    self.robot.name(),
                    scene.len()
                ),
            });
        }
        Ok(())
    }

    /// The end-effector targets implied by a joint command: the pose of the end-effector link at
    /// `command` (dof,). Errors on wrong length / non-finite values.
    pub fn ee_targets(&self, command: &[f64], ws: &mut FabricWorkspace) -> Result<EeTargets> {
        self.check_workspace(ws)?;
        self.robot.update_positions(command, &mut ws.target_kin)?;
        let pose = self.robot.link_pose(&ws.target_kin, self.robot.ee_link());
        let r = pose.rotation.to_rotation_matrix();
        Ok(EeTargets {
            position: pose.translation.vector,
            axes: [
                r.matrix().column(0).into_owned(),
                r.matrix().column(1).into_owned(),
                r.matrix().column(2).into_owned(),
            ],
        })
    }

    fn check_workspace(&self, ws: &FabricWorkspace) -> Result<()> {
        let n = self.robot.dof();
        let s = self.robot.spheres().len();
        let g = self.groups.len();
        if ws.root.dim() != n || ws.spheres.len() != s || ws.group_centers.len() != g {
            return Err(FabricError::Shape {
                what: "fabric workspace (dof, spheres, sphere groups)".to_string(),
                expected: format!("({n}, {s}, {g})"),
                got: format!(
                    "({}, {}, {})",
                    ws.root.dim(),
                    ws.spheres.len(),
                    ws.group_centers.len()
                ),
            });
        }
        Ok(())
    }

    /// q̈ (rad/s², written into `qdd` (dof,)) for the state (`q`, `qd`) (dof,) attracted to the joint-space
    /// command `command` (dof,) in `scene` (GFCS eq. 1). End-effector attractors, when enabled, aim at
    /// the end-effector pose at `command` (cached while the command does not change).
    ///
    /// Errors: `Shape` (wrong lengths, foreign workspace), `NonFinite` (NaN/∞ in inputs, or a non-finite
    /// result at this state), `Value` (root metric not positive definite). Never returns NaN.
    pub fn acceleration(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        ws: &mut FabricWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        self.check_inputs(q, qd, command, qdd, ws)?;
        let targets = if self.config.ee_position.enabled || self.config.ee_orientation.enabled {
            if ws.targets.is_none() || ws.target_command.as_slice() != command {
                let t = self.ee_targets(command, ws)?;
                ws.target_command.copy_from_slice(command);
                ws.targets = Some(t);
            }
            ws.targets
        } else {
            None
        };
        self.evaluate(scene, q, qd, command, targets.as_ref(), ws, qdd)
    }

    /// As [`Fabric::acceleration`] but with explicit end-effector targets (used only by the end-effector
    /// attractors; the joint attractor still aims at `command`).
    #[allow(clippy::too_many_arguments)]
    pub fn acceleration_with_targets(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        targets: &EeTargets,
        ws: &mut FabricWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        self.check_inputs(q, qd, command, qdd, ws)?;
        let finite = targets
            .position
            .iter()
            .chain(targets.axes.iter().flat_map(|a| a.iter()))
            .all(|v| v.is_finite());
        if !finite {
            return Err(FabricError::NonFinite {
                what: "end-effector targets".to_string(),
            });
        }
        self.evaluate(scene, q, qd, command, Some(targets), ws, qdd)
    }

    /// Diagnostics of the last evaluation in `ws`.
    pub fn diagnostics(&self, ws: &FabricWorkspace) -> Diagnostics {
        ws.diag
    }

    fn check_inputs(
        &self,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &[f64],
        ws: &FabricWorkspace,
    ) -> Result<()> {
        check_policy_inputs(self.robot.dof(), q, qd, command, qdd)?;
        self.check_workspace(ws)
    }

    #[allow(clippy::too_many_arguments)]
    fn evaluate(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        targets: Option<&EeTargets>,
        ws: &mut FabricWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        let robot = &*self.robot;
        let n = robot.dof();
        robot.update(q, qd, &mut ws.kin)?;
        ws.root.clear();
        let mut diag = Diagnostics::default();

        // 1. joint attraction on x = S (q − q_g), ẋ = S q̇ (J = S; S = I without scales, exactly:
        //    a factor of 1 changes no bit)
        let scales = self.joint_scales.as_deref();
        for i in 0..n {
            let s = scales.map_or(1.0, |s| s[i]);
            ws.x[i] = s * (q[i] - command[i]);
            ws.jrow[i] = s * qd[i];
        }
        let e = self.joint.eval(
            &ws.x,
            &ws.jrow,
            &mut ws.scratch[..n],
            &mut ws.xi[..n],
            &mut ws.f[..n],
            &mut ws.grad[..n],
        );
        let (xi, f, grad) = (&ws.xi[..n], &ws.f[..n], &ws.grad[..n]);
        match scales {
            None => ws.root.add_identity(e.mass, xi, f, grad, e.psi),
            Some(s) => ws.root.add_diagonal(s, e.mass, xi, f, grad, e.psi),
        }

        // 2. end-effector attraction (VII-A3, App. G); the position last, so that `ws.task` still holds
        // the end-effector point when the speed control needs it below
        let mut ee_point_in_task = false;
        if let Some(t) = targets {
            let ee = robot.ee_link();
            if self.config.ee_orientation.enabled {
                for (k, target) in t.axes.iter().enumerate() {
                    robot.axis(&ws.kin, ee, &Vector3::ith(k, 1.0), &mut ws.task);
                    self.add_ee_axis(ws, target);
                }
            }
            if self.config.ee_position.enabled {
                robot.point(&ws.kin, ee, &Vector3::zeros(), &mut ws.task);
                self.add_ee(ws, &t.position);
                ee_point_in_task = true;
            }
        }

        // 3. joint limits
        let mut leaves = 0;
        let (lower, upper) = (robot.lower(), robot.upper());
        let jl = &self.config.joint_limits;
        for i in 0..n {
            diag.min_joint_margin = diag
                .min_joint_margin
                .min(q[i] - lower[i])
                .min(upper[i] - q[i]);
            if !jl.enabled {
                continue;
            }
            for (sign, x) in [
                (1.0, q[i] - lower[i] - jl.margin),
                (-1.0, upper[i] - jl.margin - q[i]),
            ] {
                if x < jl.influence {
                    let b = self.joint_limits.eval(x, sign * qd[i], ws.with_potential);
                    ws.root
                        .add_coordinate(i, sign, b.m, b.xi, b.f, b.grad, b.psi);
                    leaves += 1;
                }
            }
        }

        // sphere centres and link bounding-sphere centres (cheap), lazy sphere kinematics
        let spheres = robot.spheres();
        for (k, c) in ws.centers.iter_mut().enumerate() {
            *c = robot.sphere_center(&ws.kin, k);
        }
        for (c, g) in ws.group_centers.iter_mut().zip(&self.groups) {
            *c = (robot.link_pose(&ws.kin, g.link) * nalgebra::Point3::from(g.center)).coords;
        }
        ws.sphere_ready.iter_mut().for_each(|r| *r = false);

        // 4. self-collision pairs: link pairs whose bounding spheres are within reach, then the sphere
        //    pairs within reach, processed in the order of `Robot::self_collision_pairs`
        let sc = &self.config.self_collision;
        let self_margins = self.self_margins.as_deref();
        // the culling bounds hold for the widest margin of any pair
        let reach = self.widest_self_margin + sc.influence;
        ws.active_pairs.clear();
        self.self_pairs.collect(
            &self.groups,
            spheres,
            &ws.centers,
            &ws.group_centers,
            reach,
            &mut ws.active_pairs,
        );
        let pairs = robot.self_collision_pairs();
        for t in 0..ws.active_pairs.len() {
            let (index, d2) = ws.active_pairs[t];
            let (a, b) = pairs[index as usize];
            let (ra, rb) = (spheres[a].radius, spheres[b].radius);
            let clearance = d2.sqrt() - ra - rb;
            diag.min_self_clearance = diag.min_self_clearance.min(clearance);
            if !sc.enabled {
                continue;
            }
            let margin = match self_margins {
                None => sc.margin,
                Some(m) if clearance - m[index as usize] < sc.influence => m[index as usize],
                Some(_) => continue, // within the widest pair's reach, beyond this pair's
            };
            ensure_sphere(robot, ws, a);
            ensure_sphere(robot, ws, b);
            let leaf = self_collision_leaf(
                &ws.spheres[a],
                ra,
                &ws.spheres[b],
                rb,
                margin,
                sc.min_curvature_radius,
                &mut ws.jrow,
            );
            let bv = self.self_collision.eval(leaf.x, leaf.xd, ws.with_potential);
            add_barrier_leaf(&mut ws.root, &ws.jrow, &leaf, &bv);
            leaves += 1;
        }

        // 5. obstacles: one broadphase query per link group, then exact distances per sphere
        let ob = &self.config.obstacles;
        if ob.enabled && !scene.is_empty() {
            let margins = self.obstacle_margins.as_deref();
            // the culling bounds hold for the largest margin of any sphere
            let reach = self.widest_obstacle_margin + ob.influence;
            for (gi, g) in self.groups.iter().enumerate() {
                let gc = ws.group_centers[gi];
                ws.near.clear();
                scene.query_near(&gc, g.radius + reach + CULL_SLACK, &mut ws.near);
                if ws.near.is_empty() {
                    continue;
                }
                for &k in &g.spheres {
                    let r = spheres[k].radius;
                    let center = ws.centers[k];
                    let offset = (center - gc).norm();
                    for s in 0..ws.near.len() {
                        let near = ws.near[s];
                        // 1-Lipschitz lower bound of the centre's distance from the group query
                        if near.distance - offset > r + reach + CULL_SLACK {
                            continue;
                        }
                        let Some(sample) = scene.sample_near(&near, &center, r + reach) else {
                            continue;
                        };
                        diag.min_clearance = diag.min_clearance.min(sample.distance - r);
                        let margin = margins.map_or(ob.margin, |m| m[k]);
                        if sample.distance - r - margin >= ob.influence {
                            continue;
                        }
                        ensure_sphere(robot, ws, k);
                        // the barrier before the row Jacobian: a leaf of zero metric needs no J̇q̇
                        let (x, xd) = obstacle_value(&ws.spheres[k], r, margin, &sample);
                        let bv = self.obstacles.eval(x, xd, ws.with_potential);
                        let leaf = obstacle_leaf(
                            &ws.spheres[k],
                            r,
                            margin,
                            &sample,
                            ob.min_curvature_radius,
                            bv.m != 0.0,
                            &mut ws.jrow,
                        );
                        add_barrier_leaf(&mut ws.root, &ws.jrow, &leaf, &bv);
                        leaves += 1;
                    }
                }
            }
        }

        // resolve: π̃, energization, forcing, speed control (eq. 7, 17, 40-46)
        let goal_distance = match (self.config.speed.goal_space, targets) {
            (GoalSpace::Ee, Some(t)) => {
                (robot.link_pose(&ws.kin, robot.ee_link()).translation.vector - t.position).norm()
            }
            _ => q
                .iter()
                .zip(command)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt(),
        };
        // the end-effector part of the execution energy (App. E-B), when weighted
        let ee = if self.config.speed.enabled && self.config.speed.ee_weight > 0.0 {
            if !ee_point_in_task {
                robot.point(&ws.kin, robot.ee_link(), &Vector3::zeros(), &mut ws.task);
            }
            Some(EeMotion {
                xd: ws.task.xd,
                jac: &ws.task.jac,
                jdot_qdot: ws.task.jdot_qdot,
            })
        } else {
            None
        };
        let terms = ws
            .root
            .solve(
                self.config.mode,
                &self.config.speed,
                qd,
                goal_distance,
                self.config.joint_attraction.mass,
                self.joint_scales.as_deref(),
                ee,
                qdd,
            )
            .map_err(|e| match e {
                FabricError::NonFinite { what } => FabricError::NonFinite {
                    what: format!("{what} (q = {q:?}, qd = {qd:?}, command = {command:?})"),
                },
                FabricError::Value { what, message } => FabricError::Value {
                    what,
                    message: format!("{message} (q = {q:?}, qd = {qd:?}, command = {command:?})"),
                },
                other => other,
            })?;
        diag.energy = terms.energy;
        diag.exec_energy = terms.speed.exec_energy;
        diag.potential = if ws.with_potential {
            terms.potential
        } else {
            f64::NAN
        };
        diag.alpha_le = terms.alpha_le;
        diag.alpha_ex0 = terms.speed.alpha_ex0;
        diag.alpha_expsi = terms.speed.alpha_expsi;
        diag.eta = terms.speed.eta;
        diag.s_beta = terms.speed.s_beta;
        diag.beta = terms.speed.beta;
        diag.alpha_boost = terms.speed.alpha_boost;
        diag.alpha_reg = terms.speed.alpha_reg;
        diag.leaves = leaves;
        ws.diag = diag;
        Ok(())
    }

    /// Add the end-effector position attractor for the task point in `ws.task` towards `target`.
    fn add_ee(&self, ws: &mut FabricWorkspace, target: &Vector3<f64>) {
        add_attractor_3d(&self.ee_position, ws, target);
    }

    /// Add one end-effector axis attractor for the axis in `ws.task` towards the unit vector `target`.
    fn add_ee_axis(&self, ws: &mut FabricWorkspace, target: &Vector3<f64>) {
        add_attractor_3d(&self.ee_axis, ws, target);
    }
}

/// Pull back a 3-D attractor living on the task point / axis stored in `ws.task`, on x = task.x − target.
fn add_attractor_3d(att: &Attractor<TanhMass>, ws: &mut FabricWorkspace, target: &Vector3<f64>) {
    let x = [
        ws.task.x.x - target.x,
        ws.task.x.y - target.y,
        ws.task.x.z - target.z,
    ];
    let xd = [ws.task.xd.x, ws.task.xd.y, ws.task.xd.z];
    let e = att.eval(
        &x,
        &xd,
        &mut ws.scratch[..3],
        &mut ws.xi[..3],
        &mut ws.f[..3],
        &mut ws.grad[..3],
    );
    let jdqd = [
        ws.task.jdot_qdot.x,
        ws.task.jdot_qdot.y,
        ws.task.jdot_qdot.z,
    ];
    ws.root.add_isotropic(
        &ws.task.jac,
        &jdqd,
        e.mass,
        &ws.xi[..3],
        &ws.f[..3],
        &ws.grad[..3],
        e.psi,
    );
}

/// Pull back the barrier `bv` evaluated on the 1-D leaf `leaf`, whose row Jacobian is in `jrow` (its
/// leading `leaf.width` entries: the rest are zero).
fn add_barrier_leaf(root: &mut RootSystem, jrow: &[f64], leaf: &LeafState, bv: &BarrierEval) {
    root.add_scalar(
        &jrow[..leaf.width],
        leaf.jdot_qdot,
        bv.m,
        bv.xi,
        bv.f,
        bv.grad,
        bv.psi,
    );
}

/// Compute the kinematics (J, J̇q̇) of sphere `k` once per evaluation.
fn ensure_sphere(robot: &Robot, ws: &mut FabricWorkspace, k: usize) {
    if !ws.sphere_ready[k] {
        robot.sphere(&ws.kin, k, &mut ws.spheres[k]);
        ws.sphere_ready[k] = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Obstacle, Shape};
    use nalgebra::Isometry3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_state(robot: &Robot, rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<f64>) {
        let n = robot.dof();
        let q = (0..n)
            .map(|j| rng.gen_range(robot.lower()[j]..robot.upper()[j]))
            .collect();
        let qd = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        (q, qd)
    }

    /// The two-level self-collision broadphase returns exactly the pairs of the plain loop over
    /// `Robot::self_collision_pairs` (same indices, same squared distances, same order), for reaches from
    /// 0 (touching spheres only) to 1 m (nearly every pair).
    #[test]
    fn self_pair_culling_equals_the_plain_loop() {
        let robot = Robot::panda();
        let fabric = Fabric::new(Arc::new(robot.clone()), FabricConfig::default()).unwrap();
        let mut kin = KinematicsWorkspace::new(&robot);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let spheres = robot.spheres();
        let (mut got, mut centers, mut group_centers) = (Vec::new(), Vec::new(), Vec::new());
        let mut counts = [0usize; 4];
        for _ in 0..300 {
            let (q, qd) = random_state(&robot, &mut rng);
            robot.update(&q, &qd, &mut kin).unwrap();
            centers.clear();
            centers.extend((0..spheres.len()).map(|k| robot.sphere_center(&kin, k)));
            group_centers.clear();
            group_centers.extend(fabric.groups.iter().map(|g| {
                (robot.link_pose(&kin, g.link) * nalgebra::Point3::from(g.center)).coords
            }));
            for (i, reach) in [0.0, 0.02, 0.1, 1.0].into_iter().enumerate() {
                let mut expected = Vec::new();
                for (index, &(a, b)) in robot.self_collision_pairs().iter().enumerate() {
                    let far = spheres[a].radius + spheres[b].radius + reach;
                    let d2 = (centers[a] - centers[b]).norm_squared();
                    if d2 < far * far {
                        expected.push((index as u32, d2));
                    }
                }
                got.clear();
                fabric.self_pairs.collect(
                    &fabric.groups,
                    spheres,
                    &centers,
                    &group_centers,
                    reach,
                    &mut got,
                );
                assert_eq!(got, expected, "reach {reach}, q = {q:?}");
                counts[i] += expected.len();
            }
        }
        assert!(counts[0] > 0 && counts[1] > counts[0] && counts[3] > 100 * 300);
    }

    /// Culling (self-collision runs, per-link obstacle queries and their Lipschitz bounds) changes nothing:
    /// with every bounding radius set to +∞ nothing is culled, and q̈ and the diagnostics are bitwise
    /// the same.
    #[test]
    fn culling_changes_no_bit_of_the_result() {
        let robot = Arc::new(Robot::panda());
        let mut cfg = FabricConfig::default();
        // fixed reaches (not the defaults), with margins, so that many leaves exist
        (cfg.obstacles.margin, cfg.obstacles.influence) = (0.02, 0.3);
        (cfg.self_collision.margin, cfg.self_collision.influence) = (0.01, 0.1);
        let fabric = Fabric::new(robot.clone(), cfg).unwrap();
        let mut unculled = fabric.clone();
        for g in &mut unculled.groups {
            g.radius = f64::INFINITY;
        }
        let scene = obstacle_scene();
        let (mut ws, mut ws_ref) = (
            FabricWorkspace::new(&fabric),
            FabricWorkspace::new(&unculled),
        );
        let (mut qdd, mut qdd_ref) = (vec![0.0; 7], vec![0.0; 7]);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let command = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
        let mut with_leaves = 0;
        for _ in 0..400 {
            let (q, qd) = random_state(&robot, &mut rng);
            let a = fabric.acceleration(&scene, &q, &qd, &command, &mut ws, &mut qdd);
            let b = unculled.acceleration(&scene, &q, &qd, &command, &mut ws_ref, &mut qdd_ref);
            assert_eq!(a.is_ok(), b.is_ok());
            if a.is_ok() {
                assert_eq!(qdd, qdd_ref, "q = {q:?}");
                assert_eq!(fabric.diagnostics(&ws), unculled.diagnostics(&ws_ref));
                with_leaves += (fabric.diagnostics(&ws).min_clearance.is_finite()) as usize;
                // skipping ψ (rollout workspaces) changes no bit of q̈ nor of the other diagnostics
                let mut no_psi = FabricWorkspace::for_rollouts(&fabric);
                let mut qdd_np = vec![0.0; 7];
                fabric
                    .acceleration(&scene, &q, &qd, &command, &mut no_psi, &mut qdd_np)
                    .unwrap();
                assert_eq!(qdd_np, qdd, "q = {q:?}");
                let (d, d_np) = (fabric.diagnostics(&ws), fabric.diagnostics(&no_psi));
                assert!(d.potential.is_finite() && d_np.potential.is_nan());
                assert_eq!(
                    Diagnostics {
                        potential: d.potential,
                        ..d_np
                    },
                    d
                );
            }
        }
        assert!(with_leaves > 50, "{with_leaves} states near obstacles");
    }

    /// Five obstacles around the Panda's workspace (boxes, cylinder, sphere, capsule).
    fn obstacle_scene() -> Scene {
        let mut scene = Scene::new();
        let pose = |x: f64, y: f64, z: f64| Isometry3::translation(x, y, z);
        let shapes = [
            (
                Shape::Cuboid {
                    half_extents: Vector3::new(0.3, 0.3, 0.02),
                },
                pose(0.5, 0.0, 0.2),
            ),
            (
                Shape::Cuboid {
                    half_extents: Vector3::new(0.02, 0.3, 0.3),
                },
                pose(0.75, 0.0, 0.5),
            ),
            (
                Shape::Cylinder {
                    half_height: 0.1,
                    radius: 0.03,
                },
                pose(0.45, 0.15, 0.3),
            ),
            (Shape::Sphere { radius: 0.05 }, pose(0.3, -0.3, 0.6)),
            (
                Shape::Capsule {
                    half_height: 0.2,
                    radius: 0.03,
                },
                pose(0.2, 0.4, 0.4),
            ),
        ];
        for (k, (shape, p)) in shapes.into_iter().enumerate() {
            scene.add(Obstacle::new(format!("o{k}"), shape, p)).unwrap();
        }
        scene
    }

    /// q̈ of each fabric at (q, q̇) toward the Panda ready configuration, or None when any evaluation fails.
    fn accelerations<const N: usize>(
        fabrics: [&Fabric; N],
        scene: &Scene,
        (q, qd): (&[f64], &[f64]),
        ws: &mut FabricWorkspace,
    ) -> Option<[[f64; 7]; N]> {
        let command = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
        let mut qdd = [[0.0; 7]; N];
        for (f, out) in fabrics.iter().zip(qdd.iter_mut()) {
            f.acceleration(scene, q, qd, &command, ws, out).ok()?;
        }
        Some(qdd)
    }

    /// Per-sphere obstacle margins: all equal to m, q̈ is bit for bit that of the configured margin m
    /// (culling included); None restores the configured margin; bad margins are refused, naming the sphere.
    #[test]
    fn per_sphere_obstacle_margins_act_as_the_configured_margin() {
        let robot = Arc::new(Robot::panda());
        let mut cfg = FabricConfig::default();
        (cfg.obstacles.margin, cfg.obstacles.influence) = (0.02, 0.3);
        let wide = Fabric::new(robot.clone(), cfg.clone()).unwrap();
        cfg.obstacles.margin = 0.002;
        let narrow = Fabric::new(robot.clone(), cfg).unwrap();
        let s = robot.spheres().len();
        let per_sphere = narrow
            .clone()
            .with_obstacle_margins(Some(vec![0.02; s]))
            .unwrap();
        assert_eq!(per_sphere.obstacle_margins(), Some(&vec![0.02; s][..]));
        let restored = per_sphere.clone().with_obstacle_margins(None).unwrap();
        assert!(restored.obstacle_margins().is_none());
        let scene = obstacle_scene();
        let mut ws = FabricWorkspace::new(&narrow);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut differ = 0;
        for _ in 0..300 {
            let (q, qd) = random_state(&robot, &mut rng);
            let fabrics = [&wide, &per_sphere, &narrow, &restored];
            if let Some(qdd) = accelerations(fabrics, &scene, (&q, &qd), &mut ws) {
                assert_eq!(qdd[0], qdd[1], "q = {q:?}");
                assert_eq!(qdd[2], qdd[3], "q = {q:?}");
                differ += (qdd[0] != qdd[2]) as usize;
            }
        }
        assert!(differ > 20, "{differ} states where the margin matters");
        let err = |m: Vec<f64>| narrow.clone().with_obstacle_margins(Some(m)).unwrap_err();
        assert!(matches!(err(vec![0.0; s - 1]), FabricError::Shape { .. }));
        let mut nan = vec![0.0; s];
        nan[3] = f64::NAN;
        assert!(matches!(err(nan), FabricError::NonFinite { .. }));
        let mut deep = vec![0.0; s];
        deep[s - 1] = -robot.spheres()[s - 1].radius;
        let message = err(deep).to_string();
        assert!(
            message.contains(&format!("sphere {}", s - 1)) && message.contains("panda_"),
            "{message}"
        );
        let mut shallow = vec![0.0; s];
        shallow[s - 1] = -0.9 * robot.spheres()[s - 1].radius;
        assert!(narrow.clone().with_obstacle_margins(Some(shallow)).is_ok());
    }

    /// Per-pair self-collision margins: all equal to m, q̈ is bit for bit that of the configured margin m
    /// (culling included); one pair's margin raised changes q̈ only where that pair is within its reach;
    /// None restores the configured margin; bad margins are refused, naming the pair's links.
    #[test]
    fn per_pair_self_margins_act_as_the_configured_margin() {
        let robot = Arc::new(Robot::panda());
        let mut cfg = FabricConfig::default();
        (cfg.self_collision.margin, cfg.self_collision.influence) = (0.03, 0.1);
        let wide = Fabric::new(robot.clone(), cfg.clone()).unwrap();
        cfg.self_collision.margin = 0.002;
        let narrow = Fabric::new(robot.clone(), cfg).unwrap();
        let pairs = robot.self_collision_pairs();
        let p = pairs.len();
        let per_pair = narrow
            .clone()
            .with_self_margins(Some(vec![0.03; p]))
            .unwrap();
        assert_eq!(per_pair.self_margins(), Some(&vec![0.03; p][..]));
        let restored = per_pair.clone().with_self_margins(None).unwrap();
        assert!(restored.self_margins().is_none());
        // one pair (the first of the hand against link 2) with a margin of 0.2 m
        let spheres = robot.spheres();
        let link = |name: &str| robot.link_names().iter().position(|l| l == name).unwrap();
        let (hand, link2) = (link("panda_hand"), link("panda_link2"));
        let k = pairs
            .iter()
            .position(|&(a, b)| {
                let l = [spheres[a].link, spheres[b].link];
                l.contains(&hand) && l.contains(&link2)
            })
            .expect("a hand / link 2 pair");
        let mut one = vec![0.002; p];
        one[k] = 0.2;
        let one_wide = narrow.clone().with_self_margins(Some(one)).unwrap();
        let scene = Scene::new();
        let mut ws = FabricWorkspace::new(&narrow);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (mut differ, mut one_differs) = (0, 0);
        for _ in 0..400 {
            let (q, qd) = random_state(&robot, &mut rng);
            let fabrics = [&wide, &per_pair, &narrow, &restored, &one_wide];
            let Some(qdd) = accelerations(fabrics, &scene, (&q, &qd), &mut ws) else {
                continue;
            };
            assert_eq!(qdd[0], qdd[1], "q = {q:?}");
            assert_eq!(qdd[2], qdd[3], "q = {q:?}");
            differ += (qdd[0] != qdd[2]) as usize;
            let mut kin = KinematicsWorkspace::new(&robot);
            robot.update(&q, &qd, &mut kin).unwrap();
            let (a, b) = pairs[k];
            let gap = (robot.sphere_center(&kin, a) - robot.sphere_center(&kin, b)).norm()
                - spheres[a].radius
                - spheres[b].radius;
            if gap - 0.2 >= 0.1 {
                assert_eq!(qdd[4], qdd[2], "pair {k} out of reach, q = {q:?}");
            } else {
                one_differs += (qdd[4] != qdd[2]) as usize;
            }
        }
        assert!(differ > 20, "{differ} states where the margin matters");
        assert!(
            one_differs > 5,
            "{one_differs} states where the one pair matters"
        );
        let err = |m: Vec<f64>| narrow.clone().with_self_margins(Some(m)).unwrap_err();
        assert!(matches!(err(vec![0.0; p - 1]), FabricError::Shape { .. }));
        let mut nan = vec![0.0; p];
        nan[3] = f64::INFINITY;
        assert!(matches!(err(nan), FabricError::NonFinite { .. }));
        let (a, b) = pairs[p - 1];
        let radii = spheres[a].radius + spheres[b].radius;
        let mut deep = vec![0.0; p];
        deep[p - 1] = -radii;
        let message = err(deep).to_string();
        assert!(
            message.contains(&format!("self_margins[{}]", p - 1)) && message.contains("panda_"),
            "{message}"
        );
        let mut shallow = vec![0.0; p];
        shallow[p - 1] = -0.9 * radii;
        assert!(narrow.clone().with_self_margins(Some(shallow)).is_ok());
    }
}
