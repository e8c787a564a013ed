"""gfcs.planning: retry policies, presets, the time budget, attempt records and bench rows from them."""

import dataclasses
import json
import time
from types import SimpleNamespace

import numpy as np
import pytest

import gfcs
from gfcs import bench, cli, generators, planning
from gfcs.planning import attempts as _attempts
from gfcs.planning.models import PlanningModel, RobotModels


@pytest.fixture(scope="module")
def retried_problem():
    """A generated cage problem without a mesh model whose first attempt (1 command, one batch of 4) fails
    and whose second (2 commands) succeeds."""
    p = generators.generate("cage", 1, seed=1, robot=gfcs.Robot.panda())[0]
    return dataclasses.replace(p, mesh_checker=None)


SMALL = dict(batches=1, population=4, threads=1)


# ------------------------------------------------------------------------------------ Algorithm 1
def sphere_cost(y):
    return np.sum(np.asarray(y) ** 2, axis=1)


def test_first_batches_is_what_a_shorter_run_returns():
    long = planning.solve_gfcop(sphere_cost, 3, -1, 1, batches=4, population=6, seed=2, top_m=3)
    short = planning.solve_gfcop(sphere_cost, 3, -1, 1, batches=1, population=6, seed=2, top_m=3)
    head = long.first_batches(1)
    for name in ("all_x", "all_costs", "top_x", "top_costs", "batch_best_costs", "best_x"):
        np.testing.assert_array_equal(getattr(head, name), getattr(short, name))
    assert head.n_evaluations == 6 and head.best_cost == short.best_cost


def test_a_deadline_stops_the_batches_and_cuts_the_last_one():
    def slow(y):
        time.sleep(0.002 * len(y))
        return sphere_cost(y)

    start = time.perf_counter()
    res = planning.solve_gfcop(slow, 2, -1, 1, batches=1000, population=10, seed=0, deadline=start + 0.3)
    elapsed = time.perf_counter() - start
    assert 0.2 < elapsed <= 0.33
    assert 1 < len(res.batch_times) < 1000
    sizes = np.bincount(res.all_batches)
    assert np.all(sizes[:-1] == 10) and 1 <= sizes[-1] <= 10  # only the last batch may be cut


# ------------------------------------------------------------------------------------ policies
def _record(model, n, success=False, mesh_only=False, kind="plan", margin_round=0, contact="mesh_clearance"):
    metrics = {"success": success}
    if mesh_only:
        metrics.update({"mesh_clearance": np.inf, "mesh_self_clearance": np.inf, contact: -0.001,
                        "sphere_success": True})
    result = SimpleNamespace(success=success, metrics=metrics, cost=1.0, n_evaluations=1, batch_times=[0.1])
    step = 0.002 if margin_round else 0.0
    attempt = _attempts.Attempt(model, n, kind=kind, margin_round=margin_round, margin_step=step)
    return _attempts.AttemptRecord(attempt, result=result)


@pytest.fixture(scope="module")
def context():
    robot = gfcs.Robot.panda()
    thin, own = PlanningModel("thin", robot, 0.004), PlanningModel("spheres", robot)
    models = RobotModels(robot, (thin, own), validator=None, profile=None)
    return planning.PlanContext(None, models, 1, 0.001, model_fabric=None, model_problem=None)


def test_more_commands_adds_one_command_up_to_its_extra(context):
    thin = context.models.planning[0]
    policy = planning.MoreCommands(extra=1)
    proposal = policy.propose(context, [_record(thin, 1)])
    assert proposal.n_commands == 2 and proposal.model == thin and proposal.label == "thin, 2 commands"
    assert policy.propose(context, [_record(thin, 1), _record(thin, 2)]) is None
    assert policy.propose(context, [_record(thin, 1, kind="goal_contact")]) is None


