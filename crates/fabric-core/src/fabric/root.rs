//! The root (joint-space) system of a transform tree: accumulation of pulled-back component specs
//! (GF eq. 11-12, 15-17) and its resolution into an acceleration (energization eq. 7, speed control
//! eq. 40-46). Shared by the robot engine and the 2-D particle systems.
//!
//! Every component contributes, through its task map x = φ(q) with Jacobian J and curvature J̇q̇:
//!
//! ```text
//! M̃ += Jᵀ M J                     (energy metric = geometry metric)
//! ξ̃ += Jᵀ (ξ + M J̇q̇)              (energy spec (M, ξ) pulled back, eq. 12)
//! f̃ += Jᵀ (−Mπ + M J̇q̇)            (geometry spec (M, −Mπ) pulled back, Thm IV.6)
//! ∂ψ += Jᵀ ∂ψ_x                   (forcing potential gradient)
//! ```
//!
//! Resolution: π̃ = −M̃⁻¹ f̃ (Bent) or π̃ = −M̃⁻¹ ξ̃ (Unbent: the energy's own, unbent geodesics),
//! α_Le = −(q̇ᵀM̃q̇)⁻¹ q̇ᵀ(M̃π̃ + ξ̃) (eq. 7; exactly 0 when unbent), then eq. 40:
//! q̈ = −M̃⁻¹∂ψ + π̃ + α_reg q̇ with α_reg from [`speed::regulate`](super::speed::regulate).

// Dense numeric kernels over small matrices: index loops are the clearest form here.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector, Dim, Dyn, Matrix, Storage};

use super::config::{Mode, SpeedConfig};
use super::spec::{cholesky_in_place, cholesky_solve_many, ENERGIZATION_EPSILON};
use super::speed::{regulate, regulated_acceleration, EeMotion, SpeedInputs, SpeedTerms};
use crate::error::{FabricError, Result};

/// Preallocated root accumulators and solver scratch for an n-dimensional configuration space.
#[derive(Clone, Debug)]
pub struct RootSystem {
    /// M̃ (n × n).
    pub m: DMatrix<f64>,
    /// ξ̃ (n,).
    pub xi: DVector<f64>,
    /// f̃ (n,): pulled-back geometry forces.
    pub f: DVector<f64>,
    /// ∂ψ (n,): pulled-back forcing gradients.
    pub grad: DVector<f64>,
    /// Σ ψ: total forcing potential.
    pub psi: f64,
    chol: DMatrix<f64>,
    /// π̃ (n,) after [`solve`](RootSystem::solve).
    pub pi: DVector<f64>,
    /// M̃⁻¹∂ψ (n,) after [`solve`](RootSystem::solve).
    pub minv_grad: DVector<f64>,
    scratch: DVector<f64>,
}

/// Scalars of one resolution.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RootTerms {
    /// Fabric energy L̃_e = ½ q̇ᵀ M̃ q̇ (a Finsler energy equals its Hamiltonian, GF Sec. III-A).
    pub energy: f64,
    /// Total forcing potential ψ.
    pub potential: f64,
    /// α_Le of eq. 7 for π̃ w.r.t. L̃_e (0 when unbent).
    pub alpha_le: f64,
    /// Speed-control coefficients.
    pub speed: SpeedTerms,
}

impl RootSystem {
    /// Zeroed accumulators for dimension n.
    pub fn new(n: usize) -> Self {
        RootSystem {
            m: DMatrix::zeros(n, n),
            xi: DVector::zeros(n),
            f: DVector::zeros(n),
            grad: DVector::zeros(n),
            psi: 0.0,
            chol: DMatrix::zeros(n, n),
            pi: DVector::zeros(n),
            minv_grad: DVector::zeros(n),
            scratch: DVector::zeros(n),
        }
    }

    /// Dimension n.
    pub fn dim(&self) -> usize {
        self.xi.len()
    }

