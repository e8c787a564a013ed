//! Fixed-step integrators of the double integrator of GFCS eq. 1:
//! d/dt (q̇, q) = (f(q, q̇), q̇), with the acceleration q̈ = f(q, q̇) given by a closure.
//!
//! Both schemes take the acceleration at the step-start state as an input (the caller has already
//! evaluated it, to record it and to test it for finiteness), so semi-implicit Euler costs no further
//! evaluation and RK4 three more.

use crate::error::Result;

/// Fixed-step integration scheme for (q, q̇) with q̈ = f(q, q̇).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Integrator {
    /// Semi-implicit (symplectic) Euler, first order: q̇ ← q̇ + dt·q̈, then q ← q + dt·q̇ (the new q̇).
    /// The scheme of both papers (Euler at dt = 0.01 s, GFCS Sec. IV-A after eq. 3). One evaluation of f
    /// per step.
    #[default]
    SemiImplicitEuler,
    /// Classical fourth-order Runge–Kutta on the first-order system y = (q, q̇), y' = (q̇, f(q, q̇)).
    /// Four evaluations of f per step.
    Rk4,
}

impl Integrator {
    /// Evaluations of the acceleration per step (1 for Euler, 4 for RK4), counting the step-start one.
    pub fn evaluations_per_step(self) -> usize {
        match self {
            Integrator::SemiImplicitEuler => 1,
            Integrator::Rk4 => 4,
        }
    }

    /// Advance one step of `dt` seconds from (q, q̇) = (`q`, `qd`), all slices of length dof.
    ///
    /// * `qdd`: f(q, q̇) at the step-start state (rad/s² or m/s² per joint), already evaluated.
    /// * `accel`: the acceleration f, called as `accel(q, q̇, q̈_out)`; RK4 calls it three times at stage
    ///   states, Euler never.
    /// * `q_out`, `qd_out`: the state at t + dt.
    ///
    /// Returns `Ok(false)` (outputs unspecified) when an RK4 stage state or stage acceleration is NaN or
    /// infinite: the caller treats this as a diverged rollout. Errors of `accel` are propagated.
    /// Slices must all have the length of `scratch` (checked by the callers, not here).
    #[allow(clippy::too_many_arguments)]
    pub fn step<F>(
        self,
        accel: &mut F,
        dt: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        q_out: &mut [f64],
        qd_out: &mut [f64],
        scratch: &mut StepScratch,
    ) -> Result<bool>
    where
        F: FnMut(&[f64], &[f64], &mut [f64]) -> Result<()>,
    {
        match self {
            Integrator::SemiImplicitEuler => {
                for i in 0..q.len() {
                    qd_out[i] = qd[i] + dt * qdd[i];
                    q_out[i] = q[i] + dt * qd_out[i];
                }
                Ok(true)
            }
            Integrator::Rk4 => rk4_step(accel, dt, q, qd, qdd, q_out, qd_out, scratch),
        }
    }
}

/// Stage buffers for [`Integrator::step`] (only RK4 uses them). Create once per rollout or per thread.
#[derive(Clone, Debug)]
pub struct StepScratch {
    q2: Vec<f64>,
    v2: Vec<f64>,
    a2: Vec<f64>,
    q3: Vec<f64>,
    v3: Vec<f64>,
    a3: Vec<f64>,
    q4: Vec<f64>,
    v4: Vec<f64>,
    a4: Vec<f64>,
}

impl StepScratch {
    /// Buffers for a system with `dof` coordinates.
    pub fn new(dof: usize) -> Self {
        let z = vec![0.0; dof];
        StepScratch {
            q2: z.clone(),
            v2: z.clone(),
            a2: z.clone(),
            q3: z.clone(),
            v3: z.clone(),
            a3: z.clone(),
            q4: z.clone(),
            v4: z.clone(),
            a4: z,
        }
    }

    /// Number of coordinates the buffers hold.
    pub fn dof(&self) -> usize {
        self.q2.len()
    }
}

fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// RK4 for y = (q, v), y' = (v, f(q, v)). Stage k has state (q_k, v_k) and acceleration a_k:
/// (q2, v2) = (q, v) + dt/2 (v, a1); (q3, v3) = (q, v) + dt/2 (v2, a2); (q4, v4) = (q, v) + dt (v3, a3);
/// q⁺ = q + dt/6 (v + 2 v2 + 2 v3 + v4), v⁺ = v + dt/6 (a1 + 2 a2 + 2 a3 + a4).
#[allow(clippy::too_many_arguments)]
fn rk4_step<F>(
    accel: &mut F,
    dt: f64,
    q: &[f64],
    v: &[f64],
    a1: &[f64],
    q_out: &mut [f64],
    v_out: &mut [f64],
    s: &mut StepScratch,
) -> Result<bool>
where
    F: FnMut(&[f64], &[f64], &mut [f64]) -> Result<()>,
{
    let n = q.len();
    let h = 0.5 * dt;
    for i in 0..n {
        s.q2[i] = q[i] + h * v[i];
        s.v2[i] = v[i] + h * a1[i];
    }
    if !(all_finite(&s.q2) && all_finite(&s.v2)) {
        return Ok(false);
    }
    accel(&s.q2, &s.v2, &mut s.a2)?;
    if !all_finite(&s.a2) {
        return Ok(false);
    }
    for i in 0..n {
        s.q3[i] = q[i] + h * s.v2[i];
        s.v3[i] = v[i] + h * s.a2[i];
    }
    if !(all_finite(&s.q3) && all_finite(&s.v3)) {
        return Ok(false);
    }
    accel(&s.q3, &s.v3, &mut s.a3)?;
    if !all_finite(&s.a3) {
        return Ok(false);
    }
    for i in 0..n {
        s.q4[i] = q[i] + dt * s.v3[i];
        s.v4[i] = v[i] + dt * s.a3[i];
    }
    if !(all_finite(&s.q4) && all_finite(&s.v4)) {
        return Ok(false);
    }
    accel(&s.q4, &s.v4, &mut s.a4)?;
    if !all_finite(&s.a4) {
        return Ok(false);
    }
    let w = dt / 6.0;
    for i in 0..n {
        q_out[i] = q[i] + w * (v[i] + 2.0 * s.v2[i] + 2.0 * s.v3[i] + s.v4[i]);
        v_out[i] = v[i] + w * (a1[i] + 2.0 * s.a2[i] + 2.0 * s.a3[i] + s.a4[i]);
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Under-damped oscillator ẍ = -ω² x - 2ζω ẋ, closed form x(t) for x(0) = 1, ẋ(0) = 0.
    fn exact(t: f64, w: f64, z: f64) -> (f64, f64) {
        let wd = w * (1.0 - z * z).sqrt();
        let s = z * w;
        let e = (-s * t).exp();
        let x = e * ((wd * t).cos() + s / wd * (wd * t).sin());
        let xd = e * (-(s * s / wd + wd) * (wd * t).sin());
        (x, xd)
    }

    fn final_error(integ: Integrator, dt: f64, steps: usize) -> f64 {
        let (w, z) = (3.0, 0.2);
        let mut f = |q: &[f64], qd: &[f64], out: &mut [f64]| -> Result<()> {
            out[0] = -w * w * q[0] - 2.0 * z * w * qd[0];
            Ok(())
        };
        let mut s = StepScratch::new(1);
        let (mut q, mut qd) = (vec![1.0], vec![0.0]);
        let (mut qn, mut qdn, mut a) = (vec![0.0], vec![0.0], vec![0.0]);
        for _ in 0..steps {
            f(&q, &qd, &mut a).unwrap();
            assert!(integ
                .step(&mut f, dt, &q, &qd, &a, &mut qn, &mut qdn, &mut s)
                .unwrap());
            q.copy_from_slice(&qn);
            qd.copy_from_slice(&qdn);
        }
        let (x, xd) = exact(dt * steps as f64, w, z);
        ((q[0] - x).powi(2) + (qd[0] - xd).powi(2)).sqrt()
    }

    #[test]
    fn closed_form_is_a_solution() {
        // Guards the reference itself: ẍ + 2ζω ẋ + ω² x = 0 by central differences, and x(0) = 1, ẋ(0) = 0.
        let (w, z, h) = (3.0, 0.2, 1e-4);
        assert!((exact(0.0, w, z).0 - 1.0).abs() < 1e-15 && exact(0.0, w, z).1.abs() < 1e-15);
        for &t in &[0.3, 1.1, 2.5] {
            let xdd =
                (exact(t + h, w, z).0 - 2.0 * exact(t, w, z).0 + exact(t - h, w, z).0) / (h * h);
            let xd_fd = (exact(t + h, w, z).0 - exact(t - h, w, z).0) / (2.0 * h);
            let (x, xd) = exact(t, w, z);
            assert!((xd - xd_fd).abs() < 1e-6);
            assert!((xdd + 2.0 * z * w * xd + w * w * x).abs() < 1e-5);
        }
    }

    #[test]
    fn euler_is_first_order() {
        let e1 = final_error(Integrator::SemiImplicitEuler, 0.01, 200);
        let e2 = final_error(Integrator::SemiImplicitEuler, 0.005, 400);
        let ratio = e1 / e2;
        assert!((1.8..2.2).contains(&ratio), "ratio {ratio}");
    }

    #[test]
    fn rk4_is_fourth_order() {
        let e1 = final_error(Integrator::Rk4, 0.02, 100);
        let e2 = final_error(Integrator::Rk4, 0.01, 200);
        let ratio = e1 / e2;
        assert!((14.0..18.0).contains(&ratio), "ratio {ratio}");
        assert!(e2 < 1e-6);
    }

    #[test]
    fn rk4_reports_divergence() {
        let mut f = |_: &[f64], qd: &[f64], out: &mut [f64]| -> Result<()> {
            out[0] = if qd[0] > 1.0 { f64::NAN } else { 1e3 };
            Ok(())
        };
        let mut s = StepScratch::new(1);
        let (mut qn, mut qdn) = (vec![0.0], vec![0.0]);
        let ok = Integrator::Rk4.step(
            &mut f,
            0.01,
            &[0.0],
            &[0.0],
            &[1e3],
            &mut qn,
            &mut qdn,
            &mut s,
        );
        assert_eq!(ok, Ok(false));
    }
}
