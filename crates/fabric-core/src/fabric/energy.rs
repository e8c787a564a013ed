//! Finsler energies L_e(x, ẋ) and their equations of motion M ẍ + ξ = 0 (GF Sec. III-A, Def. III.1).
//!
//! The Euler–Lagrange equation gives (GF Sec. III-A)
//!
//! ```text
//! M = ∂²L/∂ẋ∂ẋ,    ξ = (∂²L/∂ẋ∂x) ẋ − ∂L/∂x.
//! ```
//!
//! Every energy here implements [`FinslerEnergy`]: a Lagrangian generic over num-dual numbers (so the
//! equations can be derived by automatic differentiation with [`euler_lagrange_ad`]) and a closed form
//! ([`FinslerEnergy::equations`]) used at run time. Tests check that both agree.
//!
//! Two families are provided, both from the patterns of GF App. E-C:
//! - [`IsotropicEnergy`]: L = ½ m(x) ‖ẋ‖² with a position-dependent scalar mass (joint attraction
//!   VII-A1, end-effector attraction VII-A3, the Sec. VI-A attraction metric).
//! - [`SwitchedEnergy1D`]: L = ½ g(x) s(ẋ) ẋ² in a 1-D space with a velocity-direction switch s (eq. 51;
//!   the distance barrier of VII-A2 and the Sec. VI-B circle metrics).

use nalgebra::{DMatrix, DVector};
use num_dual::{hessian, Dual2DVec64, DualNum};

/// Equations of motion M ẍ + ξ = 0 of a Lagrangian at one state (GF Sec. III-A).
#[derive(Clone, Debug, PartialEq)]
pub struct EquationsOfMotion {
    /// The Lagrangian value L(x, ẋ) (for a Finsler energy this is also its energy H_e = L_e).
    pub energy: f64,
    /// Metric M = ∂²L/∂ẋ² (k × k), HD0 in ẋ.
    pub m: DMatrix<f64>,
    /// Geometric force ξ = (∂²L/∂ẋ∂x) ẋ − ∂L/∂x (k,), HD2 in ẋ.
    pub xi: DVector<f64>,
}

/// A Lagrangian L(x, ẋ) on a k-dimensional task space, usually a Finsler energy L_e = ½ L_g²
/// (GF Def. III.1): HD2 in ẋ, non-negative, with a positive semi-definite metric.
pub trait FinslerEnergy {
    /// Dimension k of the task space.
    fn dim(&self) -> usize;

    /// L(x, ẋ) for `x`, `xd` of length [`dim`](FinslerEnergy::dim), generic over dual numbers so that
    /// derivatives can be taken by automatic differentiation.
    fn lagrangian<D: DualNum<f64>>(&self, x: &[D], xd: &[D]) -> D;

    /// Closed-form equations of motion: writes M (k × k) into `m` and ξ (k,) into `xi` and returns L.
    /// `m` and `xi` must already have the right shape (they are overwritten, not resized).
    fn equations(&self, x: &[f64], xd: &[f64], m: &mut DMatrix<f64>, xi: &mut DVector<f64>) -> f64;

    /// Allocating convenience wrapper around [`equations`](FinslerEnergy::equations).
    fn equations_of_motion(&self, x: &[f64], xd: &[f64]) -> EquationsOfMotion {
        let k = self.dim();
        let mut m = DMatrix::zeros(k, k);
        let mut xi = DVector::zeros(k);
        let energy = self.equations(x, xd, &mut m, &mut xi);
        EquationsOfMotion { energy, m, xi }
    }
}

