"""The Python benchmark scripts under ``benches/`` run end to end (their figures are in BENCHMARKS.md).

Run as subprocesses, as a user would; the MotionBenchMaker case follows the shared-data rule of
``conftest.require_shared``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from conftest import REPO_ROOT

BENCHES = REPO_ROOT / "benches"


def _run(script: str, *args: str, shared: Path = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if shared is not None:
        env["GFCS_SHARED"] = str(shared)
    return subprocess.run([sys.executable, str(BENCHES / script), *args], capture_output=True, text=True,
                          env=env, timeout=600, check=True)


def test_fabric_step_counts_steps_and_times_both_thread_counts(tmp_path):
    out = tmp_path / "step.json"
    _run("fabric_step.py", "--generated", "--limit", "1", "--population", "4", "--repeat", "1",
         "--json", str(out))
    figures = json.loads(out.read_text())
    assert figures["steps"] > 7 * 4  # 7 classes × 4 candidates, each at least one step
    assert figures["us_per_step_1_thread"] > 0 and figures["wall_us_per_step_2_threads"] > 0
    assert figures["speedup"] > 0


def test_bench_suite_runs_on_motionbenchmaker_problems(tmp_path, shared_dir):
    _run("bench_suite.py", "--classes", "box", "--limit", "1", "--methods", "gf", "--out", str(tmp_path),
         "--no-progress", shared=shared_dir)
    rows = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [(r["problem"], r["method"]) for r in rows] == [("box/0001", "gf")]
    assert "box" in (tmp_path / "table.md").read_text()
