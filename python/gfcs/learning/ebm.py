"""Energy-based model ``E_θ(x^c, y)``, the InfoNCE loss (GFCS eq. 9) and the distance autoencoder.

* :class:`EnergyModel`: an MLP mapping a (context, target) pair to a scalar energy. The paper's network
  has 3 hidden layers of width 800 with ReLU (GFCS Sec. V); both are configurable. Low energy = likely
  solution (the convention that eq. 9 trains: the positive is the numerator ``e^{−E(x, y*)}``).
* :func:`info_nce_loss`: eq. 9, computed with ``logsumexp`` so it never overflows.
* :class:`DistanceAutoencoder`: optional MLP autoencoder that shortens the lattice distance code
  ``d̂_E`` (GFCS Sec. IV-B) when ``N_R`` is long.

Inputs are normalised as documented in :mod:`gfcs.learning.encoding`: context ``x^c`` as built by
:class:`~gfcs.learning.encoding.SceneEncoder`, targets ``y`` in the unit box ``[-1, 1]^D`` (joint limits
mapped by :func:`~gfcs.learning.encoding.to_unit`), ``D = n_free · dof``.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import torch
from torch import nn

from ._validate import ConfigError, as_float_array, check_positive, check_positive_int

__all__ = ["EnergyModel", "info_nce_loss", "DistanceAutoencoder", "ACTIVATIONS"]

#: Activation functions selectable by name.
ACTIVATIONS = {"relu": nn.ReLU, "silu": nn.SiLU, "elu": nn.ELU, "tanh": nn.Tanh, "gelu": nn.GELU}


def _activation(name: str) -> nn.Module:
    try:
        return ACTIVATIONS[name]()
    except KeyError:
        raise ConfigError(f"invalid activation: {name!r} (choose from {sorted(ACTIVATIONS)})") from None


def _widths(hidden: Sequence[int], what: str) -> List[int]:
    widths = [check_positive_int(f"{what} width", h) for h in hidden]
    if not widths:
        raise ConfigError(f"invalid {what}: at least one hidden layer is required")
    return widths


class EnergyModel(nn.Module):
    """``E_θ(x^c, y) -> R``: an MLP on the concatenation ``[x^c, y]`` (GFCS Sec. IV-B, eq. 9).

    The first layer is stored as two blocks, ``W_c x̃^c + W_y y + b``, which equals one linear layer on
    ``[x̃^c, y]`` but lets SGLD compute the context part once per problem for all its particles.

    ``x̃^c = (x^c − μ_c) / s_c`` standardises every context entry with statistics of the training
    contexts (:meth:`set_context_normalisation`, stored with the weights; identity until set). Without
    it the distance code, whose entries share a large common mean, shifts every first-layer unit by
    nearly the same amount in every problem, pushing the ReLU kinks out of the target box: the energy
    becomes almost linear in ``y`` and cannot hold a mode inside the limits (observed: no decrease of
    the InfoNCE loss on synthetic problems until this was added).

    Args:
        context_dim: length ``C`` of ``x^c``.
        target_dim: length ``D`` of ``y`` (``n_free · dof``).
        hidden: widths of the hidden layers (paper: ``(800, 800, 800)``).
        activation: name in :data:`ACTIVATIONS` (paper: ``"relu"``).
    """

    def __init__(self, context_dim: int, target_dim: int, hidden: Sequence[int] = (800, 800, 800),
                 activation: str = "relu") -> None:
        super().__init__()
        self.context_dim = check_positive_int("context_dim", context_dim)
        self.target_dim = check_positive_int("target_dim", target_dim)
        self.hidden = _widths(hidden, "hidden")
        self.activation = str(activation)
        self.context_layer = nn.Linear(self.context_dim, self.hidden[0])
        self.target_layer = nn.Linear(self.target_dim, self.hidden[0], bias=False)
        layers: List[nn.Module] = [_activation(self.activation)]
        for a, b in zip(self.hidden[:-1], self.hidden[1:]):
            layers += [nn.Linear(a, b), _activation(self.activation)]
        layers.append(nn.Linear(self.hidden[-1], 1))
        self.trunk = nn.Sequential(*layers)
        self.register_buffer("context_mean", torch.zeros(self.context_dim))
        self.register_buffer("context_scale", torch.ones(self.context_dim))

    def set_context_normalisation(self, contexts: torch.Tensor, min_std: float = 1e-3) -> None:
        """Set ``μ_c``, ``s_c`` from contexts ``(N, C)``: per-entry mean and standard deviation, with
        ``s_c = 1`` where the deviation is below ``min_std`` (constant entries are only centred)."""
        if contexts.dim() != 2 or contexts.shape[1] != self.context_dim or contexts.shape[0] == 0:
            raise ConfigError(f"contexts: expected shape (N >= 1, {self.context_dim}), got {tuple(contexts.shape)}")
        c = contexts.detach().to(self.context_mean)
        std = c.std(dim=0, unbiased=False)
        with torch.no_grad():
            self.context_mean.copy_(c.mean(dim=0))
            self.context_scale.copy_(torch.where(std > min_std, std, torch.ones_like(std)))

    def meta(self) -> Dict[str, Any]:
        """Constructor arguments, to rebuild the network from a checkpoint (:meth:`from_meta`)."""
        return {"context_dim": self.context_dim, "target_dim": self.target_dim,
                "hidden": list(self.hidden), "activation": self.activation}

    @classmethod
    def from_meta(cls, meta: Dict[str, Any]) -> "EnergyModel":
        """Build an untrained network from :meth:`meta`."""
        return cls(int(meta["context_dim"]), int(meta["target_dim"]), list(meta["hidden"]),
                   str(meta["activation"]))

    def context_features(self, context: torch.Tensor) -> torch.Tensor:
        """``W_c x̃^c + b``: ``(B, C) -> (B, H₀)``; reuse it for every particle of a context."""
        if context.dim() != 2 or context.shape[1] != self.context_dim:
            raise ConfigError(f"context: expected shape (B, {self.context_dim}), got {tuple(context.shape)}")
        return self.context_layer((context - self.context_mean) / self.context_scale)

    def energy_from_features(self, features: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """Energies from precomputed context features ``(B, H₀)`` and targets ``(B, P, D)`` -> ``(B, P)``."""
        if y.dim() != 3 or y.shape[0] != features.shape[0] or y.shape[2] != self.target_dim:
            raise ConfigError(f"y: expected shape ({features.shape[0]}, P, {self.target_dim}), "
                              f"got {tuple(y.shape)}")
        h = features[:, None, :] + self.target_layer(y)
        return self.trunk(h).squeeze(-1)

    def forward(self, context: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """``E_θ(x^c, y)``: context ``(B, C)`` with targets ``(B, D)`` -> ``(B,)``, or ``(B, P, D)`` -> ``(B, P)``."""
        feats = self.context_features(context)
        if y.dim() == 2:
            return self.energy_from_features(feats, y[:, None, :])[:, 0]
        return self.energy_from_features(feats, y)


def info_nce_loss(e_pos: torch.Tensor, e_neg: torch.Tensor, reduction: str = "mean") -> torch.Tensor:
    """InfoNCE loss of GFCS eq. 9 from energies.

    ``e_pos``: ``(B,)`` energies ``E_θ(x_j, y*_j)`` of the positives; ``e_neg``: ``(B, K)`` energies
    ``E_θ(x_j, ŷ_j^k)`` of the ``K = N_neg`` negatives of each positive. Per positive,

        ℓ_j = −log( e^{−E⁺_j} / (e^{−E⁺_j} + Σ_k e^{−E⁻_jk}) ) = logsumexp([−E⁺_j, −E⁻_j1, …]) + E⁺_j,

    evaluated with ``torch.logsumexp`` (stable for any energy scale). ``reduction="sum"`` returns eq. 9
    exactly; ``"mean"`` (default) divides by ``B`` so the learning rate does not depend on the batch
    size; ``"none"`` returns ``(B,)``.
    """
    if e_pos.dim() != 1 or e_neg.dim() != 2 or e_neg.shape[0] != e_pos.shape[0]:
        raise ConfigError(f"info_nce_loss: expected e_pos (B,) and e_neg (B, K), got "
                          f"{tuple(e_pos.shape)} and {tuple(e_neg.shape)}")
    logits = torch.cat([-e_pos[:, None], -e_neg], dim=1)
    per = torch.logsumexp(logits, dim=1) + e_pos
    if reduction == "mean":
        return per.mean()
    if reduction == "sum":
        return per.sum()
    if reduction == "none":
        return per
    raise ConfigError(f"invalid reduction: {reduction!r} (choose mean, sum or none)")


class DistanceAutoencoder(nn.Module):
    """MLP autoencoder ``d̂_E (N_R,) -> z (latent_dim,) -> d̂_E`` (GFCS Sec. IV-B, "further reduced").

    Inputs are standardised first, ``(d̂_E − μ) / s`` with the per-entry mean ``μ`` ``(N_R,)`` and one
    overall standard deviation ``s`` of the training codes (set by :meth:`fit`; the common part of the
    distance field would otherwise dominate the code). Encoder: ``N_R -> hidden… -> latent_dim`` with
    ``tanh`` on the code (so ``z ∈ (-1, 1)``); decoder: the mirror image back to standardised units.
    Trained by mean squared reconstruction error (in ``d̂_E`` units) with Adam (:meth:`fit`).
    """

    def __init__(self, input_dim: int, latent_dim: int = 64, hidden: Sequence[int] = (512,),
                 activation: str = "relu") -> None:
        super().__init__()
        self.input_dim = check_positive_int("input_dim", input_dim)
        self.latent_dim = check_positive_int("latent_dim", latent_dim)
        self.hidden = _widths(hidden, "autoencoder hidden")
        self.activation = str(activation)
        enc: List[nn.Module] = []
        prev = self.input_dim
        for w in self.hidden:
            enc += [nn.Linear(prev, w), _activation(self.activation)]
            prev = w
        enc += [nn.Linear(prev, self.latent_dim), nn.Tanh()]
        dec: List[nn.Module] = []
        prev = self.latent_dim
        for w in reversed(self.hidden):
            dec += [nn.Linear(prev, w), _activation(self.activation)]
            prev = w
        dec.append(nn.Linear(prev, self.input_dim))
        self.encoder = nn.Sequential(*enc)
        self.decoder = nn.Sequential(*dec)
        self.register_buffer("mean", torch.zeros(self.input_dim))
        self.register_buffer("scale", torch.ones(()))

    def encode(self, d: torch.Tensor) -> torch.Tensor:
        """Code ``(B, N_R) -> (B, latent_dim)``."""
        return self.encoder((d - self.mean) / self.scale)

    def forward(self, d: torch.Tensor) -> torch.Tensor:
        """Reconstruction ``(B, N_R) -> (B, N_R)`` in ``d̂_E`` units."""
        return self.decoder(self.encode(d)) * self.scale + self.mean

    def encode_numpy(self, d) -> np.ndarray:
        """Codes of normalised distance vectors: ``(B, N_R)`` numpy -> ``(B, latent_dim)`` float64."""
        arr = as_float_array("d_E", d, (None, self.input_dim))
        p = next(self.parameters())
        with torch.no_grad():
            z = self.encode(torch.as_tensor(arr, dtype=p.dtype, device=p.device))
        return z.cpu().double().numpy()

    def fit(self, codes, epochs: int = 300, lr: float = 1e-3, batch_size: int = 64, seed: int = 0) -> List[float]:
        """Train on normalised distance codes ``(N, N_R)``; returns the mean loss of every epoch.

        Sets the standardisation ``μ``, ``s`` from ``codes`` first. Deterministic for a given ``seed`` (a
        private ``torch.Generator`` orders the minibatches).
        """
        arr = as_float_array("codes", codes, (None, self.input_dim))
        if arr.shape[0] == 0:
            raise ConfigError("invalid codes: the autoencoder needs at least one distance vector")
        epochs = check_positive_int("epochs", epochs)
        batch_size = check_positive_int("batch_size", batch_size)
        lr = check_positive("lr", lr)
        p = next(self.parameters())
        data = torch.as_tensor(arr, dtype=p.dtype, device=p.device)
        with torch.no_grad():
            self.mean.copy_(data.mean(dim=0))
            self.scale.fill_(max(float((data - self.mean).std()) if data.shape[0] > 1 else 1.0, 1e-6))
        gen = torch.Generator().manual_seed(int(seed))
        opt = torch.optim.Adam(self.parameters(), lr=lr)
        history = []
        self.train()
        for _ in range(epochs):
            perm = torch.randperm(data.shape[0], generator=gen).to(data.device)
            total = 0.0
            for start in range(0, data.shape[0], batch_size):
                batch = data[perm[start:start + batch_size]]
                loss = torch.mean((self(batch) - batch) ** 2)
                opt.zero_grad()
                loss.backward()
                opt.step()
                total += float(loss.detach()) * batch.shape[0]
            history.append(total / data.shape[0])
        self.eval()
        return history

    def checkpoint(self) -> Dict[str, Any]:
        """Constructor arguments and weights (CPU tensors) for ``torch.save``."""
        return {"input_dim": self.input_dim, "latent_dim": self.latent_dim, "hidden": list(self.hidden),
                "activation": self.activation,
                "state": {k: v.detach().cpu() for k, v in self.state_dict().items()}}

    @classmethod
    def from_checkpoint(cls, ck: Dict[str, Any], device: Optional[torch.device] = None) -> "DistanceAutoencoder":
        """Inverse of :meth:`checkpoint`."""
        ae = cls(int(ck["input_dim"]), int(ck["latent_dim"]), list(ck["hidden"]), str(ck["activation"]))
        ae.load_state_dict(ck["state"])
        if device is not None:
            ae.to(device)
        ae.eval()
        return ae
