"""The ``gfcs`` command line (entry point ``gfcs = gfcs.cli:main``).

Subcommands::

    gfcs solve      solve one problem (a MotionBenchMaker scene + request, or a generated one)
    gfcs bench      run GFCS and the GF baseline over a problem suite; tables like GFCS Table I
    gfcs generate   write procedurally generated problems as MotionBenchMaker files
    gfcs train      self-supervised EBM training (GFCS Alg. 2)       [gfcs.learning, extra "learn"]
    gfcs view       open a rerun recording                           [gfcs.viz, extra "viz"]
    gfcs experiment the papers' experiments (GF Sec. VI, VII; GFCS Sec. V reactivity)   [gfcs.experiments]

Hooks for other packages: each entry of :data:`EXTERNAL_COMMANDS` names a module and a registration
function ``register(subparsers) -> argparse.ArgumentParser``; that function adds its own subparser (under
the command's name) and sets ``func`` with ``parser.set_defaults(func=handler)``, ``handler(args) -> int``
(the exit code). The module is imported only when its command is the one being run, so ``gfcs --help`` and
``gfcs solve`` never import torch or rerun; if the import fails, the command prints one line naming the
missing dependency and exits 2.

Errors: a :class:`gfcs.GfcsError` (or a missing file / invalid value from user input) prints one line
``gfcs: error: ...`` on stderr and exits 2, never a traceback (set ``GFCS_DEBUG=1`` to see it).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import math
import os
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

__all__ = [
    "main",
    "build_parser",
    "EXTERNAL_COMMANDS",
    "run_bench",
    "bench_problem",
    "load_mbm_suite",
    "load_problems",
    "DEFAULT_DEMO_CLASS",
]

#: Subcommands provided by other modules: name -> (module, registration function, help, pip extra).
EXTERNAL_COMMANDS: Dict[str, Tuple[Tuple[str, ...], str, str, Optional[str]]] = {
    "train": (("gfcs.learning.cli",), "register",
              "self-supervised EBM training of the warm-start sampler (GFCS Alg. 2)", "learn"),
    "view": (("gfcs.viz",), "register_cli", "open a rerun recording (.rrd) in the viewer", "viz"),
    "experiment": (("gfcs.experiments", "gfcs.experiments.particles", "gfcs.experiments.panda",
                    "gfcs.experiments.reactivity", "gfcs.experiments.constrained",
                    "gfcs.experiments.orientation"), "register_cli",
                   "the papers' experiments (GF Sec. VI particles, Sec. VII Panda; GFCS Sec. V reactivity)", None),
    "plot": (("gfcs.plots",), "register_cli", "plot benchmark rows (success rate, EE path length)", None),
}

#: Class of the built-in problem ``gfcs solve`` uses without --scene.
DEFAULT_DEMO_CLASS = "table_under_pick"

EXIT_USER_ERROR = 2


# ------------------------------------------------------------------------------------ shared options
def _integer(minimum: int) -> Any:
    """An argparse ``type``: an integer >= ``minimum`` (argparse reports anything else as a usage error,
    naming the option)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}, got {value}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def _writable_file(path: Optional[str], option: str) -> None:
    """``ValueError`` naming ``option`` unless ``path`` (a file to write; None or '-' for stdout: nothing to
    check) can be written: its directory exists and is writable, and the path is not a directory. Checked
    before solving, so that a long run does not end in a write error."""
    if path is None or path == "-":
        return
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if target.is_dir():
        raise ValueError(f"{option} {path}: is a directory")
    if not folder.is_dir():
        raise ValueError(f"{option} {path}: directory {folder} does not exist")
    if not os.access(folder, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise ValueError(f"{option} {path}: not writable")


def _writable_dir(path: Optional[str], option: str) -> None:
    """``ValueError`` naming ``option`` unless ``path`` (a folder to create or fill; None: nothing to check)
    is a writable directory or can be created in one."""
    if path is None:
        return
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise ValueError(f"{option} {path}: exists and is not a directory")
    existing = next((p for p in (target, *target.parents) if p.exists()), Path("."))
    if not os.access(existing, os.W_OK):
        raise ValueError(f"{option} {path}: {existing} is not writable")


def _add_robot_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("robot (default: the shipped Panda)")
    g.add_argument("--robot", metavar="URDF",
                   help="robot URDF file, or 'mbm' for the MotionBenchMaker Panda of the shared data folder "
                        "(spherized URDF + SRDF; use it for MotionBenchMaker problems: their goals are "
                        "collision-free for its spheres); a URDF X.urdf without collision spheres takes "
                        "those of X_spherized.urdf beside it")
    g.add_argument("--srdf", metavar="SRDF", help="SRDF whose disabled collisions prune self-collision pairs")
    g.add_argument("--group", metavar="NAME",
                   help="SRDF planning group to plan for: its joints move, the others are held at the request's "
                        "start values; the end effector is its first tip link, and the metrics report every tip's "
                        "path (default with --srdf: the group_name of the problems' first request)")
    g.add_argument("--spheres", metavar="JSON", help="collision sphere file (replaces URDF spheres)")
    g.add_argument("--ee-link", metavar="LINK", help="end-effector link (default: deepest active link)")
    g.add_argument("--mesh-dir", metavar="DIR", help="directory resolving package:// mesh paths")
    g.add_argument("--mesh-urdf", metavar="URDF",
                   help="URDF whose collision meshes validate the returned trajectories (default with "
                        "--robot URDF: that URDF when it has mesh or primitive collisions, else X.urdf beside "
                        "a spherized X_spherized.urdf, MotionBenchMaker's layout; --robot mbm: its panda.urdf)")


def _add_solver_options(p: argparse.ArgumentParser, methods_nargs: Optional[str] = None) -> None:
    g = p.add_argument_group("solver (GFCS Alg. 1)")
    if methods_nargs:
        g.add_argument("--method", nargs=methods_nargs, choices=["gfcs", "gf"], default=["gf", "gfcs"],
                       help="methods to run, in table order (default: gf gfcs)")
    else:
        g.add_argument("--method", choices=["gfcs", "gf"], default="gfcs",
                       help="gfcs: optimise commands with CMA-ES; gf: local fabric only (default gfcs)")
    g.add_argument("--batches", type=_integer(1), default=5, help="CMA-ES batches (default 5)")
    g.add_argument("--population", type=_integer(2), default=32, help="candidates per batch (default 32)")
    g.add_argument("--commands", type=_integer(0), default=1,
                   help="free commands n before the goal (default 1)")
    g.add_argument("--seed", type=_integer(0), default=0, help="optimiser seed (default 0)")
    g.add_argument("--threads", type=_integer(1), default=None,
                   help="worker threads (default: all cores; at most 4 x the cores are used)")
    g.add_argument("--config", metavar="FILE", help="fabric configuration (TOML, YAML or JSON)")
    g.add_argument("--preset", choices=["default", "paper"], default="default",
                   help="planner preset: default (the shipped planner: approach warm start, command blend, "
                        "shortest-hand-path and mesh-validated choice, finished trajectories, thin then "
                        "covering spheres, every retry) or paper (GFCS as written: uniform first batch, "
                        "lowest cost of eq. 4, command switch, the paper's barriers, no retries, no "
                        "post-processing); recorded in every result (default: default)")
    g.add_argument("--time-limit", type=float, metavar="S", default=5.0,
                   help="time budget of each solve in s: the best motion found within it is returned (default "
                        "5; 0: no limit)")
    g.add_argument("--sampler", metavar="approach|uniform|MODEL.pt", default=None,
                   help="warm-start sampler: approach (half the first batch at the goal's approach corridor, "
                        "half with the hand pulled in toward the base), uniform (the paper's), or a model "
                        "trained by `gfcs train` (needs torch); default: the preset's (approach / uniform)")
    g.add_argument("--sgld-noise", type=float, metavar="TAU",
                   help="with --sampler MODEL.pt: SGLD noise scale of the sampler (default: the model "
                        "file's; 1 is the paper's eq. 10-11)")
    g.add_argument("--length-slack", type=float, metavar="EPS", default=None,
                   help="prefer the shortest hand path among reached candidates within (1 + EPS) x the "
                        "lowest cost (default: the preset's, 0.1 / 0; 0: the lowest-cost candidate, eq. 4)")
    g.add_argument("--mesh-margin", type=float, metavar="M", default=None,
                   help="clearance in m the collision meshes must keep for a motion to succeed, when a mesh "
                        "model validates it (default 0.001; 0: contact only)")
    g.add_argument("--no-retry", action="store_true",
                   help="run no retry policy (gfcs.planning.policies: one more command, a wider obstacle "
                        "margin after a mesh-only collision, the goal-contact attempt, the covering spheres "
                        "after the thin ones): the first attempt is returned")
    r = p.add_argument_group("rollout (GFCS eq. 1-8)")
    r.add_argument("--dt", type=float, default=None, help="integration step, s (default 0.01)")
    r.add_argument("--t-max", type=float, default=None, help="time budget per command, s (default 7)")
    r.add_argument("--tol", type=float, default=None,
                   help="goal tolerance, rad (default: the preset's, 0.02 / 0.01)")
    r.add_argument("--waypoint-tol", type=float, default=None, help="tolerance of intermediate commands, rad")
    r.add_argument("--limit-hold-off", type=float, default=None, metavar="RAD",
                   help="a goal joint nearer its limit than the barrier margin plus this is commanded that far "
                        "off it and blended onto the goal, rad (default: the preset's: 0.015; the paper preset "
                        "commands every goal as it is)")
    r.add_argument("--integrator", choices=["euler", "rk4"], default=None, help="integrator (default euler)")
    r.add_argument("--no-acceleration-limits", action="store_true",
                   help="keep the fabric's own timing where it is within the velocity limits (default: "
                        "re-timed along the same path within the robot's known joint acceleration limits: "
                        "its profile's, --joint-limits' or --acceleration-limits'); the URDF velocity limits "
                        "always hold")
    r.add_argument("--joint-limits", metavar="YAML", default=None,
                   help="MoveIt joint_limits.yaml: its max_velocity tightens the URDF's, its max_acceleration "
                        "sets the acceleration limits of the re-timing")
    r.add_argument("--acceleration-limits", type=float, nargs="+", metavar="A", default=None,
                   help="acceleration limit of each active joint in order, rad/s^2 or m/s^2 (one value: all "
                        "joints); replaces the profile's and --joint-limits'")


def _joint_limit_settings(args: argparse.Namespace, robot: Any) -> Dict[str, Any]:
    """``velocity_limits`` / ``acceleration_limits`` of the finishing options from --joint-limits and
    --acceleration-limits (inf where a joint has none); {} when neither is given."""
    from gfcs.errors import InvalidValueError
    from gfcs.profile import read_joint_limits_yaml

    out: Dict[str, Any] = {}
    names = list(robot.joint_names)
    if args.joint_limits is not None:
        table = read_joint_limits_yaml(args.joint_limits)
        out["velocity_limits"] = tuple(table.velocity_limits.get(j, math.inf) for j in names)
        out["acceleration_limits"] = tuple(table.acceleration_limits.get(j, math.inf) for j in names)
    if args.acceleration_limits is not None:
        values = list(args.acceleration_limits)
        if len(values) == 1:
            values *= len(names)
        if len(values) != len(names) or not all(math.isfinite(a) and a > 0 for a in values):
            raise InvalidValueError(f"--acceleration-limits: expected 1 or {len(names)} finite values > 0 "
                                    f"(joints {', '.join(names)}), got {args.acceleration_limits}")
        out["acceleration_limits"] = tuple(values)
    return out


def _settings(args: argparse.Namespace) -> Any:
    """The preset's rollout settings with the options given on the command line."""
    from gfcs.planning import get_preset

    given = {"dt": args.dt, "t_max": args.t_max, "integrator": args.integrator, "tol": args.tol,
             "waypoint_tol": args.waypoint_tol, "limit_hold_off": args.limit_hold_off}
    return dataclasses.replace(get_preset(args.preset).settings, **{k: v for k, v in given.items() if v is not None})


def _finish(args: argparse.Namespace, robot: Any) -> Any:
    """The preset's finishing options with the limits of --joint-limits / --acceleration-limits, and without
    the acceleration re-timing for --no-acceleration-limits."""
    from gfcs.planning import get_preset

    finish = dataclasses.replace(get_preset(args.preset).finish, **_joint_limit_settings(args, robot))
    return dataclasses.replace(finish, limit_acceleration=False) if args.no_acceleration_limits else finish


def _solve_options(args: argparse.Namespace, robot: Any) -> Dict[str, Any]:
    """Keyword arguments of :func:`gfcs.planning.solve` from the command line: preset, time budget, rollout
    and finishing options, and the selection options given (others: the preset's)."""
    from gfcs.errors import InvalidValueError

    if not (math.isfinite(args.time_limit) and args.time_limit >= 0):
        raise InvalidValueError(f"--time-limit must be a number of seconds ≥ 0 (0: no limit), got {args.time_limit}")
    given = {"length_slack": args.length_slack, "mesh_margin": args.mesh_margin}
    return {"preset": args.preset, "time_limit": args.time_limit or None, "settings": _settings(args),
            "finish": _finish(args, robot), **{k: v for k, v in given.items() if v is not None}}


def _robot(args: argparse.Namespace) -> Any:
    import gfcs

    if args.robot is None or args.robot == "mbm":
        if args.srdf or args.spheres or args.ee_link or args.mesh_dir or getattr(args, "group", None):
            raise ValueError("--srdf/--group/--spheres/--ee-link/--mesh-dir need --robot URDF")
        if args.robot == "mbm":
            from gfcs.problems import mbm_panda

            return mbm_panda()
        return gfcs.Robot.panda()
    from gfcs.problems import spherized_urdf_for, with_gap_spheres, with_shipped_panda_spheres

    group = _group_name(args)
    if group is not None:  # the group's joints active, its first tip the end effector (unless --ee-link)
        from gfcs.srdf_groups import robot_for_group

        robot, args.group_tips = robot_for_group(args.robot, args.srdf, group, mesh_dir=args.mesh_dir,
                                                 spheres=args.spheres,
                                                 **({"ee_link": args.ee_link} if args.ee_link else {}))
    else:
        robot = gfcs.Robot.from_urdf(args.robot, ee_link=args.ee_link, mesh_dir=args.mesh_dir,
                                     srdf=args.srdf, spheres=args.spheres)
    sibling = spherized_urdf_for(args.robot) if len(robot.sphere_radii) == 0 else None
    if sibling is not None:  # a mesh model with its spherized twin beside it (MotionBenchMaker's panda.urdf)
        twin = gfcs.Robot.from_urdf(sibling, ee_link=robot.ee_link, active_joints=list(robot.joint_names),
                                    mesh_dir=args.mesh_dir)
        robot = robot.with_spheres(list(zip(twin.sphere_links, twin.sphere_centers_local, twin.sphere_radii)))
        print(f"gfcs: {args.robot} has no collision spheres; the fabric uses those of {sibling}",
              file=sys.stderr)
    shipped = with_shipped_panda_spheres(robot, args.srdf)
    if shipped is not None:  # a Panda description with meshes only (e.g. franka_description's)
        print(f"gfcs: {args.robot} has no collision spheres; its links move as the shipped Panda's, so the "
              "fabric uses the shipped Panda's spheres (they cover the Franka collision meshes)", file=sys.stderr)
        return shipped
    return with_gap_spheres(robot)  # MotionBenchMaker's panda_spherized.urdf gets --robot mbm's spheres


def _group_name(args: argparse.Namespace) -> Optional[str]:
    """The SRDF group to plan for: ``--group``, else with ``--srdf`` the ``group_name`` of the problems'
    first request (``--request``, or the first of ``--problems`` in suite order), as MoveIt plans the
    request's group; None without an SRDF or a request naming a group (the robot's default joints)."""
    import gfcs
    from gfcs import problems

    if getattr(args, "group", None):
        if not args.srdf:
            raise ValueError("--group needs --srdf (the SRDF defines the groups)")
        return str(args.group)
    if not args.srdf:
        return None
    request = getattr(args, "request", None)
    folder = getattr(args, "problems", None)
    if not request and folder and Path(folder).is_dir():
        wanted = set()
        for c in getattr(args, "classes", None) or []:
            wanted.add(str(c))
            try:
                wanted.add(problems.canonical_class(c))
            except ValueError:
                pass
        firsts = (sorted(d.glob("request*.y*ml")) for d in problems._class_dirs(Path(folder))
                  if not wanted or d.name in wanted)
        request = next((found[0] for found in firsts if found), None)
    if not request:
        return None
    return gfcs.load_motion_plan_request(str(request)).get("group") or None


def _with_mesh_checker(args: argparse.Namespace, suite: List[Any]) -> List[Any]:
    """The problems with the mesh checker of ``--mesh-urdf`` (or the one found for ``--robot URDF``, see
    :func:`gfcs.problems.mesh_urdf_for`); unchanged when there is none (the shipped Panda, whose problems
    carry its collision polytopes, or a sphere-only robot file). For a robot built for an SRDF group
    (:func:`_robot`) each problem's ``meta["ee_links"]`` holds the group's tips, whose paths the metrics
    report."""
    from gfcs import problems

    tips = getattr(args, "group_tips", None)
    if tips:
        suite = [dataclasses.replace(p, meta={**p.meta, "ee_links": list(tips)}) for p in suite]
    urdf = args.mesh_urdf
    if urdf is None and args.robot not in (None, "mbm"):
        urdf = problems.mesh_urdf_for(args.robot)
    if urdf is None or not suite:
        return suite
    checker = problems.urdf_mesh_checker(urdf, suite[0].robot, mesh_dir=args.mesh_dir, srdf=args.srdf)
    return [dataclasses.replace(p, mesh_checker=problems.held_as_requested(checker, p.meta.get("start_state", {})))
            for p in suite]


def _sampler(args: argparse.Namespace) -> Any:
    from gfcs.planning import ApproachSampler, UniformSampler

    if args.sampler in (None, "approach", "uniform"):
        if args.sgld_noise is not None:
            raise ValueError("--sgld-noise needs --sampler MODEL.pt")
        preset_sampler = "approach" if args.preset == "default" else "uniform"
        if args.sampler in (None, preset_sampler):
            return None  # the preset's own sampler, which the more-commands policy can widen
        return UniformSampler(args.commands) if args.sampler == "uniform" else ApproachSampler(args.commands)
    try:
        from gfcs.learning.sampler import EBMSampler
    except ImportError as e:
        raise _MissingExtra(f"--sampler needs the 'learn' extra (pip install 'gfcs[learn]'): {e}") from e
    sampler = EBMSampler(args.sampler)
    if args.sgld_noise is not None:
        sampler.sgld_config = sampler.sgld_config.with_noise(args.sgld_noise)
    return sampler


class _MissingExtra(Exception):
    """An optional dependency needed by the requested command is not installed."""


# --------------------------------------------------------------------------------------------- solve
def _fmt(v: float, unit: str = "", digits: int = 3) -> str:
    return "NA" if v is None or not math.isfinite(v) else f"{v:.{digits}g}{unit}"


def _endpoint_hints(result: Any, problem: Any) -> List[str]:
    """Lines explaining a failure by the problem itself, under the robot's collision-sphere model: a start
    in collision (every motion from it collides), or a goal closer to the obstacles than the fabric's margin
    (the barrier keeps the arm out, so no motion reaches it)."""
    import gfcs
    from gfcs import metrics
    from gfcs.results import planned_robot

    config = gfcs.FabricConfig.from_dict(result.fabric_config) if result.fabric_config else gfcs.FabricConfig()
    margin = float(config.to_dict()["obstacles"]["margin"])
    lines = []
    planned = planned_robot(result, problem)  # the thin spheres, when solve planned on them
    for what, q, limit, why in (
            ("start", problem.q0, 0.0, "every motion from it collides under this model"),
            ("goal", problem.goal, margin, f"the fabric keeps {margin * 1000:.3g} mm, so no motion reaches it")):
        clearance = float(metrics.obstacle_clearance(planned, problem.scene, q[None])[0])
        if clearance < limit:
            where = (f"overlap the obstacles by {-clearance * 1000:.2f} mm" if clearance < 0
                     else f"are {clearance * 1000:.2f} mm from the obstacles")
            remedy = "a model with tighter spheres may do"
            if what == "goal" and getattr(problem, "mesh_checker", None) is None:
                remedy += ", or one with collision meshes: solve then tries the goal's own contact"
            lines.append(f"hint      the {what}'s collision spheres {where}: {why} ({remedy})")
    return lines


def _pose_goal_line(result: Any, problem: Any) -> str:
    """The summary line of a pose goal: the constraints and how far the returned motion's end is from them."""
    import numpy as np

    from gfcs import pose_goal

    g = result.pose_goal
    o = g.get("orientation")
    text = (f"pose goal {g['link']} point {np.round(pose_goal.target_point(g), 4).tolist()} m"
            + (f", orientation within {np.round(o['tolerance'], 4).tolist()} rad" if o else "")
            + ": joint goal by inverse kinematics")
    q = np.asarray(result.trajectory.q, dtype=np.float64)
    if q.shape[0]:
        err = pose_goal.pose_errors(problem.robot, g, q[-1])
        text += f"; the motion ends {_fmt(err[0], ' m')} outside the region, {_fmt(err[1], ' rad')} beyond the tolerances"
    return text


def _attempts_line(result: Any) -> str:
    """What the solve tried, in order: each attempt's label, outcome and time (``result.attempts``)."""
    budget = f" (time limit {result.time_limit:g} s)" if result.time_limit else ""
    tried = "; ".join(f"{a['label']}: {a['outcome']}" + (f" {a['time']:.2f} s" if a["outcome"] != "not run" else "")
                      for a in result.attempts)
    return f"attempts  {tried or 'none (gf)'}{budget}"


def summary_text(result: Any, problem: Any) -> str:
    """A short human summary of a :class:`gfcs.results.SolveResult`."""
    m = result.metrics
    lines = [
        f"problem   {problem.name} ({problem.cls or 'unclassified'}), {problem.robot.name} "
        f"{problem.robot.dof} dof, {len(problem.scene)} obstacles",
    ]
    if result.method == "gfcs":
        st = result.settings
        lines.append(f"method    gfcs: {st.get('batches')} batches x {st.get('population')} candidates, "
                     f"{result.n_commands} free command(s), seed {result.seed}")
    else:
        lines.append("method    gf: local geometric fabric toward the goal")
    if result.settings.get("sphere_model") == "thin":
        margin = result.fabric_config["obstacles"]["margin"] if result.fabric_config else None
        lines.append("spheres   the shipped Panda's thin spheres (links 5-7, hand; gfcs.problems.thin_sphere_model)"
                     + (f", obstacle margin {margin * 1000:.0f} mm" if margin is not None else ""))
    if result.pose_goal is not None:
        lines.append(_pose_goal_line(result, problem))
    t_stars = " + ".join(f"{t:.2f}" for t in result.t_stars)
    contact = result.settings.get("goal_contact")
    floor = contact["clearance_floor"] if contact else 0.0
    mesh_margin = float(result.settings.get("mesh_margin", 0.0))
    why = [text for bad, text in ((not result.reached, "goal not reached"),
                                  (m["min_clearance"] < floor, "collision with obstacles"),
                                  (m["min_self_clearance"] < 0, "self-collision"),
                                  (not m["within_limits"], "joint limits violated"),
                                  (m.get("mesh_clearance", math.inf) <= mesh_margin,
                                   "mesh collision with obstacles"),
                                  (m.get("mesh_self_clearance", math.inf) <= mesh_margin, "mesh self-collision"),
                                  (m.get("velocity_ratio", 0.0) > 1.0 + 1e-6, "velocity limits exceeded"),
                                  (not m.get("mesh_check_complete", True),
                                   "mesh check not finished within the time limit"))
           if bad]
    verdict = "SUCCESS" if result.success else f"FAILURE ({', '.join(why) or 'goal tolerance'})"
    lines.append(f"result    {verdict}: cost {_fmt(result.cost, ' s')} "
                 f"(t* = {t_stars} s), goal error {_fmt(m['final_error'], ' rad')}, "
                 f"reached {result.reached}")
    if contact:
        lines.append(f"contact   the goal's collision spheres come within the fabric's margin of the obstacles: "
                     f"solved with those spheres' margins lowered to the goal's, spheres allowed down to "
                     f"{floor * 1000:.2f} mm, the collision meshes judging the contact")
    if not result.success:
        lines.extend(_endpoint_hints(result, problem))
    if len(result.attempts) > 1 or not result.success:
        lines.append(_attempts_line(result))
    lines.append(f"quality   EE length {_fmt(m['ee_length'], ' m')}, C-space length "
                 f"{_fmt(m['cspace_length'], ' rad')}, EE-LDJ {_fmt(m['ee_ldj'])}, C-space-LDJ "
                 f"{_fmt(m['cspace_ldj'])}, min clearance {_fmt(m['min_clearance'], ' m')}")
    if "mesh_clearance" in m:
        from gfcs.metrics import MESH_REPORT_RANGE

        # clearances beyond the exactly measured range are reported as inf (gfcs.metrics.mesh_check)
        beyond = f"over {(mesh_margin + MESH_REPORT_RANGE) * 1000:.3g} mm"

        def clearance(v: float) -> str:
            return beyond if v == math.inf else _fmt(v, " m")

        lines.append(f"checked   collision meshes: min clearance {clearance(m['mesh_clearance'])} to obstacles, "
                     f"{clearance(m['mesh_self_clearance'])} between links")
    else:
        lines.append("checked   collision spheres only (no collision-mesh model of this robot; --mesh-urdf adds one)")
    timing = f"time      {result.solve_time:.2f} s"
    if result.method == "gfcs" and len(result.batch_times):
        costs = " ".join(f"{c:.3g}" for c in result.batch_best_costs)
        timing += f" optimisation (batch 1: {result.batch_times[0]:.2f} s); best cost per batch: {costs}"
    lines.append(timing + f"; {result.wall_time:.2f} s in all (with the rollout and validation of the motion)")
    return "\n".join(lines)


def _solve_problem(args: argparse.Namespace) -> Any:
    from gfcs import generators, problems

    robot = _robot(args)
    if args.scene or args.request:
        if not (args.scene and args.request):
            raise ValueError("--scene and --request go together")
        suite = [problems.load_mbm(args.scene, args.request, robot=robot)]
    else:
        suite = generators.generate(args.problem_class, 1, seed=args.problem_seed, robot=robot)[:1]
    return _with_mesh_checker(args, suite)[0]


def _write_json(text: str, target: str) -> None:
    if target == "-":
        sys.stdout.write(text + "\n")
    else:
        Path(target).write_text(text + "\n")


def _viz() -> Any:
    """``gfcs.viz`` (imports rerun), or a one-line error naming the extra."""
    try:
        from gfcs import viz
    except ImportError as e:
        raise _MissingExtra(f"--rrd needs the 'viz' extra (pip install 'gfcs[viz]'): {e}") from e
    return viz


def _record(problem: Any, results: Any, path: str) -> None:
    _viz().record(problem, results, path)


def _no_retry() -> Dict[str, Any]:
    """Keyword arguments of :func:`gfcs.planning.solve` that turn all of its retries off: no policy."""
    return {"policies": []}


def cmd_solve(args: argparse.Namespace) -> int:
    """`gfcs solve`: exit 0 when the problem is solved, 1 when not."""
    from gfcs import planning

    _writable_file(args.json, "--json")
    _writable_file(args.rrd, "--rrd")
    if args.rrd:
        _viz()  # fail before solving when the extra is missing
    problem = _solve_problem(args)
    result = planning.solve(
        problem, method=args.method, batches=args.batches, population=args.population,
        n_commands=args.commands, seed=args.seed, sampler=_sampler(args), fabric_config=args.config,
        threads=args.threads, progress=args.progress,
        **(_no_retry() if args.no_retry and args.method == "gfcs" else {}),
        **_solve_options(args, problem.robot),
    )
    text = summary_text(result, problem)
    if args.json:
        _write_json(result.to_json(include_trajectory=not args.no_trajectory), args.json)
    print(text, file=sys.stderr if args.json == "-" else sys.stdout)
    if args.rrd:
        _record(problem, result, args.rrd)
    return 0 if result.success else 1


def _register_solve(sub: Any) -> None:
    p = sub.add_parser(
        "solve", help="solve one motion problem with GFCS (or the GF baseline)",
        description="Solve one problem: a MotionBenchMaker scene + request (--scene/--request), or a "
                    "built-in generated problem (default). Prints a short summary; exit code 0 on "
                    "success, 1 when the problem was not solved, 2 on a user error.",
    )
    src = p.add_argument_group("problem (default: a generated problem)")
    src.add_argument("--scene", metavar="S.yaml", help="MoveIt planning scene (MotionBenchMaker sceneNNNN.yaml)")
    src.add_argument("--request", metavar="R.yaml",
                     help="MoveIt motion plan request (requestNNNN.yaml): a joint goal, or a link pose "
                          "(position and orientation constraints), turned into a joint goal by IK")
    src.add_argument("--class", dest="problem_class", default=DEFAULT_DEMO_CLASS,
                     help=f"class of the generated problem (default {DEFAULT_DEMO_CLASS})")
    src.add_argument("--problem-seed", type=_integer(0), default=0,
                     help="seed of the generated problem (default 0)")
    _add_robot_options(p)
    _add_solver_options(p)
    out = p.add_argument_group("output")
    out.add_argument("--json", metavar="OUT.json", help="write the result as JSON ('-': stdout, summary to stderr)")
    out.add_argument("--no-trajectory", action="store_true", help="leave the trajectory out of the JSON")
    out.add_argument("--rrd", metavar="OUT.rrd", help="write a rerun recording (needs the viz extra)")
    out.add_argument("--progress", action="store_true", help="progress bar over the batches")
    p.set_defaults(func=cmd_solve)


# --------------------------------------------------------------------------------------------- bench
def load_mbm_suite(folder: str, classes: Optional[Sequence[str]], limit: Optional[int], robot: Any,
                   skip: int = 0, left_out: Optional[List[Tuple[str, str]]] = None) -> List[Any]:
    """:func:`gfcs.problems.load_mbm_dir`, leaving out (and listing on stderr) the problems that cannot be
    loaded (a malformed file) or whose start or goal lies outside the robot's joint limits: one such
    problem does not stop a whole suite.

    Args:
        left_out: when a list, (problem name, reason) of each problem left out is appended to it.
    """
    from gfcs import problems

    invalid: List[Tuple[str, str]] = []
    suite = problems.load_mbm_dir(folder, classes=classes, limit=limit, robot=robot, skip=skip, invalid=invalid)
    if invalid:
        print(f"gfcs: left out {len(invalid)} problem(s) not valid for this robot or not loadable:", file=sys.stderr)
        for _, message in invalid:
            print(f"  {message}", file=sys.stderr)
    if left_out is not None:
        left_out.extend(invalid)
    return suite


def load_problems(args: argparse.Namespace, robot: Any,
                  left_out: Optional[List[Tuple[str, str]]] = None) -> List[Any]:
    """The suite of ``gfcs bench``: a MotionBenchMaker folder, or generated problems (``left_out``: see
    :func:`load_mbm_suite`; a generated suite leaves none out)."""
    from gfcs import generators, problems

    if args.problems:
        return load_mbm_suite(args.problems, args.classes, args.limit, robot, args.skip, left_out)
    classes = args.classes or list(problems.CLASSES)
    n = args.limit if args.limit is not None else 10
    suite: List[Any] = []
    for c in classes:
        suite.extend(generators.generate(c, n, seed=args.problem_seed, robot=robot))
    return suite


def bench_problem(problem: Any, methods: Sequence[str], batches: int, population: int, seed: int,
                  n_commands: int = 1, sampler: Any = None, fabric_config: Any = None,
                  threads: Optional[int] = None, settings: Any = None,
                  retry: bool = True, solve_options: Optional[Dict[str, Any]] = None,
                  ) -> Tuple[List[Dict[str, Any]], List[Any]]:
    """Rows (:func:`gfcs.results.bench_row`) and results of the methods on one problem, one solve each.

    GFCS yields the paper's Table I rows from the solve's attempt records: "Ours (1 b)" (what its first
    attempt held after one batch, selected and judged as a one-batch solve would: the same seed gives the
    same first batch) and "Ours (B b)" (its first attempt after all B batches: a solve without retries);
    with ``retry`` and a preset that has retry policies a third row, "Ours (B b, retry)", is what the solve
    returned (time: every attempt). GF yields "GF". ``solve_options``: further keyword arguments of
    :func:`gfcs.planning.solve` for every method (e.g. ``preset``, ``time_limit``, ``mesh_margin``; GF
    ignores the GFCS-only ones such as ``length_slack``).
    """
    from gfcs import planning
    from gfcs.results import bench_row

    options = {"settings": settings, **(solve_options or {})}
    has_policies = bool(planning.get_preset(options.get("preset", "default")).policies())
    rows: List[Dict[str, Any]] = []
    results: List[Any] = []
    for method in methods:
        gfcs_only = {"record_first_batch": batches > 1, **({} if retry else _no_retry())} if method == "gfcs" else {}
        res = planning.solve(problem, method=method, batches=batches, population=population, n_commands=n_commands,
                             seed=seed, sampler=sampler, fabric_config=fabric_config, threads=threads,
                             **gfcs_only, **options)
        results.append(res)
        if method == "gf":
            rows.append(bench_row(problem.name, problem.cls, "GF", "gf", 0, seed, res.solve_time,
                                  res.cost, res.metrics, res.wall_time))
            continue
        first = res.attempt_records[0]
        if batches > 1:
            one = first.first_batch
            rows.append(bench_row(problem.name, problem.cls, "Ours (1 b)", "gfcs", 1, seed,
                                  one.solve_time, one.cost, one.metrics, one.wall_time))
        rows.append(bench_row(problem.name, problem.cls, f"Ours ({batches} b)", "gfcs", batches, seed,
                              first.result.solve_time, first.result.cost, first.result.metrics, first.time))
        if retry and has_policies:
            rows.append(bench_row(problem.name, problem.cls, f"Ours ({batches} b, retry)", "gfcs", batches,
                                  seed, res.solve_time, res.cost, res.metrics, res.wall_time))
    return rows, results


def error_rows(problem: Any, methods: Sequence[str], batches: int, seed: int, message: str) -> List[Dict[str, Any]]:
    """The rows of a problem whose solve raised ``message``: one failed row per method (the labels of
    :func:`bench_problem`'s final rows), every measure NaN, with the error under ``"error"``."""
    from gfcs.results import bench_row

    metrics: Dict[str, Any] = {k: math.nan for k in ("ee_length", "cspace_length", "ee_ldj", "cspace_ldj",
                                                      "min_clearance", "final_error")}
    metrics["success"] = False
    rows = []
    for method in methods:
        label, n = ("GF", 0) if method == "gf" else (f"Ours ({batches} b)", batches)
        row = bench_row(problem.name, problem.cls, label, method, n, seed, math.nan, math.inf, metrics, math.nan)
        row["error"] = message
        rows.append(row)
    return rows


def run_bench(problems: Sequence[Any], methods: Sequence[str], batches: int = 5, population: int = 32,
              seed: int = 0, n_commands: int = 1, sampler: Any = None, fabric_config: Any = None,
              threads: Optional[int] = None, settings: Any = None, jsonl: Optional[str] = None,
              rrd_dir: Optional[str] = None, progress: bool = True, retry: bool = True,
              solve_options: Optional[Dict[str, Any]] = None,
              results_dir: Optional[str] = None,
              left_out: Sequence[Tuple[str, str]] = ()) -> List[Dict[str, Any]]:
    """Benchmark ``methods`` on ``problems``; rows are appended to ``jsonl`` as they are produced (rows:
    :func:`bench_problem`). With ``results_dir``, the returned result of every method on every problem
    (with its trajectory, as ``gfcs solve --json`` writes it) goes to ``<results_dir>/<class>_<NNNN>.<method>.json``,
    for validators of your own (e.g. ``tools/check_trajectories.py``). ``left_out``: (name, reason) of the
    suite's problems that were not run (:func:`load_mbm_suite`); each becomes a
    :func:`gfcs.results.left_out_row`, written first.

    Returns:
        All rows, the left-out ones first (see :mod:`gfcs.results` for the row format).
    """
    from tqdm.auto import tqdm

    from gfcs.results import _enc, left_out_row

    rows: List[Dict[str, Any]] = [left_out_row(name, reason) for name, reason in left_out]
    if rrd_dir:
        _viz()  # fail before the first problem when the extra is missing
    for folder in (rrd_dir, results_dir):
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
    out = open(jsonl, "w") if jsonl else None

    def write(new: List[Dict[str, Any]]) -> None:
        if out is not None:
            for r in new:
                out.write(json.dumps(_enc(r), allow_nan=False) + "\n")
            out.flush()

    try:
        write(rows)
        bar = tqdm(problems, desc="bench", unit="problem", disable=not progress)
        for problem in bar:
            bar.set_postfix_str(problem.name)
            try:
                new, results = bench_problem(problem, methods, batches, population, seed, n_commands, sampler,
                                             fabric_config, threads, settings, retry, solve_options)
            except _user_error_types() as e:  # one bad problem does not end the bench
                message = f"{type(e).__name__}: {_message(e)}"
                print(f"gfcs: bench: {problem.name}: {message}", file=sys.stderr)
                new, results = error_rows(problem, methods, batches, seed, message), []
            rows.extend(new)
            write(new)
            stem = problem.name.replace("/", "_")
            if rrd_dir:
                _record(problem, results, str(Path(rrd_dir) / (stem + ".rrd")))
            if results_dir:
                for res in results:
                    (Path(results_dir) / f"{stem}.{res.method}.json").write_text(res.to_json())
    finally:
        if out is not None:
            out.close()
    return rows


def cmd_bench(args: argparse.Namespace) -> int:
    """`gfcs bench`: run the suite, print the tables (and write rows / markdown)."""
    from gfcs.results import format_table, format_totals, summarize

    for path, option in ((args.json, "--json"), (args.markdown, "--markdown")):
        _writable_file(path, option)
    for path, option in ((args.rrd_dir, "--rrd-dir"), (args.results_dir, "--results-dir")):
        _writable_dir(path, option)
    robot = _robot(args)
    left_out: List[Tuple[str, str]] = []
    suite = _with_mesh_checker(args, load_problems(args, robot, left_out))
    rows = run_bench(suite, args.method, batches=args.batches, population=args.population, seed=args.seed,
                     n_commands=args.commands, sampler=_sampler(args), fabric_config=args.config,
                     threads=args.threads, jsonl=args.json, rrd_dir=args.rrd_dir,
                     progress=not args.no_progress, retry=not args.no_retry,
                     solve_options=_solve_options(args, robot), results_dir=args.results_dir, left_out=left_out)
    summary = summarize(rows)
    totals = format_totals(rows) if rows else ""
    print(format_table(summary, markdown=False) + "\n" + totals, end="")
    if args.markdown:
        Path(args.markdown).write_text(format_table(summary, markdown=True) + "\n" + totals)
    return 0


def _register_bench(sub: Any) -> None:
    p = sub.add_parser(
        "bench", help="benchmark GFCS and GF on a problem suite (GFCS Table I)",
        description="Run the methods over a MotionBenchMaker folder (--problems) or over generated "
                    "problems (default: --limit problems per class, 10 unless given), write one JSON row "
                    "per problem and method (--json), and print per-class tables in the layout of GFCS "
                    "Table I (mean ± std over successful problems).",
    )
    src = p.add_argument_group("problems")
    src.add_argument("--problems", metavar="DIR", help="MotionBenchMaker folder (class folders or one class)")
    src.add_argument("--classes", nargs="+", metavar="CLASS", help="only these classes")
    src.add_argument("--limit", type=_integer(1), help="problems per class (generated suite: default 10)")
    src.add_argument("--skip", type=_integer(0), default=0, help="leave out the first N problems of each class of "
                     "--problems (e.g. --skip 40: the test problems 41-50)")
    src.add_argument("--problem-seed", type=_integer(0), default=0, help="seed of a generated suite (default 0)")
    _add_robot_options(p)
    _add_solver_options(p, methods_nargs="+")
    out = p.add_argument_group("output")
    out.add_argument("--json", metavar="RESULTS.jsonl", help="write the rows as JSON lines")
    out.add_argument("--markdown", metavar="TABLE.md", help="write the tables as markdown")
    out.add_argument("--rrd-dir", metavar="DIR", help="write one rerun recording per problem (viz extra)")
    out.add_argument("--results-dir", metavar="DIR",
                     help="write every returned result with its trajectory (the JSON of gfcs solve --json) "
                          "as DIR/<class>_<NNNN>.<method>.json")
    out.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_bench)


