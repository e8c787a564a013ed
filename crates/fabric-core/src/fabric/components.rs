//! Fabric components (GF Sec. V, VII-A): a Finsler energy (priority metric), an HD2 geometry and a
//! forcing potential, evaluated in their own task space. The engine pulls them back to joint space.
//!
//! Each evaluation returns, for the task-space state (x, ẋ):
//! - the energy's equations of motion (M, ξ) (GF Sec. III-A),
//! - the metric-weighted geometry force f = −M π (GF Thm IV.6, App. E-A),
//! - the forcing gradient ∂ψ_f and the potential value ψ_f (GF eq. 4).
//!
//! Components:
//! - [`Attractor`] (GF VII-A1, VII-A3, App. G): on an offset x = p − p_d ∈ R^k,
//!   L_e = ½ m(x)‖ẋ‖² (constant or tanh mass), π = −‖ẋ‖² ∂ψ_g, forcing ψ_f, with ψ = k ln cosh(α‖x‖).
//! - [`Barrier`] (GF VII-A2): on a distance x ∈ R, L_e = (k/2x) s(ẋ) ẋ², π = −ẋ² ∂ψ_g, forcing ψ_f, with
//!   ψ = k_b/x + (k_r/α) ln(1 + e^{−α(x − x_o)}); penetration (x < x_min) uses the continuations of
//!   [`energy::Metric1D`](super::energy::Metric1D) and [`potential::Potential1D`](super::potential::Potential1D).
//!   For explicit integration it departs from the paper where the paper's terms are too stiff for one
//!   step: a brake cap on the geometry, a damper near and inside the barrier, and an energy held on
//!   inside (see [`Barrier`]).

use super::config::{BarrierConfig, EeAttractionConfig, JointAttractionConfig};
use super::energy::{
    BarrierMetric, ConstantMass, IsotropicEnergy, ScalarField, SwitchedEnergy1D, TanhMass,
};
use super::potential::{BarrierPotential, LogCosh, Potential1D};

/// Scalars of an attractor evaluation (the vectors are written into the caller's slices).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AttractorEval {
    /// Isotropic mass m(x): M = m I.
    pub mass: f64,
    /// Energy L_e = ½ m ‖ẋ‖².
    pub energy: f64,
    /// Forcing potential ψ_f(x).
    pub psi: f64,
}

/// Attractor component on an offset x = p − p_d ∈ R^k (GF VII-A1, VII-A3, App. G).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attractor<S> {
    /// Isotropic energy ½ m(x)‖ẋ‖².
    pub energy: IsotropicEnergy<S>,
    /// ψ_g of the geometry π = −‖ẋ‖² ∂ψ_g.
    pub geometry: LogCosh,
    /// ψ_f of the forcing term −∂ψ_f.
    pub potential: LogCosh,
}

impl Attractor<ConstantMass> {
    /// The joint-space attractor of GF VII-A1 on R^dim.
    pub fn joint(cfg: &JointAttractionConfig, dim: usize) -> Self {
        Attractor {
            energy: IsotropicEnergy {
                mass: ConstantMass {
                    dim,
                    mass: cfg.mass,
                },
            },
            geometry: LogCosh::from_config(&cfg.geometry),
            potential: LogCosh::from_config(&cfg.potential),
        }
    }
}

impl Attractor<TanhMass> {
    /// The end-effector attractor of GF VII-A3 (position, dim = 3) or of one axis (App. G, dim = 3).
    pub fn end_effector(cfg: &EeAttractionConfig, dim: usize) -> Self {
        Attractor {
            energy: IsotropicEnergy {
                mass: TanhMass {
                    dim,
                    mass_max: cfg.mass_max,
                    mass_min: cfg.mass_min,
                    sharpness: cfg.mass_sharpness,
                },
            },
            geometry: LogCosh::from_config(&cfg.geometry),
            potential: LogCosh::from_config(&cfg.potential),
        }
    }
}

