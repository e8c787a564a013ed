//! Fabric configuration: every gain of the Panda fabric (GF Sec. VII-A) and of speed control (GF App. E-B),
//! with units and defaults. The defaults are also written, with comments, in
//! `crates/fabric-core/assets/fabric_default.toml` (a test checks that file equals `Default`).
//!
//! Files may be TOML, YAML or JSON and may give any subset of the fields: the given values are merged over
//! the defaults, unknown fields are rejected (`deny_unknown_fields`) and every error names the file and the
//! dotted field path.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::{FabricError, Result};

/// Whether the geometry is bent into the energy (GF Sec. VI terminology).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Geometric fabric: the pulled-back HD2 geometry π̃ is energized by the summed Finsler energy
    /// (GF eq. 17), then forced and damped with speed control (eq. 40).
    #[default]
    Bent,
    /// Unbent fabric: the same components without their geometries: the classical Lagrangian system of the
    /// summed energies, M̃q̈ + ξ̃ = −∂ψ − B q̇ (GF Sec. III-B, VI), whose own geodesic flow π = −M̃⁻¹ξ̃
    /// conserves L̃_e (α_Le = 0). Damping and speed regulation are the same as in `Bent`.
    Unbent,
}

/// Gains of an attractor potential ψ(x) = k ln cosh(α‖x‖) (GF VII-A1, VII-A3): far-field gradient norm
/// k α, near-field stiffness k α².
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogCoshConfig {
    /// k (≥ 0): scale.
    pub gain: f64,
    /// α (> 0): sharpness (1/unit of x).
    pub sharpness: f64,
}

/// Gains of a barrier potential ψ(x) = k_b / x + (k_r / α) ln(1 + e^{−α(x − x_o)}) (GF VII-A2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BarrierPotentialConfig {
    /// k_b (≥ 0): barrier gain (ψ units · m).
    pub barrier_gain: f64,
    /// k_r (≥ 0): soft-ReLU gain, the slope of ψ well inside x_o (ψ units / m).
    pub relu_gain: f64,
    /// α (≥ 0): soft-ReLU sharpness (1/m).
    pub relu_sharpness: f64,
    /// x_o (≥ 0): soft-ReLU activation distance (m).
    pub relu_shift: f64,
}

/// Joint-space attraction to the command q_g (GF VII-A1): energy L_e = (m/2)‖ẋ‖² on x = q − q_g,
/// geometry π = −‖ẋ‖² ∂ψ_g, forcing −∂ψ_f, with ψ(x) = k ln cosh(α‖x‖).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointAttractionConfig {
    /// m (> 0): isotropic mass of the attraction energy; it also keeps the root metric positive definite.
    pub mass: f64,
    /// ψ_g of the geometry (x in rad; the far-field geometry acceleration is k α ‖q̇‖²).
    pub geometry: LogCoshConfig,
    /// ψ_f of the forcing term (far-field force k α, stiffness k α² at the command).
    pub potential: LogCoshConfig,
}

impl Default for JointAttractionConfig {
    fn default() -> Self {
        Self {
            mass: 1.0,
            geometry: LogCoshConfig {
                gain: 1.0,
                sharpness: 10.0,
            },
            // far-field force 10, stiffness 1000 at the command: the sum of the weak barrier
            // potentials of ~200 leaves near a goal 1-2 cm from obstacles shifts the rest point by well
            // under the goal tolerance (docs/tuning.md)
            potential: LogCoshConfig {
                gain: 0.1,
                sharpness: 100.0,
            },
        }
    }
}

