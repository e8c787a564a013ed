//! Spec algebra (GF App. E-A): a spec (M, f) stands for the system M ẍ + f = 0, so ẍ = −M⁻¹ f.
//!
//! - sum (eq. 15): α(M₁, f₁) + β(M₂, f₂) = (αM₁ + βM₂, αf₁ + βf₂);
//! - pullback through x = φ(q), J = ∂φ/∂q (eq. 11-12, 16): (JᵀMJ, Jᵀ(f + M J̇q̇));
//! - energization (Thm IV.5, eq. 7-9): ẍ = π + α ẋ with α = −(ẋᵀMẋ)⁻¹ ẋᵀ(Mπ + ξ).
//!
//! **ẋ = 0.** Eq. 7 divides by ẋᵀMẋ. When ẋᵀMẋ ≤ [`ENERGIZATION_EPSILON`] the coefficient is defined as
//! α := 0. For an HD2 geometry π and HD2 ξ the numerator is O(‖ẋ‖³) and the denominator O(‖ẋ‖²), so α → 0
//! as ẋ → 0: the convention is the continuous extension, and α ẋ → 0 in any case.
//!
//! The allocation-free helpers (`cholesky_in_place`, `cholesky_solve_many`) are
//! used by the engine.

use nalgebra::{DMatrix, DVector};

use crate::error::{FabricError, Result};

/// Below this value of ẋᵀMẋ (units of energy, ×2) the energization coefficient is 0 (see module docs).
pub const ENERGIZATION_EPSILON: f64 = 1e-12;

/// A spec (M, f): the second-order system M ẍ + f = 0 on a k-dimensional space (GF App. E-A).
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    /// Metric / mass M (k × k), symmetric positive semi-definite.
    pub m: DMatrix<f64>,
    /// Force f (k,), so that ẍ = −M⁻¹ f.
    pub f: DVector<f64>,
}

fn shape_error(what: &str, expected: String, got: String) -> FabricError {
    FabricError::Shape {
        what: what.to_string(),
        expected,
        got,
    }
}

impl Spec {
    /// The zero spec (0, 0) on R^k.
    pub fn zeros(k: usize) -> Spec {
        Spec {
            m: DMatrix::zeros(k, k),
            f: DVector::zeros(k),
        }
    }

    /// A spec from M (k × k) and f (k,); errors when the shapes disagree.
    pub fn new(m: DMatrix<f64>, f: DVector<f64>) -> Result<Spec> {
        if m.nrows() != m.ncols() || m.nrows() != f.len() {
            return Err(shape_error(
                "spec (M, f)",
                format!("({k}, {k}) and ({k},)", k = f.len()),
                format!("({}, {}) and ({},)", m.nrows(), m.ncols(), f.len()),
            ));
        }
        Ok(Spec { m, f })
    }

    /// The metric-weighted geometry spec (M, −Mπ) of a geometry ẍ = π (GF Thm IV.6).
    pub fn from_geometry(m: DMatrix<f64>, pi: &DVector<f64>) -> Result<Spec> {
        let f = -(&m * pi);
        Spec::new(m, f)
    }

    /// Dimension k.
    pub fn dim(&self) -> usize {
        self.f.len()
    }

    /// self += w · other (GF eq. 15).
    pub fn add_scaled(&mut self, w: f64, other: &Spec) -> Result<()> {
        if other.dim() != self.dim() {
            return Err(shape_error(
                "spec sum",
                format!("dimension {}", self.dim()),
                format!("dimension {}", other.dim()),
            ));
        }
        self.m += &other.m * w;
        self.f += &other.f * w;
        Ok(())
    }

    /// Pullback through a map with Jacobian `jac` (k × n) and curvature term `jdot_qdot` = J̇q̇ (k,)
    /// (GF eq. 12, 16): (JᵀMJ, Jᵀ(f + M J̇q̇)), a spec on R^n.
    pub fn pullback(&self, jac: &DMatrix<f64>, jdot_qdot: &DVector<f64>) -> Result<Spec> {
        let mut out = Spec::zeros(jac.ncols());
        self.pullback_add_into(jac, jdot_qdot, &mut out)?;
        Ok(out)
    }

