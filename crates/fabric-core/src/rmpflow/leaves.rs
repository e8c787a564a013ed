//! The leaf RMPs in canonical form (acceleration a, metric M) on their task spaces (Cheng et al. 2018,
//! App. D; the designs of the RMP² Franka RMPflow, see [`config`](super::config)). The task maps (x, ẋ,
//! J, J̇q̇) are the fabric's: robot points from the kinematics and the distance leaves of
//! [`fabric::leaves`](crate::fabric::leaves).

use nalgebra::{Matrix3, Vector3};

use super::config::{CollisionRmp, CspaceTargetRmp, DampingRmp, JointLimitRmp, TargetRmp};

/// A 1-D leaf RMP: metric m ≥ 0 and acceleration a.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rmp1 {
    /// Metric (weight).
    pub m: f64,
    /// Acceleration in the task space.
    pub a: f64,
}

fn sigmoid(x: f64) -> f64 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

/// Posture attractor on x = q − q_g: writes a (n,) into `accel` and returns the scalar metric of M = m I.
pub fn cspace_target(c: &CspaceTargetRmp, x: &[f64], xd: &[f64], accel: &mut [f64]) -> f64 {
    let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    let scale = if norm < c.robust_position_term_thresh {
        c.position_gain
    } else {
        c.position_gain * c.robust_position_term_thresh / norm
    };
    for ((a, &xi), &vi) in accel.iter_mut().zip(x).zip(xd) {
        *a = -scale * xi - c.damping_gain * vi;
    }
    c.metric_scalar + c.inertia
}

/// Joint-limit leaf on the distance x (rad or m, to the buffered limit) and its rate ẋ.
pub fn joint_limit(c: &JointLimitRmp, x: f64, xd: f64) -> Rmp1 {
    let x = x.max(0.0);
    let m = c.metric_scalar / (x / c.metric_length_scale + c.metric_exploder_eps)
        * (1.0 - sigmoid(xd / c.metric_velocity_gate_length_scale));
    let s = x / c.accel_potential_exploder_length_scale;
    let a = c.accel_potential_gain / (s * s + c.accel_potential_exploder_eps)
        - c.accel_damper_gain * xd;
    Rmp1 { m, a }
}

/// Collision leaf on the clearance x (m, the margin already subtracted) and its rate ẋ (m/s).
pub fn collision(c: &CollisionRmp, x: f64, xd: f64) -> Rmp1 {
    let x = x.max(0.0);
    let gate = 1.0 - sigmoid(xd / c.damping_velocity_gate_length_scale);
    let r = c.metric_modulation_radius;
    let m = if x > r {
        0.0
    } else {
        let modulation = (1.0 - x / r) * (1.0 - x / r);
        gate * c.metric_scalar / (x / c.metric_exploder_std_dev + c.metric_exploder_eps)
            * modulation
    };
    let repel = c.repulsion_gain * (-x / c.repulsion_std_dev).exp();
    let mut rate = c.damping_gain / (x / c.damping_std_dev + c.damping_robustness_eps);
    if c.max_damping_rate > 0.0 {
        rate = rate.min(c.max_damping_rate);
    }
    let damp = gate * rate * xd;
    Rmp1 { m, a: repel - damp }
}

/// End-effector attractor at position `x` with velocity `xd` toward `goal`: (a, M) in the world frame.
pub fn target(
    c: &TargetRmp,
    x: &Vector3<f64>,
    xd: &Vector3<f64>,
    goal: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3<f64>) {
    let delta = goal - x;
    let dist = delta.norm();
    let accel = delta * (c.accel_p_gain / (dist + c.accel_norm_eps)) - xd * c.accel_d_gain;
    let hat = delta / dist.max(c.accel_norm_eps / 10.0);
    let s = dist / c.metric_alpha_length_scale;
    let alpha = (1.0 - c.min_metric_alpha) * (-0.5 * s * s).exp() + c.min_metric_alpha;
    let sb = dist / c.proximity_metric_boost_length_scale;
    let near = (-0.5 * sb * sb).exp();
    let boost = near * c.proximity_metric_boost_scalar + (1.0 - near);
    let metric = (Matrix3::identity() * (alpha * c.max_metric_scalar)
        + hat * hat.transpose() * ((1.0 - alpha) * c.min_metric_scalar))
        * boost;
    (accel, metric)
}

