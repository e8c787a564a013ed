"""Algorithm 2 of GFCS (Sec. IV-C): self-supervised learning of GFCS command sequences.

For ``n = 1 … passes · N_prob`` (the problems in order, ``passes`` times; paper: two passes):

1. ``D^pos ← SolveGFCOP(problem | f_sampler)`` through ``solve_fn`` (default :func:`gfcs.optimize.solve`);
2. insert the top-``m`` solutions into ``D^buffer`` and keep its length (:class:`SolutionBuffer`: top 4,
   at most 200, FIFO);
3. every ``n_train`` problems (paper: 25): negatives ``D^neg`` by SGLD (eq. 10-11) from uniform
   particles in the context of every buffer entry (``N_neg`` each), then train ``E_θ`` with eq. 9
   (Adam); the sampler becomes SGLD on the trained ``E_θ`` (:class:`EBMSampler`).

Choices the paper leaves open (all in :class:`TrainConfig`):

* Alg. 2 draws ``D^neg`` after every problem but uses it only when training, so negatives are drawn only
  at training time (same result, ``n_train`` times less work). With ``neg_refresh = k > 0`` they are
  drawn again every ``k`` epochs from the model being trained (harder negatives, as in implicit
  behavioural cloning); ``neg_refresh = 0`` draws them once per training, as Alg. 2 does literally.
* Besides the ``n_neg`` SGLD negatives, ``n_uniform_neg`` negatives per positive are drawn uniformly in
  the joint limits (default 8; 0 gives Alg. 2 exactly). With SGLD negatives alone, the synthetic
  problems of the tests showed the classic EBM failure after longer training: wells around the
  positives so narrow that SGLD particles no longer find them, and the samples drift back to uniform
  (mean distance 0.92 against 1.0 for uniform samples); the uniform negatives keep pushing up spurious
  low-energy regions anywhere in the box (0.26–0.29 over 60–240 epochs).
* Before the first training the sampler is uniform within the joint limits (``sampler=None`` to
  ``solve_fn``), since an untrained ``E_θ`` carries no information.
* ``max_cost`` optionally keeps penalised (failed, eq. 8) candidates out of the buffer.
* The autoencoder of the distance code (``latent_dim``) is fitted once, before the loop, on the codes of
  all training problems (their environments are known up front).
* Model selection (not in the paper): with ``validation`` problems (held out of training), every sampler
  is scored after its training by the mean first-batch cost (eq. 8, one CMA-ES batch, the same seed per
  problem each time) on them; the uniform sampler is scored once before the first training. The lowest
  scoring trained model is kept as ``TrainResult.best_sampler`` (file ``<out stem>.best.pt``). In one
  MotionBenchMaker run (table under) a model from the middle of the run was better on unseen problems
  than the final one, which is why every trained model is scored.

Reproducibility: every random draw is a function of ``(seed, step)``: solve ``seed`` of step ``s`` and
the training generator come from ``numpy.random.SeedSequence([seed, s, …])``, and networks are
initialised under a seeded, forked torch RNG (the global RNGs are neither used nor changed). The RNG
state of a run is therefore ``(seed, step)``, both stored in the checkpoint. A checkpoint (model,
optimiser with its Adam moments, buffer, encoder with its autoencoder, config, step, history) is
written after every ``checkpoint_every`` problems and after every training, so a resumed run ends with
the same weights as an uninterrupted one (same device and thread count, since floating-point
reductions depend on them).

Contexts are standardised with the statistics of all training problems' contexts before the first
training (see :class:`~gfcs.learning.ebm.EnergyModel`); the statistics are part of the model weights.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import torch

from ._validate import ConfigError, check_positive, check_positive_int
from .buffer import SolutionBuffer
from .ebm import DistanceAutoencoder, EnergyModel, info_nce_loss
from .encoding import EncoderConfig, SceneEncoder, to_unit
from .sampler import EBMSampler, default_device, robot_info
from .sgld import SGLDConfig, sgld

__all__ = ["TrainConfig", "TrainResult", "train", "train_energy_model", "CHECKPOINT_FORMAT",
           "default_solve_fn", "default_validate_fn", "load_checkpoint", "best_model_path"]

#: ``format`` tag of a training checkpoint.
CHECKPOINT_FORMAT = "gfcs-ebm-checkpoint"
_CHECKPOINT_VERSION = 1

#: Fields of :class:`TrainConfig` a resumed run may change (they do not alter what was done so far).
RESUME_OVERRIDABLE = frozenset({"passes", "device", "checkpoint_every"})

#: ``solve_fn(problem, sampler, seed) -> result`` with ``result.top`` a list of (candidate, cost).
SolveFn = Callable[[Any, Any, int], Any]


@dataclass
class TrainConfig:
    """Settings of Algorithm 2; defaults are the paper's figures (GFCS Sec. V) where it gives them.

    Attributes:
        passes: passes over the training problems (paper: 2).
        n_train: train every ``n_train`` solved problems (paper: 25).
        buffer_size: maximum buffer length (paper: 200).
        top_m: solutions per problem inserted into the buffer (paper: 4).
        n_neg: SGLD negatives per positive (``N_neg`` of eq. 9).
        n_uniform_neg: additional uniform negatives per positive (0: SGLD negatives only, as Alg. 2).
        hidden, activation: ``E_θ`` architecture (paper: 3 × 800, ReLU).
        lr, weight_decay: Adam settings.
        epochs: passes over the buffer per training; batch_size: positives per Adam step.
        neg_refresh: redraw the negatives every this many epochs (0: once per training).
        sgld: SGLD settings of the training negatives, and of the sampler except its noise.
        sample_noise: noise scale ``τ`` of the sampler's SGLD (stored in the model file; default 1, the
            paper's eq. 10-11). The negatives use ``sgld.noise_scale`` (1, the paper's, by default; ``gfcs train
            --negative-noise``); docs/tuning.md has the measured effect of both.
        encoder: lattice settings (paper spacing 0.15 m).
        latent_dim: autoencoder code length, or ``None`` to feed ``d̂_E`` directly.
        ae_hidden, ae_epochs: autoencoder architecture and training length.
        n_commands: free commands ``n`` of the GFCOP (paper: sequences of length two, so 1).
        solve: keyword arguments of the default ``solve_fn`` (``gfcs.optimize.solve``), e.g.
            ``{"method": "gfcs", "batches": 5, "population": 32}``.
        max_cost: drop candidates with a larger cost (s) from the buffer; ``None`` keeps all.
        seed: master seed.
        device: torch device name, or ``None`` for CUDA when available else CPU.
        checkpoint_every: write a checkpoint every this many problems (and after every training).
        shuffle: visit the problems in a seeded random order per pass instead of in order.
    """

    passes: int = 2
    n_train: int = 25
    buffer_size: int = 200
    top_m: int = 4
    n_neg: int = 16
    n_uniform_neg: int = 8
    hidden: Tuple[int, ...] = (800, 800, 800)
    activation: str = "relu"
    lr: float = 1e-3
    weight_decay: float = 0.0
    epochs: int = 100
    batch_size: int = 64
    neg_refresh: int = 10
    sgld: SGLDConfig = field(default_factory=SGLDConfig)
    sample_noise: float = 1.0
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    latent_dim: Optional[int] = None
    ae_hidden: Tuple[int, ...] = (512,)
    ae_epochs: int = 300
    n_commands: int = 1
    solve: Dict[str, Any] = field(default_factory=lambda: {"method": "gfcs", "batches": 5, "population": 32})
    max_cost: Optional[float] = None
    seed: int = 0
    device: Optional[str] = None
    checkpoint_every: int = 1
    shuffle: bool = False

    def validate(self) -> "TrainConfig":
        """Raise ``ConfigError`` naming the first bad field; returns ``self``."""
        for name in ("passes", "n_train", "buffer_size", "top_m", "n_neg", "epochs", "batch_size",
                     "ae_epochs", "n_commands", "checkpoint_every"):
            check_positive_int(name, getattr(self, name))
        check_positive_int("neg_refresh", self.neg_refresh, minimum=0)
        check_positive_int("n_uniform_neg", self.n_uniform_neg, minimum=0)
        check_positive_int("seed", self.seed, minimum=0)
        check_positive("lr", self.lr)
        if not self.sample_noise >= 0.0:
            raise ConfigError(f"invalid sample_noise: expected >= 0, got {self.sample_noise!r}")
        if not self.weight_decay >= 0.0:
            raise ConfigError(f"invalid weight_decay: expected >= 0, got {self.weight_decay!r}")
        if self.latent_dim is not None:
            check_positive_int("latent_dim", self.latent_dim)
        self.sgld.validate()
        SceneEncoder(self.encoder)  # validates the lattice settings
        if not isinstance(self.solve, dict):
            raise ConfigError(f"invalid solve: expected a dict of keyword arguments, got {self.solve!r}")
        return self

    def sampler_sgld(self) -> SGLDConfig:
        """SGLD settings of the sampler: ``sgld`` with noise scale ``sample_noise``."""
        return self.sgld.with_noise(self.sample_noise)

    def to_dict(self) -> Dict[str, Any]:
        """Plain nested dict (lists instead of tuples) for checkpoints and JSON."""
        d = asdict(self)
        d["hidden"] = list(self.hidden)
        d["ae_hidden"] = list(self.ae_hidden)
        d["sgld"] = self.sgld.to_dict()
        d["encoder"] = self.encoder.to_dict()
        d["solve"] = dict(self.solve)
        return d

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "TrainConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ``ConfigError``."""
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ConfigError(f"train config: unknown fields {sorted(unknown)}")
        d = dict(d)
        if "sgld" in d and isinstance(d["sgld"], dict):
            d["sgld"] = SGLDConfig.from_dict(d["sgld"])
        if "encoder" in d and isinstance(d["encoder"], dict):
            d["encoder"] = EncoderConfig.from_dict(d["encoder"])
        for key in ("hidden", "ae_hidden"):
            if key in d:
                d[key] = tuple(int(v) for v in d[key])
        return cls(**d).validate()


