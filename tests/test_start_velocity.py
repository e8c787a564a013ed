"""A start velocity is honoured: the returned motion starts in the requested state, and a start the robot
cannot be in is a named error before any planning."""

import dataclasses

import numpy as np
import pytest

import gfcs
from gfcs import generators, optimize


@pytest.fixture(scope="module")
def problem():
    return generators.generate("box", 1, seed=0, robot=gfcs.Robot.panda())[0]


def test_a_moving_start_is_the_first_state_of_the_motion(problem):
    qd0 = np.zeros(7)
    qd0[0] = 2.0  # below the Panda's 2.175 rad/s
    r = optimize.solve(dataclasses.replace(problem, qd0=qd0), batches=1, population=8)
    np.testing.assert_array_equal(r.trajectory.q[0], problem.q0)
    np.testing.assert_array_equal(r.trajectory.qd[0], qd0)
    assert r.metrics["velocity_ratio"] <= 1.0


def test_a_start_beyond_the_velocity_limits_is_refused_naming_the_joint(problem):
    with pytest.raises(gfcs.InvalidValueError, match="qd0: joint panda_joint1 starts at 5 .* velocity limit 2.175"):
        dataclasses.replace(problem, qd0=np.full(7, 5.0))