/// Equations of motion of any Lagrangian by automatic differentiation (GF Sec. III-A): the Hessian of
/// L over the stacked variable z = (x, ẋ) (2k,) gives M = ∂²L/∂ẋ² and ∂²L/∂ẋ∂x, its gradient ∂L/∂x.
/// This is the reference the closed forms are tested against; it allocates.
pub fn euler_lagrange_ad<E: FinslerEnergy>(energy: &E, x: &[f64], xd: &[f64]) -> EquationsOfMotion {
    let k = x.len();
    let z = DVector::from_iterator(2 * k, x.iter().chain(xd.iter()).copied());
    let (value, grad, hess) = hessian(
        |z: DVector<Dual2DVec64>| {
            let v = z.as_slice();
            energy.lagrangian(&v[..k], &v[k..])
        },
        &z,
    );
    let m = hess.view((k, k), (k, k)).into_owned();
    let cross = hess.view((k, 0), (k, k)); // rows ẋ, columns x: ∂²L/∂ẋ∂x
    let xd_v = DVector::from_column_slice(xd);
    let xi = cross * xd_v - grad.rows(0, k);
    EquationsOfMotion {
        energy: value,
        m,
        xi,
    }
}

/// A scalar field m(x) on R^k with a closed-form gradient, generic over dual numbers.
pub trait ScalarField {
    /// Dimension k of the argument.
    fn dim(&self) -> usize;
    /// m(x), generic over dual numbers.
    fn value<D: DualNum<f64>>(&self, x: &[D]) -> D;
    /// m(x) and its gradient ∂m/∂x written into `grad` (k,).
    fn value_gradient(&self, x: &[f64], grad: &mut [f64]) -> f64;
}

/// Euclidean norm of a slice of dual numbers.
pub(crate) fn dual_norm<D: DualNum<f64>>(x: &[D]) -> D {
    x.iter().map(|v| v.clone() * v.clone()).sum::<D>().sqrt()
}

/// Constant mass m on R^k: L = ½ m ‖ẋ‖² (GF VII-A1 joint attraction energy L_e = m/2 ‖ẋ‖²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstantMass {
    /// Dimension k.
    pub dim: usize,
    /// Mass m (> 0, dimensionless priority weight).
    pub mass: f64,
}

impl ScalarField for ConstantMass {
    fn dim(&self) -> usize {
        self.dim
    }
    fn value<D: DualNum<f64>>(&self, _x: &[D]) -> D {
        D::from(self.mass)
    }
    fn value_gradient(&self, _x: &[f64], grad: &mut [f64]) -> f64 {
        grad.iter_mut().for_each(|g| *g = 0.0);
        self.mass
    }
}

/// Radial tanh mass of the end-effector attractor (GF VII-A3) on x = p − p_d (the offset to the target):
/// the paper's energy L_e = ‖ẋ‖² (½(m̄ − m̲)(tanh(−α‖x‖) + 1) + m̲) is written L = ½ m(x)‖ẋ‖² with
///
/// ```text
/// m(x) = (m̄ − m̲)(tanh(−α‖x‖) + 1) + 2 m̲,
/// ```
///
/// so the mass is 2m̄ at the target and tends to 2m̲ far away. At x = 0 the gradient (a cone tip) is set
/// to 0; automatic differentiation is undefined there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TanhMass {
    /// Dimension k.
    pub dim: usize,
    /// m̄: mass scale at the target.
    pub mass_max: f64,
    /// m̲: mass scale far from the target.
    pub mass_min: f64,
    /// α (1/m for positions, dimensionless for unit axes): sharpness of the transition.
    pub sharpness: f64,
}

impl TanhMass {
    /// m and dm/dr as functions of r = ‖x‖.
    pub fn radial(&self, r: f64) -> (f64, f64) {
        let t = (-self.sharpness * r).tanh();
        let m = (self.mass_max - self.mass_min) * (t + 1.0) + 2.0 * self.mass_min;
        let dm = -(self.mass_max - self.mass_min) * self.sharpness * (1.0 - t * t);
        (m, dm)
    }
}

