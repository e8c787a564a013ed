//! The 2-D particle systems of GF Sec. VI: point attraction (VI-A) plus circle repulsion (VI-B) in four
//! variants (unbent/bent × Riemannian/Finsler), regulated to a desired speed v_d (App. E-B).
//!
//! Components, for a particle q ∈ R²:
//!
//! - Attraction on x = q − q_d (J = I): energy L = ẋᵀG_ψẋ, G_ψ = ((m̄ − m̲)e^{−(α_m‖x‖)²} + m̲) I
//!   ([`GaussianMass`]); potential with gradient ∂ψ = M_ψ ∂ψ₁, ψ₁ = k(‖x‖ + α_ψ⁻¹ ln(1 + e^{−2α_ψ‖x‖}))
//!   (= (k/α_ψ) ln cosh(α_ψ‖x‖) + const; a gradient field since M_ψ and ∂ψ₁ are radial, App. E-C).
//!   Bent geometry: π = −‖ẋ‖² ∂ψ₁. (The paper writes ẍ = −∂ψ₁, which is HD0 and not a geometry; we scale
//!   it by ‖ẋ‖² as App. E-C eq. 47 prescribes, so that the bent systems are geometric fabrics.)
//! - Repulsion on x = ‖q − q_o‖/r − 1: J = n̂ᵀ/r, J̇q̇ = q̇ᵀ(I − n̂n̂ᵀ)q̇ / (r‖q − q_o‖). Energy
//!   L₁ = G_b ẋ² (Riemannian) or L₂ = s(ẋ) G_b ẋ² (Finsler), G_b = k_b/x² ([`InverseSquareMetric`]).
//!   Potential with gradient ∂_xψ_b = M_b ψ₁,b'(x), ψ₁,b = α_b/(2x⁸), M_b = 2k_b/x² (the position-only
//!   Riemannian metric, so ψ_b is a true potential in both variants). Bent geometry ẍ = −s(ẋ)ẋ²ψ₁,b'(x).
//!
//! Variants (GF VI-C): unbent systems derive from L = L_attr + L_b − ψ − ψ_b (classical Lagrangian
//! dynamics of the summed energies, both potentials as forcing); bent systems energize the summed
//! geometry with the summed energy (eq. 17) and are forced by the attraction potential only (the
//! obstacle is encoded in the geometry, which does not shift the minimum). All four are speed-regulated
//! by eq. 40-46 with L_ex = ½‖q̇‖².
//!
//! Inside the circle (x < x_min) the barrier terms use the continuations documented in
//! [`energy`](super::energy) and [`potential`](super::potential); at the exact centre the outward direction
//! is taken as +x.
//!
//! As the Panda barriers ([`Barrier`](super::components::Barrier)), the repulsion has a braking time τ
//! ([`ParticleParams::braking_time`]): the bent geometry's brake is capped at |ẋ|/τ
//! ([`barrier_geometry`]) and a damper, the force w(x) M/τ ẋ, acts when approaching below x_min
//! ([`barrier_damping`]). **Why.** The centre particle, shot straight at the circle, moves along the
//! barrier normal, where energization (eq. 7) gives back exactly the speed the geometry takes: only the
//! energy's own brake −½ g'ẋ²/g and damping oppose the attraction. Below x_min the metric's tangent-line
//! continuation stops growing like 1/x², so the attraction pushed the bent centre particle through the
//! surface at a constant creep of a few mm/s (it ended 4–7 mm inside at v_d = 2 and 4 m/s with dt =
//! 0.01 s). In addition, the uncapped geometry (ψ₁,b' ∝ x⁻⁹, about 10¹⁷ at x_min) and its energization
//! cancelled to a few ulps of 10¹⁵, so the acceleration there was rounding noise. With τ = 0.01 s the
//! centre particle rests 6.7 mm outside; the other paths move by less than 1 mm. `braking_time = 0`
//! restores the paper's repulsion (no cap, no damper).

use super::components::{barrier_damping, barrier_geometry};
use super::config::{GoalDampingForm, Mode, SpeedConfig};
use super::energy::{
    GaussianMass, InverseSquareMetric, IsotropicEnergy, Metric1D, SwitchedEnergy1D,
};
use super::potential::{InversePower8, LogCosh, Potential1D};
use super::root::RootSystem;

/// The four systems compared in GF Sec. VI.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParticleVariant {
    /// Classical mechanics: position-only metrics, no bending.
    UnbentRiemannian,
    /// Velocity-dependent (switched) barrier metric, no bending.
    UnbentFinsler,
    /// Position-only metrics, geometry energized into the fabric.
    BentRiemannian,
    /// Full geometric fabric: switched barrier metric and energized geometry.
    BentFinsler,
}