    /// out += pull(self) (GF eq. 12, 16); `out` must have dimension n = jac.ncols().
    pub fn pullback_add_into(
        &self,
        jac: &DMatrix<f64>,
        jdot_qdot: &DVector<f64>,
        out: &mut Spec,
    ) -> Result<()> {
        let k = self.dim();
        if jac.nrows() != k || jdot_qdot.len() != k || out.dim() != jac.ncols() {
            return Err(shape_error(
                "spec pullback",
                format!(
                    "J ({k}, {n}), J̇q̇ ({k},), output dimension {n}",
                    n = out.dim()
                ),
                format!(
                    "J ({}, {}), J̇q̇ ({},)",
                    jac.nrows(),
                    jac.ncols(),
                    jdot_qdot.len()
                ),
            ));
        }
        let mj = &self.m * jac;
        out.m += jac.transpose() * mj;
        let g = &self.f + &self.m * jdot_qdot;
        out.f += jac.transpose() * g;
        Ok(())
    }

    /// Resolve ẍ = −M⁻¹ f (Cholesky); errors when M is not positive definite.
    pub fn resolve(&self) -> Result<DVector<f64>> {
        let chol = self
            .m
            .clone()
            .cholesky()
            .ok_or_else(|| FabricError::Value {
                what: "spec metric M".to_string(),
                message: "not positive definite".to_string(),
            })?;
        Ok(-chol.solve(&self.f))
    }
}

/// Energization coefficient of GF Thm IV.5 eq. 7, α = −(ẋᵀMẋ)⁻¹ ẋᵀ(Mπ + ξ), from the energy's (M, ξ),
/// the geometry π and the velocity ẋ (all length k); α := 0 when ẋᵀMẋ ≤ [`ENERGIZATION_EPSILON`].
/// The energized system ẍ = π + α ẋ conserves the energy L_e.
pub fn energization_coefficient(
    m: &DMatrix<f64>,
    xi: &DVector<f64>,
    pi: &DVector<f64>,
    xd: &DVector<f64>,
) -> f64 {
    let mxd = m * xd;
    let den = xd.dot(&mxd);
    if den <= ENERGIZATION_EPSILON {
        return 0.0;
    }
    // ẋᵀ(Mπ + ξ) = (Mẋ)ᵀπ + ẋᵀξ  (M symmetric)
    -(mxd.dot(pi) + xd.dot(xi)) / den
}

/// The energized geometry ẍ = π + α ẋ (GF eq. 7-8).
pub fn energize(
    m: &DMatrix<f64>,
    xi: &DVector<f64>,
    pi: &DVector<f64>,
    xd: &DVector<f64>,
) -> DVector<f64> {
    let a = energization_coefficient(m, xi, pi, xd);
    pi + xd * a
}

/// The bending term of the energized fabric, f_f = −P_e[Mπ + ξ] (GF eq. 8-9), with
/// P_e w = w − Mẋ (ẋᵀw)/(ẋᵀMẋ) (GF Lemma C.2). It is zero-work: ẋᵀ f_f = 0. At ẋᵀMẋ ≤ ε, P_e := I.
pub fn bending_force(
    m: &DMatrix<f64>,
    xi: &DVector<f64>,
    pi: &DVector<f64>,
    xd: &DVector<f64>,
) -> DVector<f64> {
    let w = m * pi + xi;
    let mxd = m * xd;
    let den = xd.dot(&mxd);
    if den <= ENERGIZATION_EPSILON {
        return -w;
    }
    let c = xd.dot(&w) / den;
    -(w - mxd * c)
}

/// In-place Cholesky factorisation A = L Lᵀ of a symmetric positive-definite matrix; the lower triangle
/// of `a` receives L (the strict upper triangle is left untouched). Returns false (leaving `a` partially
/// overwritten) when a pivot is not positive and finite. No allocation.
pub(crate) fn cholesky_in_place(a: &mut DMatrix<f64>) -> bool {
    let n = a.nrows();
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if d.is_nan() || d <= 0.0 || !d.is_finite() {
            return false;
        }
        let ljj = d.sqrt();
        a[(j, j)] = ljj;
        for i in (j + 1)..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / ljj;
        }
    }
    true
}

