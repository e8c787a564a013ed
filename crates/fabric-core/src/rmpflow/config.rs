//! [`RmpConfig`]: the gains of the RMPflow leaves (Cheng et al. 2018, "RMPflow: A Computational Graph for
//! Automatic Motion Policy Generation", Sec. 3 and App. D), with defaults taken from the hand-designed
//! Franka RMPflow of RMP² (Li et al. 2021, `rmp2/configs/franka_config.yaml`: the leaf designs of NVIDIA's
//! Lula RMPflow). Parsed from JSON merged over the defaults; unknown fields are rejected and every error
//! names the field.
//!
//! Units: distances m (joint-space distances rad), velocities m/s, accelerations m/s², metrics are
//! dimensionless weights (only their ratios matter at the root, where a = M⁺f).

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::{FabricError, Result};

/// Posture attractor in joint space on x = q − q_g (J = I): a = −k_p x (−k_p θ x̂ for ‖x‖ > θ) − k_d ẋ,
/// M = (m + m₀) I.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CspaceTargetRmp {
    /// Whether the leaf is in the tree.
    pub enabled: bool,
    /// m: metric weight.
    pub metric_scalar: f64,
    /// k_p (1/s²).
    pub position_gain: f64,
    /// k_d (1/s).
    pub damping_gain: f64,
    /// θ (rad): beyond it the position term saturates at k_p θ.
    pub robust_position_term_thresh: f64,
    /// m₀: metric added to `metric_scalar`.
    pub inertia: f64,
}

impl Default for CspaceTargetRmp {
    fn default() -> Self {
        Self {
            enabled: true,
            metric_scalar: 0.005,
            position_gain: 100.0,
            damping_gain: 50.0,
            robust_position_term_thresh: 0.5,
            inertia: 0.0001,
        }
    }
}

/// Joint-limit leaf per joint and side on x = q − (q_low + b) and (q_up − b) − q (J = ±e_i), x clamped at
/// 0: M = m / (x/ℓ + ε) · (1 − σ(ẋ/ℓ_v)) (heavy only near the limit and while approaching it),
/// a = g / ((x/ℓ_p)² + ε_p) − k_d ẋ.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointLimitRmp {
    /// Whether the leaves are in the tree.
    pub enabled: bool,
    /// b (rad or m): buffer inside each limit.
    pub buffer: f64,
    /// m.
    pub metric_scalar: f64,
    /// ℓ (rad).
    pub metric_length_scale: f64,
    /// ε.
    pub metric_exploder_eps: f64,
    /// ℓ_v (rad/s).
    pub metric_velocity_gate_length_scale: f64,
    /// k_d (1/s).
    pub accel_damper_gain: f64,
    /// g (rad/s²).
    pub accel_potential_gain: f64,
    /// ℓ_p (rad).
    pub accel_potential_exploder_length_scale: f64,
    /// ε_p.
    pub accel_potential_exploder_eps: f64,
}

impl Default for JointLimitRmp {
    fn default() -> Self {
        Self {
            enabled: true,
            buffer: 0.01,
            metric_scalar: 0.1,
            metric_length_scale: 0.01,
            metric_exploder_eps: 0.001,
            metric_velocity_gate_length_scale: 0.01,
            accel_damper_gain: 200.0,
            accel_potential_gain: 1.0,
            accel_potential_exploder_length_scale: 0.1,
            accel_potential_exploder_eps: 0.01,
        }
    }
}

/// End-effector position attractor on x = p_ee (m), target g, δ = g − x:
/// a = k_p δ/(‖δ‖ + ε) − k_d ẋ; M = b(‖δ‖) [α M̄ I + (1 − α) M̲ δ̂δ̂ᵀ] with
/// α = (1 − α_min) exp(−½(‖δ‖/ℓ)²) + α_min and the proximity boost b = 1 + (B − 1) exp(−½(‖δ‖/ℓ_b)²).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TargetRmp {
    /// Whether the leaf is in the tree.
    pub enabled: bool,
    /// k_p (m/s²).
    pub accel_p_gain: f64,
    /// k_d (1/s).
    pub accel_d_gain: f64,
    /// ε (m).
    pub accel_norm_eps: f64,
    /// ℓ (m).
    pub metric_alpha_length_scale: f64,
    /// α_min.
    pub min_metric_alpha: f64,
    /// M̄.
    pub max_metric_scalar: f64,
    /// M̲.
    pub min_metric_scalar: f64,
    /// B.
    pub proximity_metric_boost_scalar: f64,
    /// ℓ_b (m).
    pub proximity_metric_boost_length_scale: f64,
}

