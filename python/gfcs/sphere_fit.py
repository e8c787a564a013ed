"""Collision spheres fitted to a robot's collision geometry in about a second: the fabric's spheres for a
robot whose description has none.

The fabric avoids obstacles and itself with collision spheres. A MotionBenchMaker robot ships a spherized
URDF, the shipped Panda its own spheres; a URDF with meshes only (most MoveIt descriptions) has none, and a
fabric without spheres cannot avoid anything. :func:`with_fitted_spheres` gives such a robot spheres that
contain every point of its collision geometry, on the links that have geometry and no sphere.

Per link, from the points of its collision elements (every vertex and a seeded area-uniform sample of the
surfaces, :mod:`gfcs.coverage`, in the link frame):

1. for k = 1 … ``max_per_link``: k-means of the points, started at k points spread along the principal axis
   (Lloyd iterations);
2. the smallest k whose clusters' summed volume (a sphere around each cluster's mean through its farthest
   point) is within ``volume_slack`` of the least over all k: more spheres hug a long link more tightly, and
   past that the volume no longer drops;
3. each of its clusters' smallest enclosing sphere (Bădoiu-Clarkson iterations, then SLSQP over the
   cluster's convex hull; the radius covers every point of the cluster exactly), every point of the link then covered (a subsample fits; a point it left
   out grows the sphere it lies least outside of), every radius grown by ``margin``.

Every point of the geometry lies inside a sphere of its link (tested on generated boxes and cylinders). Link
pairs whose fitted spheres overlap in almost every configuration are left out of the self-collision checks
(:func:`always_touching`), as MoveIt Setup Assistant leaves "always in collision" pairs out of an SRDF, and so,
when the meshes are at hand, are pairs whose spheres overlap in most of the configurations in which their
meshes are apart (:func:`sphere_artefacts`: a forearm's spheres round a torso's, where the sphere model forbids
most of what the meshes allow; the meshes still judge the pair). The
spheres are conservative, not tight: ``tools/fit_spheres.py`` fits tighter covers (volume-optimal, minutes per
robot) when the planner should come closer to obstacles.
"""

from __future__ import annotations

import math
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError

__all__ = ["fit_link_spheres", "fitted_spheres", "always_touching", "sphere_artefacts", "with_fitted_spheres",
           "covering_model", "ALWAYS_SHARE", "ARTEFACT_SHARE", "CONTACT_SAMPLES"]

#: Largest number of points a link's fit iterates over (a seeded subsample; every point is covered at the end).
FIT_POINTS = 3000

#: Seeded configurations, uniform in the joint limits, on which :func:`always_touching` and
#: :func:`sphere_artefacts` judge the link pairs.
CONTACT_SAMPLES = 256
#: :func:`always_touching`: MoveIt Setup Assistant's share of samples in collision for "always in collision".
ALWAYS_SHARE = 0.95

#: :func:`sphere_artefacts`: the share of the configurations with a link pair's meshes apart in which its
#: spheres may overlap; beyond it the sphere model contradicts the meshes on most of the pair's free space.
ARTEFACT_SHARE = 0.5