/// Solve L Lᵀ xₖ = bₖ in place (bₖ ← xₖ) for K right-hand sides at once, with the factor from
/// [`cholesky_in_place`]. Every bₖ undergoes exactly the operations of a solve of its own (the same
/// values bit for bit); interleaving them lets the K chains of divisions, whose latency dominates a
/// small triangular solve, run side by side. No allocation.
///
/// # Panics
/// When a bₖ is shorter than n.
pub(crate) fn cholesky_solve_many<const K: usize>(l: &DMatrix<f64>, b: [&mut [f64]; K]) {
    let n = l.nrows();
    // column-major: L[(i, k)] = lm[i + k n]
    let lm = &l.as_slice()[..n * n];
    for i in 0..n {
        let mut s: [f64; K] = std::array::from_fn(|r| b[r][i]);
        for k in 0..i {
            let lik = lm[i + k * n];
            for r in 0..K {
                s[r] -= lik * b[r][k];
            }
        }
        let lii = lm[i + i * n];
        for r in 0..K {
            b[r][i] = s[r] / lii;
        }
    }
    for i in (0..n).rev() {
        let mut s: [f64; K] = std::array::from_fn(|r| b[r][i]);
        let col = &lm[i * n..(i + 1) * n];
        for k in (i + 1)..n {
            let lki = col[k];
            for r in 0..K {
                s[r] -= lki * b[r][k];
            }
        }
        let lii = col[i];
        for r in 0..K {
            b[r][i] = s[r] / lii;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spd(n: usize, seed: u64) -> DMatrix<f64> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let a = DMatrix::from_fn(n, n, |_, _| next());
        &a * a.transpose() + DMatrix::identity(n, n) * 0.5
    }

    #[test]
    fn cholesky_matches_nalgebra() {
        for n in 1..9 {
            let a = spd(n, n as u64);
            let b: Vec<f64> = (0..n).map(|i| (i as f64) - 1.5).collect();
            let mut l = a.clone();
            assert!(cholesky_in_place(&mut l));
            let mut x = b.clone();
            cholesky_solve_many(&l, [&mut x]);
            let reference = a
                .clone()
                .cholesky()
                .unwrap()
                .solve(&DVector::from_vec(b.clone()));
            for i in 0..n {
                assert!((x[i] - reference[i]).abs() < 1e-10);
            }
            // several right-hand sides at once: each the same bit for bit as solved alone
            let c: Vec<f64> = (0..n).map(|i| 0.7 - (i as f64) * 0.3).collect();
            let (mut x2, mut y2, mut z2) = (b.clone(), c.clone(), b.clone());
            cholesky_solve_many(&l, [&mut x2, &mut y2, &mut z2]);
            let mut y = c.clone();
            cholesky_solve_many(&l, [&mut y]);
            assert_eq!((&x2, &y2, &z2), (&x, &y, &x));
        }
        let mut bad = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        assert!(!cholesky_in_place(&mut bad));
        let mut nan = DMatrix::from_row_slice(1, 1, &[f64::NAN]);
        assert!(!cholesky_in_place(&mut nan));
    }

    #[test]
    fn energization_at_rest_is_zero_and_continuous() {
        let m = spd(3, 7);
        // HD2 geometry and ξ: scale them by |ẋ|² so that α → 0 as ẋ → 0.
        let dir = DVector::from_vec(vec![0.3, -0.5, 0.8]);
        let pi0 = DVector::from_vec(vec![1.0, 2.0, -1.0]);
        let xi0 = DVector::from_vec(vec![-0.3, 0.1, 0.4]);
        let mut last = f64::INFINITY;
        for e in [1e-1, 1e-2, 1e-3, 1e-4, 1e-5] {
            let xd = &dir * e;
            let s2 = xd.norm_squared();
            let a = energization_coefficient(&m, &(&xi0 * s2), &(&pi0 * s2), &xd);
            assert!(a.abs() < last);
            last = a.abs();
        }
        assert!(last < 1e-4);
        let zero = DVector::zeros(3);
        assert_eq!(energization_coefficient(&m, &xi0, &pi0, &zero), 0.0);
        assert_eq!(energize(&m, &xi0, &pi0, &zero), pi0);
    }

    #[test]
    fn shape_errors() {
        let s = Spec::zeros(2);
        let j = DMatrix::zeros(3, 4);
        assert!(s.pullback(&j, &DVector::zeros(3)).is_err());
        assert!(Spec::new(DMatrix::zeros(2, 2), DVector::zeros(3)).is_err());
        let mut t = Spec::zeros(3);
        assert!(t.add_scaled(1.0, &s).is_err());
        assert!(Spec::new(DMatrix::zeros(2, 2), DVector::zeros(2))
            .unwrap()
            .resolve()
            .is_err());
    }
}
