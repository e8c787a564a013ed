"""Fixed-length encoding of a GFCOP (GFCS Sec. IV-B, "Encoding a GFCOP").

The environment ``E`` is a point set ``S = {s_i}`` on obstacle surfaces (sampled from a
:class:`gfcs.Scene` with ``scene.surface_points(spacing)``, or any ``(N, 3)`` cloud from a depth camera).
It is encoded by the reference point-set approach of GFCS Sec. IV-B: for a fixed lattice of ``N_R``
reference points ``ŝ_r``,

    d_E(S, Ŝ)_r = min_{s in S} ‖s − ŝ_r‖₂                                (GFCS Sec. IV-B)

computed with a k-d tree (``scipy.spatial.cKDTree``). The context of a problem is the concatenation
``x^c = [q̂0, q̂̇0, q̂_g, d̂_E]`` of normalised start, start velocity, goal and environment code.

Normalisation (all dimensionless, chosen so that every input is O(1) for the network):

* joint positions ``q`` (start, goal, and the targets ``y``):  ``q̂ = 2 (q − q_low) / (q_up − q_low) − 1``,
  so the joint-limit box maps to ``[-1, 1]^dof``;
* joint velocities: ``q̂̇ = q̇ / q̇_max`` per joint (velocity limit from the robot; joints without a
  positive finite limit are left in rad/s);
* distances: ``d̂ = min(d, d_max) / d_max`` in ``[0, 1]`` with ``d_max = 1 m`` by default; distances
  beyond ``d_max`` saturate (a lattice point that far from every surface says only "free space"), and an
  empty point set encodes as all ones (no obstacle within ``d_max``).

The lattice lives in the scene's world frame (the frame of ``scene.surface_points``). The default box
``[-1, 1] × [-1, 1] × [-0.5, 1.5]`` m is centred on a robot base at the origin and covers the Panda's
reach (0.855 m from the shoulder, shoulder 0.333 m above the base) plus a margin; with the paper's spacing
of 0.15 m it holds 14 × 14 × 14 = 2744 reference points. Give another box for a robot whose base is
elsewhere or for a longer arm. When ``N_R`` is too long, an autoencoder
(:class:`gfcs.learning.ebm.DistanceAutoencoder`) reduces ``d̂_E`` to a short code (GFCS Sec. IV-B).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Dict, Optional, Tuple

import numpy as np
from scipy.spatial import cKDTree

from ._validate import ConfigError, as_float_array, check_positive

__all__ = [
    "EncoderConfig",
    "SceneEncoder",
    "reference_lattice",
    "distance_encoding",
    "normalise_distances",
    "to_unit",
    "from_unit",
    "normalise_velocity",
]

#: Default lattice box, world frame, metres: (lower corner, upper corner).
DEFAULT_BOX_LOWER: Tuple[float, float, float] = (-1.0, -1.0, -0.5)
DEFAULT_BOX_UPPER: Tuple[float, float, float] = (1.0, 1.0, 1.5)


def reference_lattice(
    spacing: float = 0.15,
    lower=DEFAULT_BOX_LOWER,
    upper=DEFAULT_BOX_UPPER,
) -> np.ndarray:
    """Reference points ``Ŝ`` on a regular lattice with equal distance ``spacing`` (m) (GFCS Sec. IV-B).

    Along each axis the lattice holds ``n = floor((upper − lower) / spacing) + 1`` points spaced by
    ``spacing`` and centred in ``[lower, upper]`` (the leftover ``(upper − lower) − (n − 1) spacing`` is
    split evenly on both sides). Returns ``(N_R, 3)`` float64, world frame, ordered x-major then y then z
    (``np.meshgrid(..., indexing="ij")``), so the order is fixed for a given box and spacing.
    """
    spacing = check_positive("spacing", spacing)
    lo = as_float_array("lower", lower, (3,))
    hi = as_float_array("upper", upper, (3,))
    if np.any(hi < lo):
        raise ConfigError(f"invalid lattice box: upper {hi.tolist()} below lower {lo.tolist()}")
    extent = hi - lo
    # The tiny tolerance keeps e.g. 2.0 / 0.1 = 19.999999999999996 from losing its last point.
    counts = np.floor(extent / spacing + 1e-9).astype(np.int64) + 1
    axes = [lo[a] + 0.5 * (extent[a] - (counts[a] - 1) * spacing) + spacing * np.arange(counts[a])
            for a in range(3)]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.ascontiguousarray(np.stack([g.ravel() for g in grid], axis=1))


def distance_encoding(points, reference) -> np.ndarray:
    """Raw ``d_E``: for each reference point, the Euclidean distance (m) to the nearest point of ``points``.

    ``points``: ``(N_E, 3)`` surface samples (any ``N_E >= 0``); ``reference``: ``(N_R, 3)``.
    Returns ``(N_R,)`` float64; all ``+inf`` when the point set is empty (see :func:`normalise_distances`).
    """
    pts = as_float_array("points", points, (None, 3))
    ref = as_float_array("reference", reference, (None, 3))
    if pts.shape[0] == 0:
        return np.full(ref.shape[0], np.inf)
    dist, _ = cKDTree(pts).query(ref, k=1)
    return np.asarray(dist, dtype=np.float64)


def normalise_distances(distances, max_distance: float = 1.0) -> np.ndarray:
    """``d̂ = min(d, d_max) / d_max`` elementwise: distances (m, ``>= 0`` or ``+inf``) to ``[0, 1]``."""
    max_distance = check_positive("max_distance", max_distance)
    d = np.asarray(distances, dtype=np.float64)
    if np.any(np.isnan(d)) or np.any(d < 0.0):
        raise ConfigError("invalid distances: expected non-negative values (inf allowed)")
    return np.minimum(d, max_distance) / max_distance


def _check_limits(lower, upper, size: Optional[int] = None) -> Tuple[np.ndarray, np.ndarray]:
    lo = as_float_array("lower", lower, (size,))
    hi = as_float_array("upper", upper, (lo.shape[0],))
    if np.any(hi <= lo):
        raise ConfigError("invalid joint limits: every upper limit must exceed its lower limit")
    return lo, hi


def to_unit(q, lower, upper) -> np.ndarray:
    """Map joint values to the unit box: ``q̂ = 2 (q − lower) / (upper − lower) − 1``.

    ``q``: ``(..., D)`` in rad (or m); ``lower``, ``upper``: ``(D,)``. Values inside the limits land in
    ``[-1, 1]``; values outside are mapped linearly (not clipped).
    """
    lo, hi = _check_limits(lower, upper)
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != lo.shape:
        raise ConfigError(f"q: expected last axis of size {lo.shape[0]}, got shape {q.shape}")
    return 2.0 * (q - lo) / (hi - lo) - 1.0


def from_unit(u, lower, upper) -> np.ndarray:
    """Inverse of :func:`to_unit`: ``q = lower + (u + 1) (upper − lower) / 2``; ``u``: ``(..., D)``."""
    lo, hi = _check_limits(lower, upper)
    u = np.asarray(u, dtype=np.float64)
    if u.shape[-1:] != lo.shape:
        raise ConfigError(f"u: expected last axis of size {lo.shape[0]}, got shape {u.shape}")
    return lo + 0.5 * (u + 1.0) * (hi - lo)


def normalise_velocity(qd, velocity_limits=None) -> np.ndarray:
    """``q̇ / q̇_max`` per joint; joints whose limit is missing, zero or infinite keep their rad/s value."""
    qd = np.asarray(qd, dtype=np.float64)
    if velocity_limits is None:
        return qd.copy()
    vmax = np.asarray(velocity_limits, dtype=np.float64)
    if vmax.shape != qd.shape[-1:]:
        raise ConfigError(f"velocity_limits: expected shape {qd.shape[-1:]}, got {vmax.shape}")
    scale = np.where(np.isfinite(vmax) & (vmax > 0.0), vmax, 1.0)
    return qd / scale


@dataclass
class EncoderConfig:
    """Settings of the environment encoding (GFCS Sec. IV-B). Lengths in metres, world frame.

    Attributes:
        spacing: lattice spacing of the reference points (paper: 0.15 m).
        box_lower, box_upper: corners of the lattice box.
        max_distance: saturation distance ``d_max`` of the normalisation.
        surface_spacing: spacing passed to ``scene.surface_points`` when a scene is encoded.
    """

    spacing: float = 0.15
    box_lower: Tuple[float, float, float] = DEFAULT_BOX_LOWER
    box_upper: Tuple[float, float, float] = DEFAULT_BOX_UPPER
    max_distance: float = 1.0
    surface_spacing: float = 0.04

    def to_dict(self) -> Dict[str, Any]:
        """Plain-Python dict (lists, floats) for checkpoints."""
        d = asdict(self)
        d["box_lower"] = [float(v) for v in self.box_lower]
        d["box_upper"] = [float(v) for v in self.box_upper]
        return d

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "EncoderConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ``ConfigError``."""
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ConfigError(f"encoder config: unknown fields {sorted(unknown)}")
        d = dict(d)
        for key in ("box_lower", "box_upper"):
            if key in d:
                d[key] = tuple(float(v) for v in d[key])
        return cls(**d)