/// End-effector attraction (GF VII-A3) for the position of the end-effector link origin (x = p − p_d, m)
/// or, in `ee_orientation`, for each of its three unit axes (x = R e_i − R_d e_i, App. G). The target is
/// the end-effector pose at the joint command q_g (or an explicit target). Energy
/// L_e = ‖ẋ‖²(½(m̄ − m̲)(tanh(−α_m‖x‖) + 1) + m̲), geometry π = −‖ẋ‖² ∂ψ_g, forcing −∂ψ_f, ψ = k ln cosh(α‖x‖).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EeAttractionConfig {
    /// Whether the component is used. Default: position on, orientation off.
    pub enabled: bool,
    /// m̄ (≥ 0): mass scale at the target.
    pub mass_max: f64,
    /// m̲ (> 0 when enabled): mass scale far from the target.
    pub mass_min: f64,
    /// α_m (≥ 0): sharpness of the mass transition (1/m, or 1/unit for axes).
    pub mass_sharpness: f64,
    /// ψ_g of the geometry.
    pub geometry: LogCoshConfig,
    /// ψ_f of the forcing term.
    pub potential: LogCoshConfig,
}

impl EeAttractionConfig {
    /// On: the hand is drawn toward the hand position of the joint command. Its geometry (gain 12) bends
    /// paths toward it without creating equilibria; its potential (gain 3, far-field force 30 against the
    /// joint attractor's 10) lets the hand lead the arm, so that the forearm no longer catches on rims
    /// the hand passes (more problems solved by the fabric alone, shorter hand paths with GFCS). The
    /// cost: the stronger pull can hold the arm in another configuration with the hand at the goal,
    /// which GFCS commands route around. With `SpeedConfig::ee_weight` it shortens hand paths. Figures:
    /// docs/tuning.md.
    fn position_default() -> Self {
        Self {
            enabled: true,
            mass_max: 2.0,
            mass_min: 0.2,
            mass_sharpness: 10.0,
            geometry: LogCoshConfig {
                gain: 12.0,
                sharpness: 10.0,
            },
            potential: LogCoshConfig {
                gain: 3.0,
                sharpness: 10.0,
            },
        }
    }
    /// Off: GFCS commands fix the configuration, and the joint attractor already brings the hand's
    /// orientation; switched on, it lengthens hand paths and solves fewer problems (docs/tuning.md).
    fn orientation_default() -> Self {
        Self {
            enabled: false,
            mass_max: 2.0,
            mass_min: 0.2,
            mass_sharpness: 2.0,
            geometry: LogCoshConfig {
                gain: 1.0,
                sharpness: 2.0,
            },
            potential: LogCoshConfig {
                gain: 1.0,
                sharpness: 2.0,
            },
        }
    }
}

impl Default for EeAttractionConfig {
    fn default() -> Self {
        Self::position_default()
    }
}

/// Distance-space repulsion (GF VII-A2) on a distance x (m, or rad for joint limits):
/// energy L_e = (k / 2x) s(ẋ) ẋ², geometry π = −ẋ² ∂ψ_g, forcing −∂ψ_f, both ψ of the form
/// k_b / x + (k_r / α) ln(1 + e^{−α(x − x_o)}) with their own gains. Leaves are formed only when
/// x < `influence`. Below `x_min` (penetration) the metric continues by its tangent line and the
/// potentials by their second-order Taylor polynomial: the push stays finite, nonzero and outward.
/// Inside (x < 0) the energy stays on when moving away, and `braking_time` bounds the brake and adds a
/// damper, so that explicit Euler steps stay stable (see `fabric::components::Barrier`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BarrierConfig {
    /// Whether the component is used.
    pub enabled: bool,
    /// k (≥ 0): metric gain of the barrier energy (metric = k / x).
    pub metric_gain: f64,
    /// Safety margin (≥ 0) subtracted from the raw distance: x = d − margin (m or rad).
    pub margin: f64,
    /// Influence radius (> 0): a leaf exists only while x < influence (m or rad).
    pub influence: f64,
    /// x_min (> 0): start of the penetration continuation (m or rad).
    pub x_min: f64,
    /// ρ (≥ 0, m): minimum curvature radius of the distance field in J̇q̇ (see `fabric::leaves`); 0 = exact.
    /// Unused by joint limits (their task map is linear).
    pub min_curvature_radius: f64,
    /// τ (≥ 0, s): braking time. The barrier geometry's brake is capped so that it removes at most the
    /// velocity along x within τ, and a damper of rate up to 2/τ stops an approach near and inside the
    /// barrier (see `fabric::components::Barrier::braking_time`). Explicit Euler steps up to τ never
    /// amplify the velocity along x. 0 = the paper's barrier (exact HD2 geometry, no damper).
    /// Default 0.01 s, the papers' step.
    pub braking_time: f64,
    /// ψ_g of the geometry π = −ẋ² ∂ψ_g (the main avoidance behaviour).
    pub geometry: BarrierPotentialConfig,
    /// ψ_f of the forcing term (a weak soft penalty; keep it small so goals near obstacles stay reachable).
    pub potential: BarrierPotentialConfig,
}