impl<S: ScalarField> Attractor<S> {
    /// Evaluate at offset `x` and velocity `xd` (k,). Writes ξ into `xi`, f = −Mπ = m‖ẋ‖² ∂ψ_g into `f`,
    /// ∂ψ_f into `grad`; `scratch` (k,) is overwritten. No allocation.
    pub fn eval(
        &self,
        x: &[f64],
        xd: &[f64],
        scratch: &mut [f64],
        xi: &mut [f64],
        f: &mut [f64],
        grad: &mut [f64],
    ) -> AttractorEval {
        let (mass, energy) = self.energy.eval(x, xd, scratch, xi);
        let v2: f64 = xd.iter().map(|v| v * v).sum();
        self.geometry.eval(x, scratch);
        for i in 0..f.len() {
            f[i] = mass * v2 * scratch[i];
        }
        let psi = self.potential.eval(x, grad);
        AttractorEval { mass, energy, psi }
    }

    /// The geometry π(x, ẋ) = −‖ẋ‖² ∂ψ_g(x) alone, written into `pi` (k,).
    pub fn geometry_acceleration(&self, x: &[f64], xd: &[f64], pi: &mut [f64]) {
        let v2: f64 = xd.iter().map(|v| v * v).sum();
        self.geometry.eval(x, pi);
        pi.iter_mut().for_each(|p| *p *= -v2);
    }
}

/// Ratio r = c|ẋ|τ up to which [`braking_acceleration`] is exactly the paper's geometry c ẋ².
pub const BRAKE_EXACT_RATIO: f64 = 0.5;

/// R(r) = r for r ≤ r₀ = [`BRAKE_EXACT_RATIO`], R(r) = 1 − (1 − r₀) e^{−(r − r₀)/(1 − r₀)} beyond:
/// C¹, increasing, and R(r) < 1 (≤ 1 in floating point).
fn brake_ratio(r: f64) -> f64 {
    let r0 = BRAKE_EXACT_RATIO;
    if r <= r0 {
        r
    } else {
        1.0 - (1.0 - r0) * (-(r - r0) / (1.0 - r0)).exp()
    }
}

/// The barrier geometry ẍ = c ẋ² (c = −ψ_g'(x) > 0; GF VII-A2: π = −ẋ² ∂ψ_g) with a brake that can
/// remove at most the velocity |ẋ| within the braking time τ (s):
///
/// ```text
/// π = sgn(c) (|ẋ|/τ) R(|c| |ẋ| τ),    R(r) = r (r ≤ ½),    R(r) = 1 − ½ e^{−2(r − ½)} (r > ½),
/// ```
///
/// so π = c ẋ² exactly while |c| |ẋ| τ ≤ ½ (the paper's brake needs at least 2τ to stop the motion
/// along x), |π| τ ≤ |ẋ| always, and π increases with |c| and with |ẋ|. `tau = 0` gives the paper's c ẋ².
///
/// **Why.** Off its own flow (a start inside the joint-limit margin, or close to a barrier and fast)
/// the HD2 geometry asks for c ẋ² with c = k_b/x² + … ≈ 10³–10⁴ per metre (or radian): one explicit
/// Euler step of dt reverses ẋ many times over (Δẋ = c|ẋ|dt · |ẋ|), and energization (GF eq. 7),
/// which gives back along q̇ the speed the geometry takes away, then multiplies every joint velocity by
/// 1 + α dt ≫ 1. Measured on the Panda from a start 3.9 mrad from joint 2's lower limit (inside the
/// 0.01 rad margin) moving toward it at 0.44 rad/s: π = 810 rad/s² on joint 2, α = 490 /s, and ‖q̇‖
/// went from 0.85 to 7 rad/s in one step of 0.01 s, then diverged. With the cap a step dt ≤ τ removes
/// at most |ẋ|, and α dt stays of order 1.
///
/// **Departure from GF.** Where |c||ẋ|τ > ½ the geometry is not HD2 (GF Def. IV.2, App. E-C eq. 47)
/// and its path depends on speed. Along the geometry's own flow from afar, ẋ = v e^{−(ψ_g(x) − ψ_g(∞))},
/// c|ẋ| stays below about 4 e^{−2} v / k_b + k_r v (ψ_g = k_b/x plus the soft ReLU of slope k_r), i.e.
/// |c||ẋ|τ ≲ 0.32 v (v in m/s or rad/s) for the default k_b = 0.02, k_r = 5 and τ = 0.01 s: below about
/// 1.5 m/s (rad/s) the capped and the paper's barrier coincide there, and the cap only acts on states
/// the paper's flow does not reach.
pub fn braking_acceleration(c: f64, xd: f64, tau: f64) -> f64 {
    let r = c.abs() * xd.abs() * tau;
    if tau <= 0.0 || r <= BRAKE_EXACT_RATIO {
        c * xd * xd
    } else {
        c.signum() * xd.abs() / tau * brake_ratio(r)
    }
}

