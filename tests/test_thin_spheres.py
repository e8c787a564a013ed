"""The shipped Panda's thin sphere model (``gfcs.problems.thin_sphere_model``) and the attempt of
:func:`gfcs.optimize.solve` that uses it."""

import dataclasses
import json

import numpy as np
import pytest

import gfcs
import gfcs.planning.models
from gfcs import optimize, problems


def spheres_of(robot, link):
    keep = [i for i, name in enumerate(robot.sphere_links) if name == link]
    return np.asarray(robot.sphere_centers_local)[keep], np.asarray(robot.sphere_radii)[keep]


def test_thin_model_replaces_the_listed_links_only():
    shipped = gfcs.Robot.panda()
    thin = problems.thin_sphere_model(shipped)
    data = json.loads(problems.PANDA_THIN_SPHERES.read_text())["spheres"]
    replaced = {s["link"] for s in data}
    assert replaced == {"panda_link5", "panda_link6", "panda_link7", "panda_hand"}
    for link in set(shipped.sphere_links):
        centers, radii = spheres_of(thin, link)
        if link in replaced:
            mine = [s for s in data if s["link"] == link]
            np.testing.assert_array_equal(centers, [s["center"] for s in mine])
            np.testing.assert_array_equal(radii, [s["radius"] for s in mine])
        else:
            before = spheres_of(shipped, link)
            np.testing.assert_array_equal(centers, before[0])
            np.testing.assert_array_equal(radii, before[1])
    # thinner: the forearm's largest sphere shrinks, and the joints, limits and kinematics stay
    assert spheres_of(thin, "panda_link5")[1].max() < spheres_of(shipped, "panda_link5")[1].max() - 0.005
    q = np.random.default_rng(3).uniform(shipped.lower, shipped.upper, size=(4, shipped.dof))
    np.testing.assert_array_equal(thin.link_poses(q), shipped.link_poses(q))
    assert thin.joint_names == shipped.joint_names
    # the self-collision pairs follow the shipped SRDF: none between the hand and link7 (adjacent)
    pairs = np.asarray(thin.self_collision_pairs)
    links = np.asarray(thin.sphere_links)
    assert not any({links[i], links[j]} == {"panda_hand", "panda_link7"} for i, j in pairs)
    assert len(pairs) > 0


def test_thin_model_is_for_the_shipped_panda_only():
    shipped = gfcs.Robot.panda()
    fewer = [(link, c, r) for link, c, r in zip(shipped.sphere_links, shipped.sphere_centers_local,
                                                shipped.sphere_radii) if link != "panda_hand"]
    assert problems.thin_sphere_model(shipped.with_spheres(fewer)) is None
    held = shipped.with_locked_positions({j: 0.03 for j in shipped.locked_positions})
    assert problems.thin_sphere_model(held) is not None


@pytest.fixture(scope="module")
def cage32(mbm_dir):
    """MotionBenchMaker cage 32 with the shipped Panda: its covering spheres find no mesh-clear motion
    into the cage with the configured margins (5 batches, seed 0, without the endpoint contact), its thin
    spheres do."""
    return problems.load_mbm_dir(mbm_dir / "cage", limit=32)[-1]