    /// Reset the accumulators to zero.
    pub fn clear(&mut self) {
        self.m.fill(0.0);
        self.xi.fill(0.0);
        self.f.fill(0.0);
        self.grad.fill(0.0);
        self.psi = 0.0;
    }

    /// Add an isotropic component (M = m I on R^k) through a Jacobian `jac` (k × n) and J̇q̇ `jdqd` (k,):
    /// M̃ += m JᵀJ, ξ̃ += Jᵀ(ξ + m J̇q̇), f̃ += Jᵀ(f + m J̇q̇), ∂ψ += Jᵀ grad, ψ += psi.
    #[allow(clippy::too_many_arguments)]
    pub fn add_isotropic<R: Dim, S: Storage<f64, R, Dyn>>(
        &mut self,
        jac: &Matrix<f64, R, Dyn, S>,
        jdqd: &[f64],
        mass: f64,
        xi: &[f64],
        f: &[f64],
        grad: &[f64],
        psi: f64,
    ) {
        let n = self.dim();
        let k = jac.nrows();
        for a in 0..n {
            let (mut sx, mut sf, mut sg) = (0.0, 0.0, 0.0);
            for r in 0..k {
                let j = jac[(r, a)];
                let c = mass * jdqd[r];
                sx += j * (xi[r] + c);
                sf += j * (f[r] + c);
                sg += j * grad[r];
            }
            self.xi[a] += sx;
            self.f[a] += sf;
            self.grad[a] += sg;
            if mass != 0.0 {
                for b in a..n {
                    let mut s = 0.0;
                    for r in 0..k {
                        s += jac[(r, a)] * jac[(r, b)];
                    }
                    let v = mass * s;
                    self.m[(a, b)] += v;
                    if b != a {
                        self.m[(b, a)] += v;
                    }
                }
            }
        }
        self.psi += psi;
    }

    /// Add an isotropic component living directly on the root (J = I, J̇q̇ = 0):
    /// M̃ += m I, ξ̃ += ξ, f̃ += f, ∂ψ += grad (all (n,)), ψ += psi.
    pub fn add_identity(&mut self, mass: f64, xi: &[f64], f: &[f64], grad: &[f64], psi: f64) {
        for a in 0..self.dim() {
            self.m[(a, a)] += mass;
            self.xi[a] += xi[a];
            self.f[a] += f[a];
            self.grad[a] += grad[a];
        }
        self.psi += psi;
    }

    /// Add a component living on scaled root coordinates x = S q (J = S = diag(`s`), J̇q̇ = 0) with an
    /// isotropic metric m I: M̃ += m S², ξ̃ += S ξ, f̃ += S f, ∂ψ += S grad (all (n,)), ψ += psi.
    pub fn add_diagonal(
        &mut self,
        s: &[f64],
        mass: f64,
        xi: &[f64],
        f: &[f64],
        grad: &[f64],
        psi: f64,
    ) {
        for a in 0..self.dim() {
            self.m[(a, a)] += mass * s[a] * s[a];
            self.xi[a] += s[a] * xi[a];
            self.f[a] += s[a] * f[a];
            self.grad[a] += s[a] * grad[a];
        }
        self.psi += psi;
    }

