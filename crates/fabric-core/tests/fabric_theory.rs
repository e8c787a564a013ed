//! Property tests of the fabric theory (GF Sec. III-V) on random states and random nonlinear maps
//! (seeded ChaCha8): HD2 geometries / HD0 metrics, zero-work bending, eq. 14 (pullback commutes with
//! Euler–Lagrange, checked by num-dual on the composed Lagrangian), Thm IV.6 (pull∘energize =
//! energize∘pull), energy conservation at the integrator's order, path consistency, Thm IV.4 (forced and
//! damped fabrics come to rest at the potential minimum).
#![allow(clippy::needless_range_loop)]

use fabric_core::fabric::components::{Attractor, Barrier};
use fabric_core::fabric::config::{
    GoalDampingForm, JointAttractionConfig, LogCoshConfig, Mode, SpeedConfig,
};
use fabric_core::fabric::energy::{
    euler_lagrange_ad, BarrierMetric, ConstantMass, FinslerEnergy, GaussianMass, IsotropicEnergy,
    ScalarField, SwitchedEnergy1D, TanhMass,
};
use fabric_core::fabric::potential::{BarrierPotential, LogCosh};
use fabric_core::fabric::root::RootSystem;
use fabric_core::fabric::spec::{bending_force, energization_coefficient, Spec};
use nalgebra::{DMatrix, DVector};
use num_dual::{jacobian, second_derivative, Dual, Dual2_64, DualDVec64, DualNum};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

// ---------------------------------------------------------------------------------------------------
// Random nonlinear maps φ: R^3 → R^k, generic over dual numbers so that J, J̇q̇ and the composed
// Lagrangian L(φ(q), J q̇) can be differentiated exactly.

/// φ(q) with coefficients `c` (random per test case); k = 3 or 5 outputs.
fn phi<D: DualNum<f64>>(c: &[f64; 6], k: usize, q: &[D]) -> Vec<D> {
    let (a, b, z) = (q[0].clone(), q[1].clone(), q[2].clone());
    let mut out = vec![
        a.clone().sin() * c[0] + b.clone() * b.clone() * c[1] + z.clone() * 0.7,
        b.clone() * a.clone().cos() + z.clone() * c[2] + a.clone() * 0.4,
        (z.clone() * c[3]).exp() + a.clone() * b.clone() * c[4] + b.clone() * 0.5,
    ];
    if k == 5 {
        out.push((a.clone() * c[5]).tanh() + z.clone() * z.clone() * 0.3);
        out.push(a * 0.2 + b * 0.1 + (z * 0.5).sin());
    }
    out
}

/// ẋ = J(q) q̇ by a forward-mode directional derivative (generic, for the composed Lagrangian).
fn phi_dot<D: DualNum<f64>>(c: &[f64; 6], k: usize, q: &[D], qd: &[D]) -> Vec<D> {
    let qq: Vec<Dual<D, f64>> = q
        .iter()
        .zip(qd)
        .map(|(a, b)| Dual::new(a.clone(), b.clone()))
        .collect();
    phi(c, k, &qq).into_iter().map(|v| v.eps).collect()
}

/// Numeric x, J (k × 3) and J̇q̇ (k,) of the map at (q, q̇).
fn map_eval(
    c: &[f64; 6],
    k: usize,
    q: &[f64],
    qd: &[f64],
) -> (Vec<f64>, DMatrix<f64>, DVector<f64>) {
    let qv = DVector::from_column_slice(q);
    let (x, jac) = jacobian(
        |v: DVector<DualDVec64>| DVector::from_vec(phi(c, k, v.as_slice())),
        &qv,
    );
    let mut jdqd = DVector::zeros(k);
    for i in 0..k {
        // J̇q̇ = d²/dt² φ(q + t q̇) at t = 0
        let (_, _, d2) = second_derivative(
            |t: Dual2_64| {
                let qt: Vec<Dual2_64> = q.iter().zip(qd).map(|(a, b)| t * *b + *a).collect();
                phi(c, k, &qt)[i]
            },
            0.0,
        );
        jdqd[i] = d2;
    }
    (x.as_slice().to_vec(), jac, jdqd)
}