# ------------------------------------------------------------------------------------------ generate
def cmd_generate(args: argparse.Namespace) -> int:
    """`gfcs generate`: write generated problems as MotionBenchMaker files."""
    from gfcs import generators, problems

    robot = _robot(args)
    classes = args.classes or list(problems.CLASSES)
    total = 0
    for c in classes:
        suite = generators.generate(c, args.n, seed=args.seed, robot=robot)
        generators.write_problems(suite, args.out, pose_goals=args.pose_goals)
        total += len(suite)
    print(f"wrote {total} problems ({', '.join(problems.canonical_class(c) for c in classes)}) to {args.out}")
    return 0


def _register_generate(sub: Any) -> None:
    p = sub.add_parser(
        "generate", help="write generated problems as MotionBenchMaker files",
        description="Generate seeded problems (see gfcs.generators) and write them as "
                    "<out>/<class>/sceneNNNN.yaml and requestNNNN.yaml.",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--classes", nargs="+", metavar="CLASS", help="classes (default: all)")
    p.add_argument("--n", type=_integer(1), default=10, help="problems per class (default 10)")
    p.add_argument("--seed", type=_integer(0), default=0, help="generator seed (default 0)")
    p.add_argument("--pose-goals", action="store_true",
                   help="write each goal as the hand TCP's pose (position within 1 mm, orientation within "
                        "0.01 rad; MoveIt position and orientation constraints) instead of joint positions")
    _add_robot_options(p)
    p.set_defaults(func=cmd_generate)


# -------------------------------------------------------------------------------- external commands
def _register_external(sub: Any, name: str, load: bool) -> None:
    """Register an external subcommand: the real parser when ``load``, else a lightweight stand-in."""
    modules, func_name, help_text, extra = EXTERNAL_COMMANDS[name]
    if load:
        errors = []
        for module_name in modules:
            try:
                module = importlib.import_module(module_name)
            except ImportError as e:
                missing = getattr(e, "name", None) or ""
                if missing == "gfcs" or missing.startswith("gfcs."):
                    extra = None  # the module itself is absent from this installation, not a dependency
                errors.append(f"{module_name}: {e}")
                continue
            register = getattr(module, func_name, None)
            if register is not None:
                register(sub)
                return
            errors.append(f"{module_name} has no {func_name}()")
        hint = f" (install the extra: pip install 'gfcs[{extra}]')" if extra else ""
        message = f"'gfcs {name}' is unavailable{hint}: {'; '.join(errors)}"

        def unavailable(args: argparse.Namespace) -> int:
            raise _MissingExtra(message)

        _stand_in(sub, name, help_text).set_defaults(func=unavailable)
    else:
        _stand_in(sub, name, help_text)


def _stand_in(sub: Any, name: str, help_text: str) -> argparse.ArgumentParser:
    """A parser that swallows every argument (its prefix character is never typed, so even ``--help`` is a
    plain word): listed in ``gfcs --help`` without importing the command's module."""
    p = sub.add_parser(name, help=help_text, add_help=False, prefix_chars="\x00")
    p.add_argument("rest", nargs="*")
    return p


def build_parser(argv: Optional[Sequence[str]] = None) -> argparse.ArgumentParser:
    """The ``gfcs`` parser. External commands are imported only when ``argv`` selects them."""
    parser = argparse.ArgumentParser(
        prog="gfcs",
        description="Geometric fabrics and Geometric Fabric Command Sequences: global and reactive "
                    "motion generation.",
    )
    try:
        from gfcs import __version__

        parser.add_argument("--version", action="version", version=f"gfcs {__version__}")
    except ImportError:  # pragma: no cover - extension not built
        pass
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _register_solve(sub)
    _register_bench(sub)
    _register_generate(sub)
    selected = next((a for a in (argv or []) if not a.startswith("-")), None)
    for name in EXTERNAL_COMMANDS:
        _register_external(sub, name, load=(name == selected))
    return parser


def _user_error_types() -> Tuple[type, ...]:
    types: List[type] = [OSError, ValueError, KeyError, _MissingExtra]
    try:
        from gfcs.errors import GfcsError

        types.insert(0, GfcsError)
    except ImportError:  # pragma: no cover
        pass
    return tuple(types)


def _message(e: BaseException) -> str:
    if isinstance(e, KeyError) and len(e.args) == 1:
        return str(e.args[0])
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        return f"{e.filename}: {e.strerror}"
    return str(e) or type(e).__name__


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``gfcs`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    errors = _user_error_types()
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        code = args.func(args)
        return int(code or 0)
    except BrokenPipeError:  # output piped into e.g. `head`: stop quietly (Python docs, signal notes)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except errors as e:
        if os.environ.get("GFCS_DEBUG"):
            raise
        print(f"gfcs: error: {_message(e)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("gfcs: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