@dataclass
class TrainResult:
    """Outcome of :func:`train`.

    Attributes:
        sampler: :class:`EBMSampler` on the final ``E_θ``.
        buffer: the solution buffer at the end.
        history: one dict per event: ``{"event": "solve", "step", "problem", "best_cost", "inserted"}``
            or ``{"event": "train", "step", "losses": [per-epoch mean InfoNCE], "seconds"}``.
        steps_done: problems solved so far (including those before a resume).
        trainings: number of trainings done.
        best_sampler: with validation problems, the sampler of the training with the lowest validation
            score (see :func:`train`), else ``None``.
        best: that training's ``"validate"`` history event, else ``None``.
    """

    sampler: EBMSampler
    buffer: SolutionBuffer
    history: List[Dict[str, Any]]
    steps_done: int
    trainings: int
    best_sampler: Optional[EBMSampler] = None
    best: Optional[Dict[str, Any]] = None


@contextlib.contextmanager
def _seeded_torch(seed: int) -> Iterator[None]:
    """Run a block (network initialisation) under a seeded torch CPU RNG, restoring the global state."""
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        yield


def _derived_seed(*keys: int, bits: int = 63) -> int:
    """A ``bits``-bit non-negative seed that depends only on ``keys`` (``numpy.random.SeedSequence``)."""
    state = np.random.SeedSequence([int(k) for k in keys]).generate_state(2, dtype=np.uint32)
    return ((int(state[0]) << 32) | int(state[1])) & ((1 << bits) - 1)