fn random_coeffs(rng: &mut ChaCha8Rng) -> [f64; 6] {
    std::array::from_fn(|_| rng.gen_range(0.3..1.2))
}

fn rvec(rng: &mut ChaCha8Rng, n: usize, s: f64) -> Vec<f64> {
    (0..n).map(|_| rng.gen_range(-s..s)).collect()
}

fn spd(rng: &mut ChaCha8Rng, n: usize) -> DMatrix<f64> {
    let a = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
    &a * a.transpose() + DMatrix::identity(n, n) * 0.3
}

/// The pulled-back Lagrangian L_q(q, q̇) = L(φ(q) − x_d, J(q) q̇) (GF eq. 13) as a Finsler energy on R^3.
struct Pulled<'a, E> {
    energy: &'a E,
    c: [f64; 6],
    k: usize,
    offset: Vec<f64>,
}

impl<E: FinslerEnergy> FinslerEnergy for Pulled<'_, E> {
    fn dim(&self) -> usize {
        3
    }
    fn lagrangian<D: DualNum<f64>>(&self, q: &[D], qd: &[D]) -> D {
        let x: Vec<D> = phi(&self.c, self.k, q)
            .into_iter()
            .zip(&self.offset)
            .map(|(v, o)| v - *o)
            .collect();
        let xd = phi_dot(&self.c, self.k, q, qd);
        self.energy.lagrangian(&x, &xd)
    }
    fn equations(&self, _: &[f64], _: &[f64], _: &mut DMatrix<f64>, _: &mut DVector<f64>) -> f64 {
        unreachable!("only differentiated by AD in these tests")
    }
}

// ---------------------------------------------------------------------------------------------------

#[test]
fn component_metrics_are_hd0_and_forces_hd2() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let joint = Attractor::joint(
        &JointAttractionConfig {
            mass: 1.3,
            geometry: LogCoshConfig {
                gain: 0.8,
                sharpness: 4.0,
            },
            potential: LogCoshConfig {
                gain: 0.5,
                sharpness: 3.0,
            },
        },
        4,
    );
    let ee = Attractor {
        energy: IsotropicEnergy {
            mass: TanhMass {
                dim: 3,
                mass_max: 2.0,
                mass_min: 0.2,
                sharpness: 5.0,
            },
        },
        geometry: LogCosh {
            gain: 1.0,
            sharpness: 6.0,
        },
        potential: LogCosh {
            gain: 1.0,
            sharpness: 6.0,
        },
    };
    let barrier = Barrier {
        energy: SwitchedEnergy1D {
            metric: BarrierMetric {
                gain: 0.3,
                x_min: 0.005,
                influence: f64::INFINITY,
            },
            switched: true,
            hold_inside: false,
        },
        geometry: BarrierPotential {
            barrier_gain: 0.02,
            relu_gain: 3.0,
            relu_sharpness: 20.0,
            relu_shift: 0.05,
            x_min: 0.005,
        },
        potential: BarrierPotential {
            barrier_gain: 1e-3,
            relu_gain: 0.3,
            relu_sharpness: 20.0,
            relu_shift: 0.05,
            x_min: 0.005,
        },
        // the paper's barrier: uncapped HD2 geometry, no damper (τ = 0)
        braking_time: 0.0,
    };
    for _ in 0..200 {
        let l: f64 = rng.gen_range(0.05..5.0);
        for (n, which) in [(4usize, 0), (3, 1)] {
            let x = rvec(&mut rng, n, 1.0);
            let xd = rvec(&mut rng, n, 2.0);
            let xs: Vec<f64> = xd.iter().map(|v| v * l).collect();
            let mut out = [[0.0; 4]; 8];
            let (a, b) = out.split_at_mut(4);
            let [s1, xi1, f1, g1] = a else { unreachable!() };
            let [s2, xi2, f2, g2] = b else { unreachable!() };
            let (e1, e2) = if which == 0 {
                (
                    joint.eval(
                        &x,
                        &xd,
                        &mut s1[..n],
                        &mut xi1[..n],
                        &mut f1[..n],
                        &mut g1[..n],
                    ),
                    joint.eval(
                        &x,
                        &xs,
                        &mut s2[..n],
                        &mut xi2[..n],
                        &mut f2[..n],
                        &mut g2[..n],
                    ),
                )
            } else {
                (
                    ee.eval(
                        &x,
                        &xd,
                        &mut s1[..n],
                        &mut xi1[..n],
                        &mut f1[..n],
                        &mut g1[..n],
                    ),
                    ee.eval(
                        &x,
                        &xs,
                        &mut s2[..n],
                        &mut xi2[..n],
                        &mut f2[..n],
                        &mut g2[..n],
                    ),
                )
            };
            assert!((e1.mass - e2.mass).abs() < 1e-12, "metric HD0");
            for i in 0..n {
                assert!(
                    (xi2[i] - l * l * xi1[i]).abs() < 1e-10 * (1.0 + xi1[i].abs() * l * l),
                    "ξ HD2"
                );
                assert!(
                    (f2[i] - l * l * f1[i]).abs() < 1e-10 * (1.0 + f1[i].abs() * l * l),
                    "f = −Mπ HD2"
                );
                assert_eq!(g1[i], g2[i], "potential independent of velocity");
            }
        }
        let x = rng.gen_range(0.001..0.4);
        let xd = rng.gen_range(-2.0..2.0);
        let (b1, b2) = (barrier.eval(x, xd, true), barrier.eval(x, xd * l, true));
        assert_eq!(b1.m, b2.m);
        assert!((b2.xi - l * l * b1.xi).abs() < 1e-9 * (1.0 + b1.xi.abs() * l * l));
        assert!((b2.f - l * l * b1.f).abs() < 1e-9 * (1.0 + b1.f.abs() * l * l));
    }
}