impl Default for TargetRmp {
    fn default() -> Self {
        Self {
            enabled: true,
            accel_p_gain: 50.0,
            accel_d_gain: 70.0,
            accel_norm_eps: 0.075,
            metric_alpha_length_scale: 0.05,
            min_metric_alpha: 0.03,
            max_metric_scalar: 1.0,
            min_metric_scalar: 0.5,
            proximity_metric_boost_scalar: 3.0,
            proximity_metric_boost_length_scale: 0.02,
        }
    }
}

/// Collision leaf on a distance x = d − margin (m, clamped at 0), the same sphere–obstacle and
/// sphere–sphere task maps as the fabric's barriers: with the velocity gate s = σ(ẋ/ℓ_v),
/// M = (1 − s) m / (x/σ_m + ε_m) · (1 − x/r)² for x < r (0 beyond),
/// a = k_r exp(−x/σ_r) − (1 − s) min(k_d / (x/σ_d + ε_d), β_max) ẋ.
///
/// β_max (`max_damping_rate`, off by default) is an option beyond the RMP² design: its damping rate
/// reaches k_d/ε_d = 5000 /s at contact, and explicit Euler at Δt diverges for rates above 2/Δt (200 /s
/// at 100 Hz). On the GF VII-D task at 100 Hz RMPflow as written diverged in 6 of 10 seeds, and in the
/// same 6 with β_max = 50 /s (the repulsion's 1 cm length scale and the velocity gates are stiff too), so
/// the experiments integrate RMPflow at 1 kHz instead.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CollisionRmp {
    /// Whether the leaves are in the tree.
    pub enabled: bool,
    /// Safety margin subtracted from the distance (m).
    pub margin: f64,
    /// A leaf exists while x (after the margin) < influence (m); the metric vanishes from r on anyway.
    pub influence: f64,
    /// ρ (m): the curvature of the distance field in J̇q̇ is bounded by 1/ρ, as in the fabric's leaves
    /// (`fabric::leaves`); 0 = exact.
    pub min_curvature_radius: f64,
    /// k_d (m/s² per m/s at x = 0, divided by ε_d).
    pub damping_gain: f64,
    /// σ_d (m).
    pub damping_std_dev: f64,
    /// ε_d.
    pub damping_robustness_eps: f64,
    /// β_max (1/s): cap of the damping rate; 0 = none (RMP² as written).
    pub max_damping_rate: f64,
    /// ℓ_v (m/s).
    pub damping_velocity_gate_length_scale: f64,
    /// k_r (m/s²).
    pub repulsion_gain: f64,
    /// σ_r (m).
    pub repulsion_std_dev: f64,
    /// r (m).
    pub metric_modulation_radius: f64,
    /// m.
    pub metric_scalar: f64,
    /// σ_m (m).
    pub metric_exploder_std_dev: f64,
    /// ε_m.
    pub metric_exploder_eps: f64,
}

impl Default for CollisionRmp {
    fn default() -> Self {
        Self {
            enabled: true,
            margin: 0.0,
            influence: 0.5,
            min_curvature_radius: 0.3,
            damping_gain: 50.0,
            damping_std_dev: 0.04,
            damping_robustness_eps: 0.01,
            max_damping_rate: 0.0,
            damping_velocity_gate_length_scale: 0.01,
            repulsion_gain: 800.0,
            repulsion_std_dev: 0.01,
            metric_modulation_radius: 0.5,
            metric_scalar: 1.0,
            metric_exploder_std_dev: 0.02,
            metric_exploder_eps: 0.001,
        }
    }
}