    /// Add a 1-D component through a row Jacobian `j` and scalar J̇q̇:
    /// M̃ += m jjᵀ, ξ̃ += j(ξ + m J̇q̇), f̃ += j(f + m J̇q̇), ∂ψ += j grad, ψ += psi.
    /// `j` holds the leading entries of the row (length w ≤ n), the others being zero (a point on a link
    /// that the last coordinates do not move, [`TaskPoint::width`](crate::robot::TaskPoint::width)): only
    /// the leading w × w block and w entries change, which is what the full update would add, bit for bit.
    /// Only the upper triangle of M̃ is updated here; [`solve`](RootSystem::solve) mirrors it.
    ///
    /// # Panics
    /// When `j` is longer than n.
    #[allow(clippy::too_many_arguments)]
    pub fn add_scalar(
        &mut self,
        j: &[f64],
        jdqd: f64,
        m: f64,
        xi: f64,
        f: f64,
        grad: f64,
        psi: f64,
    ) {
        let n = self.dim();
        assert!(
            j.len() <= n,
            "row Jacobian of {} entries for dimension {n}",
            j.len()
        );
        let c = m * jdqd;
        let (ex, ef) = (xi + c, f + c);
        let (mm, xs, fs, gs) = (
            self.m.as_mut_slice(),
            self.xi.as_mut_slice(),
            self.f.as_mut_slice(),
            self.grad.as_mut_slice(),
        );
        // the same kernel, unrolled for the common arm sizes
        match j.len() {
            7 => rank_one::<7>(mm, n, xs, fs, gs, j, m, ex, ef, grad),
            6 => rank_one::<6>(mm, n, xs, fs, gs, j, m, ex, ef, grad),
            _ => rank_one::<0>(mm, n, xs, fs, gs, j, m, ex, ef, grad),
        }
        self.psi += psi;
    }

    /// Add a 1-D component on coordinate `i` with J = sign · e_iᵀ (sign = ±1) and J̇q̇ = 0 (joint limits).
    #[allow(clippy::too_many_arguments)]
    pub fn add_coordinate(
        &mut self,
        i: usize,
        sign: f64,
        m: f64,
        xi: f64,
        f: f64,
        grad: f64,
        psi: f64,
    ) {
        self.m[(i, i)] += m;
        self.xi[i] += sign * xi;
        self.f[i] += sign * f;
        self.grad[i] += sign * grad;
        self.psi += psi;
    }

    /// Copy the upper triangle of M̃ into its lower triangle ([`add_scalar`](RootSystem::add_scalar) only
    /// accumulates the upper triangle; every other adder is symmetric). Called by `solve`.
    pub fn symmetrize(&mut self) {
        let n = self.dim();
        for b in 0..n {
            for a in (b + 1)..n {
                self.m[(a, b)] = self.m[(b, a)];
            }
        }
    }