#[test]
fn energized_bending_term_is_zero_work_and_conserves_energy() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for n in 1..8 {
        for _ in 0..50 {
            let m = spd(&mut rng, n);
            let xi = DVector::from_vec(rvec(&mut rng, n, 3.0));
            let pi = DVector::from_vec(rvec(&mut rng, n, 3.0));
            let xd = DVector::from_vec(rvec(&mut rng, n, 2.0));
            let ff = bending_force(&m, &xi, &pi, &xd);
            let scale = (&m * &pi + &xi).norm() * xd.norm();
            assert!(
                xd.dot(&ff).abs() <= 1e-12 * scale.max(1.0),
                "ẋᵀf_f = {}",
                xd.dot(&ff)
            );
            // M ẍ + ξ + f_f = 0 gives ẍ = π + α ẋ (GF eq. 8), and Ḣ_e = ẋᵀ(M ẍ + ξ) = 0 (Lemma C.1)
            let a = energization_coefficient(&m, &xi, &pi, &xd);
            let acc = &pi + &xd * a;
            let res = &m * &acc + &xi + &ff;
            assert!(
                res.norm() <= 1e-10 * (1.0 + scale),
                "eq. 8 residual {}",
                res.norm()
            );
            assert!(xd.dot(&(&m * &acc + &xi)).abs() <= 1e-11 * scale.max(1.0));
        }
    }
}