impl CollisionRmp {
    /// Self-collision: the obstacle design within 5 cm (the fabric's self-collision influence) and a
    /// 2 mm margin (the fabric's).
    fn self_collision_default() -> Self {
        Self {
            margin: 0.002,
            influence: 0.05,
            metric_modulation_radius: 0.05,
            ..Self::default()
        }
    }
}

/// Joint-space damping on x = q (J = I): a = −k_d ‖q̇‖ q̇, M = (m ‖q̇‖ + m₀) I.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DampingRmp {
    /// Whether the leaf is in the tree.
    pub enabled: bool,
    /// k_d (1/rad).
    pub accel_d_gain: f64,
    /// m (s/rad).
    pub metric_scalar: f64,
    /// m₀.
    pub inertia: f64,
}

impl Default for DampingRmp {
    fn default() -> Self {
        Self {
            enabled: true,
            accel_d_gain: 30.0,
            metric_scalar: 0.005,
            inertia: 0.3,
        }
    }
}

fn self_collision_default() -> CollisionRmp {
    CollisionRmp::self_collision_default()
}

/// Every leaf of the RMPflow tree with its gains (see the module docs for the sources of the defaults).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RmpConfig {
    /// Posture attractor to the command.
    pub cspace_target: CspaceTargetRmp,
    /// Joint-limit leaves.
    pub joint_limits: JointLimitRmp,
    /// End-effector position attractor.
    pub target: TargetRmp,
    /// Sphere–obstacle collision leaves.
    pub obstacles: CollisionRmp,
    /// Sphere–sphere self-collision leaves (the robot's self-collision pairs).
    #[serde(default = "self_collision_default")]
    pub self_collision: CollisionRmp,
    /// Joint damping.
    pub damping: DampingRmp,
}

impl Default for RmpConfig {
    fn default() -> Self {
        Self {
            cspace_target: CspaceTargetRmp::default(),
            joint_limits: JointLimitRmp::default(),
            target: TargetRmp::default(),
            obstacles: CollisionRmp::default(),
            self_collision: CollisionRmp::self_collision_default(),
            damping: DampingRmp::default(),
        }
    }
}

fn format_error(field: &str, message: impl Into<String>) -> FabricError {
    FabricError::Format {
        file: "rmpflow config".into(),
        field: field.into(),
        message: message.into(),
    }
}

