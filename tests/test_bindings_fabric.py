"""gfcs.Fabric bindings: construction, acceleration and diagnostics, rollouts (checked against the
semi-implicit Euler recurrence), sequences, batch evaluation (thread-count independence), scene updates,
the GIL being released, the particle systems, and errors."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

import gfcs

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
GOAL = Q0 + np.array([0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.1])


@pytest.fixture(scope="module")
def robot():
    return gfcs.Robot.panda()


@pytest.fixture()
def scene():
    s = gfcs.Scene()
    s.add_sphere([0.45, 0.2, 0.5], 0.08, name="ball")  # 8 cm from the arm at Q0: within the influence
    return s


@pytest.fixture()
def fabric(robot):
    """A fabric whose only obstacle stays beyond the influence radius: rollouts converge to the command."""
    s = gfcs.Scene()
    s.add_sphere([-0.6, -0.6, 0.3], 0.1, name="far ball")
    return gfcs.Fabric(robot, s)


def test_construction_variants(robot, scene, tmp_path):
    f = gfcs.Fabric(robot)
    assert f.dof == 7 and len(f.scene) == 0
    assert f.robot.name == "panda"
    assert f.config == gfcs.FabricConfig()
    cfg = gfcs.FabricConfig({"speed": {"desired_speed": 0.8}})
    path = tmp_path / "fabric.toml"
    path.write_text("[speed]\ndesired_speed = 0.8\n")
    for c in (cfg, {"speed": {"desired_speed": 0.8}}, path, str(path)):
        assert gfcs.Fabric(robot, scene, c).config == cfg
    assert "panda" in repr(f)


def test_acceleration_and_diagnostics(fabric):
    assert fabric.diagnostics() is None
    qdd = fabric.acceleration(Q0, np.zeros(7), GOAL)
    assert qdd.shape == (7,) and qdd.dtype == np.float64 and np.all(np.isfinite(qdd))
    d = fabric.diagnostics()
    for key in ("energy", "exec_energy", "potential", "min_clearance", "min_self_clearance", "min_joint_margin",
                "alpha_le", "beta", "eta", "leaves"):
        assert key in d
    assert d["exec_energy"] == 0.0  # at rest
    assert isinstance(d["leaves"], int)
    # at the command, at rest, the acceleration vanishes up to the barrier terms: much smaller than away
    assert np.linalg.norm(fabric.acceleration(GOAL, np.zeros(7), GOAL)) < 0.1 * np.linalg.norm(qdd)


def test_metric_and_diagnostics_describe_the_last_successful_call(robot, scene):
    """``metric()`` is M̃ (dof, dof), symmetric positive definite, of the last ``acceleration`` call; a call
    that fails in the evaluation (a finite but overflowing velocity) changes neither it nor ``diagnostics()``."""
    f = gfcs.Fabric(robot, scene)
    assert f.metric() is None
    f.acceleration(Q0, np.full(7, 0.1), GOAL)
    m, d = f.metric(), f.diagnostics()
    assert m.shape == (7, 7) and m.dtype == np.float64
    np.testing.assert_array_equal(m, m.T)
    assert np.linalg.eigvalsh(m).min() > 0.0
    with pytest.raises(gfcs.NonFiniteError):
        f.acceleration(Q0, np.full(7, 1e200), GOAL)
    np.testing.assert_array_equal(f.metric(), m)
    assert f.diagnostics() == d
    f.acceleration(GOAL, np.zeros(7), GOAL)
    assert not np.array_equal(f.metric(), m)


def test_diagnostics_potential_is_evaluated_on_demand(robot, scene):
    """``acceleration`` skips the forcing potential ψ; ``diagnostics()`` evaluates it at the last call's
    state: with only the joint attractor it is the closed form k ln cosh(α‖q − command‖) (GF VII-A1), with
    obstacles it does not depend on what was called since, and ``potential=False`` gives NaN and the same
    other fields. Asking for it changes no later acceleration, and a scene set since does not change it."""
    off = {"enabled": False}
    cfg = gfcs.FabricConfig({"joint_limits": off, "self_collision": off, "obstacles": off,
                             "ee_position": off})
    k = cfg.to_dict()["joint_attraction"]["potential"]
    f = gfcs.Fabric(robot, None, cfg)
    qd = np.full(7, 0.1)
    f.acceleration(Q0, qd, GOAL)
    r = np.linalg.norm(Q0 - GOAL)
    assert f.diagnostics()["potential"] == pytest.approx(k["gain"] * math.log(math.cosh(k["sharpness"] * r)),
                                                         rel=1e-12)
    f = gfcs.Fabric(robot, scene)
    q = Q0 + 0.05
    first = f.acceleration(q, qd, GOAL)
    with_psi = f.diagnostics()
    without = f.diagnostics(potential=False)
    assert math.isfinite(with_psi["potential"]) and math.isnan(without["potential"])
    assert {key: v for key, v in with_psi.items() if key != "potential"} == \
        {key: v for key, v in without.items() if key != "potential"}
    np.testing.assert_array_equal(f.acceleration(q, qd, GOAL), first)
    f.acceleration(Q0, qd, Q0)
    f.acceleration(q, qd, GOAL)
    assert f.diagnostics() == with_psi
    f.set_scene(gfcs.Scene())  # ψ is that of the scene the last call saw
    assert f.diagnostics() == with_psi


def test_rollout_follows_semi_implicit_euler(fabric):
    dt = 0.01
    r = fabric.rollout(Q0, np.zeros(7), GOAL, dt=dt, t_max=5.0, tol=0.01)
    t, q, qd, qdd = r.t, r.q, r.qd, r.qdd
    n = len(t)
    assert n == len(r) and q.shape == qd.shape == qdd.shape == (n, 7)
    np.testing.assert_array_equal(q[0], Q0)
    np.testing.assert_array_equal(qd[0], np.zeros(7))
    np.testing.assert_allclose(t, dt * np.arange(n), atol=1e-12)
    # q̇ₖ₊₁ = q̇ₖ + dt q̈ₖ ; qₖ₊₁ = qₖ + dt q̇ₖ₊₁
    np.testing.assert_allclose(qd[1:], qd[:-1] + dt * qdd[:-1], atol=1e-12)
    np.testing.assert_allclose(q[1:], q[:-1] + dt * qd[1:], atol=1e-12)
    # the first recorded acceleration is the fabric's
    np.testing.assert_allclose(qdd[0], fabric.acceleration(Q0, np.zeros(7), GOAL), atol=1e-12)
    assert r.reason == "reached" and r.reached
    assert np.linalg.norm(r.q_final - GOAL) < 0.01
    assert r.t_star == pytest.approx(r.steps * dt)
    assert r.min_clearance > 0
    np.testing.assert_array_equal(r.q_final, q[-1])
    # not recorded: empty arrays, same outcome
    r2 = fabric.rollout(Q0, None, GOAL, record=False)
    assert r2.q.shape == (0, 7) and r2.t.shape == (0,)
    assert r2.t_star == r.t_star
    rk = fabric.rollout(Q0, None, GOAL, integrator="rk4")
    assert rk.reached


def test_rollout_min_clearance_is_the_minimum_over_states(robot, scene):
    """Rollout.min_clearance is the minimum over the visited states of min(obstacle clearance, self
    clearance), as the diagnostics report them."""
    f = gfcs.Fabric(robot, scene)  # the ball is within the influence radius
    r = f.rollout(Q0, None, GOAL, t_max=0.5)
    clearances = []
    for q, qd in zip(r.q, r.qd):
        f.acceleration(q, qd, GOAL)
        d = f.diagnostics()
        clearances.append(min(d["min_clearance"], d["min_self_clearance"]))
    assert np.isfinite(r.min_clearance) and r.min_clearance > 0
    assert min(clearances) - 1e-12 <= r.min_clearance <= min(clearances[:-1]) + 1e-12


def test_timeout(fabric):
    r = fabric.rollout(Q0, None, GOAL, t_max=0.05)
    assert r.reason == "timeout" and not r.reached and r.t_star == pytest.approx(0.05)


def test_sequence_and_evaluate_agree(fabric):
    mid = 0.5 * (Q0 + GOAL) + 0.1
    seq = fabric.rollout_sequence(Q0, None, [mid], GOAL)
    assert seq.t_stars.shape == (2,) and len(seq.reasons) == 2
    assert seq.reached and seq.success and seq.cost == pytest.approx(seq.t_stars.sum())
    assert seq.q.shape[1] == 7 and np.all(np.diff(seq.t) > 0)
    direct = fabric.rollout_sequence(Q0, None, np.zeros((0, 7)), GOAL)
    assert direct.cost == pytest.approx(fabric.rollout(Q0, None, GOAL).t_star)
    cands = np.stack([mid, GOAL, Q0 - 0.2, Q0 + 0.3])
    costs, reached, clearance = fabric.evaluate(Q0, None, GOAL, cands)
    assert costs.shape == reached.shape == clearance.shape == (4,)
    assert reached.dtype == np.bool_
    assert costs[0] == pytest.approx(seq.cost)
    for i, c in enumerate(cands):
        s = fabric.rollout_sequence(Q0, np.zeros(7), c[None], GOAL, record=False)
        assert costs[i] == s.cost and reached[i] == s.reached and clearance[i] == s.min_clearance
    one = fabric.evaluate(Q0, None, GOAL, cands, threads=1)
    two = fabric.evaluate(Q0, None, GOAL, cands, threads=2)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)
    *_, trajs = fabric.evaluate(Q0, None, GOAL, cands, return_trajectories=True)
    assert len(trajs) == 4 and trajs[0].q.shape[1] == 7 and trajs[0].cost == costs[0]
    # the batch's recordings are rollout_sequence's, bit for bit (the solver's candidate selection uses them)
    for c, got in zip(cands, trajs):
        ref = fabric.rollout_sequence(Q0, np.zeros(7), c[None], GOAL)
        for key in ("t", "q", "qd", "qdd", "t_stars"):
            np.testing.assert_array_equal(getattr(got, key), getattr(ref, key))
        assert got.cost == ref.cost and got.reached == ref.reached
    # two free commands per candidate: (N, 2·dof)
    two_cmd = fabric.evaluate(Q0, None, GOAL, np.hstack([cands, cands]))
    assert two_cmd[0].shape == (4,)


def test_penalty_when_goal_not_reached(fabric):
    costs, reached, _ = fabric.evaluate(Q0, None, GOAL, GOAL[None], t_max=0.05, penalty=50.0)
    assert not reached[0] and costs[0] == pytest.approx(0.1 + 50.0)


def test_distance_penalty_adds_the_closest_approach_when_not_reached(fabric):
    seq = fabric.rollout_sequence(Q0, None, GOAL[None], GOAL, t_max=0.05, penalty=50.0, distance_penalty=3.0)
    # short budget: the arm barely moves, so the closest approach is (nearly) the last state's distance
    last = np.linalg.norm(seq.q[-1] - GOAL)
    assert not seq.reached and 0 < seq.goal_distance <= last + 1e-12
    assert seq.goal_distance == pytest.approx(np.linalg.norm(seq.q - GOAL, axis=1).min())
    assert seq.cost == pytest.approx(0.1 + 50.0 + 3.0 * seq.goal_distance)
    costs, _, _ = fabric.evaluate(Q0, None, GOAL, GOAL[None], t_max=0.05, penalty=50.0, distance_penalty=3.0)
    assert costs[0] == seq.cost
    reached = fabric.rollout_sequence(Q0, None, GOAL[None], GOAL, distance_penalty=3.0)
    assert reached.reached and reached.goal_distance < 0.01 and reached.cost == pytest.approx(reached.t_stars.sum())
    assert fabric.rollout(Q0, None, GOAL).min_distance < 0.01
    with pytest.raises(gfcs.InvalidValueError, match="distance_penalty"):
        fabric.evaluate(Q0, None, GOAL, GOAL[None], distance_penalty=-1.0)


def test_blend_time_smooths_the_handover(fabric):
    waypoint = 0.5 * (Q0 + GOAL) + np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    jump = fabric.rollout_sequence(Q0, None, waypoint[None], GOAL, blend_time=0.0)
    blended = fabric.rollout_sequence(Q0, None, waypoint[None], GOAL)  # default 0.5 s
    assert jump.reached and blended.reached
    # the first command is never blended; after the handover the command moves gradually
    assert blended.t_stars[0] == jump.t_stars[0]
    k = int(round(jump.t_stars[0] / 0.01))
    step = lambda r: np.abs(np.diff(r.qdd[k - 1:k + 2], axis=0)).max()  # noqa: E731
    assert step(blended) < 0.5 * step(jump)
    costs, _, _ = fabric.evaluate(Q0, None, GOAL, waypoint[None], blend_time=0.0)
    assert costs[0] == jump.cost
    with pytest.raises(gfcs.InvalidValueError, match="blend_time"):
        fabric.evaluate(Q0, None, GOAL, waypoint[None], blend_time=-0.1)


def test_collision_penalty_and_tolerance(robot):
    s = gfcs.Scene()
    # a box around the start configuration's hand: every sequence starts in collision
    hand = robot.link_poses(Q0)[robot.link_index("panda_hand")][:3, 3]
    s.add_box([0.3, 0.3, 0.3], (hand, [0, 0, 0, 1]))
    f = gfcs.Fabric(robot, s)
    base, _, clearance = f.evaluate(Q0, None, GOAL, GOAL[None], t_max=0.5)
    assert clearance[0] < 0
    penalised, _, _ = f.evaluate(Q0, None, GOAL, GOAL[None], t_max=0.5, collision_penalty=30.0)
    assert penalised[0] == pytest.approx(base[0] + 30.0)
    tolerated, _, _ = f.evaluate(
        Q0, None, GOAL, GOAL[None], t_max=0.5, collision_penalty=30.0, collision_tol=1.0 - clearance[0]
    )
    assert tolerated[0] == pytest.approx(base[0])
    seq = f.rollout_sequence(Q0, None, GOAL[None], GOAL, t_max=0.5, collision_penalty=30.0)
    assert seq.collided and not seq.success and seq.cost == pytest.approx(penalised[0])


def test_scene_is_held_by_value_and_updatable(robot, scene):
    f = gfcs.Fabric(robot, scene)
    near = f.acceleration(Q0, np.zeros(7), GOAL)
    assert np.isfinite(f.diagnostics()["min_clearance"])
    ball = scene.ids()[0]
    scene.set_pose(ball, np.eye(4))  # the fabric holds a copy: no effect
    np.testing.assert_array_equal(f.acceleration(Q0, np.zeros(7), GOAL), near)
    copy = f.scene
    copy.remove(ball)
    assert len(f.scene) == 1
    far = np.eye(4)
    far[:3, 3] = [5, 5, 5]
    f.update_obstacle(ball, pose=far)
    moved = f.acceleration(Q0, np.zeros(7), GOAL)
    np.testing.assert_allclose(f.scene.get(ball)["pose"], far)
    assert not np.allclose(moved, near)
    f.set_scene(gfcs.Scene())
    np.testing.assert_allclose(f.acceleration(Q0, np.zeros(7), GOAL), moved, atol=1e-12)  # far = absent
    f.set_scene(scene)
    assert len(f.scene) == 1
    with pytest.raises(gfcs.InvalidValueError, match="99"):
        f.update_obstacle(99, velocity=[0, 0, 1])


def test_ee_target_matches_default_targets(robot):
    cfg = {"ee_position": {"enabled": True}, "ee_orientation": {"enabled": True}}
    f = gfcs.Fabric(robot, None, cfg)
    target = robot.link_poses(GOAL)[robot.link_index(robot.ee_link)]
    qd = np.full(7, 0.1)
    np.testing.assert_allclose(
        f.acceleration(Q0, qd, GOAL, ee_target=target), f.acceleration(Q0, qd, GOAL), atol=1e-10
    )


def test_acceleration_calls_do_not_depend_on_earlier_calls(robot, scene):
    """The workspace kept between ``acceleration`` calls carries nothing over: any sequence of calls
    (commands, end-effector targets, states) gives bit for bit what a new fabric gives for each call."""
    cfg = {"ee_position": {"enabled": True}, "ee_orientation": {"enabled": True}}
    kept = gfcs.Fabric(robot, scene, cfg)
    rng = np.random.default_rng(4)
    target = robot.link_poses(Q0)[robot.link_index(robot.ee_link)]
    for k in range(12):
        q, qd = Q0 + rng.normal(0, 0.2, 7), rng.normal(0, 0.5, 7)
        command = GOAL if k % 3 else Q0  # the end-effector targets follow the command, or are given
        ee = target if k % 4 == 1 else None
        fresh = gfcs.Fabric(robot, scene, cfg)
        np.testing.assert_array_equal(kept.acceleration(q, qd, command, ee_target=ee),
                                      fresh.acceleration(q, qd, command, ee_target=ee))
        assert kept.diagnostics() == fresh.diagnostics()


def test_gil_released_during_evaluate(fabric):
    cands = np.tile(GOAL, (256, 1)) + np.random.default_rng(0).normal(scale=0.3, size=(256, 7))
    done = threading.Event()
    elapsed = {}

    def work():
        t0 = time.perf_counter()
        fabric.evaluate(Q0, None, GOAL, cands, threads=1)
        elapsed["t"] = time.perf_counter() - t0
        done.set()

    worker = threading.Thread(target=work)
    last = time.perf_counter()
    max_gap = 0.0
    worker.start()
    while not done.is_set():
        now = time.perf_counter()
        max_gap = max(max_gap, now - last)
        last = now
    worker.join()
    assert elapsed["t"] > 0.05, "the batch is too small to test the GIL"
    assert max_gap < 0.5 * elapsed["t"], f"main thread blocked {max_gap:.3f}s of {elapsed['t']:.3f}s"


def test_per_sphere_obstacle_margins(robot, scene):
    """with_obstacle_margins: a copy; margins all equal to m act as the configured margin m (same q̈ to the
    bit); lower margins on the spheres near the obstacle change q̈; bad margins name the problem."""
    config = gfcs.FabricConfig.defaults()
    plain = gfcs.Fabric(robot, scene, config)
    s = len(robot.sphere_radii)
    margin = plain.config.to_dict()["obstacles"]["margin"]
    same = plain.with_obstacle_margins(np.full(s, margin))
    assert plain.obstacle_margins is None and same.obstacle_margins.shape == (s,)
    wide = gfcs.Fabric(robot, scene, config.replace({"obstacles": {"margin": 0.03}}))
    as_wide = plain.with_obstacle_margins(np.full(s, 0.03))
    q, qd = Q0, np.full(7, 0.3)
    np.testing.assert_array_equal(same.acceleration(q, qd, GOAL), plain.acceleration(q, qd, GOAL))
    np.testing.assert_array_equal(as_wide.acceleration(q, qd, GOAL), wide.acceleration(q, qd, GOAL))
    assert not np.array_equal(as_wide.acceleration(q, qd, GOAL), plain.acceleration(q, qd, GOAL))
    assert as_wide.with_obstacle_margins(None).obstacle_margins is None
    with pytest.raises(gfcs.ShapeError, match="margins"):
        plain.with_obstacle_margins(np.zeros(s - 1))
    with pytest.raises(gfcs.NonFiniteError, match="margins"):
        plain.with_obstacle_margins(np.full(s, np.nan))
    deep = np.zeros(s)
    deep[5] = -robot.sphere_radii[5]
    with pytest.raises(gfcs.InvalidValueError, match=f"sphere 5 on link '{robot.sphere_links[5]}'"):
        plain.with_obstacle_margins(deep)


def test_per_pair_self_margins(robot, scene):
    """with_self_margins: a copy; margins all equal to m act as the configured self-collision margin m (same
    q̈ to the bit); a wider one changes q̈; the margins survive the per-sphere obstacle copy; bad margins
    name the pair's links."""
    config = gfcs.FabricConfig.defaults()
    plain = gfcs.Fabric(robot, scene, config)
    p = len(robot.self_collision_pairs)
    margin = plain.config.to_dict()["self_collision"]["margin"]
    same = plain.with_self_margins(np.full(p, margin))
    assert plain.self_margins is None and same.self_margins.shape == (p,)
    wide = gfcs.Fabric(robot, scene, config.replace({"self_collision": {"margin": 0.1}}))
    as_wide = plain.with_self_margins(np.full(p, 0.1))
    q, qd = Q0, np.full(7, 0.3)
    np.testing.assert_array_equal(same.acceleration(q, qd, GOAL), plain.acceleration(q, qd, GOAL))
    np.testing.assert_array_equal(as_wide.acceleration(q, qd, GOAL), wide.acceleration(q, qd, GOAL))
    assert not np.array_equal(as_wide.acceleration(q, qd, GOAL), plain.acceleration(q, qd, GOAL))
    both = as_wide.with_obstacle_margins(np.full(len(robot.sphere_radii), 0.01))
    np.testing.assert_array_equal(both.self_margins, as_wide.self_margins)
    assert as_wide.with_self_margins(None).self_margins is None
    with pytest.raises(gfcs.ShapeError, match="margins"):
        plain.with_self_margins(np.zeros(p + 1))
    with pytest.raises(gfcs.NonFiniteError, match="margins"):
        plain.with_self_margins(np.full(p, np.nan))
    a, b = np.asarray(robot.self_collision_pairs)[7]
    deep = np.zeros(p)
    deep[7] = -(robot.sphere_radii[a] + robot.sphere_radii[b])
    with pytest.raises(gfcs.InvalidValueError,
                       match=rf"self_margins\[7\].*'{robot.sphere_links[a]}' and '{robot.sphere_links[b]}'"):
        plain.with_self_margins(deep)


