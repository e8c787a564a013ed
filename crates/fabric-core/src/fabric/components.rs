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

/// Result of a barrier evaluation on a 1-D distance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BarrierEval {
    /// Metric M = (k/x) s(ẋ) (continued below x_min).
    pub m: f64,
    /// Geometric force ξ = ½ g'(x) s(ẋ) ẋ².
    pub xi: f64,
    /// Geometry force f = −M π = M ẋ² ψ_g'(x).
    pub f: f64,
    /// Forcing gradient ψ_f'(x) (negative: the force −ψ_f' pushes x up).
    pub grad: f64,
    /// Forcing potential ψ_f(x).
    pub psi: f64,
    /// Energy L_e = ½ M ẋ².
    pub energy: f64,
}

/// Distance-space repulsion component of GF VII-A2 on x ∈ R (distance minus margin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Barrier {
    /// Energy (k / 2x) s(ẋ) ẋ².
    pub energy: SwitchedEnergy1D<BarrierMetric>,
    /// ψ_g of the geometry π = −ẋ² ψ_g'.
    pub geometry: BarrierPotential,
    /// ψ_f of the forcing term.
    pub potential: BarrierPotential,
}

impl Barrier {
    /// Build from a configuration section.
    pub fn from_config(cfg: &BarrierConfig) -> Self {
        Barrier {
            energy: SwitchedEnergy1D {
                metric: BarrierMetric {
                    gain: cfg.metric_gain,
                    x_min: cfg.x_min,
                    influence: cfg.influence,
                },
                switched: true,
            },
            geometry: BarrierPotential::from_config(&cfg.geometry, cfg.x_min),
            potential: BarrierPotential::from_config(&cfg.potential, cfg.x_min),
        }
    }

    /// Evaluate at distance `x` and rate `xd`.
    pub fn eval(&self, x: f64, xd: f64) -> BarrierEval {
        let (m, xi, energy) = self.energy.eval(x, xd);
        let f = if m != 0.0 {
            m * xd * xd * self.geometry.slope(x)
        } else {
            0.0
        };
        let (psi, grad, _) = self.potential.eval(x);
        BarrierEval {
            m,
            xi,
            f,
            grad,
            psi,
            energy,
        }
    }

    /// The geometry π(x, ẋ) = −ẋ² ψ_g'(x) alone.
    pub fn geometry_acceleration(&self, x: f64, xd: f64) -> f64 {
        -xd * xd * self.geometry.slope(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fabric::config::FabricConfig;
    use crate::fabric::energy::{euler_lagrange_ad, FinslerEnergy};

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
        let away = b.eval(0.05, 0.2);
        assert_eq!((away.m, away.xi, away.f, away.energy), (0.0, 0.0, 0.0, 0.0));
        assert!(away.grad < 0.0, "the potential still pushes out");
        let toward = b.eval(0.05, -0.2);
        assert!(
            toward.m > 0.0 && toward.f < 0.0,
            "geometry accelerates x upward: π = −f/M > 0"
        );
        for &x in &[0.0, -0.01, -0.2] {
            let e = b.eval(x, -0.5);
            assert!(e.m.is_finite() && e.m > 0.0 && e.f.is_finite() && e.xi.is_finite());
            assert!(e.grad < 0.0 && e.grad.is_finite());
            assert!(b.geometry_acceleration(x, -0.5) > 0.0);
        }
    }
}
