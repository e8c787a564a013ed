//! Scalar potentials ψ used both as forcing terms (−∂ψ) and, through π = −‖ẋ‖² ∂ψ, as the base of HD2
//! geometries (GF App. E-C eq. 47).
//!
//! - [`LogCosh`]: the attractor ψ(x) = k log cosh(α‖x‖) on an offset x = p − p_d (GF VII-A1, VII-A3).
//!   The Sec. VI-A potential ψ₁ = k(‖x‖ + α⁻¹ log(1 + e^{−2α‖x‖})) equals (k/α) log cosh(α‖x‖) + (k/α) log 2,
//!   so it is a `LogCosh` with gain k/α.
//! - [`Potential1D`] implementations on a 1-D distance x: the barrier + soft-ReLU ψ(x) = k_b/x +
//!   (k_r/α) log(1 + e^{−α(x − x_o)}) (GF VII-A2) and the Sec. VI-B ψ₁,b(x) = α_b / (2x⁸).
//!
//! Barrier potentials blow up at x = 0. Below a threshold x_min > 0 they are continued by their second-order
//! Taylor polynomial at x_min: the gradient then continues linearly, ψ'(x) = ψ'(x_min) + ψ''(x_min)(x − x_min),
//! which stays finite, nonzero and outward (ψ' < 0 pushes x up) for any penetration depth.

use super::config::{BarrierPotentialConfig, LogCoshConfig};

/// ln cosh(y), stable for large |y|.
fn ln_cosh(y: f64) -> f64 {
    let a = y.abs();
    a + (-2.0 * a).exp().ln_1p() - std::f64::consts::LN_2
}

/// tanh(α r) / r, with its limit α at r → 0.
fn tanh_over_r(alpha: f64, r: f64) -> f64 {
    let y = alpha * r;
    if y.abs() < 1e-6 {
        alpha * (1.0 - y * y / 3.0)
    } else {
        y.tanh() / r
    }
}

/// (ln(1 + e^z), σ(z)): the softplus and its derivative, the logistic, from one exponential e^{−|z|};
/// stable for large |z|, and σ equal to [`sigmoid`] bit for bit.
fn softplus_and_sigmoid(z: f64) -> (f64, f64) {
    let e = (-z.abs()).exp();
    let sig = if z >= 0.0 {
        1.0 / (1.0 + e)
    } else {
        e / (1.0 + e)
    };
    (z.max(0.0) + e.ln_1p(), sig)
}

/// Logistic σ(z) = 1 / (1 + e^{−z}), stable for large |z|.
pub(crate) fn sigmoid(z: f64) -> f64 {
    if z >= 0.0 {
        1.0 / (1.0 + (-z).exp())
    } else {
        let e = z.exp();
        e / (1.0 + e)
    }
}

/// Radial attractor potential ψ(x) = k ln cosh(α ‖x‖) on an offset x (k,) (GF VII-A1, VII-A3), with
/// ∂ψ/∂x = k α tanh(α‖x‖) x / ‖x‖: linear (k α² x) near 0 and of constant norm k α far away.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogCosh {
    /// k: scale (the far-field gradient norm is k α).
    pub gain: f64,
    /// α: sharpness (1/unit of x).
    pub sharpness: f64,
}

impl LogCosh {
    /// From its configuration section.
    pub fn from_config(c: &LogCoshConfig) -> Self {
        LogCosh {
            gain: c.gain,
            sharpness: c.sharpness,
        }
    }

    /// ψ(x) and ∂ψ/∂x written into `grad` (same length as `x`).
    pub fn eval(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let r = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let c = self.gain * self.sharpness * tanh_over_r(self.sharpness, r);
        for (g, xi) in grad.iter_mut().zip(x) {
            *g = c * xi;
        }
        self.gain * ln_cosh(self.sharpness * r)
    }
}

/// A 1-D potential ψ(x) on a distance x, continued below x_min by its second-order Taylor polynomial.
pub trait Potential1D {
    /// x_min (> 0): below it the Taylor continuation is used.
    fn x_min(&self) -> f64;
    /// The exact (ψ, ψ', ψ'') for x ≥ x_min.
    fn exact(&self, x: f64) -> (f64, f64, f64);