/// Joint damping on x = q: writes a (n,) into `accel` and returns the scalar metric of M = m I.
pub fn damping(c: &DampingRmp, qd: &[f64], accel: &mut [f64]) -> f64 {
    let speed = qd.iter().map(|v| v * v).sum::<f64>().sqrt();
    for (a, &v) in accel.iter_mut().zip(qd) {
        *a = -c.accel_d_gain * speed * v;
    }
    c.metric_scalar * speed + c.inertia
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collision_metric_is_gated_by_approach_and_range() {
        let c = CollisionRmp::default();
        // the damping rate is capped at max_damping_rate (and uncapped with 0, the default)
        let mut capped_cfg = c.clone();
        capped_cfg.max_damping_rate = 50.0;
        let capped = collision(&capped_cfg, 0.0, -0.1).a - c.repulsion_gain;
        let raw = c.clone();
        let uncapped = collision(&raw, 0.0, -0.1).a - c.repulsion_gain;
        let gate = 1.0 - sigmoid(-10.0);
        assert!((capped - gate * 50.0 * 0.1).abs() < 1e-9);
        assert!((uncapped - gate * 5000.0 * 0.1).abs() < 1e-6);
        let approaching = collision(&c, 0.02, -0.5);
        let leaving = collision(&c, 0.02, 0.5);
        assert!(approaching.m > 100.0 * leaving.m);
        assert_eq!(collision(&c, 0.6, -0.5).m, 0.0);
        // at rest: metric (m/(x/σ + ε))(1 − x/r)²/2 and pure repulsion
        let rest = collision(&c, 0.02, 0.0);
        let want = 0.5 * 1.0 / (0.02 / 0.02 + 0.001) * (1.0 - 0.02 / 0.5_f64).powi(2);
        assert!((rest.m - want).abs() < 1e-12);
        assert!((rest.a - 800.0 * (-2.0_f64).exp()).abs() < 1e-9);
    }

    #[test]
    fn target_points_at_the_goal_and_its_metric_grows_near_it() {
        let c = TargetRmp::default();
        let goal = Vector3::new(0.5, 0.0, 0.3);
        let far = Vector3::new(0.0, 0.0, 0.3);
        let (a, m_far) = target(&c, &far, &Vector3::zeros(), &goal);
        assert!(a.x > 0.0 && a.y.abs() < 1e-15 && a.z.abs() < 1e-15);
        let (_, m_near) = target(
            &c,
            &(goal - Vector3::new(0.001, 0.0, 0.0)),
            &Vector3::zeros(),
            &goal,
        );
        assert!(m_near.trace() > 5.0 * m_far.trace());
        assert!((m_far - m_far.transpose()).norm() < 1e-15);
        // far away the metric is mostly along the direction to the goal
        assert!(m_far[(0, 0)] > 10.0 * m_far[(1, 1)]);
    }

    #[test]
    fn damping_and_cspace_target_oppose_motion_and_offset() {
        let mut a = [0.0; 2];
        let m = damping(&DampingRmp::default(), &[3.0, 4.0], &mut a);
        assert_eq!(a, [-30.0 * 5.0 * 3.0, -30.0 * 5.0 * 4.0]);
        assert!((m - (0.005 * 5.0 + 0.3)).abs() < 1e-15);
        let c = CspaceTargetRmp::default();
        cspace_target(&c, &[0.1, 0.0], &[0.0, 0.0], &mut a);
        assert!((a[0] + 10.0).abs() < 1e-12);
        cspace_target(&c, &[2.0, 0.0], &[0.0, 0.0], &mut a);
        assert!((a[0] + 50.0).abs() < 1e-12, "saturates at k_p θ");
    }

    #[test]
    fn joint_limit_pushes_away_and_weighs_only_while_approaching() {
        let c = JointLimitRmp::default();
        let near = joint_limit(&c, 0.005, -0.1);
        assert!(near.a > 0.0 && near.m > 0.1);
        assert!(joint_limit(&c, 0.005, 0.1).m < 1e-3);
    }
}
