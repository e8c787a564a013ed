"""GF App. F (gfcs.experiments.constrained): the hand held on a plane by the null-space projection of the
fabric and the Gauss-Newton projection of the state; GF App. G (gfcs.experiments.orientation)."""

from __future__ import annotations

import json

import numpy as np

from gfcs import cli
from gfcs.experiments import constrained as cx
from gfcs.experiments import orientation as ox


def test_constraint_holds_to_a_micrometre_on_a_straight_reach():
    """One target on the plane, no obstacle: |C| < 1e-6 m at every step and the hand settles on it."""
    target = cx.on_plane(np.array([0.55, 0.20, 0.40]))
    res = cx.run([target], hold=3.0, obstacle=False)
    assert res["max_violation"] < 1e-6
    assert res["settle_errors"][0] < 1e-3
    # the hand moved (the constraint did not freeze it): it started more than 10 cm away
    assert np.linalg.norm(res["hand"][0] - target) > 0.1


def test_projection_is_onto_the_plane_and_keeps_velocity_tangent():
    r = cx.ConstrainedReacher(obstacle=False)
    c, _ = r.constraint(r.q)
    assert abs(c) < 1e-12  # the start is projected onto the plane
    for _ in range(50):
        r.step(np.array([0.5, -0.2, 0.3]))
    _, jc = r.constraint(r.q)
    assert abs(float(jc @ r.qd)) < 1e-9  # the velocity is tangent to the plane
    assert np.linalg.norm(r.qd) > 1e-3
    q = r.q + 0.05
    assert abs(r.constraint(r.project(q, iterations=6))[0]) < 1e-10


def test_metric_weighted_projection_keeps_the_obstacle_clear():
    """With the fabric's metric the barrier keeps its priority; the identity-metric projection sinks the
    spheres into the obstacle on the same targets."""
    fabric = cx.run()
    identity = cx.run(identity_metric=True)
    assert fabric["min_clearance"] > 0.0 > identity["min_clearance"]
    assert fabric["max_violation"] < 1e-6


def test_constrained_cli_writes_json(tmp_path):
    out = tmp_path / "c.json"
    assert cli.main(["experiment", "constrained", "--no-obstacle", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["max_violation"] < 1e-6 and len(data["settle_errors"]) == len(cx.TARGETS)


def test_pose_reaching_converges_in_position_and_orientation():
    res = ox.reach()
    assert res["max_final_position_error"] < 5e-3
    assert res["max_final_orientation_error"] < np.radians(2.0)
    # it started far from the first pose in orientation (30°)
    assert res["orientation_error"][0] > np.radians(20.0)


def test_orientation_cli_with_a_gfcs_pose_goal(tmp_path):
    out = tmp_path / "o.json"
    assert cli.main(["experiment", "orientation", "--json", str(out)]) == 0
    g = json.loads(out.read_text())["gfcs"]
    assert g["success"] and g["orientation_violation"] <= 0.0 and g["position_violation"] <= 0.0


def test_recordings_of_both_experiments(tmp_path):
    import pytest

    pytest.importorskip("rerun")
    d = tmp_path / "rrd"
    assert cli.main(["experiment", "constrained", "--no-obstacle", "--rrd-dir", str(d)]) == 0
    assert cli.main(["experiment", "orientation", "--no-gfcs", "--rrd-dir", str(d)]) == 0
    assert (d / "constrained.rrd").stat().st_size > 10_000 and (d / "orientation.rrd").stat().st_size > 10_000


def test_projection_corrects_a_drift_of_micrometres():
    res = cx.run(obstacle=False)
    assert 1e-9 < res["max_drift"] < 1e-4  # the Euler step leaves the plane by micrometres ...
    assert res["max_violation"] < 1e-12  # ... and the Gauss-Newton steps bring it back
