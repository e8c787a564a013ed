//! Speed control through damping regulation (GF Sec. V-A, App. E-B, eq. 40-46).
//!
//! The final acceleration is eq. 40,
//!
//! ```text
//! q̈ = −M̃⁻¹ ∂ψ + π̃ + α_reg q̇,
//! α_reg = α_ex^η − β_reg + α_boost                                   (eq. 44)
//! α_ex^η = η α_ex^0 + (1 − η) α_ex^ψ
//! β_reg = s_β(q) B + B̲ + max(0, α_ex^η − α_Le)
//! s_β = ½ (tanh(−α_β (‖q − q_g‖ − r)) + 1)                          (eq. 45)
//! η = ½ (tanh(−α_η (L_ex − L_ex,d) − α_shift) + 1)                   (eq. 46)
//! α_boost = k η (1 − s_β) / (‖q̇‖ + ε)
//! ```
//!
//! with the execution energy L_ex = ½ q̇ᵀM_ex q̇, M_ex = I + w J_eeᵀJ_ee, i.e. ½(‖q̇‖² + w‖ẋ_ee‖²)
//! (`SpeedConfig::ee_weight` = w; w = 0: ½‖q̇‖², M_ex = I, ξ_ex = 0), and L_ex,d = ½ v_d². α_ex^0 and α_ex^ψ
//! are the energization coefficients (eq. 7) of π̃ and of −M̃⁻¹∂ψ + π̃ with respect to L_ex: for an
//! acceleration a, dL_ex/dt = q̇ᵀa + w ẋ_eeᵀ(J_ee a + J̇_ee q̇) = gᵀa + c with g = M_ex q̇ and
//! c = w ẋ_eeᵀ J̇_ee q̇, so a + α q̇ conserves L_ex for α = −(gᵀa + c) / q̇ᵀM_ex q̇.
//!
//! The goal damper s_β B either sits inside β_reg as above (GF, [`GoalDampingForm::Velocity`]) or acts as
//! a force-level damper −s_β B m q̇ added by the root ([`GoalDampingForm::Force`], see its docs).
//!
//! Since α_reg = min(α_ex^η, α_Le) − s_β B − B̲ + α_boost, the system is always damped with respect to the
//! energized fabric (α_reg < α_Le when α_boost = 0), which is the stability condition of App. E-B.
//!
//! **q̇ = 0.** The coefficients divide by ‖q̇‖². Below [`SPEED_EPSILON`] they are set to 0: α_ex^0 → 0
//! continuously for HD2 π̃; α_ex^ψ q̇ stays bounded by ‖M̃⁻¹∂ψ‖ + ‖π̃‖, so the term α q̇ → 0 either way. At
//! rest the acceleration is −M̃⁻¹∂ψ: finite and nonzero away from the command (the potential starts the
//! motion, as the paper notes for α_boost).

use nalgebra::{Matrix3xX, Vector3};

use super::config::{GoalDampingForm, SpeedConfig};

/// ‖q̇‖² below which the execution-energy coefficients are 0 (rad²/s²).
pub const SPEED_EPSILON: f64 = 1e-12;

/// Inputs of speed regulation, all in joint space (length n).
#[derive(Clone, Copy, Debug)]
pub struct SpeedInputs<'a> {
    /// q̇ (rad/s).
    pub qd: &'a [f64],
    /// π̃ = −M̃⁻¹ f̃: the root geometry before energization (rad/s²).
    pub pi: &'a [f64],
    /// M̃⁻¹ ∂ψ: the acceleration of the forcing potential, with sign so that it enters as −M̃⁻¹∂ψ (rad/s²).
    pub minv_grad: &'a [f64],
    /// α_Le: energization coefficient of π̃ with respect to the fabric energy L̃_e (eq. 7; 1/s).
    pub alpha_le: f64,
    /// ‖q − q_g‖: distance to the command (rad), argument of s_β (eq. 45).
    pub goal_distance: f64,
    /// Motion of the end-effector point for the w‖ẋ_ee‖² part of L_ex; ignored when w = 0, treated as
    /// ẋ_ee = 0 when `None`.
    pub ee: Option<EeMotion<'a>>,
}

/// The end-effector point's velocity terms (world frame).
#[derive(Clone, Copy, Debug)]
pub struct EeMotion<'a> {
    /// ẋ_ee = J_ee q̇ (m/s).
    pub xd: Vector3<f64>,
    /// J_ee (3 × n, m/rad).
    pub jac: &'a Matrix3xX<f64>,
    /// J̇_ee q̇ (m/s²).
    pub jdot_qdot: Vector3<f64>,
}

