"""Golden test of :func:`gfcs.optimize.solve`: on a handful of problems, the sequence of attempts a solve makes
(robot model, command count, obstacle margin, goal-contact margins, outcome) and the motion it returns are
pinned in ``tests/data/golden/solve.json``.

The problems exercise every retry path of the default solve: the built-in problem of ``gfcs solve``, the
GF baseline on it, generated problems (one without a mesh model, whose second attempt adds a command; one with
the uniform sampler, which has no retry), and MotionBenchMaker problems where the thin-sphere model falls back
to the covering spheres after both mesh retries and the goal-contact attempt, where a mesh retry succeeds,
where the goal-contact attempt succeeds, and where the meshes alone judge a goal in sphere contact.

Regenerate the fixture (only when a change of behaviour is intended, and say so in the commit)::

    python tests/test_golden.py --regenerate
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import require_shared  # noqa: E402

FIXTURE = Path(__file__).resolve().parent / "data" / "golden" / "solve.json"

#: name -> (problem source, keyword arguments of solve). Sources: ("demo",) the built-in problem of
#: ``gfcs solve``; ("generated", class, seed, keep_mesh_checker); ("mbm", class, number, robot) with robot
#: "shipped" (the default) or "mbm" (MotionBenchMaker's Panda with its meshes).
CASES: Dict[str, Tuple[Tuple[Any, ...], Dict[str, Any]]] = {
    "demo": (("demo",), {}),
    "demo_gf": (("demo",), {"method": "gf"}),
    "generated_without_meshes": (("generated", "cage", 1, False), {"batches": 1, "population": 4}),
    "generated_uniform_sampler": (("generated", "box", 1, True), {"batches": 2, "sampler": "uniform"}),
    "mbm_cage_0001": (("mbm", "cage", 1, "shipped"), {"batches": 1}),
    "mbm_cage_0001_no_repair": (("mbm", "cage", 1, "shipped"), {"batches": 1, "mesh_repair": False}),
    "mbm_cage_0006": (("mbm", "cage", 6, "shipped"), {"batches": 1}),
    # two commands at most: a fourth command solves it without the wider margin this case pins
    "mbm_cage_0006_no_repair": (("mbm", "cage", 6, "shipped"), {"batches": 1, "mesh_repair": False,
                                                                "max_commands": 2}),
    # a goal whose spheres sink into the table: planned with its contact from the first attempt; without the
    # preset's endpoint contact, by the goal-contact retry when the spheres judge too, and by the first
    # attempt when the meshes alone judge
    "mbm_table_pick_0041": (("mbm", "table_pick", 41, "mbm"),
                            {"batches": 1, "endpoint_contact": False, "spheres_judge": True}),
    "mbm_table_pick_0041_meshes": (("mbm", "table_pick", 41, "mbm"), {"batches": 1, "endpoint_contact": False}),
    "mbm_table_pick_0041_endpoint": (("mbm", "table_pick", 41, "mbm"), {"batches": 1}),
}

#: Rows of the trajectory recorded in the fixture (fractions of its length), besides its length and sums.
SAMPLE_AT = np.linspace(0.0, 1.0, 9)


def make_problem(source: Tuple[Any, ...]) -> Any:
    """The problem of a :data:`CASES` source (skips when it needs the shared data and that is absent)."""
    import gfcs
    from gfcs import cli, generators, problems

    kind = source[0]
    if kind == "demo":
        return generators.generate(cli.DEFAULT_DEMO_CLASS, 1, seed=0, robot=gfcs.Robot.panda())[0]
    if kind == "generated":
        _, cls, seed, keep_checker = source
        problem = generators.generate(cls, 1, seed=seed, robot=gfcs.Robot.panda())[0]
        return problem if keep_checker else dataclasses.replace(problem, mesh_checker=None)
    _, cls, number, robot = source
    folder = require_shared("mbm", cls)
    model = problems.mbm_panda(require_shared("robots", "mbm_panda")) if robot == "mbm" else None
    return problems.load_mbm_dir(folder, limit=number, robot=model, invalid=[])[-1]


def solve_recorded(problem: Any, options: Dict[str, Any]) -> Tuple[Any, List[Dict[str, Any]]]:
    """``solve(problem, **options)`` and the attempts it made, in order (from ``result.attempt_records``):
    which robot model (``"thin"`` when the attempt's robot is not the problem's own), free commands,
    obstacle margin, goal-contact margins and clearance floor, and outcome."""
    from gfcs import optimize

    options = dict(options)
    if options.get("sampler") == "uniform":
        options["sampler"] = optimize.UniformSampler(options.get("n_commands", 1))
    if not options.pop("endpoint_contact", True):
        from gfcs import planning

        options["preset"] = dataclasses.replace(planning.get_preset("default"), endpoint_contact=False)
    result = optimize.solve(problem, **options)
    attempts: List[Dict[str, Any]] = []
    for record in result.attempt_records:
        attempt, ran = record.attempt, record.result
        attempts.append({
            "model": "own" if attempt.model.robot is problem.robot else "thin",
            "n_commands": int(attempt.n_commands),
            "obstacle_margin": float(ran.fabric_config["obstacles"]["margin"]),
            "goal_contact_margins": None if attempt.obstacle_margins is None else list(attempt.obstacle_margins),
            "clearance_floor": float(attempt.clearance_floor),
            "success": bool(ran.success),
            "cost": float(ran.cost),
            "n_evaluations": int(ran.n_evaluations),
        })
    return result, attempts


def summary(result: Any) -> Dict[str, Any]:
    """What the fixture pins of a returned result: outcome, commands, the settings that list the attempts,
    the selection metrics and the trajectory (length, sampled rows, sums)."""
    traj = result.trajectory
    n = len(traj)
    rows = sorted({int(round(f * (n - 1))) for f in SAMPLE_AT}) if n else []
    keys = ("n_commands", "commands_tried", "obstacle_margins_tried", "sphere_model", "goal_contact")
    return {
        "method": result.method,
        "success": bool(result.success),
        "reached": bool(result.reached),
        "cost": float(result.cost),
        "commands": np.asarray(result.commands).tolist(),
        "t_stars": np.asarray(result.t_stars).tolist(),
        "n_evaluations": int(result.n_evaluations),
        "settings": {k: result.settings[k] for k in keys if k in result.settings},
        "selection_rank": result.metrics.get("selection_rank"),
        "mesh_candidates_checked": result.metrics.get("mesh_candidates_checked"),
        "ee_length": float(result.metrics["ee_length"]),
        "trajectory": {
            "samples": n,
            "t_end": float(traj.t[-1]) if n else 0.0,
            "rows": rows,
            "q": traj.q[rows].tolist(),
            "qd": traj.qd[rows].tolist(),
            "q_sum": float(traj.q.sum()),
            "qd_sum": float(traj.qd.sum()),
            "q_abs_sum": float(np.abs(traj.q).sum()),
        },
    }


def record(name: str) -> Dict[str, Any]:
    source, options = CASES[name]
    result, attempts = solve_recorded(make_problem(source), options)
    return {"attempts": attempts, "result": summary(result)}


def assert_same(actual: Any, expected: Any, where: str) -> None:
    """Equal structure and values; floats to 1e-9 relative (the solve is deterministic, the tolerance only
    absorbs the JSON round trip)."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict) and sorted(actual) == sorted(expected), f"{where}: keys {actual} != {expected}"
        for k in expected:
            assert_same(actual[k], expected[k], f"{where}.{k}")
    elif isinstance(expected, list):
        assert isinstance(actual, list) and len(actual) == len(expected), f"{where}: {actual} != {expected}"
        for i, (a, e) in enumerate(zip(actual, expected)):
            assert_same(a, e, f"{where}[{i}]")
    elif isinstance(expected, float) and not isinstance(expected, bool):
        assert isinstance(actual, (int, float)) and not isinstance(actual, bool), f"{where}: {actual!r}"
        assert math.isclose(actual, expected, rel_tol=1e-9, abs_tol=1e-12), f"{where}: {actual!r} != {expected!r}"
    else:
        assert actual == expected, f"{where}: {actual!r} != {expected!r}"


