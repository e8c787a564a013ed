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
import math
import os
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from gfcs.errors import CollisionError, GenerationError, InvalidValueError

__all__ = [
    "main",
    "build_parser",
    "EXTERNAL_COMMANDS",
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
    "collision-matrix": (("gfcs.collision_matrix",), "register_cli",
                         "the SRDF collision matrix MoveIt Setup Assistant would write, for a bare URDF", None),
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
        raise InvalidValueError(f"{option} {path}: is a directory")
    if not folder.is_dir():
        raise InvalidValueError(f"{option} {path}: directory {folder} does not exist")
    if not os.access(folder, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise InvalidValueError(f"{option} {path}: not writable")


def _writable_dir(path: Optional[str], option: str) -> None:
    """``ValueError`` naming ``option`` unless ``path`` (a folder to create or fill; None: nothing to check)
    is a writable directory or can be created in one."""
    if path is None:
        return
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise InvalidValueError(f"{option} {path}: exists and is not a directory")
    existing = next((p for p in (target, *target.parents) if p.exists()), Path("."))
    if not os.access(existing, os.W_OK):
        raise InvalidValueError(f"{option} {path}: {existing} is not writable")


def _add_robot_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("robot (default: the shipped Panda)")
    g.add_argument("--robot", metavar="URDF",
                   help="robot URDF file, or 'mbm' for the MotionBenchMaker Panda of the shared data folder "
                        "(spherized URDF + SRDF; use it for MotionBenchMaker problems: their goals are "
                        "collision-free for its spheres); a URDF X.urdf without collision spheres (on some of "
                        "its links with collision geometry) takes those of X_spherized.urdf beside it")
    g.add_argument("--srdf", metavar="SRDF", help="SRDF whose disabled collisions prune self-collision pairs")
    g.add_argument("--group", metavar="NAME",
                   help="SRDF planning group to plan for: its joints move, the others are held at the request's "
                        "start values; the end effector is its first tip link, and the metrics report every tip's "
                        "path (default with --srdf: the group_name of the problems' first request)")
    g.add_argument("--spheres", metavar="JSON", help="collision sphere file (replaces URDF spheres)")
    g.add_argument("--ee-link", metavar="LINK",
                   help="end-effector link (default: the hand at the end of the robot's only moving branch, or of "
                        "its longest arm where it branches)")
    g.add_argument("--mesh-dir", metavar="DIR", help="directory resolving package:// mesh paths")
    g.add_argument("--mesh-urdf", metavar="URDF",
                   help="URDF whose collision meshes validate the returned trajectories (default with "
                        "--robot URDF: that URDF when it has mesh or primitive collisions, else X.urdf beside "
                        "a spherized X_spherized.urdf, MotionBenchMaker's layout; --robot mbm: its panda.urdf)")


def _add_solver_options(p: argparse.ArgumentParser, methods_nargs: Optional[str] = None) -> None:
    g = p.add_argument_group("solver (GFCS Alg. 1)")
    methods = ["gfcs", "gf", "rrtconnect", "biest", "bitstar"]
    baselines = ("rrtconnect, biest, bitstar: OMPL's sampling-based planners on the same collision spheres, "
                 "simplified and timed as MoveIt does (the baselines extra; docs/baselines.md)")
    if methods_nargs:
        g.add_argument("--method", nargs=methods_nargs, choices=methods, default=["gf", "gfcs"],
                       help=f"methods to run, in table order (default: gf gfcs); {baselines}")
        g.add_argument("--planner-time", type=float, nargs="+", metavar="S", default=[5.0],
                       help="planning time of the sampling-based methods in s, one row per value (e.g. 1.2 6; "
                            "default 5)")
    else:
        g.add_argument("--method", choices=methods, default="gfcs",
                       help=f"gfcs: optimise commands with CMA-ES; gf: local fabric only; {baselines} "
                            "(default gfcs)")
        g.add_argument("--planner-time", type=float, metavar="S", default=5.0,
                       help="planning time of a sampling-based method in s (default 5)")
    g.add_argument("--batches", type=_integer(1), default=5, help="CMA-ES batches (default 5)")
    g.add_argument("--population", type=_integer(2), default=32, help="candidates per batch (default 32)")
    g.add_argument("--stall-batches", type=_integer(0), default=None, metavar="K",
                   help="early stop: end an attempt's optimisation once K batches in a row lowered the best "
                        "cost by at most --stall-tol of it (default: the preset's, 0 = every batch runs)")
    g.add_argument("--stall-tol", type=float, default=0.01, metavar="R",
                   help="relative improvement under which batches count as stalled (default 0.01)")
    g.add_argument("--commands", type=_integer(0), default=1,
                   help="free commands n before the goal (default 1)")
    g.add_argument("--seed", type=_integer(0), default=0, help="optimiser seed (default 0)")
    g.add_argument("--threads", type=_integer(1), default=None,
                   help="Rayon worker threads of each solve (default: all cores, at most 4 x the cores are "
                        "used; gfcs bench/train --executor ray: 1, and each Ray task reserves that many CPUs)")
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
                   help="clearance in m the collision meshes must keep at every configuration of a motion "
                        "(states and the segments between them) for it to succeed, when a mesh model validates "
                        "it (default 1e-4; 0: contact only)")
    g.add_argument("--restarts", type=int, metavar="K", default=None,
                   help="after every other retry failed, start again up to K times with a fresh seed and twice "
                        "the population each time while the time budget lasts (IPOP-CMA-ES; default: the "
                        "preset's, 2 / none; 0: off)")
    g.add_argument("--selection-share", type=float, metavar="F", default=None,
                   help="share in (0, 1] of the time left that an attempt's candidate selection may spend while "
                        "another attempt would still fit after it (default: the preset's, 0.75 / 1; 1: up to the "
                        "end of the time budget)")
    g.add_argument("--no-mesh-repair", action="store_true",
                   help="do not repair candidates that failed only on the collision meshes (gfcs.planning.repair: "
                        "the path moved off its mesh contacts, re-timed and judged again; the default preset "
                        "repairs, the paper preset does not)")
    g.add_argument("--spheres-judge", action="store_true",
                   help="when a mesh model validates motions, require the collision spheres' clearances too "
                        "(the paper preset does; the default preset lets the meshes alone judge collisions, as "
                        "a mesh validator does)")
    g.add_argument("--no-retry", action="store_true",
                   help="run no retry policy (gfcs.planning.policies: one more command, a wider obstacle "
                        "margin after a mesh-only collision, the goal-contact attempt, the covering spheres "
                        "after the thin ones): the first attempt is returned")
    r = p.add_argument_group("rollout (GFCS eq. 1-8; defaults: the preset's, gfcs.planning.presets)")
    r.add_argument("--dt", type=float, default=None, help="integration step, s")
    r.add_argument("--t-max", type=float, default=None, help="time budget per command, s")
    r.add_argument("--tol", type=float, default=None, help="goal tolerance, rad")
    r.add_argument("--waypoint-tol", type=float, default=None, help="tolerance of intermediate commands, rad")
    r.add_argument("--capture-tol", type=float, default=None, metavar="RAD",
                   help="goal capture: a rollout that comes to rest this near the goal counts as reached and is "
                        "blended onto it, rad (0: off, the paper preset's)")
    r.add_argument("--limit-hold-off", type=float, default=None, metavar="RAD",
                   help="a goal joint nearer its limit than the barrier margin plus this is commanded that far "
                        "off it and blended onto the goal, rad (the paper preset commands every goal as it is)")
    r.add_argument("--integrator", choices=["euler", "rk4"], default=None, help="integrator")
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
             "waypoint_tol": args.waypoint_tol, "capture_tol": args.capture_tol,
             "limit_hold_off": args.limit_hold_off}
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

    if not (math.isfinite(args.time_limit) and args.time_limit >= 0):
        raise InvalidValueError(f"--time-limit must be a number of seconds ≥ 0 (0: no limit), got {args.time_limit}")
    given = {"length_slack": args.length_slack, "mesh_margin": args.mesh_margin,
             "stall_batches": args.stall_batches, "restarts": args.restarts,
             "selection_share": args.selection_share,
             "mesh_repair": False if args.no_mesh_repair else None,
             "spheres_judge": True if args.spheres_judge else None}
    return {"preset": args.preset, "time_limit": args.time_limit or None, "settings": _settings(args),
            "finish": _finish(args, robot), "stall_tol": args.stall_tol,
            **{k: v for k, v in given.items() if v is not None}}


