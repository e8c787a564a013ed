//! The RMPflow operators at the root (Cheng et al. 2018, Sec. 3.2-3.3, eq. 5-6): an RMP in canonical form
//! (a, M) on a task space x = φ(q) with Jacobian J contributes, by **pullback**,
//! ```text
//! f_q += Jᵀ M (a − J̇q̇),   M_q += Jᵀ M J,
//! ```
//! (the natural form f = M a of each leaf, minus the curvature term M J̇q̇), and the root **resolves**
//! q̈ = M_q⁺ f_q with the Moore–Penrose pseudo-inverse. The result minimises Σᵢ ‖Jᵢ q̈ + J̇ᵢq̇ − aᵢ‖²_{Mᵢ}
//! (the least-squares reading of RMPflow, checked against a stacked solve in the tests).
//!
//! Sign convention: RMPflow's natural form is M ẍ = f (force on the right), opposite to the fabric's
//! spec M ẍ + f = 0.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix3xX, SymmetricEigen, Vector3};

use crate::error::{FabricError, Result};

/// Relative cut-off of the pseudo-inverse: eigenvalues of M_q below `PINV_RCOND × λ_max` count as zero.
pub const PINV_RCOND: f64 = 1e-12;

/// The pulled-back metric M_q (n × n) and force f_q (n,) accumulated over the leaves of one evaluation.
#[derive(Clone, Debug)]
pub struct RmpRoot {
    n: usize,
    /// M_q, column-major n × n (symmetric).
    metric: DMatrix<f64>,
    /// f_q.
    force: DVector<f64>,
}

impl RmpRoot {
    /// An empty root for `n` coordinates.
    pub fn new(n: usize) -> Self {
        RmpRoot {
            n,
            metric: DMatrix::zeros(n, n),
            force: DVector::zeros(n),
        }
    }

    /// Number of coordinates.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Drop every contribution.
    pub fn clear(&mut self) {
        self.metric.fill(0.0);
        self.force.fill(0.0);
    }

    /// M_q.
    pub fn metric(&self) -> &DMatrix<f64> {
        &self.metric
    }

    /// f_q.
    pub fn force(&self) -> &DVector<f64> {
        &self.force
    }

    /// A leaf on x = q − c (J = I, J̇q̇ = 0) with metric `m` I and acceleration `a` (n,).
    pub fn add_identity(&mut self, m: f64, a: &[f64]) {
        for (i, ai) in a.iter().enumerate().take(self.n) {
            self.metric[(i, i)] += m;
            self.force[i] += m * ai;
        }
    }

    /// A 1-D leaf on x = ±q_i (J = `sign` e_iᵀ, J̇q̇ = 0) with metric `m` and acceleration `a`.
    pub fn add_coordinate(&mut self, i: usize, sign: f64, m: f64, a: f64) {
        self.metric[(i, i)] += m;
        self.force[i] += sign * m * a;
    }

    /// A 1-D leaf with row Jacobian `jrow` (n,), curvature J̇q̇ `jdot_qdot`, metric `m` and acceleration `a`.
    pub fn add_scalar(&mut self, jrow: &[f64], jdot_qdot: f64, m: f64, a: f64) {
        if m == 0.0 {
            return;
        }
        let g = m * (a - jdot_qdot);
        for j in 0..self.n {
            let mj = m * jrow[j];
            if mj == 0.0 {
                continue;
            }
            for (i, ji) in jrow.iter().enumerate().take(self.n) {
                self.metric[(i, j)] += ji * mj;
            }
            self.force[j] += jrow[j] * g;
        }
    }

    /// A leaf of dimension m with Jacobian `jac` (m × n), curvature `jdot_qdot` (m,), metric `metric`
    /// (m × m) and acceleration `accel` (m,): the general pullback.
    pub fn add_task(
        &mut self,
        jac: &DMatrix<f64>,
        jdot_qdot: &DVector<f64>,
        metric: &DMatrix<f64>,
        accel: &DVector<f64>,
    ) {
        let mj = metric * jac;
        self.metric += jac.transpose() * &mj;
        self.force += jac.transpose() * (metric * (accel - jdot_qdot));
    }

    /// A 3-D leaf on a robot point with Jacobian `jac` (3 × n), curvature `jdot_qdot`, metric `metric`
    /// and acceleration `accel` (the pullback of [`RmpRoot::add_task`] without allocation).
    pub fn add_point(
        &mut self,
        jac: &Matrix3xX<f64>,
        jdot_qdot: &Vector3<f64>,
        metric: &Matrix3<f64>,
        accel: &Vector3<f64>,
    ) {
        let g = metric * (accel - jdot_qdot);
        for j in 0..self.n {
            let cj = jac.column(j);
            let mj = metric * cj;
            for i in 0..self.n {
                self.metric[(i, j)] += jac.column(i).dot(&mj);
            }
            self.force[j] += cj.dot(&g);
        }
    }

