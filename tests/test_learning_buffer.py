"""Solution buffer policy of Algorithm 2 (GFCS Sec. IV-C, Sec. V: top-4 per problem, at most 200, FIFO)."""

from __future__ import annotations

import numpy as np
import pytest

from gfcs.errors import ConfigError, NonFiniteError
from gfcs.learning.buffer import SolutionBuffer


def insert_problem(buf, k, n=6, dim=3, costs=None):
    """Insert problem k: candidates k*100 + i (i = 0..n-1) with costs `costs` (default i reversed)."""
    cand = np.array([[k * 100 + i] * dim for i in range(n)], dtype=float)
    costs = np.arange(n, 0, -1, dtype=float) if costs is None else np.asarray(costs, dtype=float)
    return buf.insert(f"p{k}", np.full(2, float(k)), cand, costs)


def test_inserts_top_m_sorted_by_cost():
    buf = SolutionBuffer(max_size=200, top_m=4)
    assert insert_problem(buf, 0) == 4
    # costs 6,5,4,3,2,1 for candidates 0..5: the best four are 5,4,3,2 in that order
    np.testing.assert_array_equal(buf.targets()[:, 0], [5, 4, 3, 2])
    np.testing.assert_array_equal(buf.costs(), [1, 2, 3, 4])
    assert buf.problems() == ["p0"] * 4
    np.testing.assert_array_equal(buf.contexts(), np.zeros((4, 2)))


def test_fewer_candidates_than_m_and_skipped_costs():
    buf = SolutionBuffer(max_size=10, top_m=4)
    assert insert_problem(buf, 1, n=2) == 2
    assert insert_problem(buf, 2, n=5, costs=[np.inf, 3.0, np.nan, 1.0, 2.0]) == 3
    np.testing.assert_array_equal(buf.targets()[2:, 0], [203, 204, 201])
    assert buf.insert("p3", np.zeros(2), np.ones((3, 3)), [1.0, 50.0, 101.0], max_cost=100.0) == 2
    assert insert_problem(buf, 4, n=0) == 0
    assert len(buf) == 7


def test_fifo_keeps_the_newest_max_size():
    buf = SolutionBuffer(max_size=200, top_m=4)
    for k in range(60):  # 240 solutions into a buffer of 200: the first 10 problems are dropped
        insert_problem(buf, k)
    assert len(buf) == 200
    names = buf.problems()
    assert names[0] == "p10" and names[-1] == "p59"
    assert all(names.count(f"p{k}") == 4 for k in range(10, 60))
    # within a problem the order stays best first
    np.testing.assert_array_equal(buf.costs()[:4], [1, 2, 3, 4])


def test_partial_eviction_drops_oldest_entries_first():
    buf = SolutionBuffer(max_size=6, top_m=4)
    insert_problem(buf, 0)
    insert_problem(buf, 1)
    assert buf.problems() == ["p0", "p0", "p1", "p1", "p1", "p1"]
    np.testing.assert_array_equal(buf.costs()[:2], [3, 4])


def test_state_and_file_round_trip(tmp_path):
    buf = SolutionBuffer(max_size=9, top_m=3)
    for k in range(4):
        insert_problem(buf, k)
    again = SolutionBuffer.from_state_dict(buf.state_dict())
    path = tmp_path / "buffer.npz"
    buf.save(path)
    loaded = SolutionBuffer.load(path)
    for other in (again, loaded):
        assert (other.max_size, other.top_m) == (9, 3)
        assert other.problems() == buf.problems()
        np.testing.assert_array_equal(other.contexts(), buf.contexts())
        np.testing.assert_array_equal(other.targets(), buf.targets())
        np.testing.assert_array_equal(other.costs(), buf.costs())
    empty = tmp_path / "empty.npz"
    SolutionBuffer(5, 2).save(empty)
    assert len(SolutionBuffer.load(empty)) == 0


def test_bad_inputs_are_named():
    buf = SolutionBuffer(max_size=5, top_m=2)
    with pytest.raises(ConfigError, match="max_size"):
        SolutionBuffer(max_size=0)
    with pytest.raises(ConfigError, match="costs"):
        buf.insert("p", np.zeros(2), np.zeros((3, 4)), [1.0, 2.0])
    with pytest.raises(NonFiniteError, match="candidates"):
        buf.insert("p", np.zeros(2), [[np.nan, 0.0]], [1.0])
    insert_problem(buf, 0)
    with pytest.raises(ConfigError, match="context"):
        buf.insert("p", np.zeros(5), np.zeros((1, 3)), [1.0])
    with pytest.raises(ConfigError, match="candidates"):
        buf.insert("p", np.zeros(2), np.zeros((1, 4)), [1.0])
