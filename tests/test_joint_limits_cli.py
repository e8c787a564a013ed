"""--joint-limits (MoveIt joint_limits.yaml) and --acceleration-limits reach the returned motion's timing."""

import json

import numpy as np
import pytest

from gfcs import cli


def _speeds_and_accelerations(path):
    r = json.loads(path.read_text())
    t, q = np.asarray(r["trajectory"]["t"]), np.asarray(r["trajectory"]["q"])
    v = np.diff(q, axis=0) / np.diff(t)[:, None]
    a = np.diff(v, axis=0) / np.diff(t)[1:, None]
    return r, np.abs(v).max(axis=0), np.abs(a).max(axis=0)


def test_joint_limits_yaml_tightens_velocity_and_sets_acceleration(tmp_path):
    limits = tmp_path / "joint_limits.yaml"
    limits.write_text("joint_limits:\n"
                      "  panda_joint1: {has_velocity_limits: true, max_velocity: 0.2,"
                      " has_acceleration_limits: true, max_acceleration: 0.5}\n"
                      "  panda_joint4: {has_velocity_limits: true, max_velocity: 0.3}\n")
    out = tmp_path / "r.json"
    code = cli.main(["solve", "--batches", "1", "--population", "8", "--joint-limits", str(limits),
                     "--json", str(out)])
    assert code == 0
    r, v, a = _speeds_and_accelerations(out)
    assert v[0] <= 0.2 and v[3] <= 0.3 and a[0] <= 0.5
    assert r["metrics"]["velocity_ratio"] <= 1.0


def test_acceleration_limits_are_checked_against_the_joint_count(tmp_path, capsys):
    code = cli.main(["solve", "--batches", "1", "--population", "8", "--acceleration-limits", "1", "2"])
    assert code == 2
    assert "--acceleration-limits: expected 1 or 7" in capsys.readouterr().err