def test_wider_margin_follows_a_mesh_only_failure_of_the_round(context):
    thin = context.models.planning[0]
    policy = planning.WiderMargin(step=0.002, rounds=2)
    assert policy.propose(context, [_record(thin, 1), _record(thin, 2)]) is None  # no mesh-only failure
    proposal = policy.propose(context, [_record(thin, 1, mesh_only=True), _record(thin, 2)])
    assert proposal.n_commands == 1 and proposal.margin_round == 1
    assert proposal.obstacle_margin(0.002) == pytest.approx(0.002 + 0.004 + 0.002)
    assert proposal.label == "thin, 1 command, margin +2 mm"
    last_round = [_record(thin, 1, mesh_only=True, margin_round=2)]
    assert policy.propose(context, last_round) is None  # both rounds used


def test_wider_margin_leaves_contacts_between_links_to_mesh_cover(context):
    thin = context.models.planning[0]
    between_links = _record(thin, 1, mesh_only=True, contact="mesh_self_clearance")
    assert planning.mesh_contacts(between_links, context.mesh_margin) == ("self",)
    assert planning.mesh_contacts(_record(thin, 1, mesh_only=True), context.mesh_margin) == ("obstacles",)
    assert planning.mesh_contacts(_record(thin, 1), context.mesh_margin) == ()
    policy = planning.WiderMargin(step=0.002, rounds=2)
    assert policy.propose(context, [between_links, _record(thin, 2)]) is None
    assert policy.propose(context, [between_links, _record(thin, 2, mesh_only=True)]).margin_round == 1


def test_model_cascade_moves_to_the_next_model_and_stops_after_the_last(context):
    thin, own = context.models.planning
    policy = planning.ModelCascade()
    proposal = policy.propose(context, [_record(thin, 1), _record(thin, 2)])
    assert proposal.model == own and proposal.n_commands == 1 and proposal.margin_round == 0
    assert policy.propose(context, [_record(thin, 1), _record(own, 1)]) is None


def test_model_share_hands_over_once_a_model_used_its_part_of_the_budget(context):
    """With a 6 s budget and two models, the first may use 3 s; the last model is never cut short, and
    without a budget nothing is proposed."""
    thin, own = context.models.planning
    budgeted = dataclasses.replace(context, time_limit=6.0)
    policy = planning.ModelShare()

    def timed(model, n, seconds):
        record = _record(model, n)
        record.time = seconds
        return record

    assert policy.propose(budgeted, [timed(thin, 1, 1.0), timed(thin, 2, 1.5)]) is None
    proposal = policy.propose(budgeted, [timed(thin, 1, 1.0), timed(thin, 2, 2.0)])
    assert (proposal.model, proposal.n_commands, proposal.restart) == (own, 1, 0)
    assert policy.propose(budgeted, [timed(thin, 1, 3.0), timed(own, 1, 3.0)]) is None
    assert policy.propose(context, [timed(thin, 1, 100.0)]) is None
    # a restart's run on the first model starts its share afresh, from what is left of the budget
    restarted = [timed(thin, 1, 1.0), timed(own, 1, 2.0), timed(thin, 1, 1.0)]
    assert policy.propose(budgeted, restarted) is None
    assert policy.propose(budgeted, restarted + [timed(thin, 2, 0.5)]).model == own
    # a run with a mesh-only failure (near a solution) may use twice its share, no more
    near = _record(thin, 1, mesh_only=True)
    near.time = 2.0
    assert policy.propose(budgeted, [near, timed(thin, 2, 2.0)]) is None
    assert policy.propose(budgeted, [near, timed(thin, 2, 4.0)]).model == own
    assert planning.ModelShare(near_miss=1.0).propose(budgeted, [near, timed(thin, 2, 2.0)]).model == own
    for bad in (-1.0, 0.5):
        with pytest.raises(gfcs.InvalidValueError, match="ModelShare.near_miss"):
            planning.ModelShare(near_miss=bad)


