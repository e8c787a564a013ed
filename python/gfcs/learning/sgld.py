"""Stochastic gradient Langevin dynamics on the energy ``E_θ`` (GFCS Sec. IV-B, eq. 10-11).

Particles start uniform in the joint-limit box (``y⁰ ~ U(q_low, q_up)``) and follow, for
``k = 0 … iters − 1``,

    y^{k+1} = reflect( y^k − s · (σ_k² / 2) · ∇_y E_θ(x^c, y^k) + η^k ),   η^k ~ N(0, σ_k² · τ² I),
    σ_k² = (1 + k)^{−0.5},

**Sign.** Eq. 10 is printed with ``+ ∇E``, but the loss of eq. 9 gives the positives (the solutions)
*low* energy, so the particles must move *down* the energy: we subtract the gradient. With ``s = τ = 1``
this is exactly the unadjusted Langevin algorithm with step ``ε_k = σ_k²`` whose stationary law is
``∝ exp(−E_θ)``; the schedule of eq. 11 anneals the step.

**Added scaling** (settings of :class:`SGLDConfig`; ``step_scale = noise_scale = 1``, ``max_step = None``
give eq. 10-11 exactly):

* ``step_scale`` ``s`` multiplies the drift (default 1);
* ``noise_scale`` ``τ`` multiplies the noise standard deviation (default 1, the paper's). The chain then
  samples ``∝ exp(−E_θ s / τ²)``, i.e. temperature ``T = τ² / s``. A smaller ``τ`` (``gfcs train
  --negative-noise 0.3``, the project's variant for the training negatives) concentrates the samples near
  the energy's minima while still spreading them enough to serve as InfoNCE negatives (docs/tuning.md);
* ``max_step`` clips each coordinate of the drift to ``[−max_step, max_step]`` (unit-box units, default
  0.1, ``None`` disables it): a sharp EBM has gradients that would throw every particle onto the box
  boundary in one step. 100 iterations still let a particle cross the box several times;
* reflection: a step that leaves the joint-limit box is mirrored back into it at the face it crossed
  (a reflecting boundary, under which the chain keeps sampling ``∝ exp(−E_θ s / τ²)`` restricted to the
  box). Clamping instead made the faces absorbing: with a ReLU energy that keeps sloping outward beyond
  the data, 40 % of the coordinates of trained-model samples ended exactly on a joint limit (2 % for
  uniform draws) and the learned first batch solved fewer problems than a uniform one.

Coordinates: everything runs in the unit box ``[-1, 1]^D`` of :func:`gfcs.learning.encoding.to_unit`
(joint limits map to ±1), so the schedule ``σ_k²`` has the same meaning for every joint and robot.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any, Dict, Optional, Tuple

import torch

from ._validate import ConfigError, check_positive, check_positive_int

__all__ = ["SGLDConfig", "reflect_into_box", "sigma2", "sgld"]


def sigma2(k: int) -> float:
    """Noise/step schedule of GFCS Sec. IV-B: ``σ_k² = (1 + k)^{−0.5}`` (``k = 0, 1, …``)."""
    return float((1.0 + k) ** -0.5)


@dataclass
class SGLDConfig:
    """SGLD settings (see the module docstring for the update rule).

    Attributes:
        iters: number of Langevin iterations (the paper's "maximum number of iterations").
        step_scale: factor ``s`` on the drift ``(σ_k²/2) ∇E``.
        noise_scale: factor ``τ`` on the noise standard deviation ``σ_k``.
        max_step: per-coordinate clip of the drift in unit-box units, or ``None``.
    """

    iters: int = 100
    step_scale: float = 1.0
    noise_scale: float = 1.0
    max_step: Optional[float] = 0.1

    def validate(self) -> "SGLDConfig":
        """Raise ``ConfigError`` on a bad setting; returns ``self``."""
        check_positive_int("sgld iters", self.iters, minimum=0)
        check_positive("sgld step_scale", self.step_scale)
        if not (self.noise_scale >= 0.0):
            raise ConfigError(f"invalid sgld noise_scale: expected >= 0, got {self.noise_scale!r}")
        if self.max_step is not None:
            check_positive("sgld max_step", self.max_step)
        return self

    def with_noise(self, noise_scale: float) -> "SGLDConfig":
        """A copy with noise scale ``noise_scale`` (validated)."""
        return replace(self, noise_scale=noise_scale).validate()

    def to_dict(self) -> Dict[str, Any]:
        """Plain dict for checkpoints."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "SGLDConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ``ConfigError``."""
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ConfigError(f"sgld config: unknown fields {sorted(unknown)}")
        return cls(**d).validate()


def reflect_into_box(y: torch.Tensor) -> torch.Tensor:
    """Mirror ``y`` into ``[-1, 1]`` at the faces it crossed (a triangle wave of period 4, so any
    overshoot, however large, lands inside)."""
    m = torch.remainder(y + 1.0, 4.0)
    return torch.where(m > 2.0, 4.0 - m, m) - 1.0


def sgld(
    model,
    context: torch.Tensor,
    n_particles: int,
    config: Optional[SGLDConfig] = None,
    generator: Optional[torch.Generator] = None,
    init: Optional[torch.Tensor] = None,
) -> Tuple[torch.Tensor, torch.Tensor]:
    """Run SGLD for a batch of contexts.

    Args:
        model: an :class:`gfcs.learning.ebm.EnergyModel` (its parameters are not modified and get no
            gradient).
        context: ``(B, C)`` contexts ``x^c`` on the model's device and dtype.
        n_particles: ``P`` particles per context.
        config: :class:`SGLDConfig` (defaults when ``None``).
        generator: ``torch.Generator`` on the model's device for the initial particles and the noise;
            a run is reproducible given its state.
        init: optional ``(B, P, D)`` initial particles in the unit box instead of ``U([-1, 1]^D)``.

    Returns:
        ``(y, energies)``: particles ``(B, P, D)`` in the unit box ``[-1, 1]^D`` (detached) and their
        energies ``(B, P)`` at the final iterate.
    """
    cfg = (config or SGLDConfig()).validate()
    n_particles = check_positive_int("n_particles", n_particles)
    if context.dim() != 2:
        raise ConfigError(f"context: expected shape (B, C), got {tuple(context.shape)}")
    b, d = context.shape[0], model.target_dim
    dev, dtype = context.device, context.dtype
    if init is None:
        y = torch.rand((b, n_particles, d), generator=generator, device=dev, dtype=dtype) * 2.0 - 1.0
    else:
        if tuple(init.shape) != (b, n_particles, d):
            raise ConfigError(f"init: expected shape ({b}, {n_particles}, {d}), got {tuple(init.shape)}")
        y = init.detach().to(device=dev, dtype=dtype).clamp(-1.0, 1.0)
    with torch.no_grad():
        feats = model.context_features(context)
    for k in range(cfg.iters):
        s2 = sigma2(k)
        y = y.detach().requires_grad_(True)
        energy = model.energy_from_features(feats, y)
        (grad,) = torch.autograd.grad(energy.sum(), y)
        with torch.no_grad():
            drift = (cfg.step_scale * 0.5 * s2) * grad
            if cfg.max_step is not None:
                drift = drift.clamp(-cfg.max_step, cfg.max_step)
            noise = torch.randn(y.shape, generator=generator, device=dev, dtype=dtype)
            y = reflect_into_box(y - drift + (cfg.noise_scale * s2 ** 0.5) * noise)
    y = y.detach()
    with torch.no_grad():
        energy = model.energy_from_features(feats, y)
    return y, energy