def _normalised(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists)."""
    return json.loads(json.dumps(value))


@pytest.fixture(scope="module")
def golden() -> Dict[str, Any]:
    if not FIXTURE.is_file():
        pytest.fail(f"{FIXTURE} is missing: run python tests/test_golden.py --regenerate")
    return json.loads(FIXTURE.read_text())


@pytest.mark.parametrize("name", list(CASES))
def test_solve_makes_the_pinned_attempts_and_returns_the_pinned_motion(name: str, golden: Dict[str, Any]) -> None:
    assert name in golden, f"{name} has no entry in {FIXTURE}: regenerate it"
    actual = _normalised(record(name))
    expected = golden[name]
    assert_same(actual["attempts"], expected["attempts"], f"{name}.attempts")
    assert_same(actual["result"], expected["result"], f"{name}.result")


def test_the_cases_exercise_every_retry_path(golden: Dict[str, Any]) -> None:
    """The fixture covers what it claims: a thin-then-covering cascade, a second command, a mesh retry that
    succeeds, and a goal-contact attempt that succeeds (with the mesh repair off; with the endpoint contact,
    the same margins in the first attempt), and mesh contacts that the repair undoes in the first attempt."""
    attempts = [a for entry in golden.values() for a in entry["attempts"]]
    assert {"thin", "own"} <= {a["model"] for a in attempts}
    assert any(a["n_commands"] == 2 for a in attempts)
    cage6 = golden["mbm_cage_0006_no_repair"]["attempts"]
    assert cage6[-1]["success"] and cage6[-1]["obstacle_margin"] > cage6[0]["obstacle_margin"]
    contact = golden["mbm_table_pick_0041"]["attempts"]
    assert contact[-1]["success"] and contact[-1]["goal_contact_margins"] is not None
    first = golden["mbm_table_pick_0041_endpoint"]["attempts"]
    assert len(first) == 1 and first[0]["success"] and first[0]["goal_contact_margins"] == contact[-1]["goal_contact_margins"]
    cascade = [a["model"] for a in golden["mbm_cage_0001_no_repair"]["attempts"]]
    assert cascade[0] == "thin" and cascade[-1] == "own"
    for name in ("mbm_cage_0001", "mbm_cage_0006"):  # both failed the first attempt on the meshes
        assert [a["success"] for a in golden[name]["attempts"]] == [True]


def main(argv: List[str]) -> int:
    if argv != ["--regenerate"]:
        print(__doc__)
        return 2
    out = {}
    for name in CASES:
        print(f"solving {name}", file=sys.stderr)
        out[name] = _normalised(record(name))
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    FIXTURE.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {FIXTURE}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