/// q̇ᵀM_ex q̇ and the map a ↦ gᵀa + c of the module docs, for the execution energy of `cfg`.
struct ExecEnergy<'a> {
    qd: &'a [f64],
    /// ‖q̇‖² (rad²/s²).
    qd2: f64,
    /// w ẋ_ee and J_ee when w > 0 and the motion is given.
    ee: Option<(Vector3<f64>, &'a Matrix3xX<f64>)>,
    /// q̇ᵀM_ex q̇ (rad²/s²).
    v2: f64,
    /// c = w ẋ_eeᵀ J̇_ee q̇ (rad²/s³).
    c: f64,
}

impl<'a> ExecEnergy<'a> {
    fn new(cfg: &SpeedConfig, qd: &'a [f64], ee: Option<EeMotion<'a>>) -> Self {
        let qd2 = dot(qd, qd);
        let mut e = ExecEnergy {
            qd,
            qd2,
            ee: None,
            v2: qd2,
            c: 0.0,
        };
        if let Some(m) = ee.filter(|_| cfg.ee_weight > 0.0) {
            let wxd = cfg.ee_weight * m.xd;
            e.v2 += wxd.dot(&m.xd);
            e.c = wxd.dot(&m.jdot_qdot);
            e.ee = Some((wxd, m.jac));
        }
        e
    }

    /// gᵀa = q̇ᵀa + w ẋ_eeᵀ J_ee a.
    fn g_dot(&self, a: &[f64]) -> f64 {
        let mut s = dot(self.qd, a);
        if let Some((wxd, jac)) = self.ee {
            for (k, ak) in a.iter().enumerate() {
                s += ak * wxd.dot(&jac.column(k));
            }
        }
        s
    }
}

/// Every coefficient of the regulation, for diagnostics (all in 1/s unless stated).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedTerms {
    /// L_ex = ½‖q̇‖² (rad²/s²).
    pub exec_energy: f64,
    /// α_ex^0: energization of π̃ w.r.t. L_ex.
    pub alpha_ex0: f64,
    /// α_ex^ψ: energization of −M̃⁻¹∂ψ + π̃ w.r.t. L_ex.
    pub alpha_expsi: f64,
    /// η ∈ [0, 1] of eq. 46.
    pub eta: f64,
    /// α_ex^η = η α_ex^0 + (1 − η) α_ex^ψ.
    pub alpha_ex_eta: f64,
    /// s_β ∈ [0, 1] of eq. 45.
    pub s_beta: f64,
    /// β_reg (or, with speed control disabled, β = s_β B + B̲).
    pub beta: f64,
    /// α_boost.
    pub alpha_boost: f64,
    /// α_reg of eq. 44: the final coefficient of q̇ in eq. 40.
    pub alpha_reg: f64,
    /// s_β B when the goal damper is force-level ([`GoalDampingForm::Force`]), else 0 (1/s): the root
    /// adds the acceleration −(s_β B m) M̃⁻¹ q̇.
    pub force_damping: f64,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// s_β(d) = ½ (tanh(−α_β (d − r)) + 1) of eq. 45, for the distance d = ‖q − q_g‖.
pub fn goal_switch(cfg: &SpeedConfig, goal_distance: f64) -> f64 {
    0.5 * ((-cfg.goal_switch_sharpness * (goal_distance - cfg.goal_switch_radius)).tanh() + 1.0)
}

/// η of eq. 46 for the execution energy L_ex.
pub fn eta(cfg: &SpeedConfig, exec_energy: f64) -> f64 {
    let desired = 0.5 * cfg.desired_speed * cfg.desired_speed;
    0.5 * ((-cfg.eta_rate * (exec_energy - desired) - cfg.eta_shift).tanh() + 1.0)
}