def _robot(args: argparse.Namespace) -> Any:
    import gfcs

    if args.robot is None or args.robot == "mbm":
        if args.srdf or args.spheres or args.ee_link or args.mesh_dir or getattr(args, "group", None):
            raise InvalidValueError("--srdf/--group/--spheres/--ee-link/--mesh-dir need --robot URDF")
        if args.robot == "mbm":
            from gfcs.problems import mbm_panda

            return mbm_panda()
        return gfcs.Robot.panda()
    from gfcs.problems import (
        links_without_spheres,
        spherized_urdf_for,
        with_gap_spheres,
        with_shipped_panda_spheres,
    )

    group = _group_name(args)
    if group is not None:  # the group's joints active, its first tip the end effector (unless --ee-link)
        from gfcs.srdf_groups import robot_for_group

        robot, args.group_tips = robot_for_group(args.robot, args.srdf, group, mesh_dir=args.mesh_dir,
                                                 spheres=args.spheres,
                                                 **({"ee_link": args.ee_link} if args.ee_link else {}))
    else:
        robot = gfcs.Robot.from_urdf(args.robot, ee_link=args.ee_link, mesh_dir=args.mesh_dir,
                                     srdf=args.srdf, spheres=args.spheres)
    bare = links_without_spheres(robot)
    sibling = spherized_urdf_for(args.robot) if len(robot.sphere_radii) == 0 or bare else None
    if sibling is not None:  # a mesh model with its spherized twin beside it (MotionBenchMaker's panda.urdf)
        twin = gfcs.Robot.from_urdf(sibling, ee_link=robot.ee_link, active_joints=list(robot.joint_names),
                                    mesh_dir=args.mesh_dir)
        robot = robot.with_spheres(list(zip(twin.sphere_links, twin.sphere_centers_local, twin.sphere_radii)))
        where = f" on {', '.join(bare[:3])}{', ...' if len(bare) > 3 else ''}" if bare else ""
        print(f"gfcs: {args.robot} has no collision spheres{where}; the fabric uses those of {sibling}",
              file=sys.stderr)
    shipped = with_shipped_panda_spheres(robot, args.srdf)
    if shipped is not None:  # a Panda description with meshes only (e.g. franka_description's)
        print(f"gfcs: {args.robot} has no collision spheres; its links move as the shipped Panda's, so the "
              "fabric uses the shipped Panda's spheres (they cover the Franka collision meshes)", file=sys.stderr)
        return shipped
    bare = links_without_spheres(robot)
    if bare:  # a mesh description with no spheres of its own or beside it (most MoveIt robots)
        import time

        from gfcs.sphere_fit import with_fitted_spheres

        started = time.perf_counter()
        left_out: List[Tuple[str, str]] = []
        cached: List[str] = []
        # the meshes tell which overlapping spheres are the model's, not the robot's (sphere_fit.sphere_artefacts)
        fitted = with_fitted_spheres(robot, left_out=left_out, cached=cached,
                                     mesh_checker=lambda: _mesh_checker(args, robot))
        how = f"read from the cache {cached[0]} in" if cached else "in"
        pairs = f"; {len(left_out)} link pair(s) whose spheres always overlap, or overlap where the meshes are " \
                f"apart, are not self-checked " \
                f"({', '.join('/'.join(p) for p in left_out[:3])}{', ...' if len(left_out) > 3 else ''})" \
            if left_out else ""
        print(f"gfcs: {args.robot} has no collision spheres on {len(bare)} link(s) with collision geometry; the "
              f"fabric uses {len(fitted.sphere_radii) - len(robot.sphere_radii)} spheres fitted to their "
              f"geometry {how} {time.perf_counter() - started:.1f} s{pairs} (gfcs.sphere_fit; --spheres FILE for "
              "your own, tools/fit_spheres.py fits tighter ones; GFCS_CACHE_DIR=off refits)", file=sys.stderr)
        robot = fitted
    return with_gap_spheres(robot)  # MotionBenchMaker's panda_spherized.urdf gets --robot mbm's spheres