/// Weight w(x) ∈ [0, 2] of the barrier damper, whose rate is w/τ: 0 for x ≥ x_min, rising to 1 at x = 0
/// (w = 3u² − 2u³, u = (x_min − x)/x_min), then to 2 at x ≤ −x_min (w = 1 + 3v² − 2v³, v = −x/x_min).
/// 2/τ is the largest rate an explicit Euler step dt = τ resolves without amplification
/// (q̇ → (1 − 2) q̇ at worst). It is reached inside, where a motion must stop within one step although
/// the other components sharing the leaf direction take part of the damping force: the leaf only gets
/// the fraction M/(M + M_rest) of it back as its own deceleration (M_rest: the metric of the rest of
/// the tree seen along the leaf). `x_min ≤ 0` gives a step from 0 to 2 at x = 0.
pub fn damper_weight(x: f64, x_min: f64) -> f64 {
    let smoothstep = |u: f64| {
        let u = u.clamp(0.0, 1.0);
        u * u * (3.0 - 2.0 * u)
    };
    if x_min <= 0.0 {
        return if x < 0.0 { 2.0 } else { 0.0 };
    }
    // at or beyond x_min, where a barrier leaf mostly is: 0 without a division
    if x >= x_min {
        return 0.0;
    }
    if x >= 0.0 {
        smoothstep((x_min - x) / x_min)
    } else {
        1.0 + smoothstep(-x / x_min)
    }
}

/// The barrier geometry ẍ = c ẋ² (c = −ψ_g'(x)) as the barriers use it: [`braking_acceleration`] with
/// the cap shared with the damper. Outside (x ≥ 0) the cap is |ẋ|/τ and the damper's rate w/τ ≤ 1/τ;
/// inside, where the damper's weight w(x) grows from 1 to 2 ([`damper_weight`]), the geometry's cap
/// shrinks to (2 − w)|ẋ|/τ, so that geometry and damper together never ask for more than 2|ẋ|/τ: one
/// Euler step dt ≤ τ then at worst reverses the velocity along x, never amplifies it. Deep inside
/// (x ≤ −x_min) the damper alone brakes. `tau = 0`: the paper's c ẋ².
pub fn barrier_geometry(c: f64, x: f64, xd: f64, x_min: f64, tau: f64) -> f64 {
    if tau <= 0.0 {
        return c * xd * xd;
    }
    let share = (2.0 - damper_weight(x, x_min)).min(1.0);
    if share <= 0.0 {
        0.0
    } else if share == 1.0 {
        braking_acceleration(c, xd, tau)
    } else {
        braking_acceleration(c, xd, tau / share)
    }
}

/// The barrier damper's force b ẋ on a leaf with metric `m` (GF eq. 18's f_damp = −β M ẋ with
/// β = w(x)/τ, [`damper_weight`]): nonzero only when approaching (ẋ < 0) below x_min, with τ > 0 and
/// m > 0; ≤ 0 (it enters the forcing, where −b ẋ pushes x up). See [`Barrier::braking_time`].
pub fn barrier_damping(x: f64, xd: f64, m: f64, x_min: f64, tau: f64) -> f64 {
    if xd < 0.0 && m > 0.0 && tau > 0.0 {
        match damper_weight(x, x_min) {
            // w = 0: the product w m/τ ẋ below is −0 (ẋ < 0); without its division
            0.0 => -0.0,
            w => w * m / tau * xd,
        }
    } else {
        0.0
    }
}