impl ScalarField for TanhMass {
    fn dim(&self) -> usize {
        self.dim
    }
    fn value<D: DualNum<f64>>(&self, x: &[D]) -> D {
        let r = dual_norm(x);
        ((r * (-self.sharpness)).tanh() + 1.0) * (self.mass_max - self.mass_min)
            + 2.0 * self.mass_min
    }
    fn value_gradient(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let r = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let (m, dm) = self.radial(r);
        radial_gradient(x, r, dm, grad);
        m
    }
}

/// Gaussian mass of the Sec. VI-A particle attractor on x = q − q_d: the paper's energy L = ẋᵀ G ẋ with
/// G(x) = ((m̄ − m̲) e^{−(α_m‖x‖)²} + m̲) I is written L = ½ m(x)‖ẋ‖² with m = 2((m̄ − m̲)e^{−(α_m‖x‖)²} + m̲).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussianMass {
    /// Dimension k.
    pub dim: usize,
    /// m̄: upper isotropic mass (at the target).
    pub mass_max: f64,
    /// m̲: lower isotropic mass (far away).
    pub mass_min: f64,
    /// α_m: width of the radial basis function (1/m).
    pub width: f64,
}

impl ScalarField for GaussianMass {
    fn dim(&self) -> usize {
        self.dim
    }
    fn value<D: DualNum<f64>>(&self, x: &[D]) -> D {
        let r2 = x.iter().map(|v| v.clone() * v.clone()).sum::<D>();
        ((r2 * (-self.width * self.width)).exp() * (self.mass_max - self.mass_min) + self.mass_min)
            * 2.0
    }
    fn value_gradient(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let r2: f64 = x.iter().map(|v| v * v).sum();
        let a2 = self.width * self.width;
        let e = (-a2 * r2).exp();
        let m = 2.0 * ((self.mass_max - self.mass_min) * e + self.mass_min);
        // ∂m/∂x = 2 (m̄ − m̲) e (−2 α² x)
        let c = -4.0 * (self.mass_max - self.mass_min) * e * a2;
        for (g, xi) in grad.iter_mut().zip(x) {
            *g = c * xi;
        }
        m
    }
}

/// grad = dm/dr · x/r, with the tip of the cone (r ≈ 0) given a zero gradient.
fn radial_gradient(x: &[f64], r: f64, dm: f64, grad: &mut [f64]) {
    if r > 1e-300 {
        let c = dm / r;
        for (g, xi) in grad.iter_mut().zip(x) {
            *g = c * xi;
        }
    } else {
        grad.iter_mut().for_each(|g| *g = 0.0);
    }
}

/// Isotropic energy L = ½ m(x) ‖ẋ‖² (a Riemannian Finsler energy, GF Sec. III-A). Closed form:
///
/// ```text
/// M = m(x) I,    ξ = ẋ (∇m·ẋ) − ½ ‖ẋ‖² ∇m.
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsotropicEnergy<S> {
    /// The mass field m(x) (> 0).
    pub mass: S,
}

impl<S: ScalarField> IsotropicEnergy<S> {
    /// Closed form on slices, without allocation: writes ξ (k,) into `xi`, uses `grad` (k,) as scratch
    /// for ∇m, and returns (m, L).
    pub fn eval(&self, x: &[f64], xd: &[f64], grad: &mut [f64], xi: &mut [f64]) -> (f64, f64) {
        let m = self.mass.value_gradient(x, grad);
        let v2: f64 = xd.iter().map(|v| v * v).sum();
        let gv: f64 = grad.iter().zip(xd).map(|(g, v)| g * v).sum();
        for i in 0..xi.len() {
            xi[i] = xd[i] * gv - 0.5 * v2 * grad[i];
        }
        (m, 0.5 * m * v2)
    }
}