def _group_name(args: argparse.Namespace) -> Optional[str]:
    """The SRDF group to plan for: ``--group``, else with ``--srdf`` the ``group_name`` of the problems'
    first request (``--request``, or the first of ``--problems`` in suite order), as MoveIt plans the
    request's group; None without an SRDF, a request naming a group, or a group in the SRDF (the robot's
    default joints)."""
    import gfcs
    from gfcs import problems
    from gfcs.srdf_groups import read_srdf_groups

    if getattr(args, "group", None):
        if not args.srdf:
            raise InvalidValueError("--group needs --srdf (the SRDF defines the groups)")
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
    name = gfcs.load_motion_plan_request(str(request)).get("group") or None
    if name is not None and not read_srdf_groups(args.srdf):
        return None  # an SRDF of collision pairs only names no group: the request's group is the robot's joints
    return name


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
    checker = _mesh_checker(args, suite[0].robot) if suite else None
    if checker is None:
        return suite
    # the checker holds what the problem's robot holds (a generated problem's named states or --hold values),
    # and what the request's start state says
    return [dataclasses.replace(p, mesh_checker=problems.held_as_requested(
        checker, {**p.robot.locked_positions, **p.meta.get("start_state", {})})) for p in suite]


def _mesh_checker(args: argparse.Namespace, robot: Any) -> Any:
    """The mesh checker of ``--mesh-urdf`` (or of the URDF found for ``--robot URDF``,
    :func:`gfcs.problems.mesh_urdf_for`) for ``robot``, or None when there is none."""
    from gfcs import problems

    urdf = args.mesh_urdf
    if urdf is None and args.robot not in (None, "mbm"):
        urdf = problems.mesh_urdf_for(args.robot)
    if urdf is None:
        return None
    return problems.urdf_mesh_checker(urdf, robot, mesh_dir=args.mesh_dir, srdf=args.srdf)