/// Result of a barrier evaluation on a 1-D distance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BarrierEval {
    /// Metric M = g(x) s(x, ẋ) (g = k/x tapered, continued below x_min; s: the switch of
    /// [`SwitchedEnergy1D`], held on inside).
    pub m: f64,
    /// Geometric force ξ = ½ g'(x) s ẋ².
    pub xi: f64,
    /// Geometry force f = −M π when approaching (ẋ < 0), 0 otherwise; π = [`Barrier::geometry_acceleration`].
    pub f: f64,
    /// Generalized forcing: ψ_f'(x) plus the damper force b ẋ (the root adds the acceleration
    /// −M̃⁻¹Jᵀ grad; negative pushes x up).
    pub grad: f64,
    /// The damper part b ẋ of `grad` (≤ 0; nonzero only when approaching below x_min).
    pub damping: f64,
    /// Forcing potential ψ_f(x).
    pub psi: f64,
    /// Energy L_e = ½ M ẋ².
    pub energy: f64,
}

/// Distance-space repulsion component of GF VII-A2 on x ∈ R (distance minus margin; x < 0 inside),
/// made safe for explicit integration at steps up to its braking time τ (see
/// [`braking_time`](Barrier::braking_time)).
///
/// Outside (x ≥ x_min) and at moderate speed this is the paper's component: energy
/// L_e = (k/2x) s(ẋ) ẋ², geometry π = −ẋ² ψ_g' acting when approaching (f = −s M π), forcing ψ_f.
/// The departures, each documented where it is defined:
/// - the geometry's brake is capped at |ẋ|/τ ([`braking_acceleration`]; not HD2 beyond the cap), a
///   cap shared with the damper inside ([`barrier_geometry`]);
/// - a damper acts when approaching below x_min ([`barrier_damping`], [`damper_weight`]; GF eq. 4
///   damping);
/// - inside (x < 0) the energy is not switched off when moving away
///   ([`SwitchedEnergy1D::hold_inside`]), while the geometry still only acts when approaching.
///
/// `braking_time = 0` gives the paper's component except for the last point (which is HD2 and only
/// acts inside).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Barrier {
    /// Energy (k / 2x) s(x, ẋ) ẋ².
    pub energy: SwitchedEnergy1D<BarrierMetric>,
    /// ψ_g of the geometry π = −ẋ² ψ_g'.
    pub geometry: BarrierPotential,
    /// ψ_f of the forcing term.
    pub potential: BarrierPotential,
    /// τ (s, ≥ 0): the shortest time over which the barrier may take away the velocity along x. It sets
    /// (1) the cap |π| ≤ |ẋ|/τ of the geometry ([`barrier_geometry`]) and (2) a damper acting only when
    /// approaching (ẋ < 0) below x_min, the force b ẋ with b = w(x) M/τ, w ∈ [0, 2]
    /// ([`barrier_damping`]): GF eq. 18's f_damp = −β M ẋ on the leaf with β = w/τ, a bounded positive
    /// semi-definite damping B = Jᵀ b J of GF eq. 4 (it only removes energy, Thm IV.4). The damper is
    /// needed because energization cannot let the geometry stop a head-on approach: when q̇ is along
    /// the barrier normal, eq. 7 gives back exactly the speed the geometry takes (in 1-D the energized
    /// geometry is the energy's own geodesic, whose brake −ξ/M = −½ g'ẋ²/g is weak below x_min). The
    /// damper is not part of the geometry and is not undone; it stops such a motion within about τ.
    /// Geometry and damper together ask for at most 2|ẋ|/τ, so an explicit Euler step dt ≤ τ never
    /// amplifies the velocity along x. `0` gives the paper's barrier: uncapped HD2 geometry, no damper.
    pub braking_time: f64,
}