impl BarrierConfig {
    fn obstacle_default() -> Self {
        Self {
            enabled: true,
            metric_gain: 0.05,
            // 2 mm: Euler steps at v_d = 2 rad/s overshoot the barrier by a few mm; a wider margin
            // closes narrow passages such as those between cage bars (docs/tuning.md)
            margin: 0.002,
            // the barrier geometry's deceleration is set by the near field (speed factor
            // exp(-k/x + k/influence)); 0.15 m keeps it and halves the leaves of cluttered scenes
            influence: 0.15,
            x_min: 0.005,
            min_curvature_radius: 0.3,
            braking_time: 0.01,
            geometry: BarrierPotentialConfig {
                barrier_gain: 0.02,
                relu_gain: 5.0,
                relu_sharpness: 20.0,
                relu_shift: 0.05,
            },
            potential: BarrierPotentialConfig {
                barrier_gain: 5e-4,
                relu_gain: 0.3,
                relu_sharpness: 50.0,
                relu_shift: 0.005,
            },
        }
    }
    fn self_collision_default() -> Self {
        Self {
            // 5 cm: a wider influence keeps many hand-against-forearm leaves active every step at no
            // gain in outcome (docs/tuning.md)
            influence: 0.05,
            // 2 mm, as for obstacles: Euler steps overshoot the barrier by a millimetre or two, enough to
            // bring two spheres into overlap while their meshes stay millimetres apart. Every
            // MotionBenchMaker goal keeps at least 10.7 mm of sphere self-clearance, so the margin blocks
            // none of them; its effect on success: docs/tuning.md.
            margin: 0.002,
            ..Self::obstacle_default()
        }
    }
    fn joint_limit_default() -> Self {
        Self {
            margin: 0.01,
            influence: 0.4,
            min_curvature_radius: 0.0,
            ..Self::obstacle_default()
        }
    }
}

/// Where the goal damper s_β B of eq. 45 acts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum GoalDampingForm {
    /// As in GF App. E-B: inside β_reg, an acceleration −s_β B q̇ along the motion (path consistent).
    #[default]
    Velocity,
    /// A force-level isotropic damper −s_β B m q̇ (m: the joint-attraction mass), i.e. the acceleration
    /// −s_β B m M̃⁻¹ q̇: a positive-definite damping matrix as in GF eq. 4 / Thm IV.4. Directions with a
    /// heavy metric (near obstacles) get proportionally less damping, so the damping ratio against the
    /// attraction potential is the same in every direction and convergence near obstacles is not
    /// over-damped.
    Force,
}

/// Which distance to the goal drives the goal switch s_β of eq. 45 (and with it the goal damper).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum GoalSpace {
    /// ‖q − q_g‖ (rad) to the joint command: the command is the goal (GFCS).
    #[default]
    Joint,
    /// ‖x_ee − x_d‖ (m) from the end-effector link origin to its position target (the explicit target of
    /// `Fabric::acceleration_with_targets`, or the pose at the command) when an end-effector attractor is
    /// enabled: task-space reaching, GF Sec. VII-B–D, where the joint command only postures the arm; the
    /// joint distance otherwise.
    Ee,
}

