"""gfcs.problems (Problem, MotionBenchMaker loading) and gfcs.generators (seeded problem generators)."""

import math

import warnings

import numpy as np
import pytest

import gfcs
from gfcs import generators, metrics, problems
from gfcs.problems import CLASSES, Problem, canonical_class


@pytest.fixture(scope="module")
def panda():
    return gfcs.Robot.panda()


# ------------------------------------------------------------------------------------------ Problem
def test_problem_defaults_and_validation(panda):
    p = Problem("p", panda, gfcs.Scene(), q0=generators.READY, goal=generators.READY + 0.1)
    assert p.qd0.shape == (7,) and np.all(p.qd0 == 0) and p.dof == 7 and p.cls == ""
    with pytest.raises(ValueError, match=r"q0: expected shape \(7,\)"):
        Problem("p", panda, gfcs.Scene(), q0=np.zeros(3), goal=generators.READY)
    with pytest.raises(ValueError, match="goal contains NaN"):
        Problem("p", panda, gfcs.Scene(), q0=generators.READY, goal=np.full(7, math.nan))
    outside = generators.READY.copy()
    outside[3] = panda.upper[3] + 0.01
    with pytest.raises(ValueError, match=r"problem 'p': goal: joint panda_joint4 = -0.0598 rad lies outside its "
                                         r"limits \[-3.0718, -0.0698\]"):
        Problem("p", panda, gfcs.Scene(), q0=generators.READY, goal=outside)
    with pytest.raises(ValueError, match="problem 'p': q0: joint panda_joint4"):
        Problem("p", panda, gfcs.Scene(), q0=outside, goal=generators.READY)
    at_limit = generators.READY.copy()
    at_limit[3] = panda.upper[3] + 0.5 * metrics.DEFAULT_LIMIT_TOL  # round-off at a limit is accepted
    Problem("p", panda, gfcs.Scene(), q0=generators.READY, goal=at_limit)
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.0, 0.5], 0.1)
    q = p.with_scene(scene)
    assert len(q.scene) == 1 and len(p.scene) == 0 and np.array_equal(q.q0, p.q0)


def test_class_aliases():
    assert canonical_class("table_under") == "table_under_pick"
    assert canonical_class("Single shelf") == "bookshelf_small"
    assert canonical_class("cage") == "cage"
    with pytest.raises(ValueError, match="unknown problem class 'kitchen'"):
        canonical_class("kitchen")


# -------------------------------------------------------------------------------------- generators
@pytest.fixture(scope="module")
def generated(panda):
    return {c: generators.generate(c, 2, seed=0, robot=panda) for c in CLASSES}


@pytest.mark.parametrize("cls", CLASSES)
def test_generated_problems_are_valid(generated, panda, cls):
    for p in generated[cls]:
        assert p.cls == cls and len(p.scene) >= 3
        for q in (p.q0, p.goal):
            assert metrics.within_limits(q, panda.lower, panda.upper)
            assert metrics.obstacle_clearance(panda, p.scene, q[None])[0] >= 0.01
            assert metrics.self_clearance(panda, q[None])[0] >= generators.SELF_MARGIN
        assert np.linalg.norm(p.goal - p.q0) >= 0.5
    # distinct scenes
    a, b = generated[cls]
    assert a.meta["primitives"] != b.meta["primitives"]


def test_generated_problems_for_the_mbm_panda_carry_its_meshes_and_keep_them_clear(mbm_panda_dir):
    # its spheres leave the meshes partly uncovered: sphere-clear starts and goals are checked on the meshes
    robot = problems.mbm_panda(mbm_panda_dir)
    checker = problems.mesh_checker_for(robot)
    for cls in ("box", "cage"):
        for p in generators.generate(cls, 2, seed=0, robot=robot):
            assert p.mesh_checker is checker
            q = np.stack([p.q0, p.goal])
            assert checker.min_clearance(p.scene, q) > metrics.DEFAULT_MESH_MARGIN
            assert checker.min_self_clearance(q) > metrics.DEFAULT_MESH_MARGIN


def test_self_margin_is_the_fabrics():
    # generated goals keep the clearance the default fabric's self-collision barrier keeps
    assert generators.SELF_MARGIN == gfcs.FabricConfig().to_dict()["self_collision"]["margin"]