def test_joint_scales(robot, scene):
    """with_joint_scales: a copy; unit scales change no bit of q̈, others do (and survive the per-sphere
    margins copy); gfcs.joints.velocity_scales is v_ref / v_i; bad scales name the joint."""
    from gfcs.joints import velocity_scales

    plain = gfcs.Fabric(robot, scene)
    q, qd = Q0, np.full(7, 0.3)
    unit = plain.with_joint_scales(np.ones(7))
    assert plain.joint_scales is None and unit.joint_scales.shape == (7,)
    np.testing.assert_array_equal(unit.acceleration(q, qd, GOAL), plain.acceleration(q, qd, GOAL))
    scales = velocity_scales(robot)
    v = np.asarray(robot.velocity_limits)
    np.testing.assert_allclose(scales * v, np.median(v))
    from types import SimpleNamespace

    assert velocity_scales(SimpleNamespace(velocity_limits=[2.0, 0.0])) is None  # no time scale
    heavy = plain.with_joint_scales(np.r_[5.0, np.ones(6)])
    assert not np.array_equal(heavy.acceleration(q, qd, GOAL), plain.acceleration(q, qd, GOAL))
    margins = heavy.with_obstacle_margins(np.full(len(robot.sphere_radii), 0.002))
    np.testing.assert_array_equal(margins.joint_scales, heavy.joint_scales)
    assert heavy.with_joint_scales(None).joint_scales is None
    with pytest.raises(gfcs.ShapeError, match="scales"):
        plain.with_joint_scales(np.ones(6))
    with pytest.raises(gfcs.NonFiniteError, match="scales"):
        plain.with_joint_scales(np.full(7, np.inf))
    with pytest.raises(gfcs.InvalidValueError, match=r"joint_scales\[1\].*panda_joint2"):
        plain.with_joint_scales(np.r_[1.0, -1.0, np.ones(5)])


