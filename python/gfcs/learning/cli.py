"""The ``gfcs train`` subcommand: Algorithm 2 of GFCS from the command line.

``gfcs.cli`` calls :func:`register` with its ``argparse`` subparsers; the handler stored as
``args.func(args) -> int`` (exit code) imports torch only when it runs, so ``gfcs --help`` works without
torch. Examples::

    gfcs train --problems /path/to/mbm --classes table_under --out model.pt
    gfcs train --generate table_under --n-problems 50 --out model.pt --seed 0
    gfcs train --problems DIR --out model.pt --resume model.ckpt.pt
    gfcs solve --sampler model.pt ...      # warm start with the trained model
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, Dict, List, Tuple

__all__ = ["register", "run_train"]

#: CLI flag -> TrainConfig field, for the options that change the training (None default = not given).
_CONFIG_FLAGS = {
    "passes": "passes", "n_train": "n_train", "buffer": "buffer_size", "top_m": "top_m", "seed": "seed",
    "n_neg": "n_neg", "epochs": "epochs", "batch_size": "batch_size", "lr": "lr", "hidden": "hidden",
    "latent_dim": "latent_dim", "n_commands": "n_commands", "max_cost": "max_cost", "device": "device",
    "neg_refresh": "neg_refresh", "n_uniform_neg": "n_uniform_neg", "shuffle": "shuffle",
    "sample_noise": "sample_noise",
}


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``train`` subcommand to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser(
        "train",
        help="self-supervised training of the EBM sampler (GFCS Alg. 2)",
        description="Solve training problems with GFCS, keep the best solutions in a buffer, and train "
                    "an energy-based model on them (GFCS Sec. IV-B/C, Algorithm 2). The model file "
                    "(--out) is used by `gfcs solve/bench --sampler model.pt`. Defaults follow the "
                    "paper: 2 passes, training every 25 problems, buffer 200, top-4, lattice 0.15 m, "
                    "3 hidden layers of width 800.",
    )
    src = p.add_argument_group("problems (one of --problems / --generate)")
    src.add_argument("--problems", metavar="DIR", help="MotionBenchMaker directory (class folders with "
                     "sceneNNNN.yaml / requestNNNN.yaml)")
    src.add_argument("--generate", metavar="CLASS", nargs="+",
                     help="train on procedurally generated problems of these classes")
    src.add_argument("--n-problems", type=int, default=50, help="problems per generated class (default 50)")
    src.add_argument("--classes", nargs="+", metavar="CLASS", help="keep only these classes of --problems")
    src.add_argument("--limit", type=int, help="use at most this many problems per class of --problems")
    src.add_argument("--skip", type=int, default=0, help="leave out the first N problems of each class of "
                     "--problems")
    src.add_argument("--holdout", type=int, default=0, metavar="N",
                     help="hold the last N problems of each class out of training and score every trained "
                          "model on them (mean first-batch cost); the best is written to <out stem>.best.pt")
    from gfcs.cli import _add_robot_options, _integer

    _add_robot_options(p)
    p.add_argument("--out", required=True, metavar="MODEL.pt", help="model file to write")
    p.add_argument("--resume", metavar="CKPT", help="continue from a checkpoint (default checkpoint path: "
                   "<out stem>.ckpt.pt)")
    p.add_argument("--checkpoint", metavar="CKPT", help="checkpoint path to write")
    alg = p.add_argument_group("Algorithm 2 (omitted options keep the defaults, or the checkpoint's)")
    alg.add_argument("--passes", type=int, help="passes over the problems (default 2)")
    alg.add_argument("--n-train", type=int, help="train every N solved problems (default 25)")
    alg.add_argument("--buffer", type=int, help="buffer length (default 200)")
    alg.add_argument("--top-m", type=int, help="solutions per problem into the buffer (default 4)")
    alg.add_argument("--seed", type=int, help="master seed (default 0)")
    alg.add_argument("--n-neg", type=int, help="SGLD negatives per positive (default 16)")
    alg.add_argument("--n-uniform-neg", type=int, help="uniform negatives per positive (default 8)")
    alg.add_argument("--neg-refresh", type=int, help="redraw negatives every N epochs, 0 = once (default 10)")
    alg.add_argument("--negative-noise", type=float, metavar="TAU",
                     help="SGLD noise scale of the training negatives (default 1, the paper's eq. 10-11; 0.3 is the "
                          "project's variant, which concentrates them near the energy's minima)")
    alg.add_argument("--sample-noise", type=float, metavar="TAU",
                     help="SGLD noise scale of the sampler in the model file (default 1, the paper's)")
    alg.add_argument("--epochs", type=int, help="epochs per training (default 100)")
    alg.add_argument("--batch-size", type=int, help="positives per Adam step (default 64)")
    alg.add_argument("--lr", type=float, help="Adam learning rate (default 1e-3)")
    alg.add_argument("--hidden", type=int, nargs="+", help="hidden widths (default 800 800 800)")
    alg.add_argument("--latent-dim", type=int, help="autoencoder code length for the distance encoding")
    alg.add_argument("--n-commands", type=int, help="free commands per sequence (default 1)")
    alg.add_argument("--max-cost", type=float, help="keep only candidates with cost <= this (s)")
    alg.add_argument("--shuffle", action="store_const", const=True, help="seeded random problem order")
    alg.add_argument("--device", help="torch device (default: cuda if available, else cpu)")
    opt = p.add_argument_group("GFCS solves (gfcs.planning.solve, method gfcs)")
    opt.add_argument("--batches", type=int, help="CMA-ES batches per problem (default 5)")
    opt.add_argument("--population", type=int, help="candidates per batch (default 32)")
    opt.add_argument("--config", metavar="FILE", help="fabric configuration (TOML, YAML or JSON) of the solves")
    opt.add_argument("--preset", choices=["default", "paper"],
                     help="planner preset of the solves (gfcs.planning.presets; default: default), recorded in "
                          "the checkpoint's configuration")
    opt.add_argument("--threads", type=_integer(1), default=None,
                     help="Rayon worker threads of each solve (default: all cores; --executor ray: 1, and each "
                          "Ray task reserves that many CPUs)")
    from gfcs.executors import add_executor_options

    add_executor_options(p)
    p.add_argument("--history", metavar="JSON", help="write the training history (solves, losses) as JSON")
    p.add_argument("--plot", metavar="FIG.png", help="draw the solve costs, losses and validation scores "
                   "(as `gfcs plot HISTORY.json`)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run_train)
    return p


def _split_holdout(problems: List[Any], n: int) -> Tuple[List[Any], List[Any]]:
    """(training, validation): the last ``n`` problems of each class (``Problem.cls``) are validation."""
    from gfcs.errors import ConfigError

    if n < 0:
        raise ConfigError(f"gfcs train --holdout: expected >= 0, got {n}")
    by_class: Dict[str, List[Any]] = {}
    for p in problems:
        by_class.setdefault(p.cls, []).append(p)
    for cls, ps in by_class.items():
        if n > 0 and len(ps) <= n:
            raise ConfigError(f"gfcs train --holdout {n}: class {cls or '(none)'!r} has only {len(ps)} problems")
    held = {id(p) for ps in by_class.values() for p in ps[len(ps) - n:]} if n > 0 else set()
    return [p for p in problems if id(p) not in held], [p for p in problems if id(p) in held]


def _load_problems(args: argparse.Namespace, seed: int) -> List[Any]:
    """The problems: a MotionBenchMaker folder, or generated ones (seeded by the training seed)."""
    from gfcs.errors import ConfigError

    if (args.problems is None) == (args.generate is None):
        raise ConfigError("gfcs train: give exactly one of --problems DIR or --generate CLASS ...")
    from gfcs.bench import load_mbm_suite
    from gfcs.cli import _robot, _with_mesh_checker

    robot = _robot(args)
    if args.generate is not None:
        from gfcs.generators import generate

        problems: List[Any] = []
        for cls in args.generate:
            problems += generate(cls, args.n_problems, seed=seed, robot=robot)
        return _with_mesh_checker(args, problems)
    return _with_mesh_checker(args, load_mbm_suite(args.problems, args.classes, args.limit, robot, args.skip))


def _config(args: argparse.Namespace):
    """TrainConfig from the flags; with --resume, the checkpoint's config with the allowed overrides."""
    from gfcs.errors import ConfigError

    from .train import RESUME_OVERRIDABLE, TrainConfig, load_checkpoint

    given = {field: getattr(args, flag) for flag, field in _CONFIG_FLAGS.items() if getattr(args, flag) is not None}
    solve = {k: getattr(args, k) for k in ("batches", "population", "preset") if getattr(args, k) is not None}
    if args.config is not None:
        solve["fabric_config"] = str(args.config)
    if args.resume is not None:
        bad = sorted(set(given) - RESUME_OVERRIDABLE) + (["solve options"] if solve else []) + (
            ["negative_noise"] if args.negative_noise is not None else [])
        if bad:
            raise ConfigError(f"gfcs train --resume: cannot change {bad}; only {sorted(RESUME_OVERRIDABLE)}")
        cfg = TrainConfig.from_dict(load_checkpoint(args.resume)["config"])
    else:
        cfg = TrainConfig()
        cfg.solve.update(solve)
    for field, value in given.items():
        setattr(cfg, field, tuple(value) if field == "hidden" else value)
    if args.negative_noise is not None:
        cfg.sgld = cfg.sgld.with_noise(args.negative_noise)
    return cfg.validate()