def _sampler(args: argparse.Namespace) -> Any:
    from gfcs.planning import ApproachSampler, UniformSampler

    if args.sampler in (None, "approach", "uniform"):
        if args.sgld_noise is not None:
            raise InvalidValueError("--sgld-noise needs --sampler MODEL.pt")
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


def _baseline_lines(result: Any) -> List[str]:
    """The method line of a sampling-based plan, and why it failed when it did."""
    st = result.settings
    lines = [f"method    {st.get('planner', result.method)} (OMPL): planner time {st.get('planner_time', 0):g} s "
             f"(planning {st.get('plan_time', 0):.2f} s, simplification {st.get('simplify_time', 0):.2f} s), "
             f"segments checked every {st.get('check_step', math.nan):.4f} rad, seed {result.seed}"]
    if st.get("failure"):
        lines.append(f"planner   {st['failure']}")
    return lines


def summary_text(result: Any, problem: Any) -> str:
    """A short human summary of a :class:`gfcs.results.SolveResult`."""
    from gfcs.baselines import is_ompl_method

    m = result.metrics
    lines = [
        f"problem   {problem.name} ({problem.cls or 'unclassified'}), {problem.robot.name} "
        f"{problem.robot.dof} dof, {len(problem.scene)} obstacles",
    ]
    if result.method == "gfcs":
        st = result.settings
        lines.append(f"method    gfcs: {st.get('batches')} batches x {st.get('population')} candidates, "
                     f"{result.n_commands} free command(s), seed {result.seed}")
    elif is_ompl_method(result.method):
        lines.extend(_baseline_lines(result))
    else:
        lines.append("method    gf: local geometric fabric toward the goal")
    if result.settings.get("sphere_model") == "thin":
        margin = result.fabric_config["obstacles"]["margin"] if result.fabric_config else None
        lines.append("spheres   the shipped Panda's thin spheres (links 5-7, hand; gfcs.problems.thin_sphere_model)"
                     + (f", obstacle margin {margin * 1000:.0f} mm" if margin is not None else ""))
    elif result.settings.get("sphere_model") == "covering":
        lines.append(f"spheres   {len(result.settings.get('spheres', []))} covering spheres fitted to the collision "
                     "meshes (the robot's own leave them centimetres uncovered; gfcs.planning.models.covering_model)")
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
    if (len(result.attempts) > 1 or not result.success) and not is_ompl_method(result.method):
        lines.append(_attempts_line(result))
    lines.append(f"quality   EE length {_fmt(m['ee_length'], ' m')}, C-space length "
                 f"{_fmt(m['cspace_length'], ' rad')}, EE-LDJ {_fmt(m['ee_ldj'])}, C-space-LDJ "
                 f"{_fmt(m['cspace_ldj'])}, min clearance {_fmt(m['min_clearance'], ' m')}")
    if "mesh_clearance" in m:
        from gfcs.metrics import mesh_report_cutoff

        # clearances beyond the exactly measured range are reported as inf (gfcs.metrics.mesh_check)
        beyond = f"over {mesh_report_cutoff(mesh_margin) * 1000:.3g} mm"

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
            raise InvalidValueError("--scene and --request go together")
        suite = [problems.load_mbm(args.scene, args.request, robot=robot)]
    else:
        suite = generators.generate(args.problem_class, 1, seed=args.problem_seed,
                                    robot=_held_at_named_states(args, robot))[:1]
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