impl ParticleVariant {
    /// All four variants, in the order of GF Fig. 1 (rows Riemannian/Finsler, columns unbent/bent).
    pub const ALL: [ParticleVariant; 4] = [
        Self::UnbentRiemannian,
        Self::BentRiemannian,
        Self::UnbentFinsler,
        Self::BentFinsler,
    ];

    fn bent(self) -> bool {
        matches!(self, Self::BentRiemannian | Self::BentFinsler)
    }
    fn finsler(self) -> bool {
        matches!(self, Self::UnbentFinsler | Self::BentFinsler)
    }
}

/// Parameters of the particle systems (GF Sec. VI; units: m, s).
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleParams {
    /// q_d: attraction target (m).
    pub target: [f64; 2],
    /// q_o: circle centre (m).
    pub obstacle_center: [f64; 2],
    /// r: circle radius (m, > 0).
    pub obstacle_radius: f64,
    /// m̄: upper isotropic attraction mass.
    pub mass_max: f64,
    /// m̲: lower isotropic attraction mass (> 0).
    pub mass_min: f64,
    /// α_m: width of the mass RBF (1/m).
    pub mass_width: f64,
    /// k: attraction gradient strength (m/s², the far-field ‖∂ψ₁‖).
    pub attraction_gain: f64,
    /// α_ψ: attraction transition rate (1/m).
    pub attraction_sharpness: f64,
    /// k_b: barrier metric gain.
    pub barrier_gain: f64,
    /// α_b: gain of ψ₁,b = α_b / (2x⁸).
    pub barrier_potential_gain: f64,
    /// x_min (> 0): start of the penetration continuation (dimensionless x).
    pub x_min: f64,
    /// τ (s, ≥ 0): braking time of the repulsion: the cap of the bent geometry's brake
    /// ([`barrier_geometry`]) and the rate of the barrier damper ([`barrier_damping`]); 0 = the paper's
    /// repulsion (uncapped geometry, no damper). Default 0.01 s, the experiment's step (see the module
    /// docs for why).
    pub braking_time: f64,
    /// Speed control (desired speed v_d = 2 or 4 in Fig. 1).
    pub speed: SpeedConfig,
}

impl Default for ParticleParams {
    fn default() -> Self {
        ParticleParams {
            target: [-3.0, 0.0],
            obstacle_center: [0.0, 0.0],
            obstacle_radius: 1.0,
            mass_max: 2.0,
            mass_min: 0.3,
            mass_width: 0.75,
            attraction_gain: 5.0,
            attraction_sharpness: 10.0,
            barrier_gain: 0.2,
            barrier_potential_gain: 0.2,
            x_min: 0.01,
            braking_time: 0.01,
            speed: SpeedConfig {
                desired_speed: 2.0,
                eta_rate: 2.0,
                goal_damping: 6.0,
                base_damping: 0.3,
                goal_switch_radius: 0.4,
                goal_switch_sharpness: 8.0,
                goal_damping_form: GoalDampingForm::Velocity,
                ..SpeedConfig::default()
            },
        }
    }
}