def test_solve_runs_on_the_thin_spheres(cage32):
    assert cage32.name.endswith("0032") and cage32.mesh_checker is not None
    # the goal sinks covering spheres into the cage's bars that the polytopes clear: without the endpoint
    # contact, and with the spheres judging too, no attempt with the configured margins can end there; only
    # the goal-contact retry does
    no_contact = dataclasses.replace(gfcs.planning.get_preset("default"), endpoint_contact=False,
                                     spheres_judge=True)
    covering = optimize.solve(cage32, thin_spheres=False, preset=no_contact)
    assert not any(a.success for a in covering.attempt_records if "goal contact" not in a.attempt.label)
    assert "sphere_model" not in covering.settings
    result = optimize.solve(cage32)
    assert result.success
    assert result.settings["sphere_model"] == "thin"
    base = gfcs.FabricConfig.defaults().to_dict()["obstacles"]["margin"]
    assert result.fabric_config["obstacles"]["margin"] == pytest.approx(base + optimize.THIN_SPHERE_MARGIN)
    assert problems.sphere_fingerprint(result.robot) == problems.sphere_fingerprint(
        problems.thin_sphere_model(cage32.robot))
    # judged by the polytopes over the whole motion, independently of the solver's own verdict
    met = gfcs.metrics.trajectory_metrics(result.robot, cage32.scene, result.trajectory.t,
                                          result.trajectory.q, cage32.goal, mesh_checker=cage32.mesh_checker)
    assert met["success"] and met["mesh_clearance"] >= gfcs.metrics.DEFAULT_MESH_MARGIN
    # the command's summary says which spheres moved the arm and what judged it
    from gfcs import cli

    text = cli.summary_text(result, cage32)
    assert "thin spheres (links 5-7, hand" in text and "obstacle margin 6 mm" in text
    assert "checked   collision meshes" in text
    assert "thin spheres" not in cli.summary_text(covering, cage32)
    # the replay on the result's own robot reproduces the motion
    again = optimize.replay(result, cage32.scene)
    np.testing.assert_allclose(again.trajectory.q, result.trajectory.q, atol=1e-9)


def test_no_thin_spheres_without_a_mesh_checker(cage32, monkeypatch):
    def called(robot):
        raise AssertionError("thin_sphere_model called for a problem without a mesh checker")

    monkeypatch.setattr(problems, "thin_sphere_model", called)
    bare = dataclasses.replace(cage32, mesh_checker=None)
    result = optimize.solve(bare, batches=1, max_commands=1, mesh_retry_margin=0.0, goal_contact_slack=0.0)
    assert not result.success  # on the covering spheres: the thin ones were left out for want of the checker
    assert "sphere_model" not in result.settings
    with pytest.raises(AssertionError, match="without a mesh checker"):
        optimize.solve(cage32, batches=1, max_commands=1, mesh_retry_margin=0.0, goal_contact_slack=0.0)


def test_thin_spheres_solve_a_cage_with_polytopes_certified_clear(mbm_dir):
    """MotionBenchMaker cage 15 on the thin spheres, which miss the meshes by up to 8 mm: the returned motion's
    polytopes keep the mesh margin at every configuration between its states (the continuous sweep), though
    they come within the interpolation allowance of a bar."""
    cage15 = problems.load_mbm_dir(mbm_dir / "cage", limit=15)[-1]
    assert cage15.name.endswith("0015")
    result = optimize.solve(cage15)
    assert result.success and result.settings["sphere_model"] == "thin"
    met = gfcs.metrics.trajectory_metrics(result.robot, cage15.scene, result.trajectory.t,
                                          result.trajectory.q, cage15.goal, mesh_checker=cage15.mesh_checker)
    assert met["success"] and met["mesh_clearance"] > gfcs.metrics.DEFAULT_MESH_MARGIN
    sweep = cage15.mesh_checker.sweep(cage15.scene, result.trajectory.q, margin=gfcs.metrics.DEFAULT_MESH_MARGIN)
    assert sweep["ok"] and sweep["complete"]


def test_a_franka_description_with_the_shipped_spheres_gets_the_thin_model(mbm_panda_dir):
    # MotionBenchMaker's panda.urdf: Franka's meshes, other link names (panda_grasptarget), wider limits,
    # fingers fixed at 0.065 m; given the shipped Panda's spheres, links 5-7 and the hand move as the
    # shipped Panda's do, so their thin spheres apply
    franka = gfcs.Robot.from_urdf(str(mbm_panda_dir / "panda.urdf"), srdf=str(mbm_panda_dir / "panda.srdf"))
    covered = problems.with_shipped_panda_spheres(franka, str(mbm_panda_dir / "panda.srdf"))
    thin = problems.thin_sphere_model(covered)
    assert thin is not None and thin.link_names == franka.link_names
    np.testing.assert_array_equal(thin.upper, franka.upper)
    assert spheres_of(thin, "panda_link5")[1].max() < spheres_of(covered, "panda_link5")[1].max() - 0.005
    # its own spheres (MotionBenchMaker's) are not the shipped ones: no thin model
    assert problems.thin_sphere_model(problems.mbm_panda(mbm_panda_dir)) is None