    /// ψ'(x) alone, with the continuation below x_min (cheaper than [`eval`](Potential1D::eval) when the
    /// value is not needed, e.g. for geometries).
    fn slope(&self, x: f64) -> f64 {
        let x0 = self.x_min();
        if x >= x0 {
            self.exact_slope(x)
        } else {
            let (_, p1, p2) = self.exact(x0);
            p1 + p2 * (x - x0)
        }
    }

    /// The exact ψ'(x) for x ≥ x_min (default: from [`exact`](Potential1D::exact)).
    fn exact_slope(&self, x: f64) -> f64 {
        self.exact(x).1
    }

    /// (ψ, ψ', ψ'') at any x, with the continuation below x_min.
    fn eval(&self, x: f64) -> (f64, f64, f64) {
        let x0 = self.x_min();
        if x >= x0 {
            self.exact(x)
        } else {
            let (p0, p1, p2) = self.exact(x0);
            let d = x - x0;
            (p0 + p1 * d + 0.5 * p2 * d * d, p1 + p2 * d, p2)
        }
    }
}

/// Barrier plus soft-ReLU potential of GF VII-A2:
///
/// ```text
/// ψ(x) = k_b / x + (k_r / α) ln(1 + e^{−α (x − x_o)}),
/// ψ'(x) = −k_b / x² − k_r σ(−α (x − x_o)),
/// ψ''(x) = 2 k_b / x³ + k_r α σ(−α (x − x_o)) (1 − σ(−α (x − x_o))).
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BarrierPotential {
    /// k_b: barrier gain (units of ψ · m).
    pub barrier_gain: f64,
    /// k_r: soft-ReLU gain (units of ψ / m: the slope far inside x_o).
    pub relu_gain: f64,
    /// α: soft-ReLU sharpness (1/m).
    pub relu_sharpness: f64,
    /// x_o: soft-ReLU activation distance (m).
    pub relu_shift: f64,
    /// x_min (> 0): start of the Taylor continuation (m).
    pub x_min: f64,
}

impl BarrierPotential {
    /// From its configuration section and the continuation threshold x_min.
    pub fn from_config(c: &BarrierPotentialConfig, x_min: f64) -> Self {
        BarrierPotential {
            barrier_gain: c.barrier_gain,
            relu_gain: c.relu_gain,
            relu_sharpness: c.relu_sharpness,
            relu_shift: c.relu_shift,
            x_min,
        }
    }
}

impl Potential1D for BarrierPotential {
    fn x_min(&self) -> f64 {
        self.x_min
    }
    fn exact_slope(&self, x: f64) -> f64 {
        let relu = if self.relu_sharpness > 0.0 {
            -self.relu_gain * sigmoid(-self.relu_sharpness * (x - self.relu_shift))
        } else {
            0.0
        };
        -self.barrier_gain / (x * x) + relu
    }
    fn exact(&self, x: f64) -> (f64, f64, f64) {
        let a = self.relu_sharpness;
        let (relu, relu1, relu2) = if a > 0.0 {
            let (softplus, sig) = softplus_and_sigmoid(-a * (x - self.relu_shift));
            (
                self.relu_gain / a * softplus,
                -self.relu_gain * sig,
                self.relu_gain * a * sig * (1.0 - sig),
            )
        } else {
            (0.0, 0.0, 0.0)
        };
        let b = self.barrier_gain;
        (
            b / x + relu,
            -b / (x * x) + relu1,
            2.0 * b / (x * x * x) + relu2,
        )
    }
}

/// The Sec. VI-B circle potential base ψ₁,b(x) = α_b / (2 x⁸), ψ' = −4 α_b / x⁹, ψ'' = 36 α_b / x¹⁰.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InversePower8 {
    /// α_b: gain.
    pub gain: f64,
    /// x_min (> 0): start of the Taylor continuation.
    pub x_min: f64,
}