def train_energy_model(
    model: EnergyModel,
    optimizer: torch.optim.Optimizer,
    contexts: torch.Tensor,
    targets: torch.Tensor,
    *,
    epochs: int,
    batch_size: int,
    n_neg: int,
    sgld_config: SGLDConfig,
    n_uniform_neg: int = 0,
    neg_refresh: int,
    generator: torch.Generator,
) -> List[float]:
    """Train ``E_θ`` on positives with SGLD negatives by the InfoNCE loss of GFCS eq. 9.

    ``contexts``: ``(N, C)``; ``targets``: ``(N, D)`` positives in the unit box (see
    :func:`gfcs.learning.encoding.to_unit`); both on the model's device. Negatives: ``n_neg`` SGLD particles
    per positive in its context (Alg. 2) plus ``n_uniform_neg`` uniform samples of the unit box, redrawn
    every ``neg_refresh`` epochs (0: once). Each epoch visits
    the positives in a random order (``generator``) in minibatches of ``batch_size``. Returns the mean loss
    of every epoch.
    """
    n = contexts.shape[0]
    if n == 0 or targets.shape[0] != n:
        raise ConfigError(f"train_energy_model: need N >= 1 matching contexts and targets, got "
                          f"{tuple(contexts.shape)} and {tuple(targets.shape)}")
    losses: List[float] = []
    negatives = None
    for epoch in range(epochs):
        if negatives is None or (neg_refresh > 0 and epoch % neg_refresh == 0):
            model.eval()
            negatives, _ = sgld(model, contexts, n_neg, sgld_config, generator)
            if n_uniform_neg > 0:
                uniform = torch.rand((n, n_uniform_neg, targets.shape[1]), generator=generator,
                                     device=generator.device, dtype=targets.dtype).to(targets.device)
                negatives = torch.cat([negatives, uniform * 2.0 - 1.0], dim=1)
        model.train()
        perm = torch.randperm(n, generator=generator, device=generator.device).to(contexts.device)
        total = 0.0
        for start in range(0, n, batch_size):
            idx = perm[start:start + batch_size]
            feats = model.context_features(contexts[idx])
            e_pos = model.energy_from_features(feats, targets[idx][:, None, :])[:, 0]
            e_neg = model.energy_from_features(feats, negatives[idx])
            loss = info_nce_loss(e_pos, e_neg)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * idx.shape[0]
        losses.append(total / n)
    model.eval()
    return losses