/// Acceleration q̈ (m/s²) of one particle at position `q` and velocity `qd` for a variant (see module docs).
/// Always finite for finite inputs with positive masses; returns zeros if the metric is degenerate
/// (only possible with m̲ ≤ 0).
pub fn particle_acceleration(
    variant: ParticleVariant,
    p: &ParticleParams,
    q: [f64; 2],
    qd: [f64; 2],
) -> [f64; 2] {
    let mut root = RootSystem::new(2);
    // --- attraction, x = q − q_d, J = I
    let x = [q[0] - p.target[0], q[1] - p.target[1]];
    let energy = IsotropicEnergy {
        mass: GaussianMass {
            dim: 2,
            mass_max: p.mass_max,
            mass_min: p.mass_min,
            width: p.mass_width,
        },
    };
    let psi1 = LogCosh {
        gain: p.attraction_gain / p.attraction_sharpness,
        sharpness: p.attraction_sharpness,
    };
    let (mut scratch, mut xi, mut g1) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    let (mass, _) = energy.eval(&x, &qd, &mut scratch, &mut xi);
    psi1.eval(&x, &mut g1);
    let v2 = qd[0] * qd[0] + qd[1] * qd[1];
    let f = if variant.bent() {
        [mass * v2 * g1[0], mass * v2 * g1[1]]
    } else {
        [0.0; 2]
    };
    let grad = [mass * g1[0], mass * g1[1]];
    let ident = nalgebra::Matrix2xX::from_column_slice(&[1.0, 0.0, 0.0, 1.0]);
    root.add_isotropic(&ident, &[0.0, 0.0], mass, &xi, &f, &grad, 0.0);

    // --- circle repulsion, x = ‖q − q_o‖/r − 1
    let d = [q[0] - p.obstacle_center[0], q[1] - p.obstacle_center[1]];
    let dist = (d[0] * d[0] + d[1] * d[1]).sqrt();
    let (nx, ny) = if dist > 1e-12 {
        (d[0] / dist, d[1] / dist)
    } else {
        (1.0, 0.0)
    };
    let r = p.obstacle_radius;
    let xb = dist / r - 1.0;
    let j = [nx / r, ny / r];
    let xbd = j[0] * qd[0] + j[1] * qd[1];
    let jdqd = if dist > 1e-12 {
        let along = nx * qd[0] + ny * qd[1];
        (v2 - along * along) / (r * dist)
    } else {
        0.0
    };
    let metric = InverseSquareMetric {
        gain: p.barrier_gain,
        x_min: p.x_min,
    };
    let bar_energy = SwitchedEnergy1D {
        metric,
        switched: variant.finsler(),
        // GF Sec. VI: the paper's switch on ẋ alone
        hold_inside: false,
    };
    let (mb, xib, _) = bar_energy.eval(xb, xbd);
    let pot = InversePower8 {
        gain: p.barrier_potential_gain,
        x_min: p.x_min,
    };
    let (_, dpsi1b, _) = pot.eval(xb);
    let fb = if variant.bent() && xbd < 0.0 {
        // ẍ = −s(ẋ) ẋ² ψ₁,b' (brake capped at |ẋ|/τ)  ⇒  f = −M π
        -mb * barrier_geometry(-dpsi1b, xb, xbd, p.x_min, p.braking_time)
    } else {
        0.0
    };
    // the barrier damper below x_min (GF eq. 4 / eq. 18 damping, see `Barrier::braking_time`)
    let damping = barrier_damping(xb, xbd, mb, p.x_min, p.braking_time);
    let (gb, psib) = if variant.bent() {
        (0.0, 0.0)
    } else {
        let m_riem = metric.g_dg(xb).0; // position-only M_b = 2 k_b / x²
        (m_riem * dpsi1b, 0.0)
    };
    let gb = gb + damping;
    root.add_scalar(&j, jdqd, mb, xib, fb, gb, psib);

    let mode = if variant.bent() {
        Mode::Bent
    } else {
        Mode::Unbent
    };
    let goal = (x[0] * x[0] + x[1] * x[1]).sqrt();
    let mut qdd = [0.0; 2];
    match root.solve(mode, &p.speed, &qd, goal, p.mass_min, None, None, &mut qdd) {
        Ok(_) => qdd,
        Err(_) => [0.0; 2],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(
        variant: ParticleVariant,
        p: &ParticleParams,
        q0: [f64; 2],
        t: f64,
    ) -> (Vec<[f64; 2]>, f64) {
        let dt = 0.005;
        let (mut q, mut v) = (q0, [0.0; 2]);
        let mut path = vec![q];
        let mut min_x = f64::INFINITY;
        for _ in 0..(t / dt) as usize {
            let a = particle_acceleration(variant, p, q, v);
            for i in 0..2 {
                v[i] += dt * a[i];
                q[i] += dt * v[i];
            }
            let d = ((q[0] - p.obstacle_center[0]).powi(2) + (q[1] - p.obstacle_center[1]).powi(2))
                .sqrt();
            min_x = min_x.min(d / p.obstacle_radius - 1.0);
            path.push(q);
        }
        (path, min_x)
    }

    #[test]
    fn every_variant_avoids_the_circle_and_reaches_the_target() {
        let p = ParticleParams::default();
        for variant in ParticleVariant::ALL {
            for y0 in [0.6, -1.2, 2.0] {
                let (path, min_x) = run(variant, &p, [3.0, y0], 12.0);
                let end = path.last().unwrap();
                let err = ((end[0] - p.target[0]).powi(2) + (end[1] - p.target[1]).powi(2)).sqrt();
                assert!(
                    min_x > 0.0,
                    "{variant:?} from y0={y0} entered the circle (x = {min_x})"
                );
                assert!(
                    err < 0.05,
                    "{variant:?} from y0={y0} ended {err} from the target"
                );
            }
        }
    }

    #[test]
    fn finite_everywhere_including_inside_and_at_the_centre() {
        let p = ParticleParams::default();
        for variant in ParticleVariant::ALL {
            for q in [
                [0.0, 0.0],
                [0.5, 0.1],
                [1.0, 0.0],
                [-3.0, 0.0],
                [10.0, -4.0],
            ] {
                for qd in [[0.0, 0.0], [-1.0, 0.2], [5.0, 5.0]] {
                    let a = particle_acceleration(variant, &p, q, qd);
                    assert!(a.iter().all(|v| v.is_finite()), "{variant:?} {q:?} {qd:?}");
                }
            }
            // inside the circle the push is outward
            let a = particle_acceleration(variant, &p, [0.5, 0.0], [0.0, 0.0]);
            assert!(a[0] > 0.0 || variant.bent(), "{variant:?}: {a:?}");
        }
    }
}