    /// Resolve the accumulated system at velocity `qd` into `qdd` (eq. 7, 17, 40-46). `goal_distance` is
    /// ‖q − q_g‖ for the speed switches; `damping_mass` is the mass m of a force-level goal damper
    /// (`GoalDampingForm::Force`: q̈ −= s_β B m M̃⁻¹ q̇, or q̈ −= s_β B m M̃⁻¹ S² q̇ with the joint
    /// attractor's scales S = diag(`damping_scales`), the metric of its energy); `ee` the end-effector
    /// motion for an execution energy with `speed.ee_weight` > 0. Errors when M̃ is not positive definite
    /// or the result is not finite.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        mode: Mode,
        speed: &SpeedConfig,
        qd: &[f64],
        goal_distance: f64,
        damping_mass: f64,
        damping_scales: Option<&[f64]>,
        ee: Option<EeMotion<'_>>,
        qdd: &mut [f64],
    ) -> Result<RootTerms> {
        let n = self.dim();
        self.symmetrize();
        self.chol.copy_from(&self.m);
        if !cholesky_in_place(&mut self.chol) {
            return Err(FabricError::Value {
                what: "fabric root metric M̃".to_string(),
                message: "not positive definite (or not finite) at this state".to_string(),
            });
        }
        // π̃ = −M̃⁻¹ f̃ (bent) or −M̃⁻¹ ξ̃ (unbent)
        let src = match mode {
            Mode::Bent => &self.f,
            Mode::Unbent => &self.xi,
        };
        for a in 0..n {
            self.pi[a] = -src[a];
        }
        self.minv_grad.copy_from(&self.grad);
        // M̃⁻¹ q̇ (or M̃⁻¹ S² q̇) for a force-level goal damper, solved beside π̃ and M̃⁻¹∂ψ: whether the
        // damper acts is known only after the speed regulation below, and the third right-hand side
        // costs little when solved with the other two
        self.scratch.as_mut_slice().copy_from_slice(qd);
        if let Some(s) = damping_scales {
            for a in 0..n {
                self.scratch[a] *= s[a] * s[a];
            }
        }
        cholesky_solve_many(
            &self.chol,
            [
                self.pi.as_mut_slice(),
                self.minv_grad.as_mut_slice(),
                self.scratch.as_mut_slice(),
            ],
        );

        // q̇ᵀM̃q̇ and α_Le = −q̇ᵀ(M̃π̃ + ξ̃)/q̇ᵀM̃q̇ with M̃π̃ = −f̃ (bent) or −ξ̃ (unbent, α = 0)
        let mut qmq = 0.0;
        for a in 0..n {
            let mut s = 0.0;
            for b in 0..n {
                s += self.m[(a, b)] * qd[b];
            }
            qmq += qd[a] * s;
        }
        let alpha_le = match mode {
            Mode::Bent if qmq > ENERGIZATION_EPSILON => {
                let mut num = 0.0;
                for a in 0..n {
                    num += qd[a] * (self.xi[a] - self.f[a]);
                }
                -num / qmq
            }
            _ => 0.0,
        };
        let speed_terms = regulate(
            speed,
            &SpeedInputs {
                qd,
                pi: self.pi.as_slice(),
                minv_grad: self.minv_grad.as_slice(),
                alpha_le,
                goal_distance,
                ee,
            },
        );
        regulated_acceleration(
            self.minv_grad.as_slice(),
            self.pi.as_slice(),
            speed_terms.alpha_reg,
            qd,
            qdd,
        );
        let d = speed_terms.force_damping * damping_mass;
        if d != 0.0 {
            for a in 0..n {
                qdd[a] -= d * self.scratch[a];
            }
        }
        if !qdd.iter().all(|v| v.is_finite()) {
            return Err(FabricError::NonFinite {
                what: "fabric acceleration q̈ at this state".to_string(),
            });
        }
        Ok(RootTerms {
            energy: 0.5 * qmq,
            potential: self.psi,
            alpha_le,
            speed: speed_terms,
        })
    }
}

/// The rank-one update of [`RootSystem::add_scalar`] on the raw column-major storage of M̃ (`dim` × `dim`)
/// and the vectors (`dim`,), for a row `j` of w leading entries, w = `N` (a compile-time length: the loops
/// unroll) or, for `N = 0`, `j.len()`: M̃ += m jjᵀ (upper triangle of the leading w × w block),
/// ξ̃ += j ex, f̃ += j ef, ∂ψ += j grad (leading w entries).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn rank_one<const N: usize>(
    mm: &mut [f64],
    dim: usize,
    xi: &mut [f64],
    f: &mut [f64],
    gr: &mut [f64],
    j: &[f64],
    m: f64,
    ex: f64,
    ef: f64,
    grad: f64,
) {
    let w = if N == 0 { j.len() } else { N };
    // plain slices of one length: no bounds checks in the loops
    let (j, xi, f, gr) = (&j[..w], &mut xi[..w], &mut f[..w], &mut gr[..w]);
    for a in 0..w {
        let ja = j[a];
        xi[a] += ja * ex;
        f[a] += ja * ef;
        gr[a] += ja * grad;
    }
    if m != 0.0 {
        // upper triangle only; `solve` reads the upper triangle (see `symmetrize`). Column b of the
        // column-major M̃ holds rows 0..=b of the triangle contiguously.
        for (b, col) in mm[..w * dim].chunks_exact_mut(dim).enumerate() {
            let mjb = m * j[b];
            for (mab, &ja) in col[..=b].iter_mut().zip(j) {
                *mab += ja * mjb;
            }
        }
    }
}