def default_solve_fn(config: TrainConfig, threads: Optional[int] = None) -> SolveFn:
    """``solve_fn`` calling :func:`gfcs.optimize.solve` with ``config.solve`` and ``config.n_commands``
    (``threads``: Rayon threads of each solve; None: the solve's default)."""
    from gfcs.optimize import UniformSampler, solve

    kwargs = dict(config.solve)
    kwargs.setdefault("n_commands", config.n_commands)
    if threads is not None:
        kwargs["threads"] = threads

    def solve_fn(problem: Any, sampler: Any, seed: int) -> Any:
        if sampler is None:  # before the first training: uniform, as Alg. 2 (not solve's default)
            sampler = UniformSampler(int(kwargs["n_commands"]))
        return solve(problem, sampler=sampler, seed=seed, **kwargs)

    return solve_fn


def default_validate_fn(config: TrainConfig, threads: Optional[int] = None) -> SolveFn:
    """``validate_fn``: :func:`gfcs.optimize.solve` with one CMA-ES batch (the warm start alone, as GFCS
    Table II), the population of ``config.solve`` and ``config.n_commands``; uniform when ``sampler`` is
    ``None``."""
    kwargs = dict(config.solve)
    kwargs["batches"] = 1
    return default_solve_fn(replace(config, solve=kwargs), threads)


@dataclass(frozen=True)
class Solved:
    """What the training loop uses of a solve that ran on a Ray worker: ``top`` (candidate, cost), best
    first, and ``success`` (the full result holds the robot, which does not pickle)."""

    top: List[Tuple[Any, float]]
    success: bool


def _solve_task(shared: Tuple[SolveFn, Any, Any], name: str, seed: int) -> Solved:
    """A Ray task of :func:`_solves`: ``solve_fn(problem, sampler, seed)`` on the worker, the problem from
    the suite recipe (built once per worker)."""
    from gfcs.bench import suite_problems

    solve_fn, suite, sampler = shared
    result = solve_fn(suite_problems(suite, quiet=True)[name], sampler, seed)
    return Solved([(np.asarray(c, dtype=np.float64), float(cost)) for c, cost in result.top], bool(result.success))


def _solves(executor: Any, suite: Any, solve_fn: SolveFn, sampler: Any, jobs: Sequence[Tuple[Any, Any, int]]
            ) -> Dict[Any, Any]:
    """``solve_fn(problem, sampler, seed)`` for each ``(key, problem, seed)`` of ``jobs``, by key: in this
    process for a local executor (or none), else as tasks of ``executor`` that rebuild each problem from
    ``suite`` (:class:`gfcs.bench.Suite`) and get ``solve_fn`` and ``sampler`` (its weights) once per
    call; a task the executor could not complete raises :class:`ConfigError` naming its problem."""
    from gfcs.executors import LocalExecutor

    if executor is None or isinstance(executor, LocalExecutor):
        return {key: solve_fn(problem, sampler, seed) for key, problem, seed in jobs}
    problem_of = {key: problem for key, problem, _ in jobs}
    out = {}
    for done in executor.run(_solve_task, (solve_fn, suite, sampler),
                             [(key, (problem.name, seed)) for key, problem, seed in jobs]):
        if done.error is not None:
            raise ConfigError(f"train: the solve of {problem_of[done.key].name} failed on the executor: {done.error}")
        out[done.key] = done.value
    return out