#[test]
fn pullback_commutes_with_euler_lagrange_eq14() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for case in 0..60 {
        let c = random_coeffs(&mut rng);
        let k = if case % 2 == 0 { 3 } else { 5 };
        let q = rvec(&mut rng, 3, 1.0);
        let qd = rvec(&mut rng, 3, 1.5);
        let offset = rvec(&mut rng, k, 0.5);
        let (x0, jac, jdqd) = map_eval(&c, k, &q, &qd);
        let x: Vec<f64> = x0.iter().zip(&offset).map(|(a, b)| a - b).collect();
        let xd: Vec<f64> = (&jac * DVector::from_column_slice(&qd)).as_slice().to_vec();
        let check = |em: &fabric_core::fabric::energy::EquationsOfMotion,
                     ad: &fabric_core::fabric::energy::EquationsOfMotion| {
            let pulled = Spec {
                m: em.m.clone(),
                f: em.xi.clone(),
            }
            .pullback(&jac, &jdqd)
            .unwrap();
            assert!(
                (&pulled.m - &ad.m).norm() <= 1e-9 * (1.0 + ad.m.norm()),
                "M: {} vs {}",
                pulled.m,
                ad.m
            );
            assert!(
                (&pulled.f - &ad.xi).norm() <= 1e-9 * (1.0 + ad.xi.norm()),
                "ξ: {} vs {}",
                pulled.f,
                ad.xi
            );
            assert!((em.energy - ad.energy).abs() <= 1e-12 * (1.0 + ad.energy.abs()));
        };
        let tanh = IsotropicEnergy {
            mass: TanhMass {
                dim: k,
                mass_max: 2.0,
                mass_min: 0.3,
                sharpness: 3.0,
            },
        };
        check(
            &tanh.equations_of_motion(&x, &xd),
            &euler_lagrange_ad(
                &Pulled {
                    energy: &tanh,
                    c,
                    k,
                    offset: offset.clone(),
                },
                &q,
                &qd,
            ),
        );
        let gauss = IsotropicEnergy {
            mass: GaussianMass {
                dim: k,
                mass_max: 2.0,
                mass_min: 0.3,
                width: 0.8,
            },
        };
        check(
            &gauss.equations_of_motion(&x, &xd),
            &euler_lagrange_ad(
                &Pulled {
                    energy: &gauss,
                    c,
                    k,
                    offset: offset.clone(),
                },
                &q,
                &qd,
            ),
        );
    }
}

/// The Thm IV.6 identity for one map, energy and geometry at (q, q̇): returns (q̈ of the pulled-back
/// energized system, q̈ of the energized pulled-back geometry).
fn thm_iv6_sides(
    c: &[f64; 6],
    k: usize,
    q: &[f64],
    qd: &[f64],
    target: &[f64],
) -> (DVector<f64>, DVector<f64>) {
    let att = Attractor {
        energy: IsotropicEnergy {
            mass: TanhMass {
                dim: k,
                mass_max: 2.5,
                mass_min: 0.4,
                sharpness: 2.0,
            },
        },
        geometry: LogCosh {
            gain: 1.2,
            sharpness: 2.5,
        },
        potential: LogCosh {
            gain: 0.0,
            sharpness: 1.0,
        },
    };
    let (x0, jac, jdqd) = map_eval(c, k, q, qd);
    let x: Vec<f64> = x0.iter().zip(target).map(|(a, b)| a - b).collect();
    let xd = &jac * DVector::from_column_slice(qd);
    let (mut s, mut xi, mut f, mut g) = (vec![0.0; k], vec![0.0; k], vec![0.0; k], vec![0.0; k]);
    let e = att.eval(&x, xd.as_slice(), &mut s, &mut xi, &mut f, &mut g);
    let m = DMatrix::identity(k, k) * e.mass;
    let xi = DVector::from_vec(xi);
    let mut pi = vec![0.0; k];
    att.geometry_acceleration(&x, xd.as_slice(), &mut pi);
    let pi = DVector::from_vec(pi);
    // left: energize in X (spec (M, ξ + f_f)), then pull back and resolve
    let ff = bending_force(&m, &xi, &pi, &xd);
    let left = Spec {
        m: m.clone(),
        f: &xi + ff,
    }
    .pullback(&jac, &jdqd)
    .unwrap()
    .resolve()
    .unwrap();
    // right: pull back the energy spec and the geometry spec (M, −Mπ), resolve, energize in Q
    let energy_q = Spec {
        m: m.clone(),
        f: xi,
    }
    .pullback(&jac, &jdqd)
    .unwrap();
    let geom_q = Spec::from_geometry(m, &pi)
        .unwrap()
        .pullback(&jac, &jdqd)
        .unwrap();
    let pi_q = geom_q.resolve().unwrap();
    let qdv = DVector::from_column_slice(qd);
    let a = energization_coefficient(&energy_q.m, &energy_q.f, &pi_q, &qdv);
    (left, pi_q + qdv * a)
}