/// Speed control by damping regulation (GF Sec. V-A, App. E-B, eq. 40-46) with execution energy
/// L_ex = ½(‖q̇‖² + w‖ẋ_ee‖²) and desired execution energy L_ex,d = ½ v_d².
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedConfig {
    /// With `false`, α_reg = α_Le − β with β = s_β B + B̲: the plain energized, forced and damped fabric
    /// (GF eq. 43 with β̃ = β) — used for theory checks. Default true.
    pub enabled: bool,
    /// v_d: desired execution speed √(‖q̇‖² + w‖ẋ_ee‖²) (rad/s; ‖q̇‖ when `ee_weight` = 0). Default 2.0.
    pub desired_speed: f64,
    /// w (rad²/m², ≥ 0): weight of the end-effector speed in the execution energy
    /// L_ex = ½(‖q̇‖² + w‖ẋ_ee‖²) (App. E-B: "Euclidean energy in either C-space or end-effector space
    /// (or, more commonly, some combination of both)"); ẋ_ee is the velocity (m/s, world) of the
    /// end-effector link origin. 0 = C-space only. Default 10 (a hand speed of 0.32 m/s counts as 1 rad/s
    /// of joint speed): GFCS minimises time (eq. 4), so with this weight it prefers short hand paths; a
    /// much larger weight slows long arm swings past the 7 s budget of a command.
    pub ee_weight: f64,
    /// α_η of eq. 46 (s²/rad²): rate of the energy-injection switch η. Default 5.0: η fades over
    /// ~±0.2 rad/s around v_d instead of cutting the start-up acceleration within one step (a sharper
    /// switch is the largest jerk left once commands are blended). The price: the cruise speed settles
    /// ~7 % above v_d (docs/tuning.md).
    pub eta_rate: f64,
    /// α_shift of eq. 46 (dimensionless): offset of η. Default 0.0.
    pub eta_shift: f64,
    /// B of eq. 45's damper (1/s): extra damping near the command. Default 20.0: the final approach
    /// rings about the command at a decay rate of ~B/2; stronger damping shortens that final approach
    /// (docs/tuning.md).
    pub goal_damping: f64,
    /// Where the goal damper s_β B acts (see [`GoalDampingForm`]). Default `force`.
    pub goal_damping_form: GoalDampingForm,
    /// B̲ (1/s): constant baseline damping. Default 0.5.
    pub base_damping: f64,
    /// Which distance s_β switches on (see [`GoalSpace`]). Default `joint`.
    pub goal_space: GoalSpace,
    /// α_β of eq. 45 (1/rad, or 1/m with `goal_space` `ee`): switching rate of s_β(‖q − q_g‖). Default 10.0.
    pub goal_switch_sharpness: f64,
    /// r of eq. 45 (rad, or m with `goal_space` `ee`): distance to the goal where s_β = ½. Default 0.15.
    pub goal_switch_radius: f64,
    /// k of α_boost = k η (1 − s_β)/(‖q̇‖ + ε) (rad/s²). Default 0.0 (off, as in GF except the cubby task).
    pub boost_gain: f64,
    /// ε of α_boost (rad/s, > 0). Default 1e-3.
    pub boost_epsilon: f64,
}

impl Default for SpeedConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            desired_speed: 2.0,
            ee_weight: 10.0,
            eta_rate: 5.0,
            eta_shift: 0.0,
            goal_damping: 20.0,
            goal_damping_form: GoalDampingForm::Force,
            base_damping: 0.5,
            goal_space: GoalSpace::Joint,
            goal_switch_sharpness: 10.0,
            goal_switch_radius: 0.15,
            boost_gain: 0.0,
            boost_epsilon: 1e-3,
        }
    }
}