def _plan_baseline(args: argparse.Namespace, problem: Any) -> Any:
    """`gfcs solve --method rrtconnect|biest|bitstar`: :func:`gfcs.baselines.plan_ompl` with the preset's
    sphere model, the fabric configuration's margin, and the limits and mesh margin GFCS would keep."""
    from gfcs import planning
    from gfcs.baselines import plan_ompl

    options = _solve_options(args, problem.robot)
    extra = {"mesh_margin": options["mesh_margin"]} if "mesh_margin" in options else {}
    try:
        preset = planning.get_preset(args.preset)
        return plan_ompl(problem, args.method, args.planner_time, args.seed, thin_spheres=preset.thin_spheres,
                         element_spheres=preset.element_spheres, fabric_config=args.config,
                         finish=options["finish"], **extra)
    except ImportError as e:
        raise _MissingExtra(str(e)) from e


def cmd_solve(args: argparse.Namespace) -> int:
    """`gfcs solve`: exit 0 when the problem is solved, 1 when not."""
    from gfcs import planning
    from gfcs.baselines import is_ompl_method

    _writable_file(args.json, "--json")
    _writable_file(args.rrd, "--rrd")
    if args.rrd:
        _viz()  # fail before solving when the extra is missing
    problem = _solve_problem(args)
    if is_ompl_method(args.method):
        result = _plan_baseline(args, problem)
    else:
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
def bench_suite(args: argparse.Namespace, left_out: Optional[List[Tuple[str, str]]] = None) -> List[Any]:
    """The problems of ``gfcs bench``'s options, with their robot and mesh checker (``left_out``: see
    :func:`gfcs.bench.load_mbm_suite`). A module-level function of the options alone, so that Ray workers
    build the same suite from a :class:`gfcs.bench.Suite` of it."""
    from gfcs.bench import load_problems

    robot = _robot(args)
    return _with_mesh_checker(args, load_problems(args, robot if args.problems else _held_at_named_states(args, robot),
                                                  left_out))


def _planner_times(args: argparse.Namespace) -> List[float]:
    """--planner-time's values, checked (finite, > 0, no repeats), and OMPL importable when a sampling-based
    method is asked for."""
    from gfcs.baselines import is_ompl_method

    times = [float(t) for t in args.planner_time]
    if not all(math.isfinite(t) and t > 0 for t in times) or len(set(times)) != len(times):
        raise InvalidValueError(f"--planner-time: expected distinct numbers of seconds > 0, got {args.planner_time}")
    if any(is_ompl_method(m) for m in args.method):
        try:
            import ompl  # noqa: F401
        except ImportError as e:
            raise _MissingExtra(f"--method {' '.join(args.method)} needs the 'baselines' extra "
                                f"(pip install 'gfcs[baselines]'): {e}") from e
    return times