impl Barrier {
    /// Build from a configuration section (switched energy held on inside, τ = `cfg.braking_time`).
    pub fn from_config(cfg: &BarrierConfig) -> Self {
        Barrier {
            energy: SwitchedEnergy1D {
                metric: BarrierMetric {
                    gain: cfg.metric_gain,
                    x_min: cfg.x_min,
                    influence: cfg.influence,
                },
                switched: true,
                hold_inside: true,
            },
            geometry: BarrierPotential::from_config(&cfg.geometry, cfg.x_min),
            potential: BarrierPotential::from_config(&cfg.potential, cfg.x_min),
            braking_time: cfg.braking_time,
        }
    }

    /// Evaluate at distance `x` and rate `xd`; with `potential` false, ψ is not computed (`psi` = 0)
    /// and every other field is unchanged (ψ' needs one exponential, ψ a logarithm more).
    pub fn eval(&self, x: f64, xd: f64, potential: bool) -> BarrierEval {
        let (m, xi, energy) = self.energy.eval(x, xd);
        let approaching = xd < 0.0 && m != 0.0;
        let f = if approaching {
            -m * self.geometry_acceleration(x, xd)
        } else {
            0.0
        };
        let damping = barrier_damping(x, xd, m, self.energy.metric.x_min, self.braking_time);
        let (psi, slope) = if potential {
            let (psi, slope, _) = self.potential.eval(x);
            (psi, slope)
        } else {
            (0.0, self.potential.slope(x))
        };
        BarrierEval {
            m,
            xi,
            f,
            grad: slope + damping,
            damping,
            psi,
            energy,
        }
    }