/// The complete fabric configuration (GF Sec. VII-A components + App. E-B speed control).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FabricConfig {
    /// Bent (geometric fabric) or unbent (classical Lagrangian) system. Default `bent`.
    pub mode: Mode,
    /// Joint-space attraction to the command (always on; its mass keeps the root metric invertible).
    pub joint_attraction: JointAttractionConfig,
    /// End-effector position attraction toward the hand position of the command (on by default).
    pub ee_position: EeAttractionConfig,
    /// End-effector orientation attraction through the three axis task spaces (off by default).
    pub ee_orientation: EeAttractionConfig,
    /// Joint-limit repulsion: x = q − q_low − margin and x = q_up − margin − q (rad).
    pub joint_limits: BarrierConfig,
    /// Self-collision repulsion between sphere pairs: x = ‖c_a − c_b‖ − r_a − r_b − margin (m).
    pub self_collision: BarrierConfig,
    /// Obstacle repulsion for every robot sphere: x = d(c) − r − margin (m).
    pub obstacles: BarrierConfig,
    /// Speed control.
    pub speed: SpeedConfig,
}

impl Default for FabricConfig {
    fn default() -> Self {
        Self {
            mode: Mode::Bent,
            joint_attraction: JointAttractionConfig::default(),
            ee_position: EeAttractionConfig::position_default(),
            ee_orientation: EeAttractionConfig::orientation_default(),
            joint_limits: BarrierConfig::joint_limit_default(),
            self_collision: BarrierConfig::self_collision_default(),
            obstacles: BarrierConfig::obstacle_default(),
            speed: SpeedConfig::default(),
        }
    }
}

fn format_error(source: &str, field: &str, message: impl Into<String>) -> FabricError {
    FabricError::Format {
        file: source.to_string(),
        field: field.to_string(),
        message: message.into(),
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "a table",
    }
}

/// Merge `user` over `base` (the defaults), checking field names and value kinds against `base`; errors
/// name `source` (the file, or the configuration's kind) and the dotted field path.
pub(crate) fn merge(base: &mut Value, user: Value, path: &str, source: &str) -> Result<()> {
    match (base, user) {
        (Value::Object(b), Value::Object(u)) => {
            for (key, value) in u {
                let sub = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                match b.get_mut(&key) {
                    Some(slot) => merge(slot, value, &sub, source)?,
                    None => {
                        let known: Vec<&str> = b.keys().map(|k| k.as_str()).collect();
                        return Err(format_error(
                            source,
                            &sub,
                            format!("unknown field (expected one of: {})", known.join(", ")),
                        ));
                    }
                }
            }
            Ok(())
        }
        (slot, value) => {
            let same = matches!(
                (&*slot, &value),
                (Value::Bool(_), Value::Bool(_))
                    | (Value::Number(_), Value::Number(_))
                    | (Value::String(_), Value::String(_))
            );
            if !same {
                return Err(format_error(
                    source,
                    path,
                    format!("expected {}, got {}", kind(slot), kind(&value)),
                ));
            }
            *slot = value;
            Ok(())
        }
    }
}

/// The first string field of a merged configuration tree whose value names no variant of its enum.
fn bad_variant(v: &Value) -> Option<&'static str> {
    fn fails<T: serde::de::DeserializeOwned>(v: Option<&Value>) -> bool {
        v.is_some_and(|x| serde_json::from_value::<T>(x.clone()).is_err())
    }
    let speed = v.get("speed");
    if fails::<Mode>(v.get("mode")) {
        Some("mode")
    } else if fails::<GoalDampingForm>(speed.and_then(|s| s.get("goal_damping_form"))) {
        Some("speed.goal_damping_form")
    } else if fails::<GoalSpace>(speed.and_then(|s| s.get("goal_space"))) {
        Some("speed.goal_space")
    } else {
        None
    }
}