def test_goal_targets_are_met(panda):
    # the goal's TCP lies inside the structure for a shelf: check the goal EE is between the shelf boards
    p = generators.generate("bookshelf_small", 1, seed=3, robot=panda)[0]
    prims = {d["name"]: d for d in p.meta["primitives"]}
    pose = panda.link_poses(p.goal)[panda.link_index(panda.ee_link)]
    tcp = pose[:3, :3] @ generators.PANDA_TCP + pose[:3, 3]
    assert prims["shelf_bottom"]["position"][2] < tcp[2] < prims["shelf_top"]["position"][2]


def test_generation_is_seeded_and_prefix_consistent(panda):
    a = generators.generate("box", 2, seed=5, robot=panda)
    b = generators.generate("box", 1, seed=5, robot=panda)
    c = generators.generate("box", 1, seed=6, robot=panda)
    assert np.array_equal(a[0].goal, b[0].goal) and a[0].meta == b[0].meta
    assert not np.array_equal(a[0].goal, c[0].goal)
    assert generators.generate("box", 0, robot=panda) == []
    with pytest.raises(ValueError, match="unknown problem class"):
        generators.generate("kitchen", 1)


def test_inverse_kinematics_reaches_target(panda):
    rng = np.random.default_rng(0)
    target = generators.Target(np.array([0.5, 0.2, 0.3]), np.array([0.0, 0.0, -1.0]), 5.0)
    q = generators.inverse_kinematics(panda, target, rng, q_seed=generators.READY)
    assert q is not None
    pose = panda.link_poses(q)[panda.link_index(panda.ee_link)]
    np.testing.assert_allclose(pose[:3, :3] @ generators.PANDA_TCP + pose[:3, 3], target.position, atol=2e-3)
    assert pose[:3, 2] @ target.approach >= math.cos(math.radians(5.0))
    # unreachable (3 m away): None, never an exception
    far = generators.Target(np.array([3.0, 0.0, 0.3]))
    assert generators.inverse_kinematics(panda, far, rng, restarts=2, iterations=30) is None


def test_written_problems_load_back(generated, panda, tmp_path):
    suite = generated["bookshelf_small"] + generated["cage"]
    folders = generators.write_problems(suite, tmp_path)
    assert sorted(f.name for f in folders) == ["bookshelf_small", "cage"]
    loaded = problems.load_mbm_dir(tmp_path, robot=panda)
    assert [p.name for p in loaded] == ["bookshelf_small/0001", "bookshelf_small/0002", "cage/0001", "cage/0002"]
    by_class = {"bookshelf_small": generated["bookshelf_small"], "cage": generated["cage"]}
    rng = np.random.default_rng(1)
    pts = rng.uniform([-0.2, -1.0, -0.3], [1.2, 1.0, 1.2], size=(500, 3))
    for p in loaded:
        orig = by_class[p.cls][int(p.name[-4:]) - 1]
        np.testing.assert_array_equal(p.q0, orig.q0)
        np.testing.assert_array_equal(p.goal, orig.goal)
        np.testing.assert_allclose(p.scene.signed_distance(pts), orig.scene.signed_distance(pts), atol=1e-12)
    only = problems.load_mbm_dir(tmp_path, classes=["single_shelf"], limit=1, robot=panda)
    assert [p.name for p in only] == ["bookshelf_small/0001"]
    tail = problems.load_mbm_dir(tmp_path, skip=1, robot=panda)  # the train/test split of GFCS Sec. V
    assert [p.name for p in tail] == ["bookshelf_small/0002", "cage/0002"]


