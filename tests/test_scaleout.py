"""Executors of gfcs bench (gfcs.executors, gfcs.bench): per-problem seeds, resume, and the Ray executor
against the local one (identical rows), with a worker killed mid-run."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path
from typing import Any, Dict, List

import pytest

from gfcs import bench, cli, generators
from gfcs.errors import GfcsError, InvalidValueError
from gfcs.executors import Done, LocalExecutor, make_executor
from gfcs.results import _enc

#: Row fields that are measured wall times (they differ between any two runs).
TIMES = ("time", "wall_time")
BENCH = dict(batches=2, population=6, progress=False)


def generated_suite(classes: List[str], n: int) -> List[Any]:
    """A seeded generated suite on the shipped Panda (a module-level builder: Ray workers import it)."""
    problems: List[Any] = []
    for c in classes:
        problems += generators.generate(c, n, seed=3)
    return problems


def killing_suite(marker: str, classes: List[str], n: int) -> List[Any]:
    """:func:`generated_suite`, but the first process to build it (where ``marker`` does not exist yet)
    kills itself with SIGKILL: a Ray worker that dies in the middle of its first task."""
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)  # one process wins, even at once
    except FileExistsError:
        return generated_suite(classes, n)
    os.write(fd, str(os.getpid()).encode())
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)
    return generated_suite(classes, n)


def rows_of(path: Path) -> List[Dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def by_key(rows: List[Dict[str, Any]]) -> Dict[Any, Dict[str, Any]]:
    """Rows by (problem, label) as the JSONL has them, without their wall times; asserts no (problem,
    label) appears twice."""
    out = {}
    for r in (json.loads(json.dumps(_enc(r))) for r in rows):
        key = (r["problem"], r.get("label"))
        assert key not in out, f"{key} twice"
        out[key] = {k: v for k, v in r.items() if k not in TIMES}
    return out


class Recording(LocalExecutor):
    """The local executor, remembering which problems it ran."""

    def __init__(self) -> None:
        super().__init__()
        self.ran: List[str] = []

    def run(self, fn, shared, tasks):
        for done in super().run(fn, shared, tasks):
            self.ran.append(done.key)
            yield done


# ------------------------------------------------------------------------------------------- seeds
def test_problem_seed_depends_on_run_seed_and_name_only():
    s = bench.problem_seed(0, "box/0001")
    assert s == bench.problem_seed(0, "box/0001")  # no process salt (Python's hash() would have one)
    assert 0 <= s < 2**31
    others = {bench.problem_seed(0, "box/0002"), bench.problem_seed(1, "box/0001"), bench.problem_seed(0, "box/001")}
    assert s not in others and len(others) == 3
    # recomputed independently of gfcs: numpy's SeedSequence over the run seed and the name's SHA-256
    import hashlib

    import numpy as np

    d = hashlib.sha256(b"box/0001").digest()
    words = [int.from_bytes(d[i:i + 4], "little") for i in range(0, 16, 4)]
    assert s == int(np.random.SeedSequence([0, *words]).generate_state(1)[0]) >> 1


def test_rows_carry_the_derived_seed_and_do_not_depend_on_order(tmp_path):
    suite = generated_suite(["box"], 3)
    forward = bench.run_bench(suite, ["gf", "gfcs"], seed=5, **BENCH)
    backward = bench.run_bench(suite[::-1], ["gf", "gfcs"], seed=5, **BENCH)
    assert by_key(forward) == by_key(backward)
    for r in forward:
        assert r["seed"] == bench.problem_seed(5, r["problem"])
    same = bench.run_bench(suite, ["gf"], seed=5, seeding="run", **BENCH)
    assert {r["seed"] for r in same} == {5}
    with pytest.raises(InvalidValueError, match="seeding"):
        bench.run_bench(suite, ["gf"], seeding="random", **BENCH)


def test_duplicate_problem_names_are_an_error():
    p = generated_suite(["box"], 1)[0]
    with pytest.raises(InvalidValueError, match="two problems are named"):
        bench.run_bench([p, p], ["gf"], **BENCH)


# ------------------------------------------------------------------------------------------ resume
def test_resume_skips_finished_problems_and_keeps_each_once(tmp_path):
    suite = generated_suite(["box", "table_pick"], 2)
    full = tmp_path / "full.jsonl"
    bench.run_bench(suite, ["gf", "gfcs"], jsonl=str(full), left_out=[("cage/0007", "start in collision")], **BENCH)
    lines = full.read_text().splitlines()
    # an interrupted run: the left-out row, the first problem complete, the second one's first row only,
    # and a line cut short by the interruption
    first = [ln for ln in lines if json.loads(ln)["problem"] == suite[0].name]
    second = [ln for ln in lines if json.loads(ln)["problem"] == suite[1].name]
    partial = tmp_path / "partial.jsonl"
    partial.write_text("\n".join([lines[0], *first, second[0], second[1][:25]]))
    executor = Recording()
    rows = bench.run_bench(suite, ["gf", "gfcs"], jsonl=str(partial), resume=True, executor=executor,
                           left_out=[("cage/0007", "start in collision")], **BENCH)
    assert executor.ran == [p.name for p in suite[1:]]  # the finished problem is not solved again
    assert by_key(rows_of(partial)) == by_key(rows_of(full)) == by_key(rows)
    # resuming a finished run runs nothing and changes nothing
    again = Recording()
    bench.run_bench(suite, ["gf", "gfcs"], jsonl=str(partial), resume=True, executor=again, **BENCH)
    assert again.ran == [] and by_key(rows_of(partial)) == by_key(rows_of(full))
    # a file whose damage is not at its end is not silently truncated
    (tmp_path / "bad.jsonl").write_text("{not json\n" + lines[1] + "\n")
    with pytest.raises(ValueError):
        bench.run_bench(suite, ["gf"], jsonl=str(tmp_path / "bad.jsonl"), resume=True, **BENCH)


def test_cli_resume(tmp_path):
    out = tmp_path / "rows.jsonl"
    args = ["bench", "--classes", "box", "--limit", "2", "--batches", "1", "--population", "4", "--method", "gf",
            "--no-progress", "--json", str(out)]
    assert cli.main(args) == 0
    before = by_key(rows_of(out))
    out.write_text(out.read_text().splitlines()[0] + "\n")
    assert cli.main(args + ["--resume"]) == 0
    assert by_key(rows_of(out)) == before
    assert cli.main(["bench", "--resume", "--no-progress"]) == 2  # nothing to resume from


def test_executor_arguments_are_checked():
    with pytest.raises(InvalidValueError, match="ray-address"):
        make_executor("local", address="auto")
    with pytest.raises(InvalidValueError, match="executor"):
        make_executor("spark")
    assert isinstance(make_executor("local"), LocalExecutor)


def test_an_executor_error_becomes_error_rows(tmp_path):
    class Failing(LocalExecutor):
        def run(self, fn, shared, tasks):
            for key, _ in tasks:
                yield Done(key, error="WorkerCrashedError: the worker died")

    suite = generated_suite(["box"], 2)
    out = tmp_path / "rows.jsonl"
    rows = bench.run_bench(suite, ["gf", "gfcs"], jsonl=str(out), executor=Failing(), **BENCH)
    # per problem every row a solve writes: GF, and GFCS's 1 b, 2 b and 2 b with retries
    assert [r["label"] for r in rows[:4]] == ["GF", "Ours (1 b)", "Ours (2 b)", "Ours (2 b, retry)"]
    assert len(rows) == 8 and all(not r["success"] and "WorkerCrashedError" in r["error"] for r in rows)
    assert by_key(rows_of(out)) == by_key(rows)


# --------------------------------------------------------------------------------------------- Ray
@pytest.fixture(scope="module")
def ray_executor():
    pytest.importorskip("ray", reason="the 'ray' extra is not installed")
    from gfcs.executors import RayExecutor

    executor = RayExecutor(workers=2, threads=1, max_retries=2)
    yield executor
    executor.close()


def test_ray_rows_equal_local_rows(tmp_path, ray_executor):
    classes, n = ["box", "table_pick", "bookshelf_small"], 2
    local = bench.run_bench(generated_suite(classes, n), ["gf", "gfcs"], seed=1, jsonl=str(tmp_path / "l.jsonl"),
                            **BENCH)
    suite = bench.Suite(generated_suite, (classes, n))
    remote = bench.run_bench(suite, ["gf", "gfcs"], seed=1, jsonl=str(tmp_path / "r.jsonl"),
                             executor=ray_executor, **BENCH)
    assert len(local) == 3 * n * 4
    assert by_key(local) == by_key(remote) == by_key(rows_of(tmp_path / "r.jsonl"))
    with pytest.raises(GfcsError, match="Suite"):  # Problem objects do not pickle: a recipe is required
        bench.run_bench(generated_suite(classes, 1), ["gf"], executor=ray_executor, **BENCH)


def test_ray_worker_killed_mid_run_is_retried(tmp_path, ray_executor):
    classes, n = ["box", "table_pick"], 2
    marker = tmp_path / "killed"
    suite = bench.Suite(killing_suite, (str(marker), classes, n))
    bench.suite_problems(suite, built=generated_suite(classes, n))  # the driver's copy (it must not die)
    out = tmp_path / "rows.jsonl"
    rows = bench.run_bench(suite, ["gf", "gfcs"], seed=2, jsonl=str(out), executor=ray_executor, **BENCH)
    assert marker.exists() and int(marker.read_text()) != os.getpid()  # a worker died
    expected = by_key(bench.run_bench(generated_suite(classes, n), ["gf", "gfcs"], seed=2, **BENCH))
    assert by_key(rows_of(out)) == by_key(rows) == expected  # every problem once, as a local run has it
    assert not any("error" in r for r in rows)


def test_ray_worker_killed_without_retries_gives_error_rows(tmp_path, ray_executor):
    from gfcs.executors import RayExecutor

    classes, n = ["box"], 2
    marker = tmp_path / "killed"
    suite = bench.Suite(killing_suite, (str(marker), classes, n))
    bench.suite_problems(suite, built=generated_suite(classes, n))
    no_retry = RayExecutor(threads=1, max_retries=0)  # joins the running Ray
    rows = bench.run_bench(suite, ["gf"], jsonl=str(tmp_path / "rows.jsonl"), executor=no_retry, **BENCH)
    assert sorted(r["problem"] for r in rows) == sorted(p.name for p in generated_suite(classes, n))
    failed = [r for r in rows if "error" in r]
    assert len(failed) == 1 and not failed[0]["success"]


def test_ray_training_equals_local_training(tmp_path, ray_executor):
    """Alg. 2 with the solves of each round on Ray workers: the same solves, buffer and weights as a local
    run (the sampler's weights go to the workers each round; the model is trained here)."""
    torch = pytest.importorskip("torch", reason="the 'learn' extra is not installed")
    from gfcs.learning.train import TrainConfig, train

    classes, n = ["bookshelf_small", "box"], 3
    config = TrainConfig(passes=1, n_train=2, buffer_size=20, top_m=2, n_neg=4, hidden=(16, 16), epochs=2,
                         batch_size=8, seed=4, device="cpu", solve={"batches": 1, "population": 6})
    problems = generated_suite(classes, n)
    train_set, held = problems[:5], problems[5:]
    local = train(train_set, config=config, progress=False, validation=held)
    remote = train(train_set, config=config, progress=False, validation=held, executor=ray_executor,
                   suite=bench.Suite(generated_suite, (classes, n)))

    def events(result):
        return [{k: v for k, v in e.items() if k != "seconds"} for e in result.history]

    assert [e["event"] for e in events(local)].count("train") == 3  # rounds of 2, 2 and 1 solves
    assert events(local) == events(remote)
    a, b = local.sampler.model.state_dict(), remote.sampler.model.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    with pytest.raises(GfcsError, match="suite"):
        train(train_set, config=config, progress=False, executor=ray_executor)


def test_progress_bar_shows_success_so_far(capsys):
    bench.run_bench(generated_suite(["box"], 2), ["gf", "gfcs"], batches=1, population=4, progress=True)
    err = capsys.readouterr().err
    assert "bench [local]" in err and "2/2" in err and "gf 2/2 solved, gfcs 2/2 solved" in err


def test_cli_ray_rows_equal_cli_local_rows(tmp_path, ray_executor):
    args = ["bench", "--classes", "box", "cage", "--limit", "2", "--batches", "2", "--population", "6",
            "--no-progress", "--time-limit", "0"]
    assert cli.main(args + ["--json", str(tmp_path / "l.jsonl")]) == 0
    assert cli.main(args + ["--json", str(tmp_path / "r.jsonl"), "--executor", "ray", "--threads", "1"]) == 0
    assert by_key(rows_of(tmp_path / "l.jsonl")) == by_key(rows_of(tmp_path / "r.jsonl"))
    assert len(rows_of(tmp_path / "r.jsonl")) == 4 * 4  # 4 problems: GF, 1 b, 2 b, retry


def test_ray_result_files_equal_local_ones(tmp_path, ray_executor):
    """--results-dir with Ray: the workers send the results as their JSON holds them (a Robot does not
    pickle); the files equal a local run's but for the measured times."""
    classes, n = ["box"], 2

    def untimed(x):
        if isinstance(x, dict):
            return {k: untimed(v) for k, v in x.items() if "time" not in k}
        return [untimed(v) for v in x] if isinstance(x, list) else x

    bench.run_bench(generated_suite(classes, n), ["gf", "gfcs"], results_dir=str(tmp_path / "l"), **BENCH)
    rows = bench.run_bench(bench.Suite(generated_suite, (classes, n)), ["gf", "gfcs"],
                           results_dir=str(tmp_path / "r"), executor=ray_executor, **BENCH)
    assert not any("error" in r for r in rows)
    names = sorted(p.name for p in (tmp_path / "l").iterdir())
    # per problem: GF's, the first batch's and the returned motion (a retry adds the first attempt's)
    assert len(names) >= 2 * 3 and {r["result"] for r in rows if "result" in r} == \
        {n.split(".")[1] for n in names}
    assert names == sorted(p.name for p in (tmp_path / "r").iterdir())
    for name in names:
        local, remote = (json.loads((tmp_path / side / name).read_text()) for side in ("l", "r"))
        assert untimed(local) == untimed(remote)