impl FabricConfig {
    /// Parse a configuration from an already-decoded tree, merging it over the defaults.
    fn from_value(user: Value, source: &str) -> Result<Self> {
        let user = match user {
            Value::Null => Value::Object(Default::default()),
            v @ Value::Object(_) => v,
            other => {
                return Err(format_error(
                    source,
                    "<root>",
                    format!("expected a table, got {}", kind(&other)),
                ))
            }
        };
        let mut base = serde_json::to_value(FabricConfig::default())
            .map_err(|e| format_error(source, "<root>", e.to_string()))?;
        merge(&mut base, user, "", source)?;
        // the merge checked names and kinds: what can still fail is a string that names no variant
        let field = bad_variant(&base).unwrap_or("<root>");
        let cfg: FabricConfig =
            serde_json::from_value(base).map_err(|e| format_error(source, field, e.to_string()))?;
        cfg.validate_named(source)?;
        Ok(cfg)
    }

    /// Parse TOML text (`source` names the file in errors). Missing fields take their defaults.
    pub fn from_toml_str(s: &str, source: &str) -> Result<Self> {
        let v: Value =
            toml::from_str(s).map_err(|e| format_error(source, "<toml>", e.to_string()))?;
        Self::from_value(v, source)
    }

    /// Parse YAML text (`source` names the file in errors). Missing fields take their defaults.
    pub fn from_yaml_str(s: &str, source: &str) -> Result<Self> {
        crate::limits::check_yaml(s).map_err(|m| format_error(source, "<yaml>", m))?;
        let v: Value =
            serde_yaml::from_str(s).map_err(|e| format_error(source, "<yaml>", e.to_string()))?;
        Self::from_value(v, source)
    }

    /// Parse JSON text (`source` names the file in errors). Missing fields take their defaults.
    pub fn from_json_str(s: &str, source: &str) -> Result<Self> {
        let v: Value =
            serde_json::from_str(s).map_err(|e| format_error(source, "<json>", e.to_string()))?;
        Self::from_value(v, source)
    }