#[test]
fn pull_of_energized_equals_energized_pull_thm_iv6() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for case in 0..100 {
        let c = random_coeffs(&mut rng);
        let k = if case % 2 == 0 { 3 } else { 5 };
        let q = rvec(&mut rng, 3, 1.0);
        let qd = rvec(&mut rng, 3, 1.5);
        let target = rvec(&mut rng, k, 1.0);
        let (l, r) = thm_iv6_sides(&c, k, &q, &qd, &target);
        assert!(
            (&l - &r).norm() <= 1e-8 * (1.0 + l.norm()),
            "case {case}: {l} vs {r}"
        );
    }
}

// ---------------------------------------------------------------------------------------------------
// A complete 3-DoF fabric on a random map, assembled with RootSystem like the robot engine:
// attractor on φ(q) − x_d (tanh mass), a joint-space isotropic component, and a Riemannian barrier on
// x = ‖q − c_o‖ − r_o (smooth: s ≡ 1).

struct Toy {
    c: [f64; 6],
    target: Vec<f64>,
    obstacle: [f64; 3],
    att: Attractor<TanhMass>,
    joint: Attractor<ConstantMass>,
    barrier: Barrier,
    speed: SpeedConfig,
    mode: Mode,
}

impl Toy {
    fn new(c: [f64; 6], potential: f64, damping: f64) -> Toy {
        Toy {
            c,
            target: vec![0.4, 0.9, 1.3],
            obstacle: [2.0, -1.0, 0.5],
            att: Attractor {
                energy: IsotropicEnergy {
                    mass: TanhMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.5,
                        sharpness: 2.0,
                    },
                },
                geometry: LogCosh {
                    gain: 1.0,
                    sharpness: 2.0,
                },
                potential: LogCosh {
                    gain: potential,
                    sharpness: 2.0,
                },
            },
            joint: Attractor {
                energy: IsotropicEnergy {
                    mass: ConstantMass { dim: 3, mass: 0.5 },
                },
                geometry: LogCosh {
                    gain: 0.5,
                    sharpness: 1.0,
                },
                potential: LogCosh {
                    gain: 0.0,
                    sharpness: 1.0,
                },
            },
            barrier: Barrier {
                energy: SwitchedEnergy1D {
                    metric: BarrierMetric {
                        gain: 0.5,
                        x_min: 0.01,
                        influence: f64::INFINITY,
                    },
                    switched: false,
                    hold_inside: false,
                },
                geometry: BarrierPotential {
                    barrier_gain: 0.05,
                    relu_gain: 1.0,
                    relu_sharpness: 5.0,
                    relu_shift: 0.3,
                    x_min: 0.01,
                },
                potential: BarrierPotential {
                    barrier_gain: 0.0,
                    relu_gain: 0.0,
                    relu_sharpness: 0.0,
                    relu_shift: 0.0,
                    x_min: 0.01,
                },
                braking_time: 0.0,
            },
            speed: SpeedConfig {
                enabled: false,
                goal_damping: 0.0,
                base_damping: damping,
                goal_damping_form: GoalDampingForm::Velocity,
                ..SpeedConfig::default()
            },
            mode: Mode::Bent,
        }
    }

    /// Assemble the root at (q, q̇); returns (q̈, L̃_e, ψ).
    fn eval(&self, root: &mut RootSystem, q: &[f64], qd: &[f64]) -> (Vec<f64>, f64, f64) {
        root.clear();
        let (x0, jac, jdqd) = map_eval(&self.c, 3, q, qd);
        let x: Vec<f64> = x0.iter().zip(&self.target).map(|(a, b)| a - b).collect();
        let xd = &jac * DVector::from_column_slice(qd);
        let (mut s, mut xi, mut f, mut g) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        let e = self
            .att
            .eval(&x, xd.as_slice(), &mut s, &mut xi, &mut f, &mut g);
        root.add_isotropic(&jac, jdqd.as_slice(), e.mass, &xi, &f, &g, e.psi);
        let e2 = self.joint.eval(q, qd, &mut s, &mut xi, &mut f, &mut g);
        root.add_identity(e2.mass, &xi, &f, &g, e2.psi);
        // barrier x = ‖q − c_o‖ − r_o, J = n̂ᵀ, J̇q̇ = (‖q̇‖² − (n̂ᵀq̇)²)/‖q − c_o‖
        let d: Vec<f64> = (0..3).map(|i| q[i] - self.obstacle[i]).collect();
        let dist = d.iter().map(|v| v * v).sum::<f64>().sqrt();
        let n: Vec<f64> = d.iter().map(|v| v / dist).collect();
        let along: f64 = n.iter().zip(qd).map(|(a, b)| a * b).sum();
        let v2: f64 = qd.iter().map(|v| v * v).sum();
        let b = self.barrier.eval(dist - 0.3, along, true);
        root.add_scalar(
            &n,
            (v2 - along * along) / dist,
            b.m,
            b.xi,
            b.f,
            b.grad,
            b.psi,
        );
        let mut qdd = vec![0.0; 3];
        let t = root
            .solve(self.mode, &self.speed, qd, 1.0, 1.0, None, None, &mut qdd)
            .unwrap();
        (qdd, t.energy, t.potential)
    }
}

