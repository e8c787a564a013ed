"""Self-supervised learning to sample GFCS command sequences (GFCS Sec. IV-B, IV-C, Alg. 2).

Modules:

* :mod:`~gfcs.learning.encoding`: reference-lattice environment code ``d_E`` and the context ``x^c``
  (numpy + scipy only);
* :mod:`~gfcs.learning.ebm`: the energy model ``E_θ``, the InfoNCE loss (eq. 9), the distance autoencoder;
* :mod:`~gfcs.learning.sgld`: Langevin sampling (eq. 10-11);
* :mod:`~gfcs.learning.buffer`: the solution buffer of Alg. 2;
* :mod:`~gfcs.learning.train`: Algorithm 2 with checkpoints and resume;
* :mod:`~gfcs.learning.sampler`: :class:`EBMSampler`, the learned sampler for ``gfcs.optimize.solve``;
* :mod:`~gfcs.learning.evaluate`: first-batch comparison of two samplers (GFCS Table II);
* :mod:`~gfcs.learning.cli`: the ``gfcs train`` subcommand.

torch is an optional dependency (``pip install gfcs[learn]``). The names below are imported on first
access, so ``import gfcs.learning`` and the CLI registration work without torch; using a torch-backed
name without torch raises an ``ImportError`` that says how to install it.
"""

from __future__ import annotations

import importlib
from typing import Any

#: public name -> defining submodule
_EXPORTS = {
    "EncoderConfig": "encoding",
    "SceneEncoder": "encoding",
    "reference_lattice": "encoding",
    "distance_encoding": "encoding",
    "EnergyModel": "ebm",
    "info_nce_loss": "ebm",
    "DistanceAutoencoder": "ebm",
    "SGLDConfig": "sgld",
    "sgld": "sgld",
    "SolutionBuffer": "buffer",
    "TrainConfig": "train",
    "TrainResult": "train",
    "train": "train",
    "train_energy_model": "train",
    "EBMSampler": "sampler",
    "evaluate_first_batch": "evaluate",
    "register_cli": "cli",
}

_TORCH_MODULES = frozenset({"ebm", "sgld", "train", "sampler"})

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """Import ``name`` from its submodule on first access (PEP 562)."""
    module_name = _EXPORTS.get(name)
    if module_name is None:
        raise AttributeError(f"module 'gfcs.learning' has no attribute '{name}'")
    try:
        module = importlib.import_module(f"gfcs.learning.{module_name}")
    except ModuleNotFoundError as exc:
        if exc.name == "torch" and module_name in _TORCH_MODULES:
            raise ImportError(
                f"gfcs.learning.{name} needs PyTorch: install it with `pip install gfcs[learn]`"
            ) from exc
        raise
    value = getattr(module, name if name != "register_cli" else "register")
    globals()[name] = value
    return value


def __dir__() -> list:
    return sorted(set(globals()) | set(_EXPORTS))