def test_restart_begins_a_new_round_on_the_first_model_until_its_rounds_are_used(context):
    thin, own = context.models.planning
    policy = planning.Restart(rounds=2)
    proposal = policy.propose(context, [_record(thin, 1), _record(own, 2)])
    assert (proposal.model, proposal.n_commands, proposal.restart) == (thin, 1, 1)
    assert proposal.label == "thin, 1 command, restart 1" and proposal.settings(0.002)["restart"] == 1
    second = policy.propose(context, [_record(own, 2), _attempt_record(proposal)])
    assert second.restart == 2
    assert policy.propose(context, [_attempt_record(second)]) is None
    # the other policies keep the restart of the round they continue
    assert planning.MoreCommands(extra=1).propose(context, [_attempt_record(proposal)]).restart == 1
    assert planning.ModelCascade().propose(context, [_attempt_record(proposal)]).restart == 1


def test_a_restart_has_its_own_seed_and_a_doubled_population(context):
    thin = context.models.planning[0]
    options = _attempts.OptimOptions(population=8, seed=3)
    assert _attempts.Attempt(thin, 1).optim_options(options) is options
    first, second = (_attempts.Attempt(thin, 1, restart=k).optim_options(options) for k in (1, 2))
    assert (first.population, second.population) == (16, 32)
    assert len({options.seed, first.seed, second.seed}) == 3
    assert _attempts.Attempt(thin, 2, restart=1).optim_options(options).seed == first.seed  # one seed per round


def _attempt_record(attempt):
    return _attempts.AttemptRecord(attempt, result=SimpleNamespace(success=False, metrics={}, cost=1.0))


def test_goal_contact_needs_a_validator(context):
    thin = context.models.planning[0]
    assert planning.GoalContact().propose(context, [_record(thin, 1)]) is None


def test_policy_parameters_are_checked_by_name():
    with pytest.raises(gfcs.GfcsError, match="WiderMargin.step"):
        planning.WiderMargin(step=-0.001)
    with pytest.raises(gfcs.GfcsError, match="MoreCommands.extra"):
        planning.MoreCommands(extra=1.5)
    with pytest.raises(gfcs.GfcsError, match="GoalContact.slack"):
        planning.GoalContact(slack=float("nan"))
    with pytest.raises(gfcs.GfcsError, match="Restart.rounds"):
        planning.Restart(rounds=-1)
    with pytest.raises(gfcs.GfcsError, match="restarts"):
        planning.default_policies(restarts=0.5)
    assert [type(p).__name__ for p in planning.default_policies()][-1] == "Restart"
    assert "Restart" not in [type(p).__name__ for p in planning.default_policies(restarts=0)]


# ------------------------------------------------------------------------------------ solve
def test_no_retry_is_an_empty_policy_list(retried_problem):
    retried = planning.solve(retried_problem, **SMALL)
    assert retried.success and [a["label"] for a in retried.attempts] == ["spheres, 1 command", "spheres, 2 commands"]
    assert [a["outcome"] for a in retried.attempts] == ["failure", "success"]
    assert retried.attempts[1]["policy"] == "more commands" and retried.attempts[0]["policy"] == ""
    once = planning.solve(retried_problem, policies=[], **SMALL)
    assert not once.success and len(once.attempts) == 1
    assert once.cost == retried.attempt_records[0].result.cost


def test_the_result_lists_every_attempt_and_survives_json(retried_problem):
    r = planning.solve(retried_problem, **SMALL)
    back = gfcs.results.SolveResult.from_json(r.to_json())
    assert back.attempts == json.loads(json.dumps(r.attempts)) and back.preset == "default"
    assert back.attempts[0]["settings"] == {"model": "spheres", "n_commands": 1, "kind": "plan",
                                            "obstacle_margin": 0.002, "clearance_floor": 0.0, "restart": 0}
    assert all(a["time"] > 0 and a["n_evaluations"] == 4 for a in back.attempts)