    /// Read a file, choosing the format by extension (.toml, .yaml/.yml, .json).
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| FabricError::Io {
            path: name.clone(),
            message: e.to_string(),
        })?;
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref()
        {
            Some("toml") => Self::from_toml_str(&text, &name),
            Some("yaml") | Some("yml") => Self::from_yaml_str(&text, &name),
            Some("json") => Self::from_json_str(&text, &name),
            _ => Err(format_error(
                &name,
                "<file>",
                "unknown extension (expected .toml, .yaml, .yml or .json)",
            )),
        }
    }

    /// The configuration as pretty JSON (every field, so it round-trips through `from_json_str`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|_| String::from("{}"))
    }

    /// Check ranges: every number finite; gains, margins ≥ 0; masses, x_min, influence, speeds > 0 where
    /// the formulas divide by them.
    pub fn validate(&self) -> Result<()> {
        self.validate_named("fabric config")
    }

    fn validate_named(&self, source: &str) -> Result<()> {
        let err = |field: &str, msg: &str| Err(format_error(source, field, msg));
        let check = |field: &str, v: f64, positive: bool| -> Result<()> {
            if !v.is_finite() {
                return err(field, "must be finite");
            }
            if positive && v <= 0.0 {
                return err(field, "must be > 0");
            }
            if !positive && v < 0.0 {
                return err(field, "must be >= 0");
            }
            Ok(())
        };
        let log_cosh = |name: &str, c: &LogCoshConfig| -> Result<()> {
            check(&format!("{name}.gain"), c.gain, false)?;
            check(&format!("{name}.sharpness"), c.sharpness, true)
        };
        let barrier_pot = |name: &str, c: &BarrierPotentialConfig| -> Result<()> {
            check(&format!("{name}.barrier_gain"), c.barrier_gain, false)?;
            check(&format!("{name}.relu_gain"), c.relu_gain, false)?;
            check(&format!("{name}.relu_sharpness"), c.relu_sharpness, false)?;
            check(&format!("{name}.relu_shift"), c.relu_shift, false)
        };
        let ja = &self.joint_attraction;
        check("joint_attraction.mass", ja.mass, true)?;
        log_cosh("joint_attraction.geometry", &ja.geometry)?;
        log_cosh("joint_attraction.potential", &ja.potential)?;
        for (name, ee) in [
            ("ee_position", &self.ee_position),
            ("ee_orientation", &self.ee_orientation),
        ] {
            check(&format!("{name}.mass_max"), ee.mass_max, false)?;
            check(&format!("{name}.mass_min"), ee.mass_min, ee.enabled)?;
            check(&format!("{name}.mass_sharpness"), ee.mass_sharpness, false)?;
            // the mass blends from mass_max far from the target down to mass_min at it
            if ee.mass_min > ee.mass_max {
                return Err(format_error(
                    source,
                    &format!("{name}.mass_min"),
                    format!("{} exceeds {name}.mass_max = {}", ee.mass_min, ee.mass_max),
                ));
            }
            log_cosh(&format!("{name}.geometry"), &ee.geometry)?;
            log_cosh(&format!("{name}.potential"), &ee.potential)?;
        }
        for (name, b) in [
            ("joint_limits", &self.joint_limits),
            ("self_collision", &self.self_collision),
            ("obstacles", &self.obstacles),
        ] {
            check(&format!("{name}.metric_gain"), b.metric_gain, false)?;
            check(&format!("{name}.margin"), b.margin, false)?;
            check(&format!("{name}.influence"), b.influence, true)?;
            check(&format!("{name}.x_min"), b.x_min, true)?;
            check(
                &format!("{name}.min_curvature_radius"),
                b.min_curvature_radius,
                false,
            )?;
            check(&format!("{name}.braking_time"), b.braking_time, false)?;
            barrier_pot(&format!("{name}.geometry"), &b.geometry)?;
            barrier_pot(&format!("{name}.potential"), &b.potential)?;
        }
        let s = &self.speed;
        check("speed.desired_speed", s.desired_speed, true)?;
        check("speed.ee_weight", s.ee_weight, false)?;
        check("speed.eta_rate", s.eta_rate, false)?;
        if !s.eta_shift.is_finite() {
            return err("speed.eta_shift", "must be finite");
        }
        check("speed.goal_damping", s.goal_damping, false)?;
        check("speed.base_damping", s.base_damping, false)?;
        check(
            "speed.goal_switch_sharpness",
            s.goal_switch_sharpness,
            false,
        )?;
        check("speed.goal_switch_radius", s.goal_switch_radius, false)?;
        check("speed.boost_gain", s.boost_gain, false)?;
        check("speed.boost_epsilon", s.boost_epsilon, true)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_default_file_equals_default() {
        let text = include_str!("../../assets/fabric_default.toml");
        let parsed = FabricConfig::from_toml_str(text, "fabric_default.toml").unwrap();
        assert_eq!(parsed, FabricConfig::default());
        // and every field is spelled out in the file (no silent reliance on defaults)
        let raw: Value = toml::from_str(text).unwrap();
        let full = serde_json::to_value(FabricConfig::default()).unwrap();
        fn same_keys(a: &Value, b: &Value, path: &str) {
            if let (Value::Object(x), Value::Object(y)) = (a, b) {
                for k in y.keys() {
                    assert!(x.contains_key(k), "fabric_default.toml lacks {path}.{k}");
                    same_keys(&x[k], &y[k], &format!("{path}.{k}"));
                }
            }
        }
        same_keys(&raw, &full, "");
    }

    #[test]
    fn partial_files_merge_over_defaults_in_three_formats() {
        let t = FabricConfig::from_toml_str("mode = \"unbent\"\n[obstacles]\nmetric_gain = 2.5\n[obstacles.potential]\nrelu_gain = 0.7\n", "a.toml").unwrap();
        let y = FabricConfig::from_yaml_str(
            "mode: unbent\nobstacles:\n  metric_gain: 2.5\n  potential: {relu_gain: 0.7}\n",
            "a.yaml",
        )
        .unwrap();
        let j = FabricConfig::from_json_str(r#"{"mode": "unbent", "obstacles": {"metric_gain": 2.5, "potential": {"relu_gain": 0.7}}}"#, "a.json").unwrap();
        assert_eq!(t, y);
        assert_eq!(t, j);
        assert_eq!(t.mode, Mode::Unbent);
        assert_eq!(t.obstacles.metric_gain, 2.5);
        assert_eq!(t.obstacles.potential.relu_gain, 0.7);
        assert_eq!(
            t.obstacles.potential.barrier_gain,
            FabricConfig::default().obstacles.potential.barrier_gain
        );
        // untouched fields of the same table keep the obstacle-specific defaults
        assert_eq!(
            t.obstacles.influence,
            FabricConfig::default().obstacles.influence
        );
        assert_eq!(t.joint_limits, FabricConfig::default().joint_limits);
        assert_eq!(
            FabricConfig::from_yaml_str("", "empty.yaml").unwrap(),
            FabricConfig::default()
        );
        // round trip through to_json
        let back = FabricConfig::from_json_str(&t.to_json(), "rt.json").unwrap();
        assert_eq!(back, t);
    }

    #[test]
    fn errors_name_file_and_field() {
        let e = FabricConfig::from_toml_str("[obstacles]\nmetric_gian = 1.0\n", "cfg.toml")
            .unwrap_err();
        match e {
            FabricError::Format { file, field, .. } => {
                assert_eq!(file, "cfg.toml");
                assert_eq!(field, "obstacles.metric_gian");
            }
            other => panic!("unexpected {other:?}"),
        }
        let e =
            FabricConfig::from_yaml_str("speed:\n  desired_speed: fast\n", "cfg.yaml").unwrap_err();
        assert!(
            matches!(e, FabricError::Format { ref field, .. } if field == "speed.desired_speed"),
            "{e:?}"
        );
        let e = FabricConfig::from_json_str(r#"{"speed": {"desired_speed": -1.0}}"#, "cfg.json")
            .unwrap_err();
        assert!(
            matches!(e, FabricError::Format { ref field, ref file, .. } if field == "speed.desired_speed" && file == "cfg.json")
        );
        let e = FabricConfig::from_json_str(r#"{"mode": "bendy"}"#, "m.json").unwrap_err();
        assert!(matches!(e, FabricError::Format { ref field, .. } if field == "mode"));
        for (text, name) in [
            (r#"{"speed": {"goal_space": "hand"}}"#, "speed.goal_space"),
            (
                r#"{"speed": {"goal_damping_form": "both"}}"#,
                "speed.goal_damping_form",
            ),
        ] {
            let e = FabricConfig::from_json_str(text, "s.json").unwrap_err();
            assert!(
                matches!(e, FabricError::Format { ref field, ref message, .. } if field == name && message.contains("unknown variant")),
                "{e:?}"
            );
        }
        let e = FabricConfig::from_json_str("[1, 2]", "arr.json").unwrap_err();
        assert!(matches!(e, FabricError::Format { .. }));
        let e = FabricConfig::from_toml_str("joint_attraction = 3", "x.toml").unwrap_err();
        assert!(matches!(e, FabricError::Format { ref field, .. } if field == "joint_attraction"));
        let e = FabricConfig::from_json_str(r#"{"joint_attraction": {"mass": 0.0}}"#, "z.json")
            .unwrap_err();
        assert!(
            matches!(e, FabricError::Format { ref field, .. } if field == "joint_attraction.mass")
        );
        assert!(FabricConfig::from_toml_str("not toml = = 1", "bad.toml").is_err());
    }
}
