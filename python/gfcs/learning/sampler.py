"""The learned sampler: SGLD on a trained ``E_θ`` (GFCS Sec. IV-B "Generating Samples", Alg. 2).

:class:`EBMSampler` implements the sampler protocol of :func:`gfcs.optimize.solve`,
``sample(problem, n, rng) -> (n, n_free · dof)`` (joint units, rad, within the joint limits), by running
SGLD (:func:`gfcs.learning.sgld.sgld`) in the problem's context and returning the particles sorted by
energy, lowest first. :meth:`EBMSampler.best` returns the lowest-energy particle as an approximate
solution (GFCS Sec. IV-B: "directly use the candidate solution with the lowest cost").

Model file (``torch.save`` of a plain dict, loadable with ``weights_only=True``)::

    {"format": "gfcs-ebm", "version": 1,
     "model": {"meta": EnergyModel.meta(), "state": state_dict},
     "encoder": SceneEncoder.state_dict(),          # lattice config (+ autoencoder)
     "target": {"lower": [D], "upper": [D], "dof": int, "n_free": int},
     "sgld": SGLDConfig.to_dict(),
     "robot": {"name": str, "joint_names": [str]} or None}
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
import torch

from ._validate import ConfigError, as_float_array, check_positive_int
from .ebm import EnergyModel
from .encoding import SceneEncoder, from_unit, to_unit
from .sgld import SGLDConfig, sgld

__all__ = ["EBMSampler", "MODEL_FORMAT", "default_device", "robot_info", "torch_generator"]

#: ``format`` tag of a saved model file.
MODEL_FORMAT = "gfcs-ebm"
_MODEL_VERSION = 1


def default_device(device: Optional[Union[str, torch.device]] = None) -> torch.device:
    """``device`` if given, else CUDA when torch finds a GPU, else the CPU."""
    if device is not None:
        return torch.device(device)
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def torch_generator(rng: Union[np.random.Generator, int, None], device: torch.device) -> torch.Generator:
    """A ``torch.Generator`` on ``device`` seeded from a numpy ``Generator`` (one draw) or an int seed."""
    if isinstance(rng, np.random.Generator):
        seed = int(rng.integers(0, 2**63 - 1))
    elif rng is None:
        seed = int(np.random.default_rng().integers(0, 2**63 - 1))
    else:
        seed = int(rng)
    return torch.Generator(device=device).manual_seed(seed)


class EBMSampler:
    """Sampler protocol implemented by SGLD on an energy model.

    Args:
        model: path to a model file written by :meth:`save` / ``gfcs train``, or an :class:`EnergyModel`.
        encoder: :class:`SceneEncoder` (required with an ``EnergyModel``; read from the file otherwise).
        lower, upper: ``(D,)`` target bounds in rad, the joint limits tiled ``n_free`` times (required
            with an ``EnergyModel``).
        dof: robot degrees of freedom (``D = n_free · dof``); defaults to ``D`` (one free command).
        sgld_config: :class:`SGLDConfig` (overrides the file's).
        device: torch device (default: CUDA when available, else CPU).
        n_particles: minimum number of particles per call: ``sample(problem, n, rng)`` runs
            ``max(n, n_particles)`` particles and returns the ``n`` of lowest energy (default 0: exactly
            ``n``).
        robot: optional ``{"name", "joint_names"}`` stored in the file to check the robot at sampling.
    """

    def __init__(
        self,
        model: Union[str, Path, EnergyModel],
        encoder: Optional[SceneEncoder] = None,
        lower=None,
        upper=None,
        dof: Optional[int] = None,
        sgld_config: Optional[SGLDConfig] = None,
        device: Optional[Union[str, torch.device]] = None,
        n_particles: int = 0,
        robot: Optional[Dict[str, Any]] = None,
    ) -> None:
        self.device = default_device(device)
        self.n_particles = check_positive_int("n_particles", n_particles, minimum=0)
        if isinstance(model, (str, Path)):
            data = _load_file(model)
            net = EnergyModel.from_meta(data["model"]["meta"])
            net.load_state_dict(data["model"]["state"])
            encoder = SceneEncoder.from_state_dict(data["encoder"])
            lower, upper = data["target"]["lower"], data["target"]["upper"]
            dof = int(data["target"]["dof"])
            sgld_config = sgld_config or SGLDConfig.from_dict(data["sgld"])
            robot = data.get("robot")
            model = net
        if not isinstance(model, EnergyModel):
            raise ConfigError(f"model: expected a path or an EnergyModel, got {type(model).__name__}")
        if encoder is None or lower is None or upper is None:
            raise ConfigError("EBMSampler: encoder, lower and upper are required with an EnergyModel")
        self.model = model.to(self.device).float().eval()
        self.encoder = encoder
        if encoder.autoencoder is not None:
            encoder.autoencoder.to(self.device)
        self.lower = as_float_array("lower", lower, (self.model.target_dim,))
        self.upper = as_float_array("upper", upper, (self.model.target_dim,))
        if np.any(self.upper <= self.lower):
            raise ConfigError("EBMSampler: every upper target bound must exceed its lower bound")
        self.dof = check_positive_int("dof", self.model.target_dim if dof is None else dof)
        if self.model.target_dim % self.dof:
            raise ConfigError(f"EBMSampler: target size {self.model.target_dim} is not a multiple of dof {self.dof}")
        self.n_free = self.model.target_dim // self.dof
        self.sgld_config = (sgld_config or SGLDConfig()).validate()
        self.robot = robot

    # ------------------------------------------------------------------ plain-array core
    def sample_context(self, context, n: int, rng: Union[np.random.Generator, int, None] = None
                       ) -> Tuple[np.ndarray, np.ndarray]:
        """SGLD in one context: ``context`` ``(C,)`` -> targets ``(n, D)`` (rad, sorted by energy,
        lowest first) and their energies ``(n,)``. ``rng``: numpy Generator or int seed."""
        n = check_positive_int("n", n)
        ctx = as_float_array("context", context, (self.model.context_dim,))
        p = max(n, self.n_particles)
        gen = torch_generator(rng, self.device)
        ctx_t = torch.as_tensor(ctx, dtype=torch.float32, device=self.device)[None, :]
        y, energy = sgld(self.model, ctx_t, p, self.sgld_config, gen)
        y_np = y[0].double().cpu().numpy()
        e_np = energy[0].double().cpu().numpy()
        order = np.argsort(e_np, kind="stable")[:n]
        targets = np.clip(from_unit(y_np[order], self.lower, self.upper), self.lower, self.upper)
        return targets, e_np[order]

    def energy(self, context, targets) -> np.ndarray:
        """``E_θ`` of targets ``(M, D)`` (rad) in one context ``(C,)`` -> ``(M,)``."""
        ctx = as_float_array("context", context, (self.model.context_dim,))
        tgt = as_float_array("targets", targets, (None, self.model.target_dim))
        u = to_unit(tgt, self.lower, self.upper)
        with torch.no_grad():
            c = torch.as_tensor(ctx, dtype=torch.float32, device=self.device)[None, :]
            y = torch.as_tensor(u, dtype=torch.float32, device=self.device)[None, :, :]
            e = self.model(c, y)[0]
        return e.double().cpu().numpy()

    # ------------------------------------------------------------------ sampler protocol
    def context_of(self, problem) -> np.ndarray:
        """Context ``x^c`` of a :class:`gfcs.problems.Problem` after checking the robot matches."""
        robot = problem.robot
        dof = int(robot.dof) if hasattr(robot, "dof") else len(robot.lower)
        if dof != self.dof:
            raise ConfigError(f"EBMSampler: model trained for dof {self.dof}, problem robot has dof {dof}")
        if self.robot is not None and hasattr(robot, "joint_names"):
            if list(robot.joint_names) != list(self.robot.get("joint_names", robot.joint_names)):
                raise ConfigError("EBMSampler: the problem's robot joints differ from the training robot's")
        return self.encoder.problem_context(problem)

    def sample(self, problem, n: int, rng: Union[np.random.Generator, int, None] = None) -> np.ndarray:
        """Sampler protocol: ``(n, n_free · dof)`` candidate commands (rad), lowest energy first."""
        return self.sample_context(self.context_of(problem), n, rng)[0]

    def best(self, problem, rng: Union[np.random.Generator, int, None] = None,
             n_particles: Optional[int] = None) -> np.ndarray:
        """Lowest-energy SGLD particle ``(n_free · dof,)`` (rad), an approximate GFCOP solution.

        Runs ``n_particles`` particles (default ``max(self.n_particles, 64)``).
        """
        n = n_particles if n_particles is not None else max(self.n_particles, 64)
        targets, _ = self.sample_context(self.context_of(problem), check_positive_int("n_particles", n), rng)
        return targets[0]

    # ------------------------------------------------------------------ persistence
    def to_dict(self) -> Dict[str, Any]:
        """The model file content (see the module docstring); tensors on the CPU."""
        return {
            "format": MODEL_FORMAT,
            "version": _MODEL_VERSION,
            "model": {"meta": self.model.meta(),
                      "state": {k: v.detach().cpu() for k, v in self.model.state_dict().items()}},
            "encoder": self.encoder.state_dict(),
            "target": {"lower": self.lower.tolist(), "upper": self.upper.tolist(), "dof": self.dof,
                       "n_free": self.n_free},
            "sgld": self.sgld_config.to_dict(),
            "robot": self.robot,
        }

    def save(self, path: Union[str, Path]) -> None:
        """Write the model file (``torch.save``); the parent directory must exist."""
        torch.save(self.to_dict(), str(path))

    @classmethod
    def load(cls, path: Union[str, Path], **kwargs: Any) -> "EBMSampler":
        """Same as ``EBMSampler(path, **kwargs)``."""
        return cls(path, **kwargs)


def robot_info(robot) -> Optional[Dict[str, Any]]:
    """``{"name", "joint_names"}`` of a :class:`gfcs.Robot` (``None`` when it has neither)."""
    if not hasattr(robot, "joint_names"):
        return None
    return {"name": str(getattr(robot, "name", "")), "joint_names": [str(j) for j in robot.joint_names]}


def _load_file(path: Union[str, Path]) -> Dict[str, Any]:
    from gfcs.errors import FormatError, IoError

    try:
        data = torch.load(str(path), map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise IoError(f"{path}: no such model file") from None
    except Exception as exc:  # torch raises several types for corrupt or foreign files
        raise FormatError(f"{path}: not a gfcs model file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != MODEL_FORMAT:
        fmt = data.get("format") if isinstance(data, dict) else type(data).__name__
        hint = " (a training checkpoint? pass the --out model file)" if fmt == "gfcs-ebm-checkpoint" else ""
        raise FormatError(f"{path}: field 'format': expected '{MODEL_FORMAT}', got {fmt!r}{hint}")
    if data.get("version") != _MODEL_VERSION:
        raise FormatError(f"{path}: field 'version': expected {_MODEL_VERSION}, got {data.get('version')!r}")
    return data

