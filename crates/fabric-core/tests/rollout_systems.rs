//! Rollouts, command sequences and batches (GFCS eq. 1–8) on analytic systems whose answers are known:
//! a constant-speed system whose time to reach a tolerance is a closed form, a damped oscillator, and a
//! system that diverges.

mod rollout_support;
use rollout_support::bits;

use fabric_core::rollout::{
    evaluate_batch_system, rollout_sequence_system, rollout_system, Integrator, RolloutOptions,
    RolloutResult, SequenceOptions, SequenceResult, StopReason, System,
};
use fabric_core::{FabricError, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Moves at constant `speed` straight toward the command, landing on it when closer than one step:
/// with semi-implicit Euler at time step `dt`, q̈ = (v* − q̇)/dt gives q̇⁺ = v*, q⁺ = q + dt·v*.
/// From distance d, the distance after k steps is max(d − k·speed·dt, 0).
struct Kinematic {
    dof: usize,
    speed: f64,
    dt: f64,
}

impl System for Kinematic {
    type Workspace = ();
    fn dof(&self) -> usize {
        self.dof
    }
    fn workspace(&self) {}
    fn acceleration(
        &self,
        _: &mut (),
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        let d: f64 = q
            .iter()
            .zip(command)
            .map(|(a, b)| (b - a) * (b - a))
            .sum::<f64>()
            .sqrt();
        let step = self.speed * self.dt;
        for i in 0..self.dof {
            let v = if d <= step {
                (command[i] - q[i]) / self.dt
            } else {
                self.speed * (command[i] - q[i]) / d
            };
            qdd[i] = (v - qd[i]) / self.dt;
        }
        Ok(())
    }
}

/// [`Kinematic`] that stops dead once its first coordinate reaches `wall`.
struct Walled {
    inner: Kinematic,
    wall: f64,
}

impl System for Walled {
    type Workspace = ();
    fn dof(&self) -> usize {
        self.inner.dof
    }
    fn workspace(&self) {}
    fn acceleration(
        &self,
        ws: &mut (),
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        if q[0] >= self.wall - 1e-12 {
            for i in 0..qdd.len() {
                qdd[i] = -qd[i] / self.inner.dt;
            }
            return Ok(());
        }
        self.inner.acceleration(ws, q, qd, command, qdd)
    }
}

/// Damped oscillator attracted to the command, q̈ = −ω²(q − q_g) − 2ζω q̇, with the clearance monitor
/// c = q₀ − `wall` (negative when the first coordinate passes below the wall).
struct Oscillator {
    dof: usize,
    w: f64,
    z: f64,
    wall: f64,
}

impl System for Oscillator {
    type Workspace = f64; // last clearance
    fn dof(&self) -> usize {
        self.dof
    }
    fn workspace(&self) -> f64 {
        f64::NAN
    }
    fn acceleration(
        &self,
        ws: &mut f64,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        for i in 0..self.dof {
            qdd[i] = -self.w * self.w * (q[i] - command[i]) - 2.0 * self.z * self.w * qd[i];
        }
        *ws = q[0] - self.wall;
        Ok(())
    }
    fn clearance(&self, ws: &f64) -> f64 {
        *ws
    }
}

/// Accelerates at 10 until |q₀| > 1, then returns NaN.
struct Diverging;

impl System for Diverging {
    type Workspace = ();
    fn dof(&self) -> usize {
        1
    }
    fn workspace(&self) {}
    fn acceleration(
        &self,
        _: &mut (),
        q: &[f64],
        _: &[f64],
        _: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        qdd[0] = if q[0].abs() > 1.0 { f64::NAN } else { 10.0 };
        Ok(())
    }
}

fn opts(dt: f64, t_max: f64, tol: f64) -> RolloutOptions {
    RolloutOptions {
        dt,
        t_max,
        tol,
        integrator: Integrator::SemiImplicitEuler,
        record: true,
        stall_window: 0.0,
        stall_progress: 0.0,
        capture_tol: 0.0,
    }
}

/// Steps for the constant-speed system to get strictly within `tol` from distance `d`: the smallest k
/// with d − k·s·dt < tol, or `None` when (d − tol)/(s·dt) is within 1e-6 of an integer (rounding tie).
fn steps_to_reach(d: f64, s: f64, dt: f64, tol: f64) -> Option<usize> {
    if d < tol {
        return Some(0);
    }
    let x = (d - tol) / (s * dt);
    if (x - x.round()).abs() < 1e-6 {
        return None;
    }
    Some(x.floor() as usize + 1)
}

#[test]
fn max_steps_rounds_budget_up() {
    for (t_max, dt, k) in [
        (7.0, 0.01, 700),
        (1.0, 0.1, 10),
        (0.3, 0.1, 3),
        (0.055, 0.01, 6),
        (0.001, 0.01, 1),
    ] {
        assert_eq!(opts(dt, t_max, 0.1).max_steps(), k, "t_max {t_max} dt {dt}");
    }
}

#[test]
fn reach_time_matches_closed_form() {
    let sys = Kinematic {
        dof: 1,
        speed: 1.0,
        dt: 0.01,
    };
    let r = rollout_system(
        &sys,
        &mut (),
        &[0.0],
        &[0.0],
        &[1.0],
        &opts(0.01, 7.0, 0.005),
    )
    .unwrap();
    assert_eq!(r.reason, StopReason::Reached);
    assert_eq!(r.steps, 100);
    assert!((r.t_star - 1.0).abs() < 1e-12);
    assert!((r.q[0] - 1.0).abs() < 1e-12);

    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut checked = 0;
    for _ in 0..200 {
        let dof = rng.gen_range(1..5);
        let speed = rng.gen_range(0.2..2.0);
        let dt = [0.01, 0.005, 0.02][rng.gen_range(0..3)];
        let tol = rng.gen_range(0.001..0.2);
        let sys = Kinematic { dof, speed, dt };
        let q0: Vec<f64> = (0..dof).map(|_| rng.gen_range(-2.0..2.0)).collect();
        let qg: Vec<f64> = (0..dof).map(|_| rng.gen_range(-2.0..2.0)).collect();
        let d = q0
            .iter()
            .zip(&qg)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        let Some(k) = steps_to_reach(d, speed, dt, tol) else {
            continue;
        };
        let o = RolloutOptions {
            record: false,
            ..opts(dt, 7.0, tol)
        };
        let r = rollout_system(&sys, &mut (), &q0, &vec![0.0; dof], &qg, &o).unwrap();
        let t_reach = k as f64 * dt;
        if t_reach <= 7.0 - dt {
            assert_eq!(r.reason, StopReason::Reached);
            assert_eq!(r.steps, k);
            assert!((r.t_star - t_reach).abs() < 1e-12);
            assert!(r.trajectory.is_none());
            checked += 1;
        } else {
            assert_eq!(r.reason, StopReason::Timeout);
            assert_eq!(r.t_star, 7.0);
        }
    }
    assert!(checked > 150, "only {checked} cases checked");
}

#[test]
fn timeout_spends_the_budget_and_records_every_step() {
    let sys = Kinematic {
        dof: 2,
        speed: 0.0,
        dt: 0.01,
    };
    let r = rollout_system(
        &sys,
        &mut (),
        &[0.0, 0.0],
        &[0.0, 0.0],
        &[1.0, 1.0],
        &opts(0.01, 7.0, 0.01),
    )
    .unwrap();
    assert_eq!(r.reason, StopReason::Timeout);
    assert_eq!(r.t_star, 7.0);
    assert_eq!(r.steps, 700);
    let tr = r.trajectory.unwrap();
    assert_eq!(tr.len(), 701);
    assert_eq!((tr.q.len(), tr.qd.len(), tr.qdd.len()), (1402, 1402, 1402));
    for (k, t) in tr.t.iter().enumerate() {
        assert_eq!(*t, k as f64 * 0.01);
    }

    // A budget that is not a multiple of dt: the last step overshoots, t* is still t_max (eq. 2).
    let r = rollout_system(
        &sys,
        &mut (),
        &[0.0, 0.0],
        &[0.0, 0.0],
        &[1.0, 1.0],
        &opts(0.01, 0.055, 0.01),
    )
    .unwrap();
    assert_eq!(
        (r.reason, r.steps, r.t_star),
        (StopReason::Timeout, 6, 0.055)
    );
    assert!((r.t_end - 0.06).abs() < 1e-15);
}

#[test]
fn starting_on_the_command_takes_no_time() {
    let sys = Oscillator {
        dof: 3,
        w: 2.0,
        z: 0.5,
        wall: -10.0,
    };
    let q = [0.1, 0.2, 0.3];
    let r = rollout_system(
        &sys,
        &mut sys.workspace(),
        &q,
        &[5.0, 0.0, 0.0],
        &q,
        &opts(0.01, 7.0, 0.01),
    )
    .unwrap();
    assert_eq!((r.reason, r.steps, r.t_star), (StopReason::Reached, 0, 0.0));
    assert_eq!(r.qd, vec![5.0, 0.0, 0.0]);
    assert_eq!(r.trajectory.unwrap().len(), 1);
}

#[test]
fn euler_trajectory_rows_follow_the_update_rule() {
    let sys = Oscillator {
        dof: 2,
        w: 3.0,
        z: 0.3,
        wall: -10.0,
    };
    let r = rollout_system(
        &sys,
        &mut sys.workspace(),
        &[1.0, -0.5],
        &[0.0, 1.0],
        &[0.2, 0.4],
        &opts(0.01, 7.0, 1e-3),
    )
    .unwrap();
    assert_eq!(r.reason, StopReason::Reached);
    let tr = r.trajectory.unwrap();
    let dt = 0.01;
    for k in 0..tr.len() - 1 {
        let (q, qd, qdd) = (
            tr.q_row(k).unwrap(),
            tr.qd_row(k).unwrap(),
            tr.qdd_row(k).unwrap(),
        );
        let (q1, qd1) = (tr.q_row(k + 1).unwrap(), tr.qd_row(k + 1).unwrap());
        for i in 0..2 {
            assert_eq!(qd1[i], qd[i] + dt * qdd[i]);
            assert_eq!(q1[i], q[i] + dt * qd1[i]);
            assert_eq!(
                qdd[i],
                -9.0 * (q[i] - [0.2, 0.4][i]) - 2.0 * 0.3 * 3.0 * qd[i]
            );
        }
    }
    let last = tr.len() - 1;
    assert_eq!(tr.q_row(last).unwrap(), &r.q[..]);
    assert_eq!(tr.qd_row(last).unwrap(), &r.qd[..]);
    assert!(tr.q_row(last + 1).is_none());
    let d = ((r.q[0] - 0.2f64).powi(2) + (r.q[1] - 0.4f64).powi(2)).sqrt();
    assert!(d < 1e-3);
    // The step before did not satisfy eq. 3: t* is the first time within tolerance.
    let p = tr.q_row(last - 1).unwrap();
    assert!(((p[0] - 0.2f64).powi(2) + (p[1] - 0.4f64).powi(2)).sqrt() >= 1e-3);
}

#[test]
fn rk4_reaches_the_same_rest_point() {
    let sys = Oscillator {
        dof: 2,
        w: 3.0,
        z: 0.7,
        wall: -10.0,
    };
    let o = RolloutOptions {
        integrator: Integrator::Rk4,
        ..opts(0.01, 7.0, 1e-4)
    };
    let r = rollout_system(
        &sys,
        &mut sys.workspace(),
        &[1.0, -0.5],
        &[0.0, 1.0],
        &[0.2, 0.4],
        &o,
    )
    .unwrap();
    assert_eq!(r.reason, StopReason::Reached);
    assert!(r.t_star > 0.5 && r.t_star < 7.0);
}

#[test]
fn min_clearance_is_the_minimum_over_steps() {
    // Under-damped: q₀ overshoots below the command 0, the wall at −0.2.
    let sys = Oscillator {
        dof: 1,
        w: 4.0,
        z: 0.1,
        wall: -0.2,
    };
    let r = rollout_system(
        &sys,
        &mut sys.workspace(),
        &[1.0],
        &[0.0],
        &[0.0],
        &opts(0.01, 7.0, 0.01),
    )
    .unwrap();
    let tr = r.trajectory.unwrap();
    let brute = tr.q.iter().map(|q| q + 0.2).fold(f64::INFINITY, f64::min);
    assert_eq!(r.min_clearance, brute);
    assert!(r.min_clearance < 0.0);
}

#[test]
fn divergence_stops_with_non_finite() {
    for integrator in [Integrator::SemiImplicitEuler, Integrator::Rk4] {
        let o = RolloutOptions {
            integrator,
            ..opts(0.01, 7.0, 0.01)
        };
        let r = rollout_system(&Diverging, &mut (), &[0.0], &[0.0], &[5.0], &o).unwrap();
        assert_eq!(r.reason, StopReason::NonFinite, "{integrator:?}");
        assert_eq!(r.t_star, 7.0);
        assert!(r.q[0].is_finite() && r.qd[0].is_finite());
        let tr = r.trajectory.unwrap();
        assert!(tr.qdd.iter().all(|v| v.is_finite()));
        assert!(r.t_end < 1.0);
        let last = tr.len() - 1;
        match integrator {
            // Euler: the state past |q| = 1 is finite, its acceleration is not: not a trajectory row.
            Integrator::SemiImplicitEuler => {
                assert!(r.q[0] > 1.0 && tr.q[last] <= 1.0);
                assert!((r.t_end - tr.t[last] - 0.01).abs() < 1e-12);
            }
            // RK4: a stage state passes |q| = 1, the step is refused, the final state is the last row.
            Integrator::Rk4 => {
                assert!(r.q[0] <= 1.0 && r.q[0] > 0.8);
                assert_eq!((tr.q[last], tr.t[last]), (r.q[0], r.t_end));
            }
        }
    }
}

#[test]
fn sequence_cost_matches_closed_form() {
    // From 0 toward (1, 0) at speed 1: within waypoint_tol 0.105 after 90 steps, at (0.9, 0). Then toward
    // the goal (1, 1) from distance √(0.1² + 1) = 1.00499: within tol 0.005 after 100 steps.
    let sys = Kinematic {
        dof: 2,
        speed: 1.0,
        dt: 0.01,
    };
    let so = SequenceOptions {
        rollout: opts(0.01, 7.0, 0.005),
        n_commands: 1,
        waypoint_tol: 0.105,
        penalty: 50.0,
        collision_penalty: 3.0,
        collision_tol: 0.0,
        distance_penalty: 2.0,
        blend_time: 0.0,
    };
    let r = rollout_sequence_system(
        &sys,
        &mut (),
        &[0.0, 0.0],
        &[0.0, 0.0],
        &[1.0, 0.0],
        &[1.0, 1.0],
        &so,
    )
    .unwrap();
    assert_eq!(r.reasons, vec![StopReason::Reached, StopReason::Reached]);
    assert!(
        (r.t_stars[0] - 0.9).abs() < 1e-12 && (r.t_stars[1] - 1.0).abs() < 1e-12,
        "{:?}",
        r.t_stars
    );
    // Reached: no distance term (eq. 4 unchanged), and the closest approach is within tol.
    assert!((r.cost - 1.9).abs() < 1e-12);
    assert!(r.reached && r.success() && r.goal_distance < 0.005);
    assert_eq!(r.min_clearance, f64::INFINITY);

    // Random sequences: Σ of the closed-form times, the hand-over point being where the first leg stops.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut checked = 0;
    for _ in 0..100 {
        let speed = rng.gen_range(1.0..2.0); // every leg takes < 7 s
        let sys = Kinematic {
            dof: 1,
            speed,
            dt: 0.01,
        };
        let (c, g) = (rng.gen_range(0.5..3.0), rng.gen_range(-3.0..0.0));
        let so = SequenceOptions {
            waypoint_tol: rng.gen_range(0.01..0.3),
            ..so.clone()
        };
        let Some(k1) = steps_to_reach(c, speed, 0.01, so.waypoint_tol) else {
            continue;
        };
        let handover = (k1 as f64 * speed * 0.01).min(c);
        let Some(k2) = steps_to_reach(handover - g, speed, 0.01, 0.005) else {
            continue;
        };
        let r = rollout_sequence_system(&sys, &mut (), &[0.0], &[0.0], &[c], &[g], &so).unwrap();
        let expected = (k1 + k2) as f64 * 0.01;
        assert!(
            (r.cost - expected).abs() < 1e-9,
            "cost {} expected {expected}",
            r.cost
        );
        checked += 1;
    }
    assert!(checked > 80);
}

#[test]
fn sequence_penalties() {
    // Budget too short for either leg: both time out (the first hands over anyway, eq. 7), penalty p.
    let sys = Kinematic {
        dof: 2,
        speed: 1.0,
        dt: 0.01,
    };
    let so = SequenceOptions {
        rollout: opts(0.01, 0.5, 0.005),
        n_commands: 1,
        waypoint_tol: 0.1,
        penalty: 50.0,
        collision_penalty: 3.0,
        collision_tol: 0.0,
        distance_penalty: 2.0,
        blend_time: 0.0,
    };
    let r = rollout_sequence_system(
        &sys,
        &mut (),
        &[0.0, 0.0],
        &[0.0, 0.0],
        &[1.0, 0.0],
        &[1.0, 1.0],
        &so,
    )
    .unwrap();
    assert_eq!(r.reasons, vec![StopReason::Timeout, StopReason::Timeout]);
    assert_eq!(r.t_stars, vec![0.5, 0.5]);
    // Not reached: p plus 2 s/rad times the closest approach, the final distance √1.25 − 0.5.
    let closest = 1.25f64.sqrt() - 0.5;
    assert!(
        (r.goal_distance - closest).abs() < 1e-9,
        "{}",
        r.goal_distance
    );
    assert!((r.cost - (51.0 + 2.0 * closest)).abs() < 1e-9);
    assert!(!r.reached);
    // The second leg started at (0.5, 0) and moved 0.5 toward (1, 1).
    let dir = [0.5 / 1.25f64.sqrt(), 1.0 / 1.25f64.sqrt()];
    assert!((r.q[0] - (0.5 + 0.5 * dir[0])).abs() < 1e-9 && (r.q[1] - 0.5 * dir[1]).abs() < 1e-9);

    // Collision: the oscillator dips below its wall; the goal is reached, cost = Σt* + collision penalty.
    let osc = Oscillator {
        dof: 1,
        w: 4.0,
        z: 0.1,
        wall: -0.2,
    };
    let so = SequenceOptions {
        rollout: opts(0.01, 7.0, 0.01),
        n_commands: 0,
        ..so
    };
    let r = rollout_sequence_system(&osc, &mut osc.workspace(), &[1.0], &[0.0], &[], &[0.0], &so)
        .unwrap();
    assert!(r.reached && r.collided && !r.success() && r.min_clearance < 0.0);
    assert!((r.cost - (r.t_stars[0] + 3.0)).abs() < 1e-12);
    // The same dip tolerated as a shallow penetration: no collision, no penalty.
    let tolerant = SequenceOptions {
        collision_tol: -r.min_clearance + 1e-9,
        ..so.clone()
    };
    let t = rollout_sequence_system(
        &osc,
        &mut osc.workspace(),
        &[1.0],
        &[0.0],
        &[],
        &[0.0],
        &tolerant,
    )
    .unwrap();
    assert!(t.success() && !t.collided);
    assert_eq!(t.cost, t.t_stars[0]);

    // Divergence in the first leg: every leg counts t_max, plus the penalty.
    let so = SequenceOptions {
        n_commands: 2,
        ..so
    };
    let r = rollout_sequence_system(
        &Diverging,
        &mut (),
        &[0.0],
        &[0.0],
        &[3.0, 4.0],
        &[5.0],
        &so,
    )
    .unwrap();
    assert_eq!(r.reasons, vec![StopReason::NonFinite; 3]);
    assert_eq!(r.t_stars, vec![7.0; 3]);
    // The goal was never commanded: its distance is that of the last finite state.
    assert_eq!(r.goal_distance, (r.q[0] - 5.0).abs());
    assert!((r.cost - (21.0 + 50.0 + 2.0 * r.goal_distance)).abs() < 1e-12);
}

#[test]
fn sequence_is_a_chain_of_rollouts() {
    let sys = Oscillator {
        dof: 3,
        w: 2.5,
        z: 0.4,
        wall: -10.0,
    };
    let (q0, qd0) = ([0.3, -0.2, 0.1], [0.5, 0.0, -0.4]);
    let commands = [1.0, 0.5, -0.5, -0.6, 0.8, 0.2];
    let goal = [0.0, 0.0, 1.0];
    let so = SequenceOptions {
        rollout: opts(0.01, 7.0, 0.01),
        n_commands: 2,
        waypoint_tol: 0.15,
        penalty: 10.0,
        collision_penalty: 1.0,
        collision_tol: 0.0,
        distance_penalty: 0.0,
        blend_time: 0.0,
    };
    let seq = rollout_sequence_system(&sys, &mut sys.workspace(), &q0, &qd0, &commands, &goal, &so)
        .unwrap();

    // Chain rollout_system by hand (eq. 7: state and velocity carried over).
    let (mut q, mut qd) = (q0.to_vec(), qd0.to_vec());
    let mut rows = 0;
    let mut sum = 0.0;
    for (i, cmd) in [&commands[0..3], &commands[3..6], &goal[..]]
        .into_iter()
        .enumerate()
    {
        let tol = if i < 2 { 0.15 } else { 0.01 };
        let r = rollout_system(
            &sys,
            &mut sys.workspace(),
            &q,
            &qd,
            cmd,
            &RolloutOptions {
                tol,
                ..so.rollout.clone()
            },
        )
        .unwrap();
        assert_eq!(r.t_star, seq.t_stars[i]);
        assert_eq!(r.reason, seq.reasons[i]);
        rows += r.trajectory.unwrap().len() - usize::from(i > 0);
        sum += r.t_star;
        q = r.q;
        qd = r.qd;
    }
    assert_eq!(seq.q, q);
    assert_eq!(seq.qd, qd);
    assert!(seq.reached);
    assert!((seq.cost - sum).abs() < 1e-12);

    let tr = seq.trajectory.unwrap();
    assert_eq!(tr.len(), rows);
    assert!(tr.t.windows(2).all(|w| w[1] > w[0]), "times must increase");
    assert!((tr.t[rows - 1] - sum).abs() < 1e-9);
    // Continuity of the whole trajectory: every row is one Euler step from the previous one, also across
    // the junctions (the junction row carries the acceleration toward the next command).
    for k in 0..rows - 1 {
        for i in 0..3 {
            let qd1 = tr.qd[k * 3 + i] + 0.01 * tr.qdd[k * 3 + i];
            assert_eq!(tr.qd[(k + 1) * 3 + i], qd1);
            assert_eq!(tr.q[(k + 1) * 3 + i], tr.q[k * 3 + i] + 0.01 * qd1);
        }
    }
}

/// The command blend (an extension of eq. 7): the oscillator's acceleration is linear in its command,
/// so a jump of the command is a jump of q̈ at the junction; blended, q̈ is continuous there (the
/// junction's first blended command is the previous one) and the command reaches the next one after
/// `blend_time`, from where the rollout is the unblended system's. The goal is still what is judged.
#[test]
fn blended_handover_keeps_the_acceleration_continuous() {
    let sys = Oscillator {
        dof: 2,
        w: 3.0,
        z: 0.7,
        wall: -10.0,
    };
    let (q0, qd0) = ([0.0, 0.0], [0.0, 0.0]);
    let commands = [1.0, 1.0];
    let goal = [2.0, -1.0];
    let base = SequenceOptions {
        rollout: opts(0.01, 7.0, 0.01),
        n_commands: 1,
        waypoint_tol: 0.2,
        blend_time: 0.0,
        ..SequenceOptions::default()
    };
    let run = |blend_time: f64| {
        let so = SequenceOptions {
            blend_time,
            ..base.clone()
        };
        rollout_sequence_system(&sys, &mut sys.workspace(), &q0, &qd0, &commands, &goal, &so)
            .unwrap()
    };
    // largest change of q̈ between consecutive rows after the first command's handover
    let max_jump = |r: &SequenceResult| {
        let tr = r.trajectory.as_ref().unwrap();
        let k0 = (r.t_stars[0] / 0.01).round() as usize;
        (k0 - 1..tr.len() - 1)
            .map(|k| {
                (0..2)
                    .map(|i| (tr.qdd[(k + 1) * 2 + i] - tr.qdd[k * 2 + i]).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    };
    let jump = run(0.0);
    let blended = run(0.5);
    assert!(jump.reached && blended.reached);
    assert_eq!(
        blended.t_stars[0], jump.t_stars[0],
        "the first command is not blended"
    );
    // unblended: ω² × the command step (|Δ| = 2 on the second coordinate) in one row
    assert!(max_jump(&jump) > 0.9 * 9.0 * 2.0, "{}", max_jump(&jump));
    assert!(
        max_jump(&blended) < 0.15 * max_jump(&jump),
        "{}",
        max_jump(&blended)
    );
    assert!(blended.goal_distance < 0.01);
    let bad = SequenceOptions {
        blend_time: -0.1,
        ..base
    };
    let err = rollout_sequence_system(
        &sys,
        &mut sys.workspace(),
        &q0,
        &qd0,
        &commands,
        &goal,
        &bad,
    )
    .unwrap_err();
    assert!(
        matches!(err, FabricError::Value { ref what, .. } if what == "SequenceOptions.blend_time"),
        "{err}"
    );
}

#[test]
fn batch_is_identical_whatever_the_thread_count() {
    let sys = Oscillator {
        dof: 4,
        w: 3.0,
        z: 0.3,
        wall: -1.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 2;
    let candidates: Vec<f64> = (0..37 * n * 4).map(|_| rng.gen_range(-2.0..2.0)).collect();
    let (q0, qd0, goal) = ([0.1, 0.2, -0.3, 0.0], [0.0; 4], [0.5, -0.5, 0.5, -0.5]);
    for integrator in [Integrator::SemiImplicitEuler, Integrator::Rk4] {
        let so = SequenceOptions {
            rollout: RolloutOptions {
                integrator,
                ..opts(0.01, 3.0, 0.01)
            },
            n_commands: n,
            ..SequenceOptions::default()
        };
        let one = evaluate_batch_system(&sys, &q0, &qd0, &goal, &candidates, &so, Some(1)).unwrap();
        let two = evaluate_batch_system(&sys, &q0, &qd0, &goal, &candidates, &so, Some(2)).unwrap();
        let default =
            evaluate_batch_system(&sys, &q0, &qd0, &goal, &candidates, &so, None).unwrap();
        assert_eq!(one.len(), 37);
        for j in 0..37 {
            let single = rollout_sequence_system(
                &sys,
                &mut sys.workspace(),
                &q0,
                &qd0,
                &candidates[j * 8..(j + 1) * 8],
                &goal,
                &so,
            )
            .unwrap();
            assert_eq!(bits(&one[j]), bits(&single), "candidate {j}");
            assert_eq!(bits(&two[j]), bits(&single), "candidate {j}");
            assert_eq!(bits(&default[j]), bits(&single), "candidate {j}");
            assert!(one[j].trajectory.is_some());
        }
        // The candidates differ, and so do their costs (the batch is not returning one result N times).
        assert!(one.iter().any(|r| r.cost != one[0].cost));
        assert!(one.iter().any(|r| r.collided) && one.iter().any(|r| !r.collided));
    }
    let empty = evaluate_batch_system(
        &sys,
        &q0,
        &qd0,
        &goal,
        &[],
        &SequenceOptions::default(),
        Some(2),
    )
    .unwrap();
    assert!(empty.is_empty());
}

fn what(e: FabricError) -> String {
    match e {
        FabricError::Shape { what, .. }
        | FabricError::NonFinite { what }
        | FabricError::Value { what, .. } => what,
        other => panic!("unexpected error {other:?}"),
    }
}

#[test]
fn invalid_inputs_name_the_culprit() {
    let sys = Oscillator {
        dof: 2,
        w: 1.0,
        z: 1.0,
        wall: 0.0,
    };
    let mut ws = sys.workspace();
    let o = RolloutOptions::default();
    let z = [0.0, 0.0];
    let err = |r: Result<fabric_core::rollout::RolloutResult>| what(r.unwrap_err());
    assert_eq!(err(rollout_system(&sys, &mut ws, &[0.0], &z, &z, &o)), "q0");
    assert_eq!(
        err(rollout_system(&sys, &mut ws, &z, &[0.0; 3], &z, &o)),
        "qd0"
    );
    assert_eq!(
        err(rollout_system(&sys, &mut ws, &z, &z, &[1.0], &o)),
        "command"
    );
    assert_eq!(
        err(rollout_system(&sys, &mut ws, &[f64::NAN, 0.0], &z, &z, &o)),
        "q0"
    );
    assert_eq!(
        err(rollout_system(
            &sys,
            &mut ws,
            &z,
            &[0.0, f64::INFINITY],
            &z,
            &o
        )),
        "qd0"
    );
    assert_eq!(
        err(rollout_system(&sys, &mut ws, &z, &z, &[f64::NAN, 0.0], &o)),
        "command"
    );
    for (field, bad) in [
        (
            "RolloutOptions.dt",
            RolloutOptions {
                dt: 0.0,
                ..o.clone()
            },
        ),
        (
            "RolloutOptions.dt",
            RolloutOptions {
                dt: f64::NAN,
                ..o.clone()
            },
        ),
        (
            "RolloutOptions.t_max",
            RolloutOptions {
                t_max: -1.0,
                ..o.clone()
            },
        ),
        (
            "RolloutOptions.t_max",
            RolloutOptions {
                t_max: f64::INFINITY,
                ..o.clone()
            },
        ),
        (
            "RolloutOptions.t_max",
            RolloutOptions {
                t_max: 1e9,
                ..o.clone()
            },
        ),
        (
            "RolloutOptions.tol",
            RolloutOptions {
                tol: 0.0,
                ..o.clone()
            },
        ),
    ] {
        assert_eq!(err(rollout_system(&sys, &mut ws, &z, &z, &z, &bad)), field);
    }

    let so = SequenceOptions::default();
    let seq = |c: &[f64], g: &[f64], so: &SequenceOptions| {
        rollout_sequence_system(&sys, &mut sys.workspace(), &z, &z, c, g, so)
    };
    assert_eq!(what(seq(&[0.0; 3], &z, &so).unwrap_err()), "commands");
    assert_eq!(what(seq(&z, &[0.0], &so).unwrap_err()), "goal");
    assert_eq!(
        what(seq(&[0.0, f64::NAN], &z, &so).unwrap_err()),
        "commands"
    );
    for (field, bad) in [
        (
            "SequenceOptions.waypoint_tol",
            SequenceOptions {
                waypoint_tol: -0.1,
                ..so.clone()
            },
        ),
        (
            "SequenceOptions.penalty",
            SequenceOptions {
                penalty: f64::NAN,
                ..so.clone()
            },
        ),
        (
            "SequenceOptions.collision_penalty",
            SequenceOptions {
                collision_penalty: -1.0,
                ..so.clone()
            },
        ),
        (
            "SequenceOptions.collision_tol",
            SequenceOptions {
                collision_tol: f64::INFINITY,
                ..so.clone()
            },
        ),
        (
            "SequenceOptions.distance_penalty",
            SequenceOptions {
                distance_penalty: -0.5,
                ..so.clone()
            },
        ),
        (
            "RolloutOptions.tol",
            SequenceOptions {
                rollout: RolloutOptions {
                    tol: -1.0,
                    ..o.clone()
                },
                ..so.clone()
            },
        ),
    ] {
        assert_eq!(what(seq(&z, &z, &bad).unwrap_err()), field);
    }

    let batch =
        |c: &[f64], so: &SequenceOptions, th| evaluate_batch_system(&sys, &z, &z, &z, c, so, th);
    assert_eq!(what(batch(&[0.0; 3], &so, None).unwrap_err()), "candidates");
    assert_eq!(
        what(batch(&[0.0, f64::NAN], &so, None).unwrap_err()),
        "candidates"
    );
    assert_eq!(what(batch(&[0.0; 4], &so, Some(0)).unwrap_err()), "threads");
    let zero = SequenceOptions {
        n_commands: 0,
        ..so.clone()
    };
    assert_eq!(
        what(batch(&[0.0; 4], &zero, None).unwrap_err()),
        "SequenceOptions.n_commands"
    );
    assert_eq!(
        what(evaluate_batch_system(&sys, &z, &z, &[0.0], &[0.0; 4], &so, None).unwrap_err()),
        "goal"
    );
}

/// Stall detection: a system creeping toward its command at 0.005 rad/s gains less than
/// `stall_progress` = 0.01 rad per `stall_window` = 1 s and stops after one window
/// (t = 1 s, t* = t_max); at 0.02 rad/s it keeps going until the budget; with the window 0 it never stalls.
/// Goal capture turns a stall near the command into an arrival.
#[test]
fn stall_detection_stops_rollouts_without_progress() {
    let dt = 0.01;
    let stalling = RolloutOptions {
        stall_window: 1.0,
        stall_progress: 0.01,
        ..opts(dt, 5.0, 0.01)
    };
    /// From rest at the origin toward (1, 0).
    fn run<S: System<Workspace = ()>>(sys: &S, opts: &RolloutOptions) -> RolloutResult {
        rollout_system(sys, &mut (), &[0.0, 0.0], &[0.0, 0.0], &[1.0, 0.0], opts).unwrap()
    }
    let slow = Kinematic {
        dof: 2,
        speed: 0.005,
        dt,
    };
    let r = run(&slow, &stalling);
    assert_eq!(r.reason, StopReason::Stalled);
    assert_eq!(r.steps, 100);
    assert_eq!(r.t_star, 5.0);
    let progressing = Kinematic {
        dof: 2,
        speed: 0.02,
        dt,
    };
    let r = run(&progressing, &stalling);
    assert_eq!(r.reason, StopReason::Timeout);
    assert_eq!(r.steps, 500);
    // the window slides: a system that progresses at 0.02 rad/s until it hits a wall at q₀ = 0.03 (t =
    // 1.5 s) stops once the last second has gained less than 0.01 rad, at t ≈ 2 s (fixed windows
    // starting at t = 0 would only notice at t = 3 s)
    let walled = Walled {
        inner: progressing,
        wall: 0.03,
    };
    let r = run(&walled, &stalling);
    assert_eq!(r.reason, StopReason::Stalled);
    assert!(
        (200..=202).contains(&r.steps),
        "stopped after {} steps",
        r.steps
    );
    // goal capture: the same wall 0.02 from a command at (0.05, 0) holds the system off it; a stall
    // within capture_tol of the command counts as reached at the time it stalled, one outside it does
    // not, and neither does a stall when capture_tol is not looser than tol
    let near = [0.05, 0.0];
    let walled_run = |o: &RolloutOptions| {
        rollout_system(&walled, &mut (), &[0.0, 0.0], &[0.0, 0.0], &near, o).unwrap()
    };
    let captured = walled_run(&RolloutOptions {
        capture_tol: 0.025,
        ..stalling.clone()
    });
    assert_eq!(captured.reason, StopReason::Reached);
    assert_eq!(captured.t_star, captured.t_end);
    assert!(
        (2.0..=2.03).contains(&captured.t_star),
        "t* = {}",
        captured.t_star
    );
    for capture_tol in [0.015, 0.0] {
        let held = walled_run(&RolloutOptions {
            capture_tol,
            ..stalling.clone()
        });
        assert_eq!(held.reason, StopReason::Stalled);
        assert_eq!(held.t_star, 5.0);
    }
    let loose_tol = walled_run(&RolloutOptions {
        capture_tol: 0.025,
        tol: 0.03,
        ..stalling.clone()
    });
    assert_eq!(loose_tol.reason, StopReason::Reached); // within tol itself: reached on arrival
    let off = RolloutOptions {
        stall_window: 0.0,
        ..stalling.clone()
    };
    let r = rollout_system(&slow, &mut (), &[0.0, 0.0], &[0.0, 0.0], &[1.0, 0.0], &off).unwrap();
    assert_eq!(r.reason, StopReason::Timeout);
    let bad = RolloutOptions {
        stall_progress: -1.0,
        ..stalling
    };
    let err =
        rollout_system(&slow, &mut (), &[0.0, 0.0], &[0.0, 0.0], &[1.0, 0.0], &bad).unwrap_err();
    assert!(
        matches!(err, FabricError::Value { ref what, .. } if what == "RolloutOptions.stall_progress"),
        "{err}"
    );
}