/// Compute the regulation coefficients of eq. 44-46 (see module docs). With `cfg.enabled == false` the
/// result is the plain energized, forced and damped fabric: α_reg = α_Le − (s_β B + B̲).
pub fn regulate(cfg: &SpeedConfig, inp: &SpeedInputs<'_>) -> SpeedTerms {
    let ex = ExecEnergy::new(cfg, inp.qd, inp.ee);
    let exec_energy = 0.5 * ex.v2;
    let s_beta = goal_switch(cfg, inp.goal_distance);
    let (damping, force_damping) = match cfg.goal_damping_form {
        GoalDampingForm::Velocity => (s_beta * cfg.goal_damping + cfg.base_damping, 0.0),
        GoalDampingForm::Force => (cfg.base_damping, s_beta * cfg.goal_damping),
    };
    if !cfg.enabled {
        return SpeedTerms {
            exec_energy,
            s_beta,
            beta: damping,
            alpha_reg: inp.alpha_le - damping,
            force_damping,
            ..SpeedTerms::default()
        };
    }
    let (alpha_ex0, alpha_expsi) = if ex.v2 > SPEED_EPSILON {
        let g_pi = ex.g_dot(inp.pi) + ex.c;
        let g_grad = ex.g_dot(inp.minv_grad);
        (-g_pi / ex.v2, -(g_pi - g_grad) / ex.v2)
    } else {
        (0.0, 0.0)
    };
    let eta = eta(cfg, exec_energy);
    let alpha_ex_eta = eta * alpha_ex0 + (1.0 - eta) * alpha_expsi;
    let beta = damping + (alpha_ex_eta - inp.alpha_le).max(0.0);
    let alpha_boost = cfg.boost_gain * eta * (1.0 - s_beta) / (ex.qd2.sqrt() + cfg.boost_epsilon);
    SpeedTerms {
        exec_energy,
        alpha_ex0,
        alpha_expsi,
        eta,
        alpha_ex_eta,
        s_beta,
        beta,
        alpha_boost,
        alpha_reg: alpha_ex_eta - beta + alpha_boost,
        force_damping,
    }
}