def run_train(args: argparse.Namespace) -> int:
    """Handler of ``gfcs train``: returns the exit code (0 on success)."""
    try:
        import torch  # noqa: F401
    except ModuleNotFoundError:
        print("gfcs train needs PyTorch: pip install gfcs[learn]", file=sys.stderr)
        return 2
    from .train import train

    from gfcs.bench import Suite, suite_problems
    from gfcs.executors import executor_from_args

    config = _config(args)
    everything = _load_problems(args, config.seed)
    suite = Suite(_load_problems, (args, config.seed))  # what Ray workers build the problems from
    suite_problems(suite, built=everything)
    problems, validation = _split_holdout(everything, args.holdout)
    with executor_from_args(args) as executor:
        result = train(problems, out=args.out, config=config, resume=args.resume, checkpoint=args.checkpoint,
                       progress=not args.no_progress, validation=validation, executor=executor, suite=suite)
    if args.history:
        with open(args.history, "w", encoding="utf-8") as f:
            json.dump(result.history, f, indent=1)
    if args.plot:
        from gfcs.plots import save_training_figure

        print(f"wrote {save_training_figure(result.history, args.plot)}")
    solved = [h for h in result.history if h["event"] == "solve"]
    print(f"trained on {len(problems)} problems x {config.passes} passes: {result.trainings} trainings, "
          f"buffer {len(result.buffer)}, model written to {args.out}")
    if solved:
        print(f"last solve best cost {solved[-1]['best_cost']:.3f} s")
    for h in result.history:
        if h["event"] == "validate":
            who = "uniform" if h["trainings"] == 0 else f"after training {h['trainings']} ({h['step']} solves)"
            print(f"validation {who}: mean first-batch cost {h['mean_cost']:.3f} s, solved {h['solved']}/{h['n']}")
    if result.best is not None:
        from .train import best_model_path

        print(f"best validated model (training {result.best['trainings']}) written to {best_model_path(args.out)}")
    return 0