fn rk4(toy: &Toy, root: &mut RootSystem, q: &mut [f64], qd: &mut [f64], dt: f64) {
    let f = |root: &mut RootSystem, q: &[f64], v: &[f64]| toy.eval(root, q, v).0;
    let add = |a: &[f64], b: &[f64], s: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(x, y)| x + s * y).collect()
    };
    let a1 = f(root, q, qd);
    let (q2, v2) = (add(q, qd, dt / 2.0), add(qd, &a1, dt / 2.0));
    let a2 = f(root, &q2, &v2);
    let (q3, v3) = (add(q, &v2, dt / 2.0), add(qd, &a2, dt / 2.0));
    let a3 = f(root, &q3, &v3);
    let (q4, v4) = (add(q, &v3, dt), add(qd, &a3, dt));
    let a4 = f(root, &q4, &v4);
    for i in 0..q.len() {
        q[i] += dt / 6.0 * (qd[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
        qd[i] += dt / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
    }
}

fn semi_implicit_euler(toy: &Toy, root: &mut RootSystem, q: &mut [f64], qd: &mut [f64], dt: f64) {
    let a = toy.eval(root, q, qd).0;
    for i in 0..q.len() {
        qd[i] += dt * a[i];
        q[i] += dt * qd[i];
    }
}

/// Max |L̃_e(t) − L̃_e(0)| over [0, T] for an unforced, undamped energized toy fabric.
fn drift(toy: &Toy, q0: &[f64], qd0: &[f64], dt: f64, t: f64, use_rk4: bool) -> f64 {
    let mut root = RootSystem::new(3);
    let (mut q, mut qd) = (q0.to_vec(), qd0.to_vec());
    let e0 = toy.eval(&mut root, &q, &qd).1;
    let mut worst: f64 = 0.0;
    for _ in 0..(t / dt).round() as usize {
        if use_rk4 {
            rk4(toy, &mut root, &mut q, &mut qd, dt);
        } else {
            semi_implicit_euler(toy, &mut root, &mut q, &mut qd, dt);
        }
        worst = worst.max((toy.eval(&mut root, &q, &qd).1 - e0).abs());
    }
    worst
}

#[test]
fn energized_fabric_conserves_energy_at_the_integrator_order() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..3 {
        let toy = Toy::new(random_coeffs(&mut rng), 0.0, 0.0);
        let q0 = rvec(&mut rng, 3, 0.5);
        let qd0 = rvec(&mut rng, 3, 1.0);
        let r: Vec<f64> = [0.02, 0.01, 0.005]
            .iter()
            .map(|&dt| drift(&toy, &q0, &qd0, dt, 1.0, true))
            .collect();
        assert!(r[2] < 1e-6, "RK4 drift {r:?}");
        assert!(
            r[0] / r[1] > 10.0 && r[1] / r[2] > 10.0,
            "RK4 drift should shrink ~16x per halving: {r:?}"
        );
        let e: Vec<f64> = [0.004, 0.002, 0.001]
            .iter()
            .map(|&dt| drift(&toy, &q0, &qd0, dt, 1.0, false))
            .collect();
        assert!(
            e[0] / e[1] > 1.6 && e[1] / e[2] > 1.6,
            "Euler drift should shrink ~2x per halving: {e:?}"
        );
    }
}