def test_json_encoding_keeps_arrays_exact_and_spells_non_finite_values():
    enc = gfcs.results._enc
    finite = np.array([[0.1, -2.5], [1e-300, 3.0]])
    assert enc(finite) == finite.tolist() and enc(np.array([True, False])) == [True, False]
    assert enc(np.array([1.0, np.inf, -np.inf, np.nan])) == [1.0, "Infinity", "-Infinity", "NaN"]
    assert enc({"a": np.arange(3), "b": (np.float64(np.nan),)}) == {"a": [0, 1, 2], "b": ["NaN"]}


def test_a_tiny_budget_lists_what_was_tried_and_what_was_not(retried_problem):
    r = planning.solve(retried_problem, time_limit=1e-3, **SMALL)
    assert not r.success and r.time_limit == 1e-3
    assert [a["outcome"] for a in r.attempts] == ["failure", "not run"]
    assert r.attempts[1]["label"] == "spheres, 2 commands" and r.attempts[1]["policy"] == "more commands"
    text = cli.summary_text(r, retried_problem)
    assert "attempts  spheres, 1 command: failure" in text and "spheres, 2 commands: not run" in text
    assert "time limit 0.001 s" in text


def test_solve_keeps_its_time_budget(retried_problem):
    limit = 1.0
    start = time.perf_counter()
    r = planning.solve(retried_problem, batches=10_000, population=32, threads=1, time_limit=limit)
    elapsed = time.perf_counter() - start  # the solve's own time, measured around the call
    assert elapsed <= 1.1 * limit
    assert r.wall_time <= elapsed and 1 < r.attempts[0]["batches_run"] < 10_000
    assert r.attempts and all(a["outcome"] != "not run" or a["time"] == 0 for a in r.attempts)


