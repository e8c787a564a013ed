#!/usr/bin/env python
"""Nearest-neighbour retrieval from a training buffer, against the learned EBM sampler (GFCS Table II).

A diagnostic for the learned warm start (issue "Self-supervised learning"): does the buffer of solutions
that Algorithm 2 collected carry what the test problems need, and does the energy model pass it on?
Three first-batch warm starts are compared on the test problems, each with ``--seeds``:

* ``uniform``: ``UniformSampler`` (the paper's "No learning");
* ``ebm``: the trained model (``--model``, SGLD from uniform particles as eq. 10-11);
* ``retrieval``: the buffer solutions of the training problems nearest in context (Euclidean distance
  of the contexts standardised by the buffer's mean and standard deviation; each problem's top-m
  entries in cost order), one candidate per entry, plus N(0, (``--sigma`` · range)²) per joint, clipped
  into the joint limits;
* ``retrieval+sgld`` (with ``--sgld-iters K``): those candidates as SGLD initial particles, then K
  SGLD iterations on the model (the model's settings otherwise).

The buffer and encoder come from the training checkpoint (``<out>.ckpt.pt`` of ``gfcs train``); the
contexts of the test problems are computed with that encoder. Prints one line per warm start and seed
(success, mean end-effector and C-space path length of the successes); ``--json`` writes them.

    python benches/retrieval_baseline.py --checkpoint mix.ckpt.pt --model mix.pt \\
        --problems ../shared/mbm --classes table_under_pick --skip 40 --robot mbm --sgld-iters 20
"""

from __future__ import annotations

import argparse
import json
from types import SimpleNamespace
from typing import Any, Dict, List

import numpy as np