def load_checkpoint(path: Union[str, Path]) -> Dict[str, Any]:
    """Read and check a training checkpoint written by :func:`train`."""
    from gfcs.errors import FormatError, IoError

    try:
        data = torch.load(str(path), map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise IoError(f"{path}: no such checkpoint") from None
    except Exception as exc:  # torch raises several types for corrupt or foreign files
        raise FormatError(f"{path}: not a gfcs training checkpoint ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        fmt = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise FormatError(f"{path}: field 'format': expected '{CHECKPOINT_FORMAT}', got {fmt!r}")
    if data.get("version") != _CHECKPOINT_VERSION:
        raise FormatError(f"{path}: field 'version': expected {_CHECKPOINT_VERSION}, got {data.get('version')!r}")
    return data


def _resolve_config(config: Optional[TrainConfig], ckpt: Optional[Dict[str, Any]]) -> TrainConfig:
    if ckpt is None:
        return (config or TrainConfig()).validate()
    saved = TrainConfig.from_dict(ckpt["config"])
    if config is None:
        return saved
    given, old = config.validate().to_dict(), saved.to_dict()
    differ = sorted(k for k in old if k not in RESUME_OVERRIDABLE and given[k] != old[k])
    if differ:
        raise ConfigError(f"resume: config fields {differ} differ from the checkpoint's "
                          f"(only {sorted(RESUME_OVERRIDABLE)} may change)")
    return config


def _atomic_save(obj: Dict[str, Any], path: Union[str, Path]) -> None:
    """``torch.save`` to ``<path>.tmp`` then rename, so an interrupted write never corrupts ``path``."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, str(tmp))
    os.replace(tmp, path)


def best_model_path(out: Union[str, Path]) -> Path:
    """Where :func:`train` writes the best validated model next to ``out``: ``<out stem>.best.pt``."""
    return Path(out).with_suffix(".best.pt")


def _problem_limits(problems: Sequence[Any]) -> Tuple[np.ndarray, np.ndarray, int]:
    robot = problems[0].robot
    lower = np.asarray(robot.lower, dtype=np.float64)
    upper = np.asarray(robot.upper, dtype=np.float64)
    for i, p in enumerate(problems):
        lo, hi = np.asarray(p.robot.lower, dtype=np.float64), np.asarray(p.robot.upper, dtype=np.float64)
        if lo.shape != lower.shape or not (np.allclose(lo, lower) and np.allclose(hi, upper)):
            raise ConfigError(f"problems[{i}] ({getattr(p, 'name', i)}): robot joint limits differ from "
                              "problems[0]'s; learning needs one robot (GFCS Sec. IV-B)")
    return lower, upper, int(lower.shape[0])


def _problem_name(problem: Any, index: int) -> str:
    return str(getattr(problem, "name", None) or f"problem{index}")


def _round_end(step: int, total: int, n_train: int) -> int:
    """The step after the last one solved with the sampler of ``step``: the model is trained after each
    step ``s`` with ``(s + 1) % n_train == 0`` (and after the last step of the run)."""
    return min(total, (step // n_train + 1) * n_train)


def _check_executor(executor: Any, suite: Any, problems: Sequence[Any]) -> None:
    """A remote executor needs a suite recipe holding every problem under its (unique) name."""
    if executor is None or executor.name == "local":
        return
    from gfcs.bench import suite_problems

    if suite is None:
        raise ConfigError(f"train: executor {executor.name!r} needs suite= (a gfcs.bench.Suite the workers build "
                          "the problems from)")
    names = [getattr(p, "name", "") for p in problems]
    missing = sorted(set(names) - set(suite_problems(suite)))
    if len(set(names)) != len(names) or missing:
        raise ConfigError(f"train: with executor {executor.name!r} every problem needs a unique name found in "
                          f"the suite ({len(names) - len(set(names))} repeated; not in the suite: {missing[:3]})")


def _visit_order(n: int, passes: int, seed: int, shuffle: bool) -> np.ndarray:
    orders = [np.random.default_rng(_derived_seed(seed, 0xC0DE, p)).permutation(n) if shuffle else np.arange(n)
              for p in range(passes)]
    return np.concatenate(orders)


def train(
    problems: Sequence[Any],
    out: Optional[Union[str, Path]] = None,
    config: Optional[TrainConfig] = None,
    solve_fn: Optional[SolveFn] = None,
    resume: Optional[Union[str, Path]] = None,
    checkpoint: Optional[Union[str, Path]] = None,
    progress: bool = True,
    stop_after: Optional[int] = None,
    validation: Optional[Sequence[Any]] = None,
    validate_fn: Optional[SolveFn] = None,
    executor: Optional[Any] = None,
    suite: Optional[Any] = None,
) -> TrainResult:
    """Run Algorithm 2 on ``problems`` and return the trained sampler.

    Args:
        problems: :class:`gfcs.problems.Problem` list (fields ``name, robot, scene, q0, qd0, goal``), all
            on one robot.
        out: model file (:meth:`EBMSampler.save` format), rewritten after every training and at the end,
            or ``None``.
        config: :class:`TrainConfig` (defaults: the paper's figures). With ``resume`` it may be ``None``
            (the checkpoint's config is used) or differ only in :data:`RESUME_OVERRIDABLE`.
        solve_fn: ``solve_fn(problem, sampler, seed) -> result`` whose ``result.top`` lists
            ``(candidate (n_commands · dof,), cost)``, best first; ``sampler`` is ``None`` (uniform) or an
            :class:`EBMSampler`. Default: :func:`default_solve_fn`.
        resume: checkpoint to continue from.
        checkpoint: checkpoint path to write (default ``<out stem>.ckpt.pt`` next to ``out``; none when
            both are ``None``).
        progress: show a tqdm bar.
        stop_after: stop after this many problems in total (counting those before a resume), for
            splitting a run; ``None`` runs all ``passes · len(problems)``.
        validation: problems held out of training (same robot) for model selection. Every sampler is
            scored after its training by the mean over them of the best first-batch cost (s; eq. 8, so a
            failed problem counts its penalty), solved by ``validate_fn`` with the same seed per problem
            every time; the uniform sampler is scored once before the first training. History events
            ``{"event": "validate", "step", "trainings", "mean_cost", "solved", "n", "costs", "seconds"}``
            (``trainings = 0``: uniform). The trained model with the lowest score is returned as
            ``best_sampler`` and written to :func:`best_model_path` ``(out)``.
        validate_fn: like ``solve_fn``, for the validation problems; default :func:`default_validate_fn`.
        executor: where the solves run (:mod:`gfcs.executors`; default: this process). With a Ray executor
            the solves of a round (the problems between two trainings, all solved with the same sampler)
            are tasks on the workers, the sampler (its weights) is sent to them once per round, and the
            energy model is trained here; the results are used in step order, so the run is the one a
            local run makes. ``solve_fn`` and ``validate_fn`` must then pickle (the defaults do).
        suite: with a Ray executor, a :class:`gfcs.bench.Suite` whose problems include ``problems`` and
            ``validation`` under the same (unique) names: the workers build the problems from it.
    """
    if len(problems) == 0:
        raise ConfigError("train: no problems given")
    ckpt = load_checkpoint(resume) if resume is not None else None
    cfg = _resolve_config(config, ckpt)
    run = _Alg2(list(problems), list(validation or []), cfg, ckpt, resume, executor, suite)
    threads = getattr(executor, "threads", None)
    run.solve_fn = solve_fn or default_solve_fn(cfg, threads)
    run.validate_fn = validate_fn or default_validate_fn(cfg, threads)
    run.out = out
    run.checkpoint = Path(out).with_suffix(".ckpt.pt") if checkpoint is None and out is not None else checkpoint
    return run.run(stop_after, progress)


def _encode(problems: Sequence[Any], cfg: TrainConfig, ckpt: Optional[Dict[str, Any]], device: Any,
            lower: np.ndarray, upper: np.ndarray) -> Tuple[SceneEncoder, np.ndarray]:
    """The scene encoder (GFCS Sec. IV-B; its autoencoder fitted when ``cfg.latent_dim`` asks, or restored
    from the checkpoint) and the context x^c of every problem, encoded once."""
    encoder = SceneEncoder(cfg.encoder)
    distances = np.stack([encoder.distances(encoder.scene_points(p.scene)) for p in problems])
    if ckpt is not None:
        encoder = SceneEncoder.from_state_dict(ckpt["encoder"])
    elif cfg.latent_dim is not None:
        with _seeded_torch(_derived_seed(cfg.seed, 0xAE)):
            ae = DistanceAutoencoder(encoder.n_reference, cfg.latent_dim, cfg.ae_hidden).to(device)
        ae.fit(distances, epochs=cfg.ae_epochs, seed=_derived_seed(cfg.seed, 0xAE, 1))
        encoder = SceneEncoder(cfg.encoder, ae)
    codes = distances if encoder.autoencoder is None else encoder.autoencoder.to(device).encode_numpy(distances)
    contexts = np.stack([
        encoder.context(p.q0, p.qd0, p.goal, codes[i], lower, upper, getattr(p.robot, "velocity_limits", None))
        for i, p in enumerate(problems)
    ])
    return encoder, contexts


class _Alg2:
    """One run of Algorithm 2 (see :func:`train`): the encoded problems, the model, its optimiser, the
    solution buffer, the history and the counters, restored from a checkpoint when resuming; its steps are
    the methods."""

    solve_fn: SolveFn
    validate_fn: SolveFn
    out: Optional[Union[str, Path]] = None
    checkpoint: Optional[Union[str, Path]] = None

    def __init__(self, problems: List[Any], validation: List[Any], cfg: TrainConfig,
                 ckpt: Optional[Dict[str, Any]], resume: Any, executor: Any, suite: Any) -> None:
        self.problems, self.validation, self.cfg, self.executor, self.suite = problems, validation, cfg, executor, suite
        self.device = default_device(cfg.device)
        self.names = [_problem_name(p, i) for i, p in enumerate(problems)]
        if ckpt is not None and list(ckpt["problem_names"]) != self.names:
            raise ConfigError(f"resume: the problem set differs from the one in {resume}")
        self.val_names = [_problem_name(p, i) for i, p in enumerate(validation)]
        if ckpt is not None and list(ckpt.get("validation_names", [])) != self.val_names:
            raise ConfigError(f"resume: the validation problems differ from the ones in {resume}")
        lower, upper, self.dof = _problem_limits(problems + validation)
        self.t_lower, self.t_upper = np.tile(lower, cfg.n_commands), np.tile(upper, cfg.n_commands)
        _check_executor(executor, suite, problems + validation)
        self.encoder, self.contexts = _encode(problems, cfg, ckpt, self.device, lower, upper)
        with _seeded_torch(_derived_seed(cfg.seed, 0xE3)):
            self.model = EnergyModel(self.contexts.shape[1], self.dof * cfg.n_commands, cfg.hidden, cfg.activation)
        self.model.set_context_normalisation(torch.as_tensor(self.contexts, dtype=torch.float32))
        self.model.to(self.device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        self.buffer = SolutionBuffer(cfg.buffer_size, cfg.top_m)
        self.history: List[Dict[str, Any]] = []
        self.start, self.trainings = 0, 0
        self.best: Optional[Dict[str, Any]] = None  # {"event": validate event, "state": model weights}
        if ckpt is not None:
            self.model.load_state_dict(ckpt["model"]["state"])
            self.optimizer.load_state_dict(ckpt["optimizer"])
            self.buffer = SolutionBuffer.from_state_dict(ckpt["buffer"])
            self.history = list(ckpt["history"])
            self.start, self.trainings = int(ckpt["step"]), int(ckpt["trainings"])
            self.best = ckpt.get("best")
        self.robot = robot_info(problems[0].robot)
        self.sampler: Optional[EBMSampler] = self.make_sampler() if self.trainings > 0 else None

    def make_sampler(self, net: Optional[EnergyModel] = None) -> EBMSampler:
        return EBMSampler(self.model if net is None else net, self.encoder, self.t_lower, self.t_upper, self.dof,
                          self.cfg.sampler_sgld(), self.device, robot=self.robot)

    def validate(self, step: int, current: Optional[EBMSampler]) -> Dict[str, Any]:
        """Score ``current`` (None: uniform) on the validation problems; the history event."""
        t0 = time.perf_counter()
        jobs = [(i, p, _derived_seed(self.cfg.seed, 0x7A11D, i, bits=31)) for i, p in enumerate(self.validation)]
        solved = _solves(self.executor, self.suite, self.validate_fn, current, jobs)
        results = [solved[i] for i in range(len(self.validation))]
        costs = [min((float(c) for _, c in r.top), default=float("inf")) for r in results]
        event = {"event": "validate", "step": step, "trainings": self.trainings, "mean_cost": float(np.mean(costs)),
                 "solved": int(sum(bool(r.success) for r in results)), "n": len(results), "costs": costs,
                 "seconds": time.perf_counter() - t0}
        self.history.append(event)
        return event

    def save_checkpoint(self, step: int) -> None:
        if self.checkpoint is None:
            return
        state = self.buffer.state_dict()
        state.update({k: torch.from_numpy(np.asarray(state[k])) for k in ("contexts", "targets", "costs")})
        model = self.model
        _atomic_save({
            "format": CHECKPOINT_FORMAT, "version": _CHECKPOINT_VERSION, "config": self.cfg.to_dict(),
            "step": step, "trainings": self.trainings, "problem_names": self.names,
            "model": {"meta": model.meta(), "state": {k: v.detach().cpu() for k, v in model.state_dict().items()}},
            "optimizer": self.optimizer.state_dict(), "buffer": state, "encoder": self.encoder.state_dict(),
            "history": self.history, "validation_names": self.val_names, "best": self.best,
            "rng": {"scheme": "numpy.random.SeedSequence([seed, step, ...])", "seed": self.cfg.seed,
                    "next_step": step},
        }, self.checkpoint)

    def record(self, step: int, idx: int, result: Any) -> None:
        """Put the top solutions of problem ``idx``'s solve at ``step`` into the buffer (Alg. 2)."""
        cfg = self.cfg
        top = list(result.top)
        cands = np.array([np.asarray(c, dtype=np.float64) for c, _ in top]).reshape(len(top), -1)
        costs = np.array([float(c) for _, c in top], dtype=np.float64)
        if cands.shape[0] and cands.shape[1] != self.dof * cfg.n_commands:
            raise ConfigError(f"solve_fn returned candidates of length {cands.shape[1]}, expected "
                              f"{self.dof * cfg.n_commands} (n_commands={cfg.n_commands}, dof={self.dof})")
        inserted = self.buffer.insert(self.names[idx], self.contexts[idx], cands, costs, cfg.max_cost)
        best_cost = float(costs.min()) if costs.size else float("nan")
        self.history.append({"event": "solve", "step": step, "problem": self.names[idx], "best_cost": best_cost,
                             "inserted": inserted})

    def train_model(self, step: int) -> Dict[str, Any]:
        """Train the energy model on the buffer (eq. 9), write the sampler, score it on the validation
        problems and keep the best; the progress bar's new fields."""
        cfg, device = self.cfg, self.device
        t0 = time.perf_counter()
        gen = torch.Generator(device=device).manual_seed(_derived_seed(cfg.seed, step, 0x7A))
        ctx_t = torch.as_tensor(self.buffer.contexts(), dtype=torch.float32, device=device)
        tgt_t = torch.as_tensor(to_unit(self.buffer.targets(), self.t_lower, self.t_upper), dtype=torch.float32,
                                device=device)
        losses = train_energy_model(self.model, self.optimizer, ctx_t, tgt_t, epochs=cfg.epochs,
                                    batch_size=cfg.batch_size, n_neg=cfg.n_neg, sgld_config=cfg.sgld,
                                    n_uniform_neg=cfg.n_uniform_neg, neg_refresh=cfg.neg_refresh, generator=gen)
        self.trainings += 1
        self.history.append({"event": "train", "step": step, "losses": losses, "seconds": time.perf_counter() - t0})
        self.sampler = self.make_sampler()
        if self.out is not None:
            _atomic_save(self.sampler.to_dict(), self.out)
        if self.validation:
            event = self.validate(step + 1, self.sampler)
            if self.best is None or event["mean_cost"] < self.best["event"]["mean_cost"]:
                self.best = {"event": event, "state": {k: v.detach().cpu().clone()
                                                       for k, v in self.model.state_dict().items()}}
                if self.out is not None:
                    _atomic_save(self.sampler.to_dict(), best_model_path(self.out))
        return {"buffer": len(self.buffer), "loss": f"{losses[-1]:.3f}",
                **({"val": f"{self.history[-1]['mean_cost']:.2f}s"} if self.validation else {})}

    def run(self, stop_after: Optional[int], progress: bool) -> TrainResult:
        """Solve, record and train over the visit order (every ``n_train`` solves, and once more at the
        end so that the last solves are learned), checkpointing as it goes."""
        from tqdm.auto import tqdm

        from gfcs.executors import describe

        cfg, executor, start = self.cfg, self.executor, self.start
        order = _visit_order(len(self.problems), cfg.passes, cfg.seed, cfg.shuffle)
        total = len(order) if stop_after is None else min(len(order), int(stop_after))
        bar = tqdm(total=total, initial=min(start, total), disable=not progress, unit="problem",
                   desc=f"gfcs train [{describe(executor) if executor is not None else 'local'}]")
        postfix: Dict[str, Any] = {}
        n_solved = 0  # solves of this run that succeeded (the progress bar's "solved")
        try:
            if self.validation and not any(h["event"] == "validate" for h in self.history):
                self.validate(start, None)  # the uniform sampler's score, for reference
            round_results: Dict[int, Any] = {}
            for step in range(start, total):
                if step not in round_results:  # the solves until the next training (one at a time locally)
                    end = step + 1 if executor is None or executor.name == "local" else _round_end(step, total,
                                                                                                  cfg.n_train)
                    round_results = _solves(executor, self.suite, self.solve_fn, self.sampler,
                                            [(s, self.problems[int(order[s])], _derived_seed(cfg.seed, s, bits=31))
                                             for s in range(step, end)])
                result = round_results.pop(step)
                n_solved += bool(getattr(result, "success", False))
                self.record(step, int(order[step]), result)
                trained = ((step + 1) % cfg.n_train == 0 or step + 1 == len(order)) and len(self.buffer) > 0
                if trained:
                    postfix.update(self.train_model(step))
                if trained or (step + 1) % cfg.checkpoint_every == 0 or step + 1 == total:
                    self.save_checkpoint(step + 1)
                postfix["solved"] = f"{n_solved}/{step + 1 - start}"
                bar.set_postfix(postfix, refresh=False)
                bar.update(1)
        finally:
            bar.close()
        return self.result(total)

    def result(self, total: int) -> TrainResult:
        final = self.sampler if self.sampler is not None else self.make_sampler()
        if self.out is not None:
            _atomic_save(final.to_dict(), self.out)
        best_sampler = None
        if self.best is not None:
            net = EnergyModel.from_meta(self.model.meta())
            net.load_state_dict(self.best["state"])
            best_sampler = self.make_sampler(net)
        return TrainResult(final, self.buffer, self.history, max(self.start, total), self.trainings, best_sampler,
                           None if self.best is None else self.best["event"])