def test_locked_joints_are_held_where_the_request_starts_them(generated, panda, tmp_path):
    """A request that opens the fingers (MotionBenchMaker: 0.065 m) gets a copy of the shipped Panda holding
    them there, as MoveIt keeps joints outside the planning group at their start values; the robot passed
    in is untouched, and one copy serves every problem with the same fingers."""
    import yaml

    generators.write_problems(generated["box"], tmp_path)
    for k in (1, 2):
        request = tmp_path / "box" / f"request000{k}.yaml"
        doc = yaml.safe_load(request.read_text())
        state = doc["start_state"]["joint_state"]
        # the written start state lists the fingers where the shipped Panda holds them
        assert state["name"][7:] == ["panda_finger_joint1"] and state["position"][7:] == [0.04]
        state["name"] += ["panda_finger_joint2"]
        state["position"][7:] = [0.065, 0.065]
        request.write_text(yaml.safe_dump(doc))
    loaded = problems.load_mbm_dir(tmp_path, robot=panda)
    assert panda.locked_positions == {"panda_finger_joint1": 0.04}
    assert loaded[0].robot is loaded[1].robot and loaded[0].robot is not panda
    assert loaded[0].robot.locked_positions == {"panda_finger_joint1": 0.065}
    assert loaded[0].meta["start_state"]["panda_finger_joint1"] == 0.065
    q = loaded[0].q0
    for robot, width in ((panda, 0.04), (loaded[0].robot, 0.065)):
        poses = robot.link_poses(q)
        hand, left = (poses[robot.link_index(name)] for name in ("panda_hand", "panda_leftfinger"))
        offset = hand[:3, :3].T @ (left[:3, 3] - hand[:3, 3])  # in the hand frame
        np.testing.assert_allclose(offset, [0.0, width, 0.0584], atol=1e-12)
    assert loaded[0].robot.joint_names == panda.joint_names
    np.testing.assert_array_equal(loaded[0].robot.sphere_radii, panda.sphere_radii)
    assert len(loaded[0].robot.self_collision_pairs) == len(panda.self_collision_pairs)
    # with the fingers where the robot holds them (as written), or without them, the robot passed in is the
    # problem's
    generators.write_problems(generated["cage"][:1], tmp_path / "plain")
    assert problems.load_mbm_dir(tmp_path / "plain", robot=panda)[0].robot is panda
    request = tmp_path / "plain" / "cage" / "request0001.yaml"
    doc = yaml.safe_load(request.read_text())
    state = doc["start_state"]["joint_state"]
    state["name"], state["position"] = state["name"][:7], state["position"][:7]
    request.write_text(yaml.safe_dump(doc))
    assert problems.load_mbm_dir(tmp_path / "plain", robot=panda)[0].robot is panda