class RetrievalSampler:
    """Sampler protocol (:class:`gfcs.optimize.Sampler`): buffer targets of the nearest contexts.

    Args:
        contexts: ``(N, C)`` buffer contexts; targets: ``(N, D)`` buffer targets (rad).
        context_of: ``problem -> (C,)`` context (the training encoder's).
        sigma: joint noise as a fraction of each joint range.
    """

    def __init__(self, contexts: np.ndarray, targets: np.ndarray, context_of: Any, sigma: float) -> None:
        self.mean = contexts.mean(axis=0)
        self.scale = contexts.std(axis=0) + 1e-9
        self.contexts = (contexts - self.mean) / self.scale
        self.targets = targets
        self.context_of = context_of
        self.sigma = float(sigma)

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:
        """``(n, D)`` candidates: the targets of the ``n`` nearest buffer entries with noise (fewer entries:
        the nearest repeated)."""
        c = (self.context_of(problem) - self.mean) / self.scale
        order = np.argsort(np.linalg.norm(self.contexts - c, axis=1), kind="stable")
        picks = order[np.arange(int(n)) % order.shape[0]]
        dof = len(problem.robot.lower)
        lo = np.tile(np.asarray(problem.robot.lower, dtype=np.float64), self.targets.shape[1] // dof)
        up = np.tile(np.asarray(problem.robot.upper, dtype=np.float64), self.targets.shape[1] // dof)
        y = self.targets[picks] + rng.standard_normal((picks.shape[0], lo.shape[0])) * self.sigma * (up - lo)
        return np.clip(y, lo, up)


class RefinedSampler:
    """``RetrievalSampler`` candidates as SGLD initial particles on an :class:`EBMSampler`'s model."""

    def __init__(self, retrieval: RetrievalSampler, ebm: Any, iters: int) -> None:
        from gfcs.learning.sgld import SGLDConfig

        self.retrieval, self.ebm = retrieval, ebm
        self.config = SGLDConfig(**{**ebm.sgld_config.to_dict(), "iters": int(iters)})

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:
        import torch

        from gfcs.learning.encoding import from_unit, to_unit
        from gfcs.learning.sampler import torch_generator
        from gfcs.learning.sgld import sgld

        ebm = self.ebm
        y0 = self.retrieval.sample(problem, n, rng)
        ctx = torch.as_tensor(ebm.context_of(problem), dtype=torch.float32, device=ebm.device)[None]
        init = torch.as_tensor(to_unit(y0, ebm.lower, ebm.upper), dtype=torch.float32, device=ebm.device)[None]
        y, _ = sgld(ebm.model, ctx, int(n), self.config, torch_generator(rng, ebm.device), init=init)
        return np.clip(from_unit(y[0].double().cpu().numpy(), ebm.lower, ebm.upper), ebm.lower, ebm.upper)


def first_batch(problems: List[Any], sampler: Any, seed: int, population: int) -> Dict[str, Any]:
    """First-batch GFCS solves of ``problems``: success count and mean lengths of the successes."""
    from gfcs import optimize

    results = [optimize.solve(p, batches=1, population=population, seed=seed, sampler=sampler,
                              max_commands=1) for p in problems]
    ok = [r for r in results if r.success]
    mean = (lambda key: float(np.mean([r.metrics[key] for r in ok])) if ok else float("nan"))
    return {"seed": seed, "solved": len(ok), "problems": len(results), "ee_length": mean("ee_length"),
            "cspace_length": mean("cspace_length")}


def main(argv: Any = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", required=True, help="training checkpoint (<out>.ckpt.pt of gfcs train)")
    ap.add_argument("--model", help="model file (gfcs train --out) for the 'ebm' and 'retrieval+sgld' rows")
    ap.add_argument("--problems", help="MotionBenchMaker folder (default: generated problems)")
    ap.add_argument("--classes", nargs="+", help="classes to test (default: all)")
    ap.add_argument("--skip", type=int, default=0, help="leave out the first SKIP problems per class")
    ap.add_argument("--limit", type=int, help="at most LIMIT problems per class (generated: default 10)")
    ap.add_argument("--problem-seed", type=int, default=12345, help="seed of generated problems")
    ap.add_argument("--robot", choices=["panda", "mbm"], default="panda",
                    help="the shipped Panda or the MotionBenchMaker Panda (needs GFCS_SHARED)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--population", type=int, default=32)
    ap.add_argument("--sigma", type=float, default=0.02, help="retrieval noise, fraction of joint range")
    ap.add_argument("--sgld-iters", type=int, default=0, help="add the retrieval+sgld row with this many")
    ap.add_argument("--json", help="write the rows as JSON lines")
    args = ap.parse_args(argv)

    import gfcs
    from gfcs import bench, optimize, problems
    from gfcs.learning.encoding import SceneEncoder
    from gfcs.learning.sampler import EBMSampler
    from gfcs.learning.train import load_checkpoint

    ckpt = load_checkpoint(args.checkpoint)
    encoder = SceneEncoder.from_state_dict(ckpt["encoder"])
    buffer = ckpt["buffer"]
    contexts = np.asarray(buffer["contexts"], dtype=np.float64)
    targets = np.asarray(buffer["targets"], dtype=np.float64)
    robot = problems.mbm_panda() if args.robot == "mbm" else gfcs.Robot.panda()
    suite = SimpleNamespace(problems=args.problems, classes=args.classes, limit=args.limit, skip=args.skip,
                            problem_seed=args.problem_seed)
    tests = bench.load_problems(suite, robot)
    retrieval = RetrievalSampler(contexts, targets, encoder.problem_context, args.sigma)
    n_free = targets.shape[1] // len(robot.lower)
    samplers = {"uniform": optimize.UniformSampler(n_free), "retrieval": retrieval}
    if args.model:
        ebm = EBMSampler(args.model)
        samplers["ebm"] = ebm
        if args.sgld_iters > 0:
            samplers["retrieval+sgld"] = RefinedSampler(retrieval, ebm, args.sgld_iters)
    print(f"buffer {contexts.shape[0]} entries of {len(set(buffer['problems']))} problems; "
          f"{len(tests)} test problems")
    rows = []
    for name, sampler in samplers.items():
        for seed in args.seeds:
            row = {"sampler": name, **first_batch(tests, sampler, seed, args.population)}
            rows.append(row)
            print(f"{name:15s} seed {seed}: {row['solved']}/{row['problems']}  EE {row['ee_length']:.2f} m  "
                  f"C-space {row['cspace_length']:.2f} rad", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            f.writelines(json.dumps(r) + "\n" for r in rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