impl<S: ScalarField> FinslerEnergy for IsotropicEnergy<S> {
    fn dim(&self) -> usize {
        self.mass.dim()
    }
    fn lagrangian<D: DualNum<f64>>(&self, x: &[D], xd: &[D]) -> D {
        let v2 = xd.iter().map(|v| v.clone() * v.clone()).sum::<D>();
        self.mass.value(x) * v2 * 0.5
    }
    fn equations(&self, x: &[f64], xd: &[f64], m: &mut DMatrix<f64>, xi: &mut DVector<f64>) -> f64 {
        let k = self.dim();
        let mut grad = vec![0.0; k];
        let (mass, energy) = self.eval(x, xd, &mut grad, xi.as_mut_slice());
        m.fill(0.0);
        m.fill_diagonal(mass);
        energy
    }
}

/// A positive 1-D metric g(x) with first derivative, generic over dual numbers, continued below `x_min`
/// by its tangent line g(x_min) + g'(x_min)(x − x_min) (still positive since g' < 0 for barriers): this is
/// the documented penetration behaviour, finite and growing with penetration depth.
pub trait Metric1D {
    /// Lower bound x_min (> 0) of the exact formula.
    fn x_min(&self) -> f64;
    /// The exact formula g(x) (valid for x ≥ x_min), generic.
    fn exact<D: DualNum<f64>>(&self, x: D) -> D;
    /// The exact g(x) and g'(x) for x ≥ x_min.
    fn exact_with_derivative(&self, x: f64) -> (f64, f64);

    /// g(x) with the linear continuation below x_min, generic.
    fn g<D: DualNum<f64>>(&self, x: D) -> D {
        let x0 = self.x_min();
        if x.re() >= x0 {
            self.exact(x)
        } else {
            let (g0, g1) = self.exact_with_derivative(x0);
            (x - x0) * g1 + g0
        }
    }
    /// g(x) and g'(x) with the linear continuation below x_min.
    fn g_dg(&self, x: f64) -> (f64, f64) {
        let x0 = self.x_min();
        if x >= x0 {
            self.exact_with_derivative(x)
        } else {
            let (g0, g1) = self.exact_with_derivative(x0);
            (g0 + g1 * (x - x0), g1)
        }
    }
}

/// Barrier metric g(x) = k / x of the distance-space repulsion energy L_e = (k / 2x) s(ẋ) ẋ² (GF VII-A2),
/// tapered to zero over the outer half of the influence radius r: g(x) = (k / x)·w(u) with
/// u = (x − r/2)/(r/2) clamped to [0, 1] and w(u) = 1 − 3u² + 2u³ (so g = k/x exactly for x ≤ r/2 and
/// g = 0 for x ≥ r). The taper is a position-only factor (the metric stays HD0 in ẋ) that makes g and g'
/// continuous where a leaf enters or leaves the transform tree, so the fabric's acceleration does not jump
/// there (smoother motion, lower jerk). `influence = ∞` gives the paper's untapered k / x.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BarrierMetric {
    /// k: barrier metric gain (units: metric · m).
    pub gain: f64,
    /// x_min (> 0): below it the metric continues linearly.
    pub x_min: f64,
    /// Influence radius r (> x_min, m or rad) where the metric reaches zero; `f64::INFINITY` for no taper.
    pub influence: f64,
}

impl Metric1D for BarrierMetric {
    fn x_min(&self) -> f64 {
        self.x_min
    }
    fn exact<D: DualNum<f64>>(&self, x: D) -> D {
        if !self.influence.is_finite() {
            return x.recip() * self.gain;
        }
        let half = 0.5 * self.influence;
        if x.re() >= self.influence {
            return x * 0.0;
        }
        if x.re() <= half {
            return x.recip() * self.gain;
        }
        let u = (x.clone() - half) / half;
        let w = u.clone() * u.clone() * (u * 2.0 - 3.0) + 1.0;
        x.recip() * self.gain * w
    }
    fn exact_with_derivative(&self, x: f64) -> (f64, f64) {
        if !self.influence.is_finite() {
            return (self.gain / x, -self.gain / (x * x));
        }
        let half = 0.5 * self.influence;
        if x >= self.influence {
            return (0.0, 0.0);
        }
        let g = self.gain / x;
        if x <= half {
            return (g, -g / x);
        }
        let u = (x - half) / half;
        let w = 1.0 - 3.0 * u * u + 2.0 * u * u * u;
        let dw = (-6.0 * u + 6.0 * u * u) / half;
        (g * w, -g / x * w + g * dw)
    }
}