def cmd_bench(args: argparse.Namespace) -> int:
    """`gfcs bench`: run the suite, print the tables (and write rows / markdown)."""
    from gfcs.bench import Suite, run_bench, suite_problems
    from gfcs.executors import executor_from_args
    from gfcs.results import format_table, format_totals, summarize

    for path, option in ((args.json, "--json"), (args.markdown, "--markdown")):
        _writable_file(path, option)
    for path, option in ((args.rrd_dir, "--rrd-dir"), (args.results_dir, "--results-dir")):
        _writable_dir(path, option)
    if args.resume and not args.json:
        raise InvalidValueError("--resume needs --json (the rows of the run to resume)")
    left_out: List[Tuple[str, str]] = []
    problems = bench_suite(args, left_out)
    suite = Suite(bench_suite, (args,))
    suite_problems(suite, built=problems)  # the driver's copy: built once, with its messages
    robot = problems[0].robot if problems else _robot(args)
    with executor_from_args(args) as executor:
        rows = run_bench(suite, args.method, batches=args.batches, population=args.population, seed=args.seed,
                         planner_times=_planner_times(args),
                         n_commands=args.commands, sampler=_sampler(args), fabric_config=args.config,
                         threads=args.threads, jsonl=args.json, rrd_dir=args.rrd_dir,
                         progress=not args.no_progress, retry=not args.no_retry,
                         solve_options=_solve_options(args, robot), results_dir=args.results_dir,
                         left_out=left_out, executor=executor, resume=args.resume,
                         seeding="run" if args.same_seed else "problem")
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
                     help="write the motion behind every row with its trajectory (the JSON of gfcs solve --json) "
                          "as DIR/<class>_<NNNN>.<name>.json, the name in the row's 'result' (docs/moveit.md)")
    out.add_argument("--resume", action="store_true",
                     help="keep the problems already in --json (a row of every --method) and run the others, "
                          "appending their rows (with the same options as the first run)")
    out.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--same-seed", action="store_true",
                   help="solve every problem with --seed itself (default: with a seed derived from --seed and "
                        "the problem's name, gfcs.bench.problem_seed, recorded in each row)")
    from gfcs.executors import add_executor_options

    add_executor_options(p)
    p.set_defaults(func=cmd_bench)


# ------------------------------------------------------------------------------------------ generate
def _held_positions(items: Sequence[str], robot: Any) -> Dict[str, float]:
    """``--hold JOINT=VALUE ...`` as {joint: value}; InvalidValueError naming an item that is not
    JOINT=number or a joint the robot does not hold (an active joint, or no joint of the robot)."""
    held: Dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            held[name] = float(value) if sep and name else math.nan
        except ValueError:
            held[name] = math.nan
        if not math.isfinite(held[name]):
            raise InvalidValueError(f"--hold {item!r}: expected JOINT=VALUE with a finite number (rad or m)")
        if name not in robot.locked_positions:
            moved = "is planned (in the group)" if name in robot.joint_names else "is not a movable joint of the robot"
            raise InvalidValueError(f"--hold {item!r}: joint {name!r} {moved}; held joints: "
                                    f"{', '.join(sorted(robot.locked_positions)[:8]) or 'none'}")
    return held


def _named_holds(srdf: Optional[str], robot: Any, given: Dict[str, float]) -> Tuple[Dict[str, float], List[str]]:
    """Held positions from the SRDF's named states (``<group_state>``, e.g. a second arm's ``ready``): each
    joint the robot holds, not in ``given`` (``--hold``), takes its value in the first state that names it.
    Returns ({joint: value}, the states used as "group/name"). MoveIt's dual-arm configurations hold the other
    arm at such a state, where 0 in every joint can fold it into itself."""
    if not srdf:
        return {}, []
    from gfcs.srdf_groups import read_group_states

    held, used = {}, []
    for group, name, values in read_group_states(srdf):
        taken = {j: v for j, v in values.items()
                 if j in robot.locked_positions and j not in given and j not in held}
        if taken:
            held.update(taken)
            used.append(f"{group}/{name}")
    return held, used