impl RmpConfig {
    /// The configuration given by the JSON text `s` merged over the defaults, validated.
    pub fn from_json_str(s: &str) -> Result<Self> {
        let user: Value =
            serde_json::from_str(s).map_err(|e| format_error("<json>", e.to_string()))?;
        let user = match user {
            Value::Null => Value::Object(Default::default()),
            v @ Value::Object(_) => v,
            other => {
                return Err(format_error(
                    "<root>",
                    format!("expected a table, got {other}"),
                ))
            }
        };
        let mut base = serde_json::to_value(RmpConfig::default())
            .map_err(|e| format_error("<root>", e.to_string()))?;
        crate::fabric::config::merge(&mut base, user, "", "rmpflow config")?;
        let cfg: RmpConfig =
            serde_json::from_value(base).map_err(|e| format_error("<root>", e.to_string()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Every field as pretty JSON (round-trips through [`RmpConfig::from_json_str`]).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|_| String::from("{}"))
    }

    /// Every number finite and ≥ 0; the length scales and epsilons the leaves divide by > 0.
    pub fn validate(&self) -> Result<()> {
        let v = serde_json::to_value(self).map_err(|e| format_error("<root>", e.to_string()))?;
        check_tree(&v, "")?;
        let positive: [(&str, f64); 15] = [
            (
                "cspace_target.robust_position_term_thresh",
                self.cspace_target.robust_position_term_thresh,
            ),
            (
                "joint_limits.metric_length_scale",
                self.joint_limits.metric_length_scale,
            ),
            (
                "joint_limits.metric_exploder_eps",
                self.joint_limits.metric_exploder_eps,
            ),
            (
                "joint_limits.metric_velocity_gate_length_scale",
                self.joint_limits.metric_velocity_gate_length_scale,
            ),
            (
                "joint_limits.accel_potential_exploder_length_scale",
                self.joint_limits.accel_potential_exploder_length_scale,
            ),
            (
                "joint_limits.accel_potential_exploder_eps",
                self.joint_limits.accel_potential_exploder_eps,
            ),
            ("target.accel_norm_eps", self.target.accel_norm_eps),
            (
                "target.metric_alpha_length_scale",
                self.target.metric_alpha_length_scale,
            ),
            (
                "target.proximity_metric_boost_length_scale",
                self.target.proximity_metric_boost_length_scale,
            ),
            ("damping.inertia", self.damping.inertia),
            (
                "cspace_target.inertia + metric_scalar",
                self.cspace_target.inertia + self.cspace_target.metric_scalar,
            ),
            (
                "obstacles.metric_modulation_radius",
                self.obstacles.metric_modulation_radius,
            ),
            (
                "self_collision.metric_modulation_radius",
                self.self_collision.metric_modulation_radius,
            ),
            ("target.min_metric_alpha", self.target.min_metric_alpha),
            ("target.max_metric_scalar", self.target.max_metric_scalar),
        ];
        for (field, x) in positive {
            if x <= 0.0 {
                return Err(format_error(field, "must be > 0"));
            }
        }
        for (name, c) in [
            ("obstacles", &self.obstacles),
            ("self_collision", &self.self_collision),
        ] {
            for (field, x) in [
                ("damping_std_dev", c.damping_std_dev),
                ("damping_robustness_eps", c.damping_robustness_eps),
                (
                    "damping_velocity_gate_length_scale",
                    c.damping_velocity_gate_length_scale,
                ),
                ("repulsion_std_dev", c.repulsion_std_dev),
                ("metric_exploder_std_dev", c.metric_exploder_std_dev),
                ("metric_exploder_eps", c.metric_exploder_eps),
                ("influence", c.influence),
            ] {
                if x <= 0.0 {
                    return Err(format_error(&format!("{name}.{field}"), "must be > 0"));
                }
            }
        }
        if self.target.min_metric_alpha > 1.0 {
            return Err(format_error("target.min_metric_alpha", "must be <= 1"));
        }
        Ok(())
    }
}

/// Every number of the tree finite and ≥ 0.
fn check_tree(v: &Value, path: &str) -> Result<()> {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let sub = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                check_tree(x, &sub)?;
            }
            Ok(())
        }
        Value::Number(n) => match n.as_f64() {
            Some(x) if x.is_finite() && x >= 0.0 => Ok(()),
            _ => Err(format_error(path, "must be finite and >= 0")),
        },
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_merges_over_the_defaults_and_names_bad_fields() {
        let c = RmpConfig::from_json_str(r#"{"target": {"accel_p_gain": 10.0}}"#).unwrap();
        assert_eq!(c.target.accel_p_gain, 10.0);
        assert_eq!(c.target.accel_d_gain, TargetRmp::default().accel_d_gain);
        assert_eq!(c.self_collision.influence, 0.05);
        let e = RmpConfig::from_json_str(r#"{"target": {"gain": 1.0}}"#).unwrap_err();
        assert!(e.to_string().contains("target.gain"), "{e}");
        let e =
            RmpConfig::from_json_str(r#"{"obstacles": {"repulsion_std_dev": 0.0}}"#).unwrap_err();
        assert!(e.to_string().contains("obstacles.repulsion_std_dev"), "{e}");
        let e = RmpConfig::from_json_str(r#"{"damping": {"accel_d_gain": -1}}"#).unwrap_err();
        assert!(e.to_string().contains("damping.accel_d_gain"), "{e}");
        let back = RmpConfig::from_json_str(&RmpConfig::default().to_json()).unwrap();
        assert_eq!(back, RmpConfig::default());
    }
}