/// Inverse-square metric of the Sec. VI-B circle repulsion: the paper's L = G_b(x) ẋ² with
/// G_b = k_b / x² is written L = ½ g ẋ² with g(x) = 2 k_b / x².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseSquareMetric {
    /// k_b: barrier gain.
    pub gain: f64,
    /// x_min (> 0): below it the metric continues linearly.
    pub x_min: f64,
}

impl Metric1D for InverseSquareMetric {
    fn x_min(&self) -> f64 {
        self.x_min
    }
    fn exact<D: DualNum<f64>>(&self, x: D) -> D {
        (x.clone() * x).recip() * (2.0 * self.gain)
    }
    fn exact_with_derivative(&self, x: f64) -> (f64, f64) {
        (2.0 * self.gain / (x * x), -4.0 * self.gain / (x * x * x))
    }
}

/// One-dimensional switched energy L = ½ g(x) s(x, ẋ) ẋ² (GF App. E-C eq. 51-52). With `switched`,
/// s = 1 for ẋ < 0 and 0 otherwise (a Finsler energy that forgets the barrier when moving away,
/// GF VII-A2); without it s ≡ 1 (Riemannian). With `hold_inside` as well, s = 1 also for ẋ ≥ 0 while
/// x < 0 (inside the barrier: penetration, or a joint inside its limit margin). Closed form (s is
/// piecewise constant in x and ẋ):
///
/// ```text
/// M = g(x) s,    ξ = ½ g'(x) s ẋ².
/// ```
///
/// **Why `hold_inside` (a departure from GF VII-A2, where s depends on ẋ only).** Inside, moving away
/// is the motion the barrier must still weight. With the paper's switch, a leaf leaving a penetration
/// loses its metric, and its forcing term ψ_f'(x) (large in there, and summed over every robot sphere
/// inside the same obstacle) is resolved against the light joint-attraction mass alone: the push out
/// reached metres per second within one step of 0.01 s and diverged. Keeping g in M̃ makes the push
/// an acceleration of order ψ_f'/g, independent of how many spheres are inside. s stays HD0 in ẋ, so
/// L stays a Finsler energy; at x = 0 (moving out) the energy ½ g ẋ² is dropped, which only removes
/// energy (GF Thm IV.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchedEnergy1D<G> {
    /// The position metric g(x) > 0.
    pub metric: G,
    /// Whether the velocity-direction switch s(ẋ) is applied.
    pub switched: bool,
    /// With `switched`: keep s = 1 inside (x < 0) whatever the direction of motion.
    pub hold_inside: bool,
}

impl<G: Metric1D> SwitchedEnergy1D<G> {
    /// s(x, ẋ): 1 when approaching (ẋ < 0), when not switched, or inside with `hold_inside`; else 0.
    pub fn switch(&self, x: f64, xd: f64) -> f64 {
        if !self.switched || xd < 0.0 || (self.hold_inside && x < 0.0) {
            1.0
        } else {
            0.0
        }
    }

    /// Closed form on scalars: returns (M, ξ, L).
    pub fn eval(&self, x: f64, xd: f64) -> (f64, f64, f64) {
        let s = self.switch(x, xd);
        if s == 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let (g, dg) = self.metric.g_dg(x);
        (g * s, 0.5 * dg * s * xd * xd, 0.5 * g * s * xd * xd)
    }
}