def _hull(points: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``points`` (M, 3) (all of them when it is flat or tiny): the
    points that decide an enclosing sphere."""
    from scipy.spatial import ConvexHull, QhullError

    if points.shape[0] < 5:
        return points
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def _enclosing_sphere(points: np.ndarray, iterations: int = 100) -> Tuple[np.ndarray, float]:
    """(centre (3,), radius) of a sphere containing every one of ``points`` (M, 3), the smallest to within
    the solver's tolerance: Bădoiu-Clarkson iterations (the centre steps toward the farthest point by
    1/(i + 1)) start SLSQP on min r subject to ‖p − c‖² ≤ r² over the hull's vertices, whose centre is kept
    when it covers the points with a smaller radius; the radius is the one that covers every point from the
    centre kept."""
    from scipy.optimize import minimize

    def cover_radius(centre: np.ndarray) -> float:
        return float(np.sqrt(np.max(np.einsum("ij,ij->i", points - centre, points - centre))))

    hull = _hull(points)
    c = hull.mean(axis=0)
    for i in range(1, iterations + 1):
        far = hull[np.argmax(np.einsum("ij,ij->i", hull - c, hull - c))]
        c = c + (far - c) / (i + 1)
    r = float(np.sqrt(np.max(np.einsum("ij,ij->i", hull - c, hull - c))))
    if hull.shape[0] > 1 and r > 0:
        res = minimize(lambda x: x[3], np.r_[c, r], jac=lambda x: np.r_[0.0, 0.0, 0.0, 1.0], method="SLSQP",
                       constraints={"type": "ineq",
                                    "fun": lambda x: x[3] ** 2 - np.einsum("ij,ij->i", hull - x[:3], hull - x[:3]),
                                    "jac": lambda x: np.c_[2.0 * (hull - x[:3]), np.full(hull.shape[0], 2.0 * x[3])]},
                       options={"maxiter": 100, "ftol": 1e-10})
        # SLSQP can step far off on a degenerate hull (a thin cylinder's); its centre is kept only when it
        # covers the points with a smaller sphere than the iterations' centre
        if np.all(np.isfinite(res.x)) and cover_radius(res.x[:3]) < cover_radius(c):
            c = res.x[:3]
    return c, cover_radius(c)


def _kmeans(points: np.ndarray, k: int, iterations: int = 20) -> np.ndarray:
    """(M,) cluster labels of ``points`` (M, 3): Lloyd's k-means started at k points spread along the
    principal axis."""
    centred = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    order = np.argsort(centred @ vt[0], kind="stable")
    centres = points[order[((np.arange(k) + 0.5) * points.shape[0] / k).astype(int)]]
    label = np.zeros(points.shape[0], dtype=int)
    for _ in range(iterations):
        # nearest centre: argmin over j of ‖c_j‖² − 2 p·c_j (‖p − c_j‖² less the row constant ‖p‖²)
        label = np.argmin(np.einsum("ij,ij->i", centres, centres)[None] - 2.0 * (points @ centres.T), axis=1)
        # cluster means by counting sums (one pass over the points, not one boolean mask per cluster); an
        # empty cluster keeps its centre
        counts = np.bincount(label, minlength=k)
        sums = np.stack([np.bincount(label, weights=points[:, a], minlength=k) for a in range(3)], axis=1)
        moved = np.where(counts[:, None] > 0, sums / np.maximum(counts, 1)[:, None], centres)
        if np.all(np.abs(moved - centres) <= 1e-9 + 1e-5 * np.abs(centres)):  # np.allclose(atol=1e-9), inlined
            break
        centres = moved
    return label


def _spread(points: np.ndarray, label: np.ndarray) -> float:
    """Σ over clusters of (largest distance from the cluster's mean)³: the volume (over 4π/3) of the cover
    by spheres around the means, an upper bound of the enclosing spheres'."""
    total = 0.0
    for j in np.unique(label):
        members = points[label == j]
        total += float(np.max(np.linalg.norm(members - members.mean(axis=0), axis=1))) ** 3
    return total


def fit_link_spheres(points: Any, max_per_link: int = 8, margin: float = 0.001, volume_slack: float = 0.15,
                     seed: int = 0) -> List[Tuple[np.ndarray, float]]:
    """Spheres [(centre (3,) m, radius m)] containing every one of ``points`` (N, 3) with ``margin`` [m] to
    spare (see the module docstring); [] for no points.

    Raises:
        gfcs.InvalidValueError: points not (N, 3) finite, ``max_per_link`` < 1, a negative ``margin`` or
            ``volume_slack``.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise InvalidValueError(f"points: expected finite (N, 3) coordinates, got shape {pts.shape}")
    if int(max_per_link) < 1:
        raise InvalidValueError(f"max_per_link must be >= 1, got {max_per_link}")
    if not (margin >= 0 and volume_slack >= 0):
        raise InvalidValueError(f"margin and volume_slack must be >= 0, got {margin} and {volume_slack}")
    if pts.shape[0] == 0:
        return []
    sample = pts
    if pts.shape[0] > FIT_POINTS:
        sample = pts[np.random.default_rng(seed).choice(pts.shape[0], FIT_POINTS, replace=False)]
    labels = [_kmeans(sample, k) for k in range(1, min(int(max_per_link), sample.shape[0]) + 1)]
    volumes = [_spread(sample, label) for label in labels]
    best = min(volumes)
    label = next(lab for lab, v in zip(labels, volumes) if v <= (1.0 + volume_slack) * best)
    cover = [_enclosing_sphere(sample[label == j]) for j in np.unique(label)]
    centres = np.array([c for c, _ in cover])
    radii = np.array([r for _, r in cover])
    # every point, the ones left out of the subsample too: a point outside every sphere grows the sphere it
    # lies least outside of
    dist = np.linalg.norm(pts[:, None, :] - centres[None], axis=2)
    outside = dist - radii[None]
    missed = np.flatnonzero(outside.min(axis=1) > 0)
    for i in missed:
        j = int(np.argmin(outside[i]))
        radii[j] = max(radii[j], float(dist[i, j]))
    return [(centres[j], float(radii[j] + margin)) for j in range(len(radii))]


def fitted_spheres(robot: Any, links: Optional[Sequence[str]] = None, max_per_link: int = 8,
                   margin: float = 0.001, cached: Optional[List[str]] = None) -> List[Tuple[str, List[float], float]]:
    """Spheres fitted to the collision geometry of ``robot``'s ``links`` (default: every link with geometry),
    as ``Robot.with_spheres`` takes them: (link, centre in the link frame [m], radius [m]), link by link in
    ``robot.link_names`` order. Links whose meshes are missing get none.

    The result is kept in the disk cache (:mod:`gfcs.cache`) under the digest of the collision elements, the
    bytes of their mesh files, ``links``, the parameters and the source of this module and
    :mod:`gfcs.coverage`: a robot is fitted once per machine. ``cached``, when given, receives the path of
    the cache entry the result was read from."""
    from gfcs import cache as _cache
    from gfcs.coverage import _key, _link_points

    geometry = tuple(_key(e) for e in robot.collision_geometry())
    wanted = None if links is None else set(links)
    key = _fit_key(geometry, wanted, int(max_per_link), float(margin))
    hit = _cache.load("spheres", key)
    if isinstance(hit, list):
        if cached is not None:
            cached.append(str(_cache.entry("spheres", key)))
        return [(str(link), [float(x) for x in c], float(r)) for link, c, r in hit]
    points: Dict[str, np.ndarray] = _link_points(geometry)
    out: List[Tuple[str, List[float], float]] = []
    for link in robot.link_names:
        if link not in points or (wanted is not None and link not in wanted):
            continue
        for c, r in fit_link_spheres(points[link], max_per_link, margin):
            out.append((str(link), [float(x) for x in c], math.ceil(r * 1e6) / 1e6))
    _cache.store("spheres", key, out)
    return out


def _fit_key(geometry: Tuple[Tuple[Any, ...], ...], wanted: Optional[set], max_per_link: int,
             margin: float) -> str:
    """The cache key of a fit (:func:`fitted_spheres`): what the spheres depend on, mesh bytes and code
    included."""
    from gfcs import cache as _cache
    from gfcs import coverage

    meshes = sorted({path for _, _, path, _, _, _ in geometry if path})
    return _cache.digest("fitted_spheres", geometry, None if wanted is None else sorted(wanted), max_per_link,
                         margin, FIT_POINTS, [(m, _cache.file_digest(m)) for m in meshes],
                         _cache.file_digest(__file__), _cache.file_digest(coverage.__file__))


def _sphere_contacts(robot: Any, links: Sequence[str], samples: int,
                     seed: int) -> Tuple[np.ndarray, List[Tuple[str, str]], np.ndarray]:
    """(q (samples, dof) seeded uniform in the joint limits, the self-collision link pairs of ``robot`` with a
    link in ``links`` (sorted names), (samples, pairs) bool: some sphere pair of the link pair overlaps)."""
    q = np.random.default_rng(seed).uniform(np.asarray(robot.lower), np.asarray(robot.upper),
                                            (int(samples), int(robot.dof)))
    pairs = np.asarray(robot.self_collision_pairs, dtype=np.int64).reshape(-1, 2)
    # each sphere pair as its link pair (indices into the sorted link names: lo < hi), those touching a
    # fitted link only
    names, link = np.unique(np.asarray(robot.sphere_links, dtype=str), return_inverse=True)
    lo, hi = np.minimum(link[pairs[:, 0]], link[pairs[:, 1]]), np.maximum(link[pairs[:, 0]], link[pairs[:, 1]])
    fitted = np.isin(names, list(links))
    keep = np.flatnonzero(fitted[lo] | fitted[hi])
    if keep.size == 0:
        return q, [], np.zeros((q.shape[0], 0), dtype=bool)
    centres = np.asarray(robot.sphere_centers(q), dtype=np.float64).reshape(q.shape[0], -1, 3)
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    a, b = pairs[keep, 0], pairs[keep, 1]
    hit = np.linalg.norm(centres[:, a] - centres[:, b], axis=2) - radii[a] - radii[b] < 0  # (samples, kept)
    # a link pair touches in a sample when any of its sphere pairs does
    code = lo[keep] * len(names) + hi[keep]
    order = np.argsort(code, kind="stable")
    groups, starts = np.unique(code[order], return_index=True)
    touching = np.logical_or.reduceat(hit[:, order], starts, axis=1)
    return q, [(str(names[g // len(names)]), str(names[g % len(names)])) for g in groups], touching


def always_touching(robot: Any, links: Sequence[str], samples: int = CONTACT_SAMPLES, share: float = ALWAYS_SHARE,
                    seed: int = 0) -> List[Tuple[str, str]]:
    """The self-collision link pairs of ``robot`` with a link in ``links`` whose spheres overlap in at least
    ``share`` of ``samples`` seeded configurations uniform in the joint limits: MoveIt Setup Assistant's
    "always in collision" pairs, which it disables, found on the spheres. Spheres fitted around two
    links that meet at a joint two links apart can overlap in every configuration; a fabric pushing them
    apart would fight the robot's own shape."""
    return _always(_sphere_contacts(robot, links, samples, seed), share)


def _always(contacts: Tuple[np.ndarray, List[Tuple[str, str]], np.ndarray], share: float) -> List[Tuple[str, str]]:
    """:func:`always_touching` of the samples ``contacts`` (:func:`_sphere_contacts`)."""
    _, names, touching = contacts
    return [pair for pair, t in zip(names, touching.mean(axis=0)) if t >= share]


def sphere_artefacts(robot: Any, links: Sequence[str], mesh_checker: Any, samples: int = CONTACT_SAMPLES,
                     share: float = ARTEFACT_SHARE, seed: int = 0, cache: bool = True,
                     contacts: Optional[Tuple[np.ndarray, List[Tuple[str, str]], np.ndarray]] = None
                     ) -> List[Tuple[str, str]]:
    """The self-collision link pairs of ``robot`` with a link in ``links`` whose spheres overlap in at least
    ``share`` of the seeded configurations (``samples``, uniform in the joint limits) in which the pair's
    collision meshes (``mesh_checker``'s: a :class:`gfcs.MeshChecker` of ``robot``, or a function that builds
    one, called only when the cache misses; None from it: no pair) are apart: the sphere model
    forbids most of what the meshes allow (spheres round a torso and round an upper arm beside it). Pairs whose
    meshes the checker does not check, or that are apart in fewer than a tenth of the samples, are not judged
    here (:func:`always_touching` judges those). The mesh distances take a fraction of a second on a two-arm
    robot, so the result is kept in the disk cache (:mod:`gfcs.cache`; ``cache=False`` recomputes) under the
    digest of everything it depends on. ``contacts``: the sphere overlaps of these samples when the caller
    has them already (:func:`with_fitted_spheres`, from the samples :func:`always_touching` judged)."""
    from gfcs import cache as _cache
    from gfcs.coverage import _key

    q, names, touching = _sphere_contacts(robot, links, samples, seed) if contacts is None else contacts
    if not names:
        return []
    geometry = tuple(_key(e) for e in robot.collision_geometry())
    key = _cache.digest(
        "sphere_artefacts", names, touching.tobytes().hex(), share, tuple(robot.joint_names),
        np.asarray(robot.lower).tolist(), np.asarray(robot.upper).tolist(), sorted(robot.locked_positions.items()),
        np.asarray(robot.link_poses(q[:4])).round(12).tolist(), geometry,
        sorted({(path, _cache.file_digest(path)) for _, _, path, _, _, _ in geometry if path}),
        np.asarray(robot.self_collision_pairs).tolist(), _cache.file_digest(__file__))
    hit = _cache.load("sphere_artefacts", key) if cache else None
    if isinstance(hit, list):
        return [(str(a), str(b)) for a, b in hit]
    if callable(mesh_checker) and not hasattr(mesh_checker, "pair_clearances"):
        mesh_checker = mesh_checker()
    if mesh_checker is None:  # the factory found no meshes: nothing to judge by
        return []
    wanted = {pair: k for k, pair in enumerate(names)}
    d = np.atleast_2d(mesh_checker.pair_clearances(q, cutoff=0.0, depth=False))
    contact = np.zeros((q.shape[0], len(names)), dtype=bool)
    checked = np.zeros(len(names), dtype=bool)
    for j, (a, b) in enumerate(mesh_checker.self_pair_links):
        k = wanted.get((a, b) if a <= b else (b, a))
        if k is not None:
            contact[:, k] |= d[:, j] <= 0.0
            checked[k] = True
    apart = ~contact
    count = apart.sum(axis=0)
    overlap = (touching & apart).sum(axis=0) / np.maximum(count, 1)
    out = [pair for pair, c, n, o in zip(names, checked, count, overlap) if c and n >= 0.1 * q.shape[0] and o >= share]
    _cache.store("sphere_artefacts", key, [list(p) for p in out])
    return out


def with_fitted_spheres(robot: Any, max_per_link: int = 8, margin: float = 0.001,
                        left_out: Optional[List[Tuple[str, str]]] = None, cached: Optional[List[str]] = None,
                        mesh_checker: Any = None) -> Any:
    """``robot`` with spheres fitted (:func:`fitted_spheres`) on each link whose collision geometry carries
    no collision sphere (:func:`gfcs.problems.links_without_spheres`), its own spheres kept, and the link
    pairs whose fitted spheres always overlap (:func:`always_touching`) left out of its self-collision
    checks, as MoveIt Setup Assistant leaves them out of an SRDF, and with a ``mesh_checker`` (a
    :class:`gfcs.MeshChecker` of ``robot`` or a function that builds one) the pairs whose spheres overlap
    where their meshes are apart (:func:`sphere_artefacts`); ``robot`` itself when every link with geometry
    has spheres. The SRDF's disabled pairs still apply to the new spheres. ``left_out``, when given,
    receives the (link, link) pairs left out; ``cached`` the cache entry the spheres were read from, when
    they were (:func:`fitted_spheres`)."""
    from gfcs.problems import _robot_spheres, links_without_spheres

    bare = links_without_spheres(robot)
    if not bare:
        return robot
    fitted = robot.with_spheres(_robot_spheres(robot) + fitted_spheres(robot, bare, max_per_link, margin, cached))
    return _without_overlapping_pairs(fitted, bare, mesh_checker, left_out)


def covering_model(robot: Any, mesh_checker: Any, max_per_link: int = 8, margin: float = 0.001) -> Any:
    """``robot`` with its collision spheres replaced by spheres fitted (:func:`fitted_spheres`) to the collision
    geometry of ``mesh_checker.robot`` (the meshes that judge its motions; links ``robot`` does not have are
    left out), with the link pairs whose fitted spheres always overlap, or overlap where the meshes are apart,
    left out of its self-collision checks (:func:`with_fitted_spheres`). Every point of those meshes lies
    inside a sphere of its link: a motion whose spheres are clear has clear meshes, where a sphere model made
    for another checker leaves centimetres of them uncovered (:func:`gfcs.coverage.sphere_deficits`). A link
    the description models by ``<sphere>`` elements alone (the Fetch's head) carries those spheres exactly
    (:func:`gfcs.coverage.element_spheres`), not spheres fitted around them."""
    from gfcs.coverage import element_spheres
    from gfcs.problems import _robot_spheres

    mesh_robot = mesh_checker.robot
    known = set(robot.link_names)
    shaped = sorted({e["link"] for e in mesh_robot.collision_geometry() if e["type"] != "sphere"} & known)
    fitted = fitted_spheres(mesh_robot, shaped, max_per_link, margin) if shaped else []
    exact = [s for s in element_spheres(mesh_robot) if s[0] in known and s[0] not in shaped]
    links = sorted({link for link, _, _ in fitted + exact})
    if not links:
        return robot
    kept = [s for s in _robot_spheres(robot) if s[0] not in links]
    return _without_overlapping_pairs(robot.with_spheres(kept + fitted + exact), links, mesh_checker, None)


def _without_overlapping_pairs(fitted: Any, links: Sequence[str], mesh_checker: Any,
                               left_out: Optional[List[Tuple[str, str]]]) -> Any:
    """``fitted`` with its link pairs (a link of ``links`` in each) whose spheres always overlap
    (:func:`always_touching`) or, with a ``mesh_checker``, overlap where the meshes are apart
    (:func:`sphere_artefacts`) left out of its self-collision checks; ``left_out`` receives them."""
    contacts = _sphere_contacts(fitted, links, CONTACT_SAMPLES, 0)  # one set of samples judges both ways
    touching = _always(contacts, ALWAYS_SHARE)
    if mesh_checker is not None:
        touching += [p for p in sphere_artefacts(fitted, links, mesh_checker, contacts=contacts) if p not in touching]
    if left_out is not None:
        left_out.extend(touching)
    return fitted.with_disabled_pairs(touching) if touching else fitted