class _Clock:
    """A settable stand-in for ``time.perf_counter`` in :mod:`gfcs.planning.budget`."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_a_selection_spends_its_share_while_another_attempt_fits(monkeypatch):
    from gfcs.planning import budget as _budget

    clock = _Clock()
    monkeypatch.setattr(_budget.time, "perf_counter", clock)
    b = _budget.Budget(10.0)
    b.observe_first_batch(0.4)
    b.observe_selection(0.6)  # another attempt needs 1 s
    clock.now = 102.0  # 8 s left
    assert b.selection_deadline(0.5) == pytest.approx(106.0)
    assert b.selection_deadline(1.0) == pytest.approx(110.0)
    assert b.selection_deadline() == pytest.approx(110.0)
    clock.now = 108.5  # 1.5 s left: after half of it no attempt would fit, so the selection may use it all
    assert b.selection_deadline(0.5) == pytest.approx(110.0)
    assert _budget.Budget(None).selection_deadline(0.5) is None


def test_an_attempt_selects_within_its_share(retried_problem, monkeypatch):
    seen = []
    select = _attempts.select_candidate

    def recording(*args, **kwargs):
        deadline, now = args[9], time.perf_counter()
        seen.append((deadline - now, args[10]))
        return select(*args, **kwargs)

    monkeypatch.setattr(_attempts, "select_candidate", recording)
    r = planning.solve(retried_problem, time_limit=60.0, selection_share=0.25, **SMALL)
    assert len(seen) == 2 and r.settings["selection_share"] == 0.25
    first_left = 60.0 - r.attempts[0]["time"]  # about what the first selection had left
    assert 0.2 * first_left < seen[0][0] <= 0.25 * 60.0
    assert all(timing["first_verdict"] > 0 for _, timing in seen)
    with pytest.raises(gfcs.GfcsError, match="selection_share"):
        planning.solve(retried_problem, selection_share=0.0, **SMALL)
    with pytest.raises(gfcs.GfcsError, match="selection_share"):
        planning.solve(retried_problem, selection_share="half", **SMALL)
    assert planning.get_preset("default").selection_share == 0.75
    assert planning.get_preset("paper").selection_share == 1.0


def test_paper_preset_is_the_method_as_written(retried_problem):
    r = planning.solve(retried_problem, preset="paper", batches=2, population=6, threads=1)
    s = r.settings
    assert r.preset == "paper" and len(r.attempts) == 1 and s["sampler"] == "UniformSampler"
    assert s["blend_time"] == 0 and s["tol"] == 0.01 and s["collision_penalty"] == 0 and s["length_slack"] == 0
    assert s["limit_hold_off"] is None and s["stall_window"] == 0
    assert not any(s[k] for k in ("retime_start", "goal_blend", "limit_velocity", "limit_acceleration"))
    for barrier in ("obstacles", "self_collision", "joint_limits"):
        assert r.fabric_config[barrier]["braking_time"] == 0
    # no post-processing: the trajectory is the fabric's own, at the integration step from t = 0
    np.testing.assert_allclose(np.diff(r.trajectory.t), 0.01, atol=1e-12)
    default = planning.solve(retried_problem, batches=2, population=6, threads=1)
    assert default.preset == "default" and default.settings["blend_time"] == 0.5


def test_bad_arguments_are_gfcs_errors_naming_them(retried_problem):
    cases = [(dict(preset="fast"), "preset"), (dict(time_limit=-1.0), "time_limit"),
             (dict(n_commands=0), "n_commands"), (dict(method="rrt"), "method"),
             (dict(policies=[], mesh_retries=1), "mesh_retries"), (dict(length_slack=-0.1), "length_slack"),
             (dict(mesh_candidates=0), "mesh_candidates"), (dict(max_commands=0), "max_commands")]
    for kwargs, name in cases:
        with pytest.raises(gfcs.GfcsError, match=name):
            planning.solve(retried_problem, **SMALL, **kwargs)


def test_a_policy_list_with_more_commands_refuses_a_sampler_of_your_own(retried_problem):
    with pytest.raises(gfcs.GfcsError, match="policies"):
        planning.solve(retried_problem, sampler=planning.UniformSampler(1), policies=[planning.MoreCommands()],
                       **SMALL)


def test_bench_reads_its_rows_from_one_solve(retried_problem, monkeypatch):
    calls = []
    real = planning.solve

    def counting(*args, **kwargs):
        calls.append(kwargs.get("method"))
        return real(*args, **kwargs)

    monkeypatch.setattr(planning, "solve", counting)
    rows, results = bench.bench_problem(retried_problem, ["gfcs"], batches=2, population=4, seed=0, threads=1)
    assert calls == ["gfcs"]
    assert [r["label"] for r in rows] == ["Ours (1 b)", "Ours (2 b)", "Ours (2 b, retry)"]
    first = results["gfcs"].attempt_records[0]
    assert rows[1]["cost"] == first.result.cost and rows[2]["cost"] == results["gfcs"].cost
    assert rows[0]["time"] == pytest.approx(first.result.batch_times[0])
    # the first attempt's motion is the returned one: its row names the returned motion's file
    assert len(results["gfcs"].attempt_records) == 1 and list(results) == ["gfcs-1b", "gfcs"]
    assert [r["result"] for r in rows] == ["gfcs-1b", "gfcs", "gfcs"]
    # a retry followed the first attempt: its motion goes to a file of its own, as the first batch's does
    rows, results = bench.bench_problem(retried_problem, ["gfcs"], batches=2, population=4, seed=2, threads=1)
    first = results["gfcs"].attempt_records[0]
    assert len(results["gfcs"].attempt_records) > 1
    assert [r["result"] for r in rows] == ["gfcs-1b", "gfcs-2b", "gfcs"]
    assert results["gfcs-1b"] is first.first_batch and results["gfcs-2b"] is first.result
    paper, kept = bench.bench_problem(retried_problem, ["gfcs"], batches=2, population=4, seed=0, threads=1,
                                      solve_options={"preset": "paper"})
    assert [r["label"] for r in paper] == ["Ours (1 b)", "Ours (2 b)"]  # no policies: no retry row
    assert [r["result"] for r in paper] == list(kept) == ["gfcs-1b", "gfcs"]