    /// The geometry π(x, ẋ) = −ẋ² ψ_g'(x) with its brake capped ([`barrier_geometry`]).
    pub fn geometry_acceleration(&self, x: f64, xd: f64) -> f64 {
        barrier_geometry(
            -self.geometry.slope(x),
            x,
            xd,
            self.energy.metric.x_min,
            self.braking_time,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fabric::config::FabricConfig;
    use crate::fabric::energy::{euler_lagrange_ad, FinslerEnergy, Metric1D};

    #[test]
    fn attractor_matches_its_definitions() {
        let cfg = FabricConfig::default();
        let a = Attractor::end_effector(
            &EeAttractionConfig {
                enabled: true,
                ..cfg.ee_position.clone()
            },
            3,
        );
        let x = [0.1, -0.2, 0.05];
        let xd = [0.3, 0.1, -0.4];
        let (mut s, mut xi, mut f, mut g) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        let e = a.eval(&x, &xd, &mut s, &mut xi, &mut f, &mut g);
        let ad = euler_lagrange_ad(&a.energy, &x, &xd);
        for (i, x) in xi.iter().enumerate() {
            assert!((ad.xi[i] - x).abs() < 1e-12);
            assert!((ad.m[(i, i)] - e.mass).abs() < 1e-12);
        }
        assert!((ad.energy - e.energy).abs() < 1e-14);
        let mut pi = [0.0; 3];
        a.geometry_acceleration(&x, &xd, &mut pi);
        for i in 0..3 {
            assert!((f[i] + e.mass * pi[i]).abs() < 1e-14, "f = −Mπ");
        }
        let mut gg = [0.0; 3];
        let psi = a.potential.eval(&x, &mut gg);
        assert_eq!(gg, g);
        assert_eq!(psi, e.psi);
        assert_eq!(a.energy.dim(), 3);
    }

    #[test]
    fn barrier_switches_off_when_moving_away_and_pushes_out_when_penetrating() {
        let b = Barrier::from_config(&FabricConfig::default().obstacles);
        let away = b.eval(0.05, 0.2, true);
        assert_eq!((away.m, away.xi, away.f, away.energy), (0.0, 0.0, 0.0, 0.0));
        assert!(away.grad < 0.0, "the potential still pushes out");
        let toward = b.eval(0.05, -0.2, true);
        assert!(
            toward.m > 0.0 && toward.f < 0.0,
            "geometry accelerates x upward: π = −f/M > 0"
        );
        for &x in &[0.0, -0.01, -0.2] {
            let e = b.eval(x, -0.5, true);
            assert!(e.m.is_finite() && e.m > 0.0 && e.f.is_finite() && e.xi.is_finite());
            assert!(e.grad < 0.0 && e.grad.is_finite());
            // braking: the geometry (capped, sharing with the damper) and the damper
            assert!(b.geometry_acceleration(x, -0.5) >= 0.0 && e.damping < 0.0);
        }
        // deep inside the damper alone brakes; at contact both do
        assert_eq!(b.geometry_acceleration(-0.2, -0.5), 0.0);
        assert!(b.geometry_acceleration(0.0, -0.5) > 0.0);
    }

    #[test]
    fn brake_is_the_paper_geometry_up_to_half_a_stop_per_tau_and_never_more_than_a_stop() {
        let tau = 0.01;
        // exact (and HD2) while c|ẋ|τ ≤ ½
        for (c, xd) in [(10.0, -1.0), (40.0, 0.5), (50.0, -1.0), (2.0e4, -2.0e-3)] {
            assert_eq!(braking_acceleration(c, xd, tau), c * xd * xd);
            assert_eq!(braking_acceleration(c, 0.5 * xd, tau), 0.25 * c * xd * xd);
        }
        // the cap: 0 < π τ ≤ |ẋ|, increasing in c and in |ẋ|, and always ≤ the paper's c ẋ²
        let mut last_c = 0.0;
        for k in 0..60 {
            let c = 10f64.powf(-1.0 + 0.15 * k as f64);
            let pi = braking_acceleration(c, -0.7, tau);
            assert!(
                pi > 0.0 && pi * tau <= 0.7 * (1.0 + 1e-12) && pi <= c * 0.49 + 1e-12,
                "c = {c}: π = {pi}"
            );
            assert!(pi >= last_c, "non-decreasing in c");
            last_c = pi;
        }
        let mut last_v = 0.0;
        for k in 1..200 {
            let v = 0.05 * k as f64;
            let pi = braking_acceleration(800.0, -v, tau);
            assert!(
                pi * tau <= v * (1.0 + 1e-12) && pi > last_v,
                "|ẋ| = {v}: π = {pi}"
            );
            last_v = pi;
        }
        // C¹ across c|ẋ|τ = ½ (here at |ẋ| = 0.5 for c = 100): one-sided slopes in ẋ agree
        let h = 1e-7;
        let f = |v: f64| braking_acceleration(100.0, -v, tau);
        let left = (f(0.5) - f(0.5 - h)) / h;
        let right = (f(0.5 + h) - f(0.5)) / h;
        assert!((left - right).abs() < 1e-4 * left, "{left} {right}");
        // shared with the damper: geometry cap + damper rate ≤ 2|ẋ|/τ everywhere, the cap fading inside
        let x_min = 0.005;
        for k in 0..=40 {
            let x = 0.01 - 0.02 * k as f64 / 40.0;
            let pi = barrier_geometry(1e6, x, -0.8, x_min, tau);
            let w = damper_weight(x, x_min);
            assert!(
                pi >= 0.0 && pi * tau + w * 0.8 <= 2.0 * 0.8 * (1.0 + 1e-12),
                "x = {x}: π = {pi}, w = {w}"
            );
            if x >= 0.0 {
                assert_eq!(pi, braking_acceleration(1e6, -0.8, tau));
            }
        }
        assert_eq!(barrier_geometry(1e6, -x_min, -0.8, x_min, tau), 0.0);
        assert_eq!(barrier_geometry(1e6, -x_min, -0.8, x_min, 0.0), 1e6 * 0.64);
        // sign follows c; τ = 0 is the paper's c ẋ²
        assert!(braking_acceleration(-1e5, 1.0, tau) < 0.0);
        assert_eq!(braking_acceleration(1e5, -3.0, 0.0), 9.0e5);
    }

    #[test]
    fn damper_weight_ramps_from_zero_at_x_min_to_one_at_contact_to_two_inside() {
        let x_min = 0.005;
        assert_eq!(damper_weight(0.1, x_min), 0.0);
        assert_eq!(damper_weight(x_min, x_min), 0.0);
        assert_eq!(damper_weight(0.0, x_min), 1.0);
        assert_eq!(damper_weight(-x_min, x_min), 2.0);
        assert_eq!(damper_weight(-1.0, x_min), 2.0);
        assert!((damper_weight(0.5 * x_min, x_min) - 0.5).abs() < 1e-12);
        let mut last = 0.0;
        for k in 0..=300 {
            let x = x_min - 2.0 * x_min * k as f64 / 300.0;
            let w = damper_weight(x, x_min);
            assert!(w >= last && (0.0..=2.0).contains(&w));
            // continuous with a continuous slope (smoothsteps meet with zero slope at 0)
            let d = (damper_weight(x + 1e-9, x_min) - damper_weight(x - 1e-9, x_min)) / 2e-9;
            assert!(d.abs() <= 1.5 / x_min + 1e-6, "slope {d} at {x}");
            last = w;
        }
        assert_eq!(damper_weight(-1e-9, 0.0), 2.0);
        assert_eq!(damper_weight(1e-9, 0.0), 0.0);
        assert_eq!(damper_weight(0.0, 0.0), 0.0);
        // the early return for x ≥ x_min lets NaN through
        assert!(damper_weight(f64::NAN, x_min).is_nan());
    }

    #[test]
    fn barrier_inside_keeps_its_metric_when_leaving_and_damps_only_approach_below_x_min() {
        let cfg = FabricConfig::default().obstacles;
        let b = Barrier::from_config(&cfg);
        let tau = cfg.braking_time;
        assert!(tau > 0.0);
        let slope = |x: f64| b.potential.eval(x).1;
        // inside, moving out: the metric (and energy) stay, no geometry force, no damping
        let out = b.eval(-0.01, 0.3, true);
        let (g, dg) = b.energy.metric.g_dg(-0.01);
        assert_eq!(out.m, g);
        assert_eq!(out.xi, 0.5 * dg * 0.09);
        assert!((out.energy - 0.5 * g * 0.09).abs() < 1e-12);
        assert_eq!((out.f, out.damping, out.grad), (0.0, 0.0, slope(-0.01)));
        // outside, moving out: the paper's switch
        assert_eq!(b.eval(0.002, 0.3, true).m, 0.0);
        // approaching below x_min: damper b ẋ with b = w M / τ, added to the forcing
        let x = 0.002;
        let e = b.eval(x, -0.4, true);
        let w = damper_weight(x, cfg.x_min);
        assert!(w > 0.0 && e.m > 0.0);
        assert!((e.damping - w * e.m / tau * -0.4).abs() < 1e-12 * e.m);
        assert!((e.grad - (slope(x) + e.damping)).abs() < 1e-12 * e.grad.abs());
        assert!((e.f + e.m * b.geometry_acceleration(x, -0.4)).abs() < 1e-12 * e.f.abs());
        // approaching above x_min: no damper, paper's geometry while c|ẋ|τ ≤ ½
        let far = b.eval(0.08, -0.2, true);
        assert_eq!(far.damping, 0.0);
        let c = -b.geometry.slope(0.08);
        assert!(c * 0.2 * tau <= BRAKE_EXACT_RATIO);
        assert!((far.f - far.m * 0.04 * b.geometry.slope(0.08)).abs() < 1e-12 * far.f.abs());
        // braking_time = 0: the paper's geometry and no damper, wherever the state
        let paper = Barrier {
            braking_time: 0.0,
            ..b
        };
        for (x, xd) in [(0.002, -0.4), (-0.02, -2.0), (0.001, -5.0)] {
            let e = paper.eval(x, xd, true);
            assert_eq!(e.damping, 0.0);
            assert!((e.f - e.m * xd * xd * paper.geometry.slope(x)).abs() < 1e-9 * e.f.abs());
        }
    }
}