def test_bad_inputs(fabric, robot):
    with pytest.raises(gfcs.ShapeError, match=r"q: expected shape \(7,\), got \(6,\)"):
        fabric.acceleration(np.zeros(6), np.zeros(7), GOAL)
    with pytest.raises(gfcs.ShapeError, match="command"):
        fabric.acceleration(Q0, np.zeros(7), GOAL[:3])
    with pytest.raises(gfcs.NonFiniteError, match="qd"):
        fabric.acceleration(Q0, np.full(7, np.nan), GOAL)
    with pytest.raises(gfcs.NonFiniteError, match="q0"):
        fabric.rollout(np.full(7, np.inf), None, GOAL)
    with pytest.raises(gfcs.InvalidValueError, match="dt"):
        fabric.rollout(Q0, None, GOAL, dt=0.0)
    with pytest.raises(gfcs.InvalidValueError, match="integrator"):
        fabric.rollout(Q0, None, GOAL, integrator="verlet")
    with pytest.raises(gfcs.ShapeError, match=r"candidates: expected shape \(N, n\*7\)"):
        fabric.evaluate(Q0, None, GOAL, np.zeros((3, 5)))
    with pytest.raises(gfcs.ShapeError, match="commands"):
        fabric.rollout_sequence(Q0, None, np.zeros(7), GOAL)
    with pytest.raises(gfcs.NonFiniteError, match="candidates"):
        fabric.evaluate(Q0, None, GOAL, np.full((2, 7), np.nan))
    with pytest.raises(gfcs.InvalidValueError, match="threads"):
        fabric.evaluate(Q0, None, GOAL, np.zeros((2, 7)), threads=0)
    with pytest.raises(gfcs.InvalidValueError, match="penalty"):
        fabric.evaluate(Q0, None, GOAL, np.zeros((2, 7)), penalty=-1.0)
    with pytest.raises(gfcs.FormatError, match="obstacles.nope"):
        gfcs.Fabric(robot, None, {"obstacles": {"nope": 1}})
    with pytest.raises(TypeError):
        gfcs.Fabric("not a robot")