def test_load_errors_name_the_culprit(generated, panda, tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere"):
        problems.load_mbm_dir(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no MotionBenchMaker problems"):
        problems.load_mbm_dir(tmp_path / "empty")
    generators.write_problems(generated["box"][:1], tmp_path / "suite")
    request = tmp_path / "suite" / "box" / "request0001.yaml"
    text = request.read_text()
    # drop panda_joint3 from the goal constraints
    lines = text.splitlines()
    i = next(k for k, s in enumerate(lines) if "joint_name: panda_joint3" in s)
    request.write_text("\n".join(lines[:i] + lines[i + 2:]) + "\n")
    with pytest.raises(gfcs.LinkError, match="panda_joint3.*goal constraints"):
        problems.load_mbm_dir(tmp_path / "suite", robot=panda)
    request.unlink()
    with pytest.raises(FileNotFoundError, match="request0001"):
        problems.load_mbm_dir(tmp_path / "suite", robot=panda)


# ----------------------------------------------------------------------- MotionBenchMaker (shared)
def test_load_mbm_bookshelf_small_with_both_robots(panda, shared_dir):
    root = shared_dir  # conftest fixture: skipped when absent, a failure under CI=true
    folder = root / "mbm" / "bookshelf_small"
    p = problems.load_mbm(folder / "scene0001.yaml", folder / "request0001.yaml", robot=panda)
    assert p.name == "bookshelf_small/0001" and p.cls == "bookshelf_small" and len(p.scene) == 7
    np.testing.assert_allclose(p.q0, [0, -0.785, 0, -2.356, 0, 1.571, 0.785])
    assert p.goal[0] == pytest.approx(1.48904932702624)
    mbm = problems.mbm_panda(root / "robots" / "mbm_panda")
    assert mbm.dof == 7 and mbm.ee_link == "panda_hand" and len(mbm.sphere_radii) > 0
    suite = problems.load_mbm_dir(root / "mbm", classes=["single_shelf"], limit=3, robot=mbm)
    assert [s.name for s in suite] == [f"bookshelf_small/000{k}" for k in (1, 2, 3)]
    assert all(s.robot is mbm for s in suite)


# --------------------------------------------------------------------------- shipped spheres for a Panda
def test_a_panda_without_spheres_gets_the_shipped_ones(panda):
    bare = gfcs.Robot.from_urdf(gfcs.panda_urdf(), ee_link="panda_hand")  # the shipped URDF: no collisions
    assert len(bare.sphere_radii) == 0
    fitted = problems.with_shipped_panda_spheres(bare)
    np.testing.assert_array_equal(fitted.sphere_radii, panda.sphere_radii)
    assert fitted.sphere_links == panda.sphere_links
    # the shipped SRDF prunes the pairs as for Robot.panda() (fingers at the URDF's 0 m there: same pairs)
    np.testing.assert_array_equal(fitted.self_collision_pairs, panda.self_collision_pairs)
    q = np.random.default_rng(3).uniform(panda.lower, panda.upper, (4, 7))
    held = panda.with_locked_positions(bare.locked_positions)  # the fingers where the bare robot holds them
    np.testing.assert_allclose(fitted.sphere_centers(q), held.sphere_centers(q), atol=1e-12)
    assert problems.with_shipped_panda_spheres(panda) is None  # it has spheres of its own
    longer = gfcs.Robot.from_urdf(gfcs.panda_urdf().replace('xyz="0.0825 0 0"', 'xyz="0.0835 0 0"', 1))
    assert problems.with_shipped_panda_spheres(longer) is None  # link 4 on: 1 mm off, not a Panda
    renamed = gfcs.Robot.from_urdf(gfcs.panda_urdf().replace("panda_joint7", "wrist_joint"))
    assert problems.with_shipped_panda_spheres(renamed) is None


def test_the_mbm_mesh_panda_gets_the_shipped_spheres(mbm_panda_dir, panda):
    mesh_model = gfcs.Robot.from_urdf(mbm_panda_dir / "panda.urdf", ee_link="panda_hand", mesh_dir=mbm_panda_dir)
    fitted = problems.with_shipped_panda_spheres(mesh_model, mbm_panda_dir / "panda.srdf")
    assert fitted is not None and len(fitted.sphere_radii) == len(panda.sphere_radii)
    np.testing.assert_array_equal(fitted.lower, mesh_model.lower)  # its own limits (joint 4 to 0.0873 rad)
    assert mesh_model.locked_positions == {}  # its fingers are fixed joints, at another opening
    q = np.random.default_rng(4).uniform(panda.lower, panda.upper, (4, 7))
    arm = [k for k, link in enumerate(panda.sphere_links) if "finger" not in link]
    np.testing.assert_allclose(fitted.sphere_centers(q)[:, arm], panda.sphere_centers(q)[:, arm], atol=1e-9)
    # they cover its meshes, fingers included: no obstacle comes nearer the meshes than the spheres
    checker = problems.urdf_mesh_checker(mbm_panda_dir / "panda.urdf", fitted, srdf=mbm_panda_dir / "panda.srdf")
    rng = np.random.default_rng(5)
    for qk in q:
        for link in ("panda_link5", "panda_hand", "panda_leftfinger"):
            k = rng.choice([i for i, name in enumerate(fitted.sphere_links) if name == link])
            centre = fitted.sphere_centers(qk[None])[0, k]
            scene = gfcs.Scene()
            scene.add_sphere(centre + rng.normal(size=3) * 0.1, 0.02)
            spheres = scene.signed_distance(fitted.sphere_centers(qk[None])[0]) - fitted.sphere_radii
            assert spheres.min() <= checker.min_clearance(scene, qk[None]) + 1e-6


def _one_joint_robot(kind: str, limits: str = 'lower="-3.14159" upper="3.14159"'):
    import gfcs

    return gfcs.Robot.from_urdf(f"""<robot name="r"><link name="a"/><link name="b"/>
      <joint name="j" type="{kind}"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
      <limit {limits} velocity="1" effort="1"/></joint></robot>""")


def test_continuous_goals_turn_the_short_way_and_bounds_snap_only_within_tolerance():
    import math

    from gfcs.joints import continuous_mask, snap_to_bounds, unwrap_goal

    cont = _one_joint_robot("continuous", "")
    rev = _one_joint_robot("revolute")
    assert continuous_mask(cont).tolist() == [True] and continuous_mask(rev).tolist() == [False]
    # a revolute joint limited to ∓2π (the xArm's, many UR descriptions') is bounded: its goal is not wrapped,
    # though its range is the one the core gives continuous joints
    full = _one_joint_robot("revolute", f'lower="{-math.tau!r}" upper="{math.tau!r}"')
    assert full.lower.tolist() == [-math.tau] and full.continuous.tolist() == [False]
    assert continuous_mask(full).tolist() == [False] and cont.continuous.tolist() == [True]
    np.testing.assert_allclose(unwrap_goal([3.0], [-3.0], [True]), [math.tau - 3.0])
    assert unwrap_goal([3.0], [-3.0], [False]).tolist() == [-3.0]
    q, moved = snap_to_bounds(rev, [math.pi])  # a request's π against a URDF bound of 3.14159
    assert q.tolist() == [3.14159] and moved == [f"j = {math.pi!r} -> 3.14159"]
    q, moved = snap_to_bounds(rev, [3.2])  # too far: left for the problem's check to name
    assert q.tolist() == [3.2] and moved == []
    assert snap_to_bounds(cont, [9.0])[0].tolist() == [9.0]
    problems.Problem("p", cont, gfcs_scene(), [9.0], [-9.0])  # continuous: any angle


def test_a_request_keeps_the_goal_of_a_revolute_joint_limited_to_two_turns(tmp_path):
    """MoveIt compares a revolute joint's goal as written, whatever its range; a continuous joint's modulo 2π
    (the goal is commanded as the equivalent angle nearest the start)."""
    import math

    (tmp_path / "scene0001.yaml").write_text("name: s\nworld:\n  collision_objects: []\n")
    (tmp_path / "request0001.yaml").write_text("""group_name: g
start_state:
  joint_state:
    name: [j]
    position: [3.0]
goal_constraints:
  - joint_constraints:
      - joint_name: j
        position: -3.0
        tolerance_above: 0.001
        tolerance_below: 0.001
        weight: 1.0
""")
    full = _one_joint_robot("revolute", f'lower="{-math.tau!r}" upper="{math.tau!r}"')
    cont = _one_joint_robot("continuous", "")
    load = lambda robot: problems.load_mbm(tmp_path / "scene0001.yaml", tmp_path / "request0001.yaml",
                                           robot=robot)
    assert load(full).goal.tolist() == [-3.0]
    assert load(cont).goal.tolist() == pytest.approx([math.tau - 3.0])


def gfcs_scene():
    import gfcs

    return gfcs.Scene()


def test_a_request_at_pi_on_a_pi_bound_loads_with_one_warning(tmp_path):
    import math

    rev = _one_joint_robot("revolute")
    (tmp_path / "scene0001.yaml").write_text("name: s\nworld:\n  collision_objects: []\n")
    (tmp_path / "request0001.yaml").write_text(f"""group_name: g
start_state:
  joint_state:
    name: [j]
    position: [{math.pi!r}]
goal_constraints:
  - joint_constraints:
      - joint_name: j
        position: {-math.pi!r}
        tolerance_above: 0.001
        tolerance_below: 0.001
        weight: 1.0
""")
    with pytest.warns(gfcs.GfcsWarning, match="planned on the bound: start j = .* -> 3.14159; goal j"):
        p = problems.load_mbm(tmp_path / "scene0001.yaml", tmp_path / "request0001.yaml", robot=rev)
    assert p.q0.tolist() == [3.14159] and p.goal.tolist() == [-3.14159]

    # a folder of such requests: one warning that counts them, not one per request
    for k in (2, 3):
        (tmp_path / f"scene000{k}.yaml").write_text((tmp_path / "scene0001.yaml").read_text())
        (tmp_path / f"request000{k}.yaml").write_text((tmp_path / "request0001.yaml").read_text())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = problems.load_mbm_dir(tmp_path, robot=rev)
    assert len(loaded) == 3 and all(q.q0.tolist() == [3.14159] for q in loaded)
    bound = [str(w.message) for w in caught if "joint bounds" in str(w.message)]
    assert len(bound) == 1 and "3 requests hold values just outside their joint bounds" in bound[0]
    assert "request0001.yaml" in bound[0]