    /// q̈ = M_q⁺ f_q (written into `qdd` (n,)) by the symmetric eigen-decomposition of M_q, eigenvalues
    /// below [`PINV_RCOND`] λ_max dropped. Errors (`NonFinite`) when M_q or f_q hold NaN or ±inf.
    pub fn resolve(&self, qdd: &mut [f64]) -> Result<()> {
        if !self
            .metric
            .iter()
            .chain(self.force.iter())
            .all(|v| v.is_finite())
        {
            return Err(FabricError::NonFinite {
                what: "RMPflow root metric or force".into(),
            });
        }
        let eig = SymmetricEigen::new(self.metric.clone());
        let lmax = eig.eigenvalues.iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
        qdd.iter_mut().for_each(|v| *v = 0.0);
        if lmax == 0.0 {
            return Ok(());
        }
        for (k, &l) in eig.eigenvalues.iter().enumerate() {
            if l <= PINV_RCOND * lmax {
                continue;
            }
            let v = eig.eigenvectors.column(k);
            let c = v.dot(&self.force) / l;
            for (o, vi) in qdd.iter_mut().zip(v.iter()) {
                *o += c * vi;
            }
        }
        Ok(())
    }
}

/// The pullback of one RMP (a, M) through a map with Jacobian `jac` (m × n) and curvature `jdot_qdot`
/// (m,): (f_q, M_q) = (Jᵀ M (a − J̇q̇), Jᵀ M J).
pub fn pullback(
    jac: &DMatrix<f64>,
    jdot_qdot: &DVector<f64>,
    metric: &DMatrix<f64>,
    accel: &DVector<f64>,
) -> (DVector<f64>, DMatrix<f64>) {
    let mut root = RmpRoot::new(jac.ncols());
    root.add_task(jac, jdot_qdot, metric, accel);
    (root.force, root.metric)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random(rng: &mut ChaCha8Rng, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| rng.gen_range(-1.0..1.0))
    }

    fn spd(rng: &mut ChaCha8Rng, m: usize) -> DMatrix<f64> {
        let a = random(rng, m, m);
        &a * a.transpose() + DMatrix::identity(m, m) * 0.1
    }

    #[test]
    fn pullback_of_a_linear_map_is_jt_m_j() {
        // x = A q (J = A, J̇q̇ = 0): M_q = AᵀMA, f_q = AᵀMa, entry by entry
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (a, m) = (random(&mut rng, 3, 5), spd(&mut rng, 3));
        let acc = DVector::from_vec(vec![0.3, -1.2, 2.0]);
        let (f, mq) = pullback(&a, &DVector::zeros(3), &m, &acc);
        for i in 0..5 {
            for j in 0..5 {
                let want: f64 = (0..3)
                    .flat_map(|k| (0..3).map(move |l| (k, l)))
                    .map(|(k, l)| a[(k, i)] * m[(k, l)] * a[(l, j)])
                    .sum();
                assert!((mq[(i, j)] - want).abs() < 1e-12);
            }
            let want: f64 = (0..3)
                .flat_map(|k| (0..3).map(move |l| (k, l)))
                .map(|(k, l)| a[(k, i)] * m[(k, l)] * acc[l])
                .sum();
            assert!((f[i] - want).abs() < 1e-12);
        }
        // the curvature term enters as a − J̇q̇
        let c = DVector::from_vec(vec![0.1, 0.2, -0.4]);
        let (f2, _) = pullback(&a, &c, &m, &(&acc + &c));
        assert!((f2 - f).norm() < 1e-12);
    }

    #[test]
    fn resolve_of_a_single_leaf_inverts_the_task_map() {
        // one leaf with an invertible J: q̈ = J⁻¹(a − J̇q̇) whatever the (SPD) metric
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let n = 4;
        let j = random(&mut rng, n, n) + DMatrix::identity(n, n) * 2.0;
        let m = spd(&mut rng, n);
        let a = DVector::from_fn(n, |_, _| rng.gen_range(-1.0..1.0));
        let c = DVector::from_fn(n, |_, _| rng.gen_range(-1.0..1.0));
        let mut root = RmpRoot::new(n);
        root.add_task(&j, &c, &m, &a);
        let mut qdd = vec![0.0; n];
        root.resolve(&mut qdd).unwrap();
        let want = j.clone().lu().solve(&(&a - &c)).unwrap();
        for i in 0..n {
            assert!((qdd[i] - want[i]).abs() < 1e-9, "{qdd:?} vs {want}");
        }
        // a 1-D leaf on a redundant map: the minimum-norm solution J⁺(a − J̇q̇), reached exactly
        let row = [0.5, -1.0, 2.0, 0.0];
        let mut root = RmpRoot::new(n);
        root.add_scalar(&row, 0.3, 7.0, 1.5);
        root.resolve(&mut qdd).unwrap();
        let along: f64 = row.iter().zip(&qdd).map(|(r, q)| r * q).sum();
        assert!((along - 1.2).abs() < 1e-12);
        let norm2: f64 = row.iter().map(|r| r * r).sum();
        for i in 0..n {
            assert!((qdd[i] - row[i] * 1.2 / norm2).abs() < 1e-12);
        }
    }

    #[test]
    fn resolve_solves_the_weighted_least_squares_of_all_leaves() {
        // RMPflow's combination: argmin Σ ‖J_i q̈ + c_i − a_i‖²_{M_i}, against a stacked solve
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = 5;
        let dims = [3, 1, 2, 5];
        let mut root = RmpRoot::new(n);
        let (mut rows, mut rhs) = (Vec::new(), Vec::new());
        for &m in &dims {
            let (j, w) = (random(&mut rng, m, n), spd(&mut rng, m));
            let a = DVector::from_fn(m, |_, _| rng.gen_range(-1.0..1.0));
            let c = DVector::from_fn(m, |_, _| rng.gen_range(-1.0..1.0));
            root.add_task(&j, &c, &w, &a);
            let l = w.clone().cholesky().unwrap().l().transpose(); // w = Lᵀ... : ‖·‖_w = ‖Lᵀ ·‖
            rows.push(&l * &j);
            rhs.push(&l * (&a - &c));
        }
        let big = DMatrix::from_rows(
            &rows
                .iter()
                .flat_map(|r| r.row_iter().map(|x| x.into_owned()).collect::<Vec<_>>())
                .collect::<Vec<_>>(),
        );
        let b = DVector::from_iterator(
            rhs.iter().map(|v| v.len()).sum(),
            rhs.iter().flat_map(|v| v.iter().copied()),
        );
        let want = big.svd(true, true).solve(&b, 1e-14).unwrap();
        let mut qdd = vec![0.0; n];
        root.resolve(&mut qdd).unwrap();
        for i in 0..n {
            assert!((qdd[i] - want[i]).abs() < 1e-9);
        }
        // coordinate, scalar and identity leaves equal the general pullback
        let mut fast = RmpRoot::new(n);
        let mut slow = RmpRoot::new(n);
        let accel = [0.1, 0.2, 0.3, 0.4, 0.5];
        fast.add_identity(2.0, &accel);
        slow.add_task(
            &DMatrix::identity(n, n),
            &DVector::zeros(n),
            &(DMatrix::identity(n, n) * 2.0),
            &DVector::from_row_slice(&accel),
        );
        fast.add_coordinate(2, -1.0, 3.0, 0.7);
        let mut e = DMatrix::zeros(1, n);
        e[(0, 2)] = -1.0;
        slow.add_task(
            &e,
            &DVector::zeros(1),
            &DMatrix::from_element(1, 1, 3.0),
            &DVector::from_element(1, 0.7),
        );
        let j3 = random(&mut rng, 3, n);
        let w3 = spd(&mut rng, 3);
        let (a3, c3) = (Vector3::new(0.3, -0.2, 0.9), Vector3::new(-0.1, 0.4, 0.2));
        fast.add_point(
            &Matrix3xX::from_column_slice(j3.as_slice()),
            &c3,
            &Matrix3::from_column_slice(w3.as_slice()),
            &a3,
        );
        slow.add_task(
            &j3,
            &DVector::from_column_slice(c3.as_slice()),
            &w3,
            &DVector::from_column_slice(a3.as_slice()),
        );
        assert!((fast.metric() - slow.metric()).norm() < 1e-12);
        assert!((fast.force() - slow.force()).norm() < 1e-12);
    }

    #[test]
    fn resolve_rejects_non_finite_and_returns_zero_for_an_empty_root() {
        let mut root = RmpRoot::new(2);
        let mut qdd = vec![1.0; 2];
        root.resolve(&mut qdd).unwrap();
        assert_eq!(qdd, vec![0.0, 0.0]);
        root.add_coordinate(0, 1.0, f64::INFINITY, 1.0);
        assert!(matches!(
            root.resolve(&mut qdd),
            Err(FabricError::NonFinite { .. })
        ));
    }
}