# ----------------------------------------------------------------------------------------- particles

VARIANTS = ["unbent_riemannian", "unbent_finsler", "bent_riemannian", "bent_finsler"]


@pytest.mark.parametrize("variant", VARIANTS)
def test_particle_rollout(variant):
    d = gfcs._core.particle_defaults()
    start = np.array([3.0, 0.7])
    r = gfcs.particle_rollout(variant, 2.0, start, t_max=20.0, tol=0.05)
    assert r.q.shape[1] == 2
    np.testing.assert_array_equal(r.q[0], start)
    np.testing.assert_allclose(r.qd[1:], r.qd[:-1] + 0.01 * r.qdd[:-1], atol=1e-12)
    np.testing.assert_allclose(
        r.qdd[0], gfcs._core.particle_acceleration(variant, start, [0, 0], speed=2.0), atol=1e-12
    )
    # the particle goes around the unit circle to the target on its left
    assert r.reached and np.linalg.norm(r.q_final - d["target"]) < 0.05
    assert r.min_clearance > 0
    np.testing.assert_allclose(
        r.min_clearance, (np.linalg.norm(r.q - d["obstacle_center"], axis=1) - d["obstacle_radius"]).min(), atol=1e-12
    )


def test_particle_batch_and_params():
    starts = np.array([[3.0, 0.5], [3.0, -0.5], [2.5, 1.5]])
    rs = gfcs.particle_rollout("bent_finsler", 4.0, starts, t_max=2.0)
    assert isinstance(rs, list) and len(rs) == 3
    for s, r in zip(starts, rs):
        np.testing.assert_array_equal(r.q[0], s)
    moved = gfcs.particle_rollout("bent_finsler", 2.0, [3.0, 0.5], t_max=1.0, target=[0.0, 3.0])
    single = gfcs.particle_rollout("bent_finsler", 2.0, [3.0, 0.5], t_max=1.0)
    assert not np.allclose(moved.q[-1], single.q[-1])
    with pytest.raises(gfcs.InvalidValueError, match="variant"):
        gfcs.particle_rollout("curved", 2.0, [3.0, 0.5])
    with pytest.raises(gfcs.InvalidValueError, match="unknown keyword 'gravity'"):
        gfcs.particle_rollout("bent_finsler", 2.0, [3.0, 0.5], gravity=1.0)
    with pytest.raises(gfcs.ShapeError, match="qd0"):
        gfcs.particle_rollout("bent_finsler", 2.0, starts, qd0=[0.0, 0.0])
    with pytest.raises(gfcs.InvalidValueError, match="speed"):
        gfcs.particle_rollout("bent_finsler", -1.0, [3.0, 0.5])