/// Eq. 40: qdd = −M̃⁻¹∂ψ + π̃ + α_reg q̇ (all slices of length n).
pub fn regulated_acceleration(
    minv_grad: &[f64],
    pi: &[f64],
    alpha_reg: f64,
    qd: &[f64],
    qdd: &mut [f64],
) {
    for i in 0..qdd.len() {
        qdd[i] = -minv_grad[i] + pi[i] + alpha_reg * qd[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> SpeedConfig {
        SpeedConfig {
            boost_gain: 2.0,
            goal_damping_form: GoalDampingForm::Velocity,
            desired_speed: 1.2,
            goal_damping: 8.0,
            base_damping: 0.5,
            goal_switch_sharpness: 10.0,
            goal_switch_radius: 0.3,
            ..SpeedConfig::default()
        }
    }

    /// `regulate` at these inputs.
    fn at(
        c: &SpeedConfig,
        qd: &[f64],
        pi: &[f64],
        minv_grad: &[f64],
        alpha_le: f64,
        goal_distance: f64,
        ee: Option<EeMotion<'_>>,
    ) -> SpeedTerms {
        regulate(
            c,
            &SpeedInputs {
                qd,
                pi,
                minv_grad,
                alpha_le,
                goal_distance,
                ee,
            },
        )
    }

    #[test]
    fn at_rest_the_potential_drives_and_nothing_blows_up() {
        let c = cfg();
        let qd = [0.0; 3];
        let pi = [0.0; 3];
        let g = [0.5, -1.0, 0.2];
        let t = at(&c, &qd, &pi, &g, 0.0, 1.0, None);
        assert!(t.alpha_reg.is_finite() && t.alpha_boost.is_finite());
        let mut a = [0.0; 3];
        regulated_acceleration(&g, &pi, t.alpha_reg, &qd, &mut a);
        assert_eq!(a, [-0.5, 1.0, -0.2]);
        // tiny velocities: α q̇ stays bounded by ‖M⁻¹∂ψ‖ + ‖π‖ + boost gain
        for e in [1e-3, 1e-6, 1e-9] {
            let qd = [e, 0.3 * e, -e];
            let t = at(&c, &qd, &pi, &g, 0.0, 1.0, None);
            let n = dot(&qd, &qd).sqrt();
            assert!(
                (t.alpha_reg * n).abs() <= 1.2 + 2.0 + 1e-9,
                "{}",
                t.alpha_reg * n
            );
        }
    }

    #[test]
    fn closed_forms_of_the_coefficients() {
        let c = cfg();
        let qd = [1.0, 0.5];
        let pi = [0.2, -0.4];
        let g = [1.0, 1.0];
        let t = at(&c, &qd, &pi, &g, -0.1, 0.2, None);
        let v2 = 1.25;
        assert!((t.alpha_ex0 - 0.0 / v2).abs() < 1e-15); // q̇ᵀπ = 0.2 − 0.2 = 0
        assert!((t.alpha_expsi - 1.5 / v2).abs() < 1e-15);
        let eta = 0.5 * ((-c.eta_rate * (0.625 - 0.72)).tanh() + 1.0);
        assert!((t.eta - eta).abs() < 1e-15);
        let sb = 0.5 * ((-10.0f64 * (0.2 - 0.3)).tanh() + 1.0);
        assert!((t.s_beta - sb).abs() < 1e-15);
        let ex = eta * 0.0 + (1.0 - eta) * 1.5 / v2;
        assert!((t.beta - (sb * 8.0 + 0.5 + (ex + 0.1).max(0.0))).abs() < 1e-14);
        assert!(
            t.alpha_reg < -0.1 + t.alpha_boost,
            "damped w.r.t. the energized fabric"
        );
        // the execution energy is conserved by the η = 1 energized geometry: q̇ᵀ(π + α_ex^0 q̇) = 0
        let mut a = [0.0; 2];
        regulated_acceleration(&[0.0, 0.0], &pi, t.alpha_ex0, &qd, &mut a);
        assert!(dot(&qd, &a).abs() < 1e-15);
    }

    #[test]
    fn end_effector_weight_energizes_the_combined_execution_energy() {
        // L_ex = ½(‖q̇‖² + w‖J q̇‖²): dL_ex/dt along a = q̇ᵀa + w ẋᵀ(J a + J̇q̇) vanishes for a + α q̇
        let c = SpeedConfig {
            ee_weight: 4.0,
            ..cfg()
        };
        let qd = [0.7, -0.2, 0.4];
        let pi = [0.3, 1.1, -0.6];
        let g = [0.5, -1.0, 0.2];
        let jac = Matrix3xX::from_column_slice(&[0.1, 0.5, -0.2, 0.3, 0.0, 0.4, -0.6, 0.2, 0.1]);
        let xd = &jac * Vector3::from_row_slice(&qd);
        let jdot_qdot = Vector3::new(0.05, -0.3, 0.2);
        let ee = Some(EeMotion {
            xd,
            jac: &jac,
            jdot_qdot,
        });
        let t = at(&c, &qd, &pi, &g, 0.0, 1.0, ee);
        let v2 = dot(&qd, &qd) + 4.0 * xd.norm_squared();
        assert!((t.exec_energy - 0.5 * v2).abs() < 1e-15);
        let ldot = |a: &[f64]| {
            let ja = &jac * Vector3::from_row_slice(a);
            dot(&qd, a) + 4.0 * xd.dot(&(ja + jdot_qdot))
        };
        let mut a = [0.0; 3];
        regulated_acceleration(&[0.0; 3], &pi, t.alpha_ex0, &qd, &mut a);
        assert!(ldot(&a).abs() < 1e-14, "{}", ldot(&a));
        regulated_acceleration(&g, &pi, t.alpha_expsi, &qd, &mut a);
        assert!(ldot(&a).abs() < 1e-14, "{}", ldot(&a));
        // w = 0 (or no end-effector motion) is the C-space energy
        let plain = |w: f64, ee: Option<EeMotion<'_>>| {
            let c = SpeedConfig {
                ee_weight: w,
                ..cfg()
            };
            at(&c, &qd, &pi, &g, 0.0, 1.0, ee)
        };
        assert_eq!(plain(0.0, ee), plain(4.0, None));
        assert!((plain(0.0, ee).exec_energy - 0.5 * dot(&qd, &qd)).abs() < 1e-15);
    }

    #[test]
    fn eta_switches_around_desired_speed() {
        let c = SpeedConfig::default();
        let d = 0.5 * c.desired_speed * c.desired_speed;
        assert!((eta(&c, d) - 0.5).abs() < 1e-12);
        assert!(eta(&c, 0.0) > 0.99);
        assert!(eta(&c, d + 3.0) < 1e-6);
        assert!(goal_switch(&c, 0.0) > 0.9 && goal_switch(&c, 2.0) < 1e-6);
    }

    #[test]
    fn disabled_is_plain_damped_energization() {
        let c = SpeedConfig {
            enabled: false,
            goal_damping_form: GoalDampingForm::Velocity,
            ..SpeedConfig::default()
        };
        let t = at(&c, &[1.0], &[3.0], &[0.0], -3.0, 5.0, None);
        assert!((t.alpha_reg - (-3.0 - t.beta)).abs() < 1e-15);
        assert!((t.beta - (t.s_beta * c.goal_damping + c.base_damping)).abs() < 1e-15);
        assert_eq!(t.force_damping, 0.0);
        let f = SpeedConfig {
            goal_damping_form: GoalDampingForm::Force,
            ..c
        };
        let t = at(&f, &[1.0], &[3.0], &[0.0], -3.0, 0.0, None);
        assert!((t.beta - f.base_damping).abs() < 1e-15);
        assert!(
            (t.force_damping - t.s_beta * f.goal_damping).abs() < 1e-15 && t.force_damping > 0.0
        );
    }
}