impl Potential1D for InversePower8 {
    fn x_min(&self) -> f64 {
        self.x_min
    }
    fn exact(&self, x: f64) -> (f64, f64, f64) {
        let x8 = x.powi(8);
        (
            0.5 * self.gain / x8,
            -4.0 * self.gain / (x8 * x),
            36.0 * self.gain / (x8 * x * x),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fd<F: Fn(f64) -> f64>(f: F, x: f64) -> f64 {
        let h = 1e-6 * x.abs().max(1e-3);
        (f(x + h) - f(x - h)) / (2.0 * h)
    }

    #[test]
    fn barrier_derivatives_match_finite_differences_including_continuation() {
        let p = BarrierPotential {
            barrier_gain: 0.02,
            relu_gain: 3.0,
            relu_sharpness: 20.0,
            relu_shift: 0.1,
            x_min: 0.01,
        };
        for &x in &[-0.05, -0.001, 0.004, 0.0099, 0.0101, 0.05, 0.1, 0.3, 1.0] {
            let (_, d1, d2) = p.eval(x);
            assert!(
                (d1 - fd(|y| p.eval(y).0, x)).abs() <= 1e-5 * d1.abs().max(1.0),
                "ψ' at {x}"
            );
            assert!(
                (d2 - fd(|y| p.eval(y).1, x)).abs() <= 1e-4 * d2.abs().max(1.0),
                "ψ'' at {x}"
            );
            assert!(d1 < 0.0, "outward push at {x}");
        }
        for &x in &[-0.05, 0.004, 0.02, 0.3] {
            assert!((p.slope(x) - p.eval(x).1).abs() < 1e-12);
        }
        // continuity at x_min
        let a = p.eval(0.01 - 1e-12);
        let b = p.eval(0.01 + 1e-12);
        assert!((a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-3);
    }

    #[test]
    fn softplus_and_sigmoid_match_their_definitions() {
        for z in [-800.0, -30.0, -2.5, -1e-9, 0.0, 1e-9, 0.7, 30.0, 800.0] {
            let (sp, sig) = softplus_and_sigmoid(z);
            assert_eq!(sig, sigmoid(z));
            let exact = if z > 30.0 {
                z + (-z).exp().ln_1p()
            } else {
                z.exp().ln_1p()
            };
            assert!(
                (sp - exact).abs() <= 1e-12 * exact.abs().max(1e-300) + 1e-15,
                "{z}: {sp} vs {exact}"
            );
            assert!(sp.is_finite() && sig.is_finite() && (0.0..=1.0).contains(&sig));
        }
    }

    #[test]
    fn inverse_power8_derivatives() {
        let p = InversePower8 {
            gain: 0.5,
            x_min: 0.05,
        };
        for &x in &[0.01, 0.06, 0.3, 2.0] {
            let (_, d1, d2) = p.eval(x);
            assert!((d1 - fd(|y| p.eval(y).0, x)).abs() <= 1e-5 * d1.abs().max(1.0));
            assert!((d2 - fd(|y| p.eval(y).1, x)).abs() <= 1e-4 * d2.abs().max(1.0));
        }
    }

    #[test]
    fn log_cosh_gradient_and_limits() {
        let p = LogCosh {
            gain: 1.5,
            sharpness: 4.0,
        };
        let x = [0.3, -0.2, 0.05];
        let mut g = [0.0; 3];
        p.eval(&x, &mut g);
        for i in 0..3 {
            let f = |h: f64| {
                let mut y = x;
                y[i] += h;
                p.eval(&y, &mut [0.0; 3])
            };
            let num = (f(1e-6) - f(-1e-6)) / 2e-6;
            assert!((g[i] - num).abs() < 1e-7);
        }
        // far field: |∇ψ| → k α; near field: ∇ψ ≈ k α² x
        let mut gf = [0.0; 1];
        p.eval(&[100.0], &mut gf);
        assert!((gf[0] - 6.0).abs() < 1e-12);
        let mut gn = [0.0; 1];
        p.eval(&[1e-9], &mut gn);
        assert!((gn[0] - 1.5 * 16.0 * 1e-9).abs() < 1e-18);
        assert_eq!(p.eval(&[0.0, 0.0], &mut [0.0; 2]), 0.0);
        // Sec. VI-A identity: k(r + ln(1 + e^{−2αr})/α) = (k/α)(ln cosh(αr) + ln 2)
        let (k, a, r): (f64, f64, f64) = (2.0, 3.0, 0.7);
        let lhs = k * (r + (1.0 + (-2.0 * a * r).exp()).ln() / a);
        let rhs = LogCosh {
            gain: k / a,
            sharpness: a,
        }
        .eval(&[r], &mut [0.0])
            + k / a * std::f64::consts::LN_2;
        assert!((lhs - rhs).abs() < 1e-12);
    }
}
