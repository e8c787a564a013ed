"""First-batch comparison of two samplers in the layout of GFCS Table II (no torch, no robot needed)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from gfcs.errors import ConfigError
from gfcs.learning.evaluate import evaluate_first_batch, format_first_batch_table


class FakeSolver:
    """Stand-in for gfcs.optimize.solve: metrics depend on (problem index, sampler), recorded calls."""

    def __init__(self):
        self.calls = []

    def __call__(self, problem, batches, population, n_commands, seed, sampler):
        self.calls.append((problem.name, batches, population, n_commands, seed, sampler))
        i = problem.index
        learned = sampler == "ebm"
        success = learned or i % 2 == 0  # uniform fails on odd problems
        metrics = {"success": success, "ee_length": 1.0 + i + (0.0 if learned else 0.5),
                   "cspace_length": 5.0 + 2 * i, "ee_ldj": -6.0 - i, "cspace_ldj": -7.0,
                   "min_clearance": 0.05, "final_error": 0.001}
        return SimpleNamespace(solve_time=0.1 * (i + 1), wall_time=0.12 * (i + 1), cost=2.0 + i, metrics=metrics,
                               to_json=lambda: json.dumps({"problem": problem.name, "sampler": str(sampler)}))


def test_rows_match_direct_statistics():
    problems = [SimpleNamespace(name=f"p{i}", index=i) for i in range(4)]
    solver = FakeSolver()
    raw = []
    rows = evaluate_first_batch(problems, None, "ebm", population=8, seed=10, solve_fn=solver, per_problem=raw)
    # both samplers, one batch each, paired seeds seed + i
    assert len(solver.calls) == 8
    assert all(c[1] == 1 and c[2] == 8 and c[3] == 1 for c in solver.calls)
    assert [c[4] for c in solver.calls] == [10, 10, 11, 11, 12, 12, 13, 13]
    assert [r["label"] for r in rows] == ["No learning", "Learning"]
    uniform, learned = rows
    assert uniform["n"] == 4 and uniform["success"] == pytest.approx(50.0)
    assert learned["success"] == pytest.approx(100.0)
    ok = [0, 2]  # statistics over the successful problems only
    ee = np.array([1.5 + i for i in ok])
    assert uniform["ee_length"] == pytest.approx((ee.mean(), ee.std()))
    ee_l = np.array([1.0 + i for i in range(4)])
    assert learned["ee_length"] == pytest.approx((ee_l.mean(), ee_l.std()))
    assert learned["cspace_ldj"] == pytest.approx((-7.0, 0.0))
    assert learned["time"] == pytest.approx((0.25, np.std([0.1, 0.2, 0.3, 0.4])))
    assert len(raw) == 8 and raw[0]["label"] == "No learning" and raw[0]["batches"] == 1
    table = format_first_batch_table(rows)
    assert "Table II" in table and "| No learning | 50 | 4 |" in table and "| Learning | 100 | 4 |" in table


def test_every_result_is_written_for_the_validator(tmp_path):
    problems = [SimpleNamespace(name=f"box/000{i}", index=i) for i in range(2)]
    raw = []
    evaluate_first_batch(problems, None, "ebm", solve_fn=FakeSolver(), per_problem=raw, results_dir=str(tmp_path))
    # the names of `gfcs bench --results-dir`: <class>_<NNNN>.<result>.json, the row naming its file
    assert sorted(f.name for f in tmp_path.iterdir()) == [
        "box_0000.learning.json", "box_0000.no-learning.json", "box_0001.learning.json", "box_0001.no-learning.json"]
    assert [r["result"] for r in raw] == ["no-learning", "learning"] * 2
    assert json.loads((tmp_path / "box_0001.learning.json").read_text()) == {"problem": "box/0001", "sampler": "ebm"}


def test_bad_arguments():
    with pytest.raises(ConfigError, match="no problems"):
        evaluate_first_batch([], None, None, solve_fn=FakeSolver())
    with pytest.raises(ConfigError, match="labels"):
        evaluate_first_batch([SimpleNamespace(name="p", index=0)], None, None, labels=("a", "a"),
                             solve_fn=FakeSolver())