@dataclass
class SceneEncoder:
    """Encoder from a problem (q0, q̇0, q_g, E) to the context vector ``x^c`` (GFCS Sec. IV-B).

    Attributes:
        config: lattice and normalisation settings.
        autoencoder: optional trained :class:`gfcs.learning.ebm.DistanceAutoencoder`; when present the
            environment code is its latent vector instead of the ``N_R`` normalised distances.
        reference: ``(N_R, 3)`` reference lattice (derived from ``config``).
    """

    config: EncoderConfig = field(default_factory=EncoderConfig)
    autoencoder: Any = None
    reference: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        c = self.config
        check_positive("max_distance", c.max_distance)
        check_positive("surface_spacing", c.surface_spacing)
        self.reference = reference_lattice(c.spacing, c.box_lower, c.box_upper)

    @property
    def n_reference(self) -> int:
        """``N_R``, the number of lattice points (length of the raw distance code)."""
        return int(self.reference.shape[0])

    @property
    def env_dim(self) -> int:
        """Length of the environment code: ``N_R``, or the autoencoder's latent size."""
        return self.n_reference if self.autoencoder is None else int(self.autoencoder.latent_dim)

    def distances(self, points) -> np.ndarray:
        """Normalised ``d̂_E`` (``(N_R,)`` in ``[0, 1]``) of a point set ``(N_E, 3)`` (m, world frame)."""
        return normalise_distances(distance_encoding(points, self.reference), self.config.max_distance)

    def encode_points(self, points) -> np.ndarray:
        """Environment code ``(env_dim,)`` of a point set: ``d̂_E``, through the autoencoder if any."""
        d = self.distances(points)
        if self.autoencoder is None:
            return d
        return self.autoencoder.encode_numpy(d[None, :])[0]

    def scene_points(self, scene) -> np.ndarray:
        """Obstacle surface samples of a :class:`gfcs.Scene`: ``scene.surface_points(surface_spacing)``."""
        return np.asarray(scene.surface_points(self.config.surface_spacing), dtype=np.float64).reshape(-1, 3)

    def encode_scene(self, scene) -> np.ndarray:
        """Environment code ``(env_dim,)`` of a :class:`gfcs.Scene`."""
        return self.encode_points(self.scene_points(scene))

    def context(self, q0, qd0, goal, env_code, lower, upper, velocity_limits=None) -> np.ndarray:
        """``x^c = [q̂0, q̂̇0, q̂_g, env_code]``, shape ``(3 dof + env_dim,)``.

        ``q0``, ``qd0``, ``goal``, ``lower``, ``upper``, ``velocity_limits``: ``(dof,)`` (rad, rad/s);
        ``env_code``: ``(env_dim,)`` from :meth:`encode_points` / :meth:`encode_scene`.
        """
        lo, hi = _check_limits(lower, upper)
        dof = lo.shape[0]
        q0 = as_float_array("q0", q0, (dof,))
        qd0 = as_float_array("qd0", qd0, (dof,))
        goal = as_float_array("goal", goal, (dof,))
        env = as_float_array("env_code", env_code, (self.env_dim,))
        return np.concatenate([
            to_unit(q0, lo, hi),
            normalise_velocity(qd0, velocity_limits),
            to_unit(goal, lo, hi),
            env,
        ])

    def problem_context(self, problem, env_code: Optional[np.ndarray] = None) -> np.ndarray:
        """Context of a :class:`gfcs.problems.Problem` (uses ``robot.lower/upper/velocity_limits``).

        ``env_code`` may be given to reuse a precomputed :meth:`encode_scene` of ``problem.scene``.
        """
        robot = problem.robot
        if env_code is None:
            env_code = self.encode_scene(problem.scene)
        return self.context(problem.q0, problem.qd0, problem.goal, env_code, robot.lower, robot.upper,
                            getattr(robot, "velocity_limits", None))

    def state_dict(self) -> Dict[str, Any]:
        """Checkpointable state: config dict and the autoencoder's state (or ``None``)."""
        return {
            "config": self.config.to_dict(),
            "autoencoder": None if self.autoencoder is None else self.autoencoder.checkpoint(),
        }

    @classmethod
    def from_state_dict(cls, state: Dict[str, Any]) -> "SceneEncoder":
        """Inverse of :meth:`state_dict` (imports torch only when an autoencoder is stored)."""
        ae = None
        if state.get("autoencoder") is not None:
            from .ebm import DistanceAutoencoder

            ae = DistanceAutoencoder.from_checkpoint(state["autoencoder"])
        return cls(EncoderConfig.from_dict(state["config"]), ae)