def _held_at_named_states(args: argparse.Namespace, robot: Any, given: Optional[Dict[str, float]] = None) -> Any:
    """``robot`` holding its joints outside the group at the SRDF's named states (:func:`_named_holds`) and at
    ``given`` (``--hold``) for a generated problem (a request's start state sets them otherwise); stderr names
    the states used."""
    given = given or {}
    srdf = getattr(args, "srdf", None) if args.robot not in (None, "mbm") else None
    named, states = _named_holds(srdf, robot, given)
    if states:
        print(f"gfcs: held joints at the SRDF's named states {', '.join(states)} (--hold in gfcs generate overrides)",
              file=sys.stderr)
    return robot.with_locked_positions({**named, **given}) if named or given else robot


def cmd_generate(args: argparse.Namespace) -> int:
    """`gfcs generate`: write generated problems as MotionBenchMaker files."""
    from gfcs import generators, problems

    if not getattr(args, "group", None) and getattr(args, "srdf", None) and args.robot not in (None, "mbm"):
        args.group = _first_group_unless_exact(args)
    robot = _robot(args)  # built once: a mesh robot's spheres are fitted here
    robot = _held_at_named_states(args, robot, _held_positions(args.hold, robot))
    group = _planning_group(args, robot)
    checker = _mesh_checker(args, robot)
    if checker is not None:
        checker = problems.held_as_requested(checker, robot.locked_positions)
    classes = args.classes or list(problems.CLASSES)
    total, written = 0, []
    for c in classes:
        try:  # a class this robot cannot be given (its layouts are sized for a Panda-sized arm) ends alone
            suite = generators.generate(c, args.n, seed=args.seed, robot=robot, mesh_checker=checker)
        except GenerationError as e:
            print(f"gfcs: generate: {e}", file=sys.stderr)
            continue
        except CollisionError as e:  # held links in contact: every class would fail alike
            raise CollisionError(f"gfcs generate: {args.robot}: {e} (--hold JOINT=VALUE moves a held joint)") from None
        generators.write_problems(suite, args.out, pose_goals=args.pose_goals, group=group)
        total += len(suite)
        written.append(problems.canonical_class(c))
    print(f"wrote {total} problems ({', '.join(written)}) to {args.out}")
    return 0 if len(written) == len(classes) else 1


def _first_group_unless_exact(args: argparse.Namespace) -> Optional[str]:
    """For `gfcs generate --robot X.urdf --srdf S` without --group: None when a group of S moves exactly the
    robot's default joints (:func:`_planning_group` finds it), else S's first group, said on stderr (a gripper
    joint besides the arm's): a request must name a group of the SRDF."""
    import gfcs
    from gfcs.srdf_groups import group_of, read_srdf_groups

    joints = gfcs.Robot.from_urdf(args.robot, ee_link=args.ee_link, mesh_dir=args.mesh_dir).joint_names
    first = next(iter(read_srdf_groups(args.srdf)), None)
    if first is None or group_of(args.robot, args.srdf, joints) is not None:
        return None
    print(f"gfcs: generate: no group of {args.srdf} moves exactly {', '.join(joints)}; the problems are for its "
          f"first group, '{first}' (--group NAME for another)", file=sys.stderr)
    return first


def _planning_group(args: argparse.Namespace, robot: Any) -> Optional[str]:
    """The group_name of generated requests: --group, else the SRDF group (the shipped Panda's, or --srdf's on
    --robot) whose joints are the robot's, else None (the robot's name)."""
    import gfcs
    from gfcs.srdf_groups import group_of

    if getattr(args, "group", None):
        return str(args.group)
    if args.robot is None:
        return group_of(gfcs.panda_urdf(), gfcs.panda_srdf(), robot.joint_names)
    if args.robot == "mbm":
        from gfcs import problems

        folder = problems._mbm_folder(None)
        return group_of(str(folder / "panda_spherized.urdf"), str(folder / "panda.srdf"), robot.joint_names)
    return group_of(args.robot, args.srdf, robot.joint_names) if getattr(args, "srdf", None) else None


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
    p.add_argument("--hold", nargs="+", metavar="JOINT=VALUE", default=[],
                   help="hold joints outside the planned group at these positions (rad or m; default: the first "
                        "SRDF named state (group_state) naming the joint, else 0 clamped into the joint's limits); "
                        "written into every request's start state")
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