#[test]
fn unbent_system_conserves_its_energy_too() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let mut toy = Toy::new(random_coeffs(&mut rng), 0.0, 0.0);
    toy.mode = Mode::Unbent;
    let q0 = rvec(&mut rng, 3, 0.5);
    let qd0 = rvec(&mut rng, 3, 1.0);
    let r: Vec<f64> = [0.02, 0.01]
        .iter()
        .map(|&dt| drift(&toy, &q0, &qd0, dt, 1.0, true))
        .collect();
    assert!(r[1] < 1e-5 && r[0] / r[1] > 10.0, "{r:?}");
}

#[test]
fn energized_geometry_is_path_consistent() {
    // q(t; λ q̇0) = q(λ t; q̇0): the path does not depend on the speed.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let toy = Toy::new(random_coeffs(&mut rng), 0.0, 0.0);
    let q0 = rvec(&mut rng, 3, 0.5);
    let qd0 = rvec(&mut rng, 3, 1.0);
    let mut root = RootSystem::new(3);
    let (mut qa, mut va) = (q0.clone(), qd0.clone());
    let (mut qb, mut vb): (Vec<f64>, Vec<f64>) =
        (q0.clone(), qd0.iter().map(|v| 2.0 * v).collect());
    let dt = 0.002;
    for _ in 0..400 {
        // 0.8 s at speed 1 vs 0.4 s at speed 2
        rk4(&toy, &mut root, &mut qa, &mut va, dt);
        rk4(&toy, &mut root, &mut qa, &mut va, dt);
        rk4(&toy, &mut root, &mut qb, &mut vb, dt);
    }
    let moved: f64 = qa
        .iter()
        .zip(&q0)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let gap: f64 = qa
        .iter()
        .zip(&qb)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved > 0.3, "the test must move ({moved})");
    assert!(gap < 1e-7, "paths differ by {gap}");
    for i in 0..3 {
        assert!(
            (vb[i] - 2.0 * va[i]).abs() < 1e-6,
            "velocities scale with λ"
        );
    }
}

#[test]
fn root_geometry_is_hd2_in_velocity() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for _ in 0..30 {
        let toy = Toy::new(random_coeffs(&mut rng), 0.0, 0.0);
        let q = rvec(&mut rng, 3, 0.5);
        let qd = rvec(&mut rng, 3, 1.0);
        let mut root = RootSystem::new(3);
        let a1 = toy.eval(&mut root, &q, &qd).0;
        let pi1 = root.pi.clone();
        let l = rng.gen_range(0.1..4.0);
        let qs: Vec<f64> = qd.iter().map(|v| v * l).collect();
        let a2 = toy.eval(&mut root, &q, &qs).0;
        assert!((&root.pi - &pi1 * (l * l)).norm() < 1e-9 * (1.0 + pi1.norm() * l * l));
        for i in 0..3 {
            assert!(
                (a2[i] - l * l * a1[i]).abs() < 1e-9 * (1.0 + a1[i].abs() * l * l),
                "energized q̈ HD2"
            );
        }
    }
}