impl<G: Metric1D> FinslerEnergy for SwitchedEnergy1D<G> {
    fn dim(&self) -> usize {
        1
    }
    fn lagrangian<D: DualNum<f64>>(&self, x: &[D], xd: &[D]) -> D {
        let s = self.switch(x[0].re(), xd[0].re());
        self.metric.g(x[0].clone()) * xd[0].clone() * xd[0].clone() * (0.5 * s)
    }
    fn equations(&self, x: &[f64], xd: &[f64], m: &mut DMatrix<f64>, xi: &mut DVector<f64>) -> f64 {
        let (mm, xx, l) = self.eval(x[0], xd[0]);
        m[(0, 0)] = mm;
        xi[0] = xx;
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_close(a: &EquationsOfMotion, b: &EquationsOfMotion, tol: f64) {
        assert!(
            (a.energy - b.energy).abs() <= tol * (1.0 + a.energy.abs()),
            "energy {} vs {}",
            a.energy,
            b.energy
        );
        for (x, y) in a.m.iter().zip(b.m.iter()) {
            assert!(
                (x - y).abs() <= tol * (1.0 + x.abs()),
                "M {} vs {}",
                a.m,
                b.m
            );
        }
        for (x, y) in a.xi.iter().zip(b.xi.iter()) {
            assert!(
                (x - y).abs() <= tol * (1.0 + x.abs()),
                "ξ {} vs {}",
                a.xi,
                b.xi
            );
        }
    }

    fn check<E: FinslerEnergy>(e: &E, x: &[f64], xd: &[f64]) {
        assert_close(
            &e.equations_of_motion(x, xd),
            &euler_lagrange_ad(e, x, xd),
            1e-10,
        );
    }

    #[test]
    fn closed_forms_match_automatic_differentiation() {
        let states: [(&[f64], &[f64]); 4] = [
            (&[0.3, -0.2, 0.1], &[1.0, 0.5, -0.7]),
            (&[-1.5, 0.02, 2.0], &[-0.1, 0.0, 0.3]),
            (&[0.01, 0.01, -0.01], &[3.0, -2.0, 1.0]),
            (&[4.0, 1.0, -2.0], &[0.0, 0.0, 0.0]),
        ];
        for (x, xd) in states {
            check(
                &IsotropicEnergy {
                    mass: ConstantMass { dim: 3, mass: 1.7 },
                },
                x,
                xd,
            );
            check(
                &IsotropicEnergy {
                    mass: TanhMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.3,
                        sharpness: 4.0,
                    },
                },
                x,
                xd,
            );
            check(
                &IsotropicEnergy {
                    mass: GaussianMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.3,
                        width: 0.8,
                    },
                },
                x,
                xd,
            );
        }
        for &x in &[0.5, 0.02, 0.004, -0.3] {
            for &xd in &[-1.2, -0.01, 0.0, 0.7] {
                for (switched, hold_inside) in [(true, false), (false, false), (true, true)] {
                    check(
                        &SwitchedEnergy1D {
                            metric: BarrierMetric {
                                gain: 0.4,
                                x_min: 0.005,
                                influence: f64::INFINITY,
                            },
                            switched,
                            hold_inside,
                        },
                        &[x],
                        &[xd],
                    );
                    check(
                        &SwitchedEnergy1D {
                            metric: InverseSquareMetric {
                                gain: 0.4,
                                x_min: 0.01,
                            },
                            switched,
                            hold_inside,
                        },
                        &[x],
                        &[xd],
                    );
                }
            }
        }
    }

    #[test]
    fn finsler_properties_hd0_metric_hd2_forces_energy_is_half_xmx() {
        let e = IsotropicEnergy {
            mass: TanhMass {
                dim: 3,
                mass_max: 2.0,
                mass_min: 0.3,
                sharpness: 4.0,
            },
        };
        let (x, xd) = ([0.3, -0.2, 0.1], [1.0, 0.5, -0.7]);
        let a = e.equations_of_motion(&x, &xd);
        for l in [0.1, 2.0, 7.5] {
            let xs: Vec<f64> = xd.iter().map(|v| v * l).collect();
            let b = e.equations_of_motion(&x, &xs);
            assert!((&b.m - &a.m).norm() < 1e-12);
            assert!((&b.xi - &a.xi * (l * l)).norm() < 1e-12 * (1.0 + l * l));
            assert!((b.energy - a.energy * l * l).abs() < 1e-12 * (1.0 + l * l));
        }
        let v = DVector::from_column_slice(&xd);
        assert!((a.energy - 0.5 * v.dot(&(&a.m * &v))).abs() < 1e-14);
        let b = SwitchedEnergy1D {
            metric: BarrierMetric {
                gain: 0.4,
                x_min: 0.005,
                influence: f64::INFINITY,
            },
            switched: true,
            hold_inside: false,
        };
        let (m, xi, l) = b.eval(0.2, -0.3);
        let (m2, xi2, l2) = b.eval(0.2, -0.9);
        assert_eq!(m, m2);
        assert!((xi2 - 9.0 * xi).abs() < 1e-14 && (l2 - 9.0 * l).abs() < 1e-14);
        assert!((l - 0.5 * m * 0.09).abs() < 1e-15);
    }

    #[test]
    fn hold_inside_keeps_the_metric_inside_whatever_the_direction() {
        let e = SwitchedEnergy1D {
            metric: BarrierMetric {
                gain: 0.4,
                x_min: 0.01,
                influence: f64::INFINITY,
            },
            switched: true,
            hold_inside: true,
        };
        let paper = SwitchedEnergy1D {
            hold_inside: false,
            ..e
        };
        let (g_in, _) = e.metric.g_dg(-0.02);
        assert_eq!(e.eval(-0.02, 0.5).0, g_in);
        assert_eq!(paper.eval(-0.02, 0.5), (0.0, 0.0, 0.0));
        for (x, xd) in [(-0.02, -0.5), (0.03, -0.5), (0.03, 0.5), (0.0, 0.5)] {
            assert_eq!(e.eval(x, xd), paper.eval(x, xd), "({x}, {xd})");
        }
    }

    #[test]
    fn barrier_metric_continuation_is_positive_and_c1() {
        let g = BarrierMetric {
            gain: 0.4,
            x_min: 0.01,
            influence: f64::INFINITY,
        };
        let (a, da) = g.g_dg(0.01 - 1e-12);
        let (b, db) = g.g_dg(0.01 + 1e-12);
        assert!((a - b).abs() < 1e-6 && (da - db).abs() < 1e-3);
        for &x in &[0.0, -0.05, -3.0] {
            let (v, d) = g.g_dg(x);
            assert!(v > 40.0 && v.is_finite() && d < 0.0);
        }
    }

    #[test]
    fn tapered_barrier_metric_is_c1_at_the_influence_radius_and_matches_ad() {
        let g = BarrierMetric {
            gain: 0.4,
            x_min: 0.01,
            influence: 0.3,
        };
        let (a, da) = g.g_dg(0.3 - 1e-9);
        assert!(
            a.abs() < 1e-12 && da.abs() < 1e-6,
            "g and g' vanish at r: {a} {da}"
        );
        assert_eq!(g.g_dg(0.5), (0.0, 0.0));
        let (g_in, dg_in) = g.g_dg(0.1);
        assert!(
            (g_in - 4.0).abs() < 1e-12 && (dg_in + 40.0).abs() < 1e-10,
            "exact k/x inside r/2"
        );
        for &x in &[0.02, 0.1, 0.16, 0.25, 0.29] {
            let (v, d) = g.g_dg(x);
            let h = 1e-6;
            let fd = (g.g_dg(x + h).0 - g.g_dg(x - h).0) / (2.0 * h);
            assert!(
                (d - fd).abs() < 1e-6 * (1.0 + d.abs()),
                "g' vs FD at {x}: {d} {fd}"
            );
            let ad = g.g(num_dual::Dual64::from(x).derivative());
            assert!((ad.re - v).abs() < 1e-12 && (ad.eps - d).abs() < 1e-9);
        }
    }
}