#[test]
fn forced_damped_fabric_comes_to_rest_at_the_potential_minimum_thm_iv4() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut cases = 0;
    while cases < 3 {
        let c = random_coeffs(&mut rng);
        let toy = Toy::new(c, 1.5, 2.0);
        // the minimum of ψ(φ(q) − x_d) is any q with φ(q) = x_d: take x_d = φ(q*), with J(q*)
        // well conditioned so that the minimum is isolated and non-degenerate
        let q_star = rvec(&mut rng, 3, 0.3);
        let (_, j, _) = map_eval(&c, 3, &q_star, &[0.0; 3]);
        let sv = j.singular_values();
        if sv.min() < 0.5 {
            continue;
        }
        cases += 1;
        let mut toy = toy;
        toy.target = phi(&c, 3, &q_star);
        let mut root = RootSystem::new(3);
        let (mut q, mut qd): (Vec<f64>, Vec<f64>) = (
            q_star.iter().map(|v| v + 0.4).collect(),
            rvec(&mut rng, 3, 1.0),
        );
        let (_, e0, p0) = toy.eval(&mut root, &q, &qd);
        let mut h_prev = e0 + p0;
        for _ in 0..4000 {
            rk4(&toy, &mut root, &mut q, &mut qd, 0.02);
            let (_, e, p) = toy.eval(&mut root, &q, &qd);
            assert!(
                e + p <= h_prev + 1e-9,
                "H = L_e + ψ must not increase (Lemma IV.1)"
            );
            h_prev = e + p;
        }
        let speed: f64 = qd.iter().map(|v| v * v).sum::<f64>().sqrt();
        let x = phi(&c, 3, &q);
        let err: f64 = x
            .iter()
            .zip(&toy.target)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(speed < 1e-5, "at rest: {speed}");
        assert!(err < 1e-5, "at the minimum of ψ: {err}");
        assert!(
            root.grad.norm() < 1e-4,
            "stationary: ∂ψ = {}",
            root.grad.norm()
        );
    }
}

#[test]
fn scalar_field_gradients_match_ad() {
    // the mass fields feed ξ: check ∇m against num-dual for the three shapes
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    for _ in 0..50 {
        let x = rvec(&mut rng, 3, 1.0);
        type Closed<'a> = &'a dyn Fn(&[f64], &mut [f64]) -> f64;
        type Generic = Box<dyn Fn(DVector<DualDVec64>) -> DualDVec64>;
        let fields: [(Closed, Generic); 2] = [
            (
                &|x: &[f64], g: &mut [f64]| {
                    TanhMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.3,
                        sharpness: 3.0,
                    }
                    .value_gradient(x, g)
                },
                Box::new(|v: DVector<DualDVec64>| {
                    TanhMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.3,
                        sharpness: 3.0,
                    }
                    .value(v.as_slice())
                }),
            ),
            (
                &|x: &[f64], g: &mut [f64]| {
                    GaussianMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.3,
                        width: 0.9,
                    }
                    .value_gradient(x, g)
                },
                Box::new(|v: DVector<DualDVec64>| {
                    GaussianMass {
                        dim: 3,
                        mass_max: 2.0,
                        mass_min: 0.3,
                        width: 0.9,
                    }
                    .value(v.as_slice())
                }),
            ),
        ];
        for (closed, generic) in fields.iter() {
            let mut g = [0.0; 3];
            let m = closed(&x, &mut g);
            let (m_ad, g_ad) = num_dual::gradient(generic, &DVector::from_column_slice(&x));
            assert!((m - m_ad).abs() < 1e-12);
            for i in 0..3 {
                assert!((g[i] - g_ad[i]).abs() < 1e-10);
            }
        }
    }
}
