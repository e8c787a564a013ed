#!/usr/bin/env python3
"""Fit conservative collision spheres to the collision geometry of a URDF.

For every selected link, the link's collision elements (meshes, boxes, cylinders, spheres; each placed by its
``<origin>``) are merged into one triangle mesh expressed in the URDF link frame. The tool then looks for few
spheres whose union contains every point of that mesh (surface and enclosed volume) and exceeds it little:

1. Targets: every mesh vertex, a seeded area-uniform sample of the surface, and the points of a regular grid
   that lie inside the mesh (generalised winding number >= 1/2, which also works for the open, non-manifold
   meshes some robots ship).
2. For a sphere count k: starts from k-means of the surface sample (each sphere just holding its targets) and
   from the best (k-1)-sphere cover with its largest sphere split in two. Each start minimises the volume of
   the union outside the mesh (soft union membership of outside grid points) plus a rising penalty on
   uncovered targets (L-BFGS-B), is then grown to cover every target exactly and cleared of redundant spheres.
   The cover of smallest union volume wins; the (k-1) cover competes, so the volume never rises with k.
3. Budget: every link starts with one sphere; one more sphere goes, again and again, to the link whose union
   volume drops most, while the drop is at least ``--min-gain`` times the total mesh volume, no link has more
   than ``--max-per-link`` and the total stays within ``--max-total``.
4. ``--margin`` is added to every radius, then a denser, independent sample (vertices, surface, interior) is
   checked and any sphere that misses one of its points is grown just enough (centres stay).
   With ``--gap g`` (default 0) steps 2-4 fit and repair that cover while the volume they minimise is that of
   the spheres shrunk by g, and the output is the shrunk spheres: thinner spheres that miss the mesh by at
   most g (a fabric then avoids obstacles with them and a mesh check validates its motions).
5. A third independent sample gives the reported coverage; the union volume is counted on a grid and the
   protrusion (how far the union reaches beyond the mesh) from points on the union's boundary.

Output (``--out``, JSON): ``{"spheres": [{"link": name, "center": [x, y, z], "radius": r}, ...]}``, centres
in metres in the URDF link frame, radii in metres, rounded outwards to 1 micrometre. The per-link report
(sphere count, largest uncovered distance, union-to-mesh volume ratio, largest protrusion) goes to stderr and,
with ``--report``, to a JSON file.

Everything is seeded (``--seed``): the same input and options give the same output.

Example (the shipped Panda spheres)::

    python tools/fit_spheres.py ../shared/robots/mbm_panda/panda.urdf \
        --out crates/fabric-core/assets/panda_spheres.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

# One BLAS thread: the optimisation solves many tiny problems, for which OpenBLAS's thread start-up costs
# about 30 times the work (measured: 10 ms against 0.3 ms per L-BFGS-B iteration). Only effective when this
# file is run as a program (numpy not yet imported); the caller's own settings win.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import trimesh
import yourdfpy
from scipy.optimize import minimize
from scipy.spatial.distance import cdist

#: Slack (normalised length) when deciding which sphere holds a target (see :func:`split_largest`).
COVER_TOL = 1e-7
#: Smallest radius (m) a sphere keeps when ``--gap`` is taken off.
MIN_RADIUS = 0.001

#: Coverage weights ``mu`` of the successive :class:`UnionObjective` minimisations.
PENALTY_STAGES = (1e1, 1e2, 1e3, 1e4)

#: Decimal places written for centres and radii (1e-6 m).
DECIMALS = 6


class FitError(RuntimeError):
    """A URDF, a mesh file or an option the tool cannot use (the message names the culprit)."""


@dataclass
class Sphere:
    """One sphere in a link frame: ``center`` (3,) in metres, ``radius`` in metres (> 0)."""

    center: np.ndarray
    radius: float


@dataclass
class FitOptions:
    """Tunables of :func:`fit_robot` (see the module doc and ``--help``).

    ``margin`` and ``gap`` in metres; ``min_gain`` a fraction of the total mesh volume; ``tau`` (soft union
    width) in units of each link's bounding-box diagonal; ``iterations`` per L-BFGS-B stage; the
    ``*_points`` are sample sizes (surface points, or points of a grid over the bounding box before the
    inside test).
    """

    margin: float = 0.001
    gap: float = 0.0
    max_per_link: int = 10
    max_total: int = 64
    min_gain: float = 0.0015
    restarts: int = 2
    tau: float = 0.01
    iterations: int = 150
    seed: int = 0
    fit_surface_points: int = 3000
    fit_grid_points: int = 3000
    outside_grid_points: int = 15000
    check_surface_points: int = 60000
    check_grid_points: int = 60000


@dataclass
class LinkReport:
    """Figures for one fitted link (lengths in metres, volumes in cubic metres)."""

    link: str
    spheres: int
    max_uncovered: float
    max_uncovered_vertices: float
    mesh_volume: float
    union_volume: float
    max_protrusion: float
    checked_points: int

    @property
    def volume_ratio(self) -> float:
        """Union-of-spheres volume divided by the mesh volume (inf for a mesh without volume)."""
        return self.union_volume / self.mesh_volume if self.mesh_volume > 0 else math.inf


@dataclass
class LinkFit:
    """Spheres of one link plus its report."""

    link: str
    spheres: list[Sphere]
    report: LinkReport | None = None


# --------------------------------------------------------------------------------------------- URDF input


def resolve_mesh_path(filename: str, mesh_dir: Path, urdf_dir: Path) -> Path:
    """Find the file a URDF mesh ``filename`` names.

    ``package://pkg/rest`` is tried as ``mesh_dir/pkg/rest``, ``mesh_dir/rest``, ``urdf_dir/pkg/rest`` and
    ``urdf_dir/rest``; ``file://`` and plain paths are taken as absolute or relative to ``mesh_dir`` then
    ``urdf_dir``. Raises :class:`FitError` naming the file when none exists.
    """
    if filename.startswith("package://"):
        rest = filename[len("package://"):]
        parts = Path(rest).parts
        tails = [Path(rest)] + ([Path(*parts[1:])] if len(parts) > 1 else [])
    else:
        rest = filename[len("file://"):] if filename.startswith("file://") else filename
        if Path(rest).is_absolute():
            if Path(rest).is_file():
                return Path(rest)
            raise FitError(f"mesh file {filename!r} does not exist")
        tails = [Path(rest)]
    tried = []
    for base in (mesh_dir, urdf_dir):
        for tail in tails:
            path = base / tail
            tried.append(str(path))
            if path.is_file():
                return path
    raise FitError(f"mesh file {filename!r} not found (tried {', '.join(tried)})")


def clean_mesh(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Merge duplicated vertices (OBJ files split them by normal/texture) and drop degenerate faces."""
    out = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces), process=True)
    out.merge_vertices(merge_tex=True, merge_norm=True)
    out.update_faces(out.nondegenerate_faces())
    out.remove_unreferenced_vertices()
    return out


def load_mesh_file(path: Path) -> trimesh.Trimesh:
    """Load every triangle of a mesh file (OBJ, STL, DAE, ...) as one cleaned mesh in the file's frame."""
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many exception types for bad files
        raise FitError(f"cannot read mesh file {path}: {exc}") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise FitError(f"mesh file {path} holds no triangles")
    return clean_mesh(loaded)


def geometry_mesh(geometry: yourdfpy.Geometry, link: str, mesh_dir: Path, urdf_dir: Path) -> trimesh.Trimesh:
    """Triangle mesh of one URDF ``<geometry>`` in its element frame (before the collision origin).

    Cylinders (axis z, centred) use 96 sections and spheres an icosphere of 4 subdivisions; both are
    inscribed polyhedra whose gap to the true surface (< 0.06 % of the radius) the margin and the repair step
    absorb.
    """
    if geometry.mesh is not None:
        mesh = load_mesh_file(resolve_mesh_path(geometry.mesh.filename, mesh_dir, urdf_dir))
        scale = geometry.mesh.scale
        if scale is not None:
            factors = np.broadcast_to(np.asarray(scale, dtype=float), (3,))
            if not np.all(np.isfinite(factors)) or np.any(factors == 0):
                raise FitError(f"link {link!r}: mesh scale {scale!r} is not usable")
            mesh.apply_transform(np.diag([*factors, 1.0]))
        return mesh
    if geometry.box is not None:
        return trimesh.creation.box(extents=np.asarray(geometry.box.size, dtype=float))
    if geometry.cylinder is not None:
        return trimesh.creation.cylinder(radius=float(geometry.cylinder.radius),
                                         height=float(geometry.cylinder.length), sections=96)
    if geometry.sphere is not None:
        return trimesh.creation.icosphere(subdivisions=4, radius=float(geometry.sphere.radius))
    raise FitError(f"link {link!r}: collision geometry has no mesh, box, cylinder or sphere")


def load_link_meshes(urdf_path: str | Path, mesh_dir: str | Path | None = None,
                     links: Sequence[str] | None = None) -> dict[str, trimesh.Trimesh]:
    """Collision geometry of each link, merged into one mesh in the URDF link frame.

    Each collision element's ``<origin>`` is applied. ``links`` selects links (all links with collision
    geometry when None); asking for a link that does not exist or has no collision geometry is an error.
    Returns ``{link name: mesh}`` in URDF order.
    """
    urdf_path = Path(urdf_path)
    if not urdf_path.is_file():
        raise FitError(f"URDF file {urdf_path} does not exist")
    try:
        urdf = yourdfpy.URDF.load(str(urdf_path), build_scene_graph=False, load_meshes=False,
                                  load_collision_meshes=False)
    except Exception as exc:  # yourdfpy/lxml raise various errors on bad XML
        raise FitError(f"cannot parse URDF {urdf_path}: {exc}") from exc
    urdf_dir = urdf_path.resolve().parent
    base = Path(mesh_dir).resolve() if mesh_dir is not None else urdf_dir
    by_name = {link.name: link for link in urdf.robot.links}
    if links is not None:
        missing = [name for name in links if name not in by_name]
        if missing:
            raise FitError(f"links {missing} are not in {urdf_path}")
    wanted = list(links) if links is not None else [link.name for link in urdf.robot.links]
    result: dict[str, trimesh.Trimesh] = {}
    for name in wanted:
        parts = []
        for collision in by_name[name].collisions:
            mesh = geometry_mesh(collision.geometry, name, base, urdf_dir)
            if collision.origin is not None:
                mesh.apply_transform(np.asarray(collision.origin, dtype=float))
            parts.append(mesh)
        if not parts:
            if links is not None:
                raise FitError(f"link {name!r} has no collision geometry")
            continue
        result[name] = clean_mesh(trimesh.util.concatenate(parts))
    if not result:
        raise FitError(f"no link of {urdf_path} has collision geometry")
    return result


# ----------------------------------------------------------------------------------------------- geometry


def winding_numbers(mesh: trimesh.Trimesh, points: np.ndarray, chunk_elems: int = 400_000) -> np.ndarray:
    """Generalised winding number of ``mesh`` at ``points`` (N, 3) -> (N,).

    Sum of the signed solid angles of the triangles seen from each point over 4 pi (Jacobson et al. 2013,
    solid angle by Van Oosterom and Strackee 1983): about 1 inside a closed outward-oriented mesh, 0 outside,
    and a smooth, still usable value for open or self-overlapping meshes.
    """
    tri = np.asarray(mesh.triangles, dtype=float)
    out = np.empty(len(points))
    step = max(1, chunk_elems // max(1, len(tri)))
    for start in range(0, len(points), step):
        p = points[start:start + step, None, None, :]
        abc = tri[None, :, :, :] - p  # (n, m, 3, 3)
        a, b, c = abc[:, :, 0], abc[:, :, 1], abc[:, :, 2]
        la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
        det = np.einsum("nmi,nmi->nm", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("nmi,nmi->nm", a, b) * lc
               + np.einsum("nmi,nmi->nm", b, c) * la + np.einsum("nmi,nmi->nm", c, a) * lb)
        out[start:start + step] = np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)
    return out


def inside(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Boolean (N,): ``|winding number| >= 1/2`` (inside, whatever the face orientation)."""
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    return np.abs(winding_numbers(mesh, points)) >= 0.5


def centred_grid(lower: np.ndarray, upper: np.ndarray, count: int) -> tuple[np.ndarray, float]:
    """About ``count`` points of a cubic grid centred on the box [lower, upper]; returns (points (N,3), step)."""
    span = np.asarray(upper, dtype=float) - np.asarray(lower, dtype=float)
    extent = np.maximum(span, 1e-3 * max(float(span.max()), 1e-9))  # flat boxes: no vanishing step
    step = float((np.prod(extent) / max(count, 1)) ** (1.0 / 3.0))
    axes = []
    for lo, hi in zip(lower, upper):
        n = int(math.floor((hi - lo) / step)) + 1
        axes.append((lo + hi) / 2.0 + step * (np.arange(n) - (n - 1) / 2.0))
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid, step


def surface_distance(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Unsigned distance (N,) from ``points`` (N, 3) to the mesh surface (exact, via trimesh)."""
    if len(points) == 0:
        return np.zeros(0)
    _, dist, _ = trimesh.proximity.closest_point(mesh, points)
    return np.asarray(dist, dtype=float)


def sample_points(mesh: trimesh.Trimesh, surface_count: int, grid_count: int, seed: int) -> np.ndarray:
    """Vertices + ``surface_count`` seeded surface samples + interior points of a ``grid_count`` grid, (N, 3)."""
    surface, _ = trimesh.sample.sample_surface(mesh, surface_count, seed=seed)
    grid, step = centred_grid(mesh.bounds[0], mesh.bounds[1], grid_count)
    # shift the grid by a seeded fraction of a step so samples of different seeds do not share points
    grid = grid + np.random.default_rng(seed).uniform(-0.5, 0.5, 3) * step
    return np.vstack([mesh.vertices, surface, grid[inside(mesh, grid)]])


def excess(points: np.ndarray, spheres: Sequence[Sphere]) -> np.ndarray:
    """Per point (N,): ``min_j |p - c_j| - r_j``, the distance by which the union misses it (<= 0: covered)."""
    if not spheres:
        return np.full(len(points), np.inf)
    centers = np.array([s.center for s in spheres])
    radii = np.array([s.radius for s in spheres])
    best = np.full(len(points), np.inf)
    for start in range(0, len(points), 20000):
        p = points[start:start + 20000]
        d = np.linalg.norm(p[:, None, :] - centers[None], axis=-1) - radii[None]
        best[start:start + 20000] = d.min(axis=1)
    return best


# ------------------------------------------------------------------------------------------------ fitting


def drop_redundant(targets: np.ndarray, spheres: list[Sphere]) -> list[Sphere]:
    """Remove spheres whose targets (N, 3) the remaining spheres all hold (tried last sphere first)."""
    if not spheres:
        return spheres
    centers = np.array([s.center for s in spheres])
    radii = np.array([s.radius for s in spheres])
    holds = np.linalg.norm(targets[:, None, :] - centers[None], axis=-1) <= radii[None]
    count = holds.sum(axis=1)
    keep = np.ones(len(spheres), dtype=bool)
    for j in reversed(range(len(spheres))):
        mine = holds[:, j]
        if np.all(count[mine] >= 2):
            keep[j] = False
            count[mine] -= 1
    return [s for s, k in zip(spheres, keep) if k]


def repair(points: np.ndarray, spheres: list[Sphere]) -> list[Sphere]:
    """Grow spheres so every point of ``points`` (N, 3) is covered: a missed point grows the sphere it is
    nearest to leaving (smallest ``|p - c| - r``) to ``|p - c|``. Centres do not move."""
    spheres = [Sphere(s.center.copy(), s.radius) for s in spheres]
    centers = np.array([s.center for s in spheres])
    radii = np.array([s.radius for s in spheres])
    gap = np.linalg.norm(points[:, None, :] - centers[None], axis=-1) - radii[None]
    nearest = np.argmin(gap, axis=1)
    missed = gap[np.arange(len(points)), nearest] > 0
    for j in np.unique(nearest[missed]):
        rows = missed & (nearest == j)
        spheres[j].radius += float(gap[rows, j].max())
    return spheres


def kmeans(points: np.ndarray, k: int, rng: np.random.Generator, iterations: int = 60) -> np.ndarray:
    """Lloyd's k-means with k-means++ seeding: ``k`` centres (k, 3) of ``points`` (N, 3), N >= 1."""
    centers = [points[rng.integers(len(points))]]
    d2 = ((points - centers[0]) ** 2).sum(axis=1)
    for _ in range(1, k):
        total = d2.sum()
        pick = rng.choice(len(points), p=d2 / total) if total > 0 else rng.integers(len(points))
        centers.append(points[pick])
        d2 = np.minimum(d2, ((points - centers[-1]) ** 2).sum(axis=1))
    centers = np.array(centers)
    for _ in range(iterations):
        label = cdist(points, centers, "sqeuclidean").argmin(axis=1)
        moved = np.array([points[label == j].mean(axis=0) if np.any(label == j) else centers[j]
                          for j in range(k)])
        if np.allclose(moved, centers):
            break
        centers = moved
    return centers


def spheres_around(targets: np.ndarray, centers: np.ndarray) -> list[Sphere]:
    """One sphere per centre (k, 3), just large enough to hold the targets nearest to that centre."""
    label = cdist(targets, centers).argmin(axis=1)
    return [Sphere(centers[j].copy(), float(np.linalg.norm(targets[label == j] - centers[j], axis=1).max()))
            for j in range(len(centers)) if np.any(label == j)]


def split_largest(targets: np.ndarray, spheres: list[Sphere], rng: np.random.Generator) -> list[Sphere]:
    """Replace the largest sphere by two covering the targets it holds most deeply (2-means split)."""
    centers = np.array([s.center for s in spheres])
    radii = np.array([s.radius for s in spheres])
    dist = cdist(targets, centers)
    owner = np.argmin(np.where(dist <= radii + COVER_TOL, dist / np.maximum(radii, 1e-12), np.inf), axis=1)
    big = int(np.argmax(radii))
    mine = targets[owner == big]
    if len(mine) < 2:
        return list(spheres)
    return [s for j, s in enumerate(spheres) if j != big] + spheres_around(mine, kmeans(mine, 2, rng))


class UnionObjective:
    """Smooth objective of a k-sphere cover, in the normalised frame of :class:`LinkFitter`.

    ``E = cell * sum_q sigmoid(-m_q / tau) + mu * sum_p max(0, min_j |p - c_j| - r_j)^2`` where ``q`` runs over
    grid points outside the mesh (``cell`` = grid cell volume), ``m_q = -tau log sum_j exp(-(|q - c_j| - r_j)
    / tau)`` is a smooth signed distance to the union, and ``p`` over the coverage targets. The first term is
    the volume by which the union exceeds the mesh, the second the squared uncovered distances. With a
    ``gap`` g > 0 the radii r_j are those of the cover and the volume term sees the spheres r_j - g: the
    fitted spheres (radii r_j - g) may miss the targets by up to g. Parameters
    ``x = [c_1 .. c_k (3k), r_1 .. r_k (k)]``; :meth:`__call__` returns ``(E, dE/dx)``.
    """

    def __init__(self, targets: np.ndarray, outside: np.ndarray, cell: float, tau: float, gap: float = 0.0):
        self.targets, self.outside, self.cell, self.tau, self.gap = targets, outside, cell, tau, gap
        self.mu = 1.0

    def __call__(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        k = len(x) // 4
        centers, radii = x[:3 * k].reshape(k, 3), x[3 * k:]
        grad_c, grad_r = np.zeros((k, 3)), np.zeros(k)
        # coverage: hard minimum, gradient on the nearest sphere surface
        diff = self.targets[:, None, :] - centers[None]
        dist = np.linalg.norm(diff, axis=-1) + 1e-12
        gap = dist - radii[None]
        near = np.argmin(gap, axis=1)
        rows = np.arange(len(self.targets))
        viol = np.maximum(gap[rows, near], 0.0)
        value = self.mu * float(viol @ viol)
        coef = 2.0 * self.mu * viol
        np.add.at(grad_c, near, -(coef / dist[rows, near])[:, None] * diff[rows, near])
        np.add.at(grad_r, near, -coef)
        # excess volume: soft membership of the outside grid points in the union
        diff = self.outside[:, None, :] - centers[None]
        dist = np.linalg.norm(diff, axis=-1) + 1e-12
        z = -(dist - (radii[None] - self.gap)) / self.tau
        zmax = z.max(axis=1, keepdims=True)
        ez = np.exp(z - zmax)
        weight = ez / ez.sum(axis=1, keepdims=True)
        smooth = -self.tau * (zmax[:, 0] + np.log(ez.sum(axis=1)))
        member = 0.5 * (1.0 - np.tanh(0.5 * smooth / self.tau))  # sigmoid(-smooth / tau), overflow-free
        value += self.cell * float(member.sum())
        dmember = (-self.cell / self.tau) * member * (1.0 - member)
        coef = dmember[:, None] * weight
        grad_c -= np.einsum("qk,qki->ki", coef / dist, diff)
        grad_r -= coef.sum(axis=0)
        return value, np.concatenate([grad_c.ravel(), grad_r])


class LinkFitter:
    """Covers of one link mesh with at most ``k`` spheres, each computed once, on demand (:meth:`best`).

    Work happens in a normalised frame: origin at the centre of the mesh bounding box, unit length the box
    diagonal ``scale`` (m). For each ``k`` the starts are ``opts.restarts`` k-means seedings and the best
    ``k - 1`` cover with its largest sphere split; each start is optimised on :class:`UnionObjective` with a
    rising coverage weight (L-BFGS-B), made exact on the targets (:func:`repair`), cleared of redundant
    spheres, and scored by its union volume. The best ``k - 1`` cover also competes, so the volume never
    rises with ``k``.
    """

    def __init__(self, mesh: trimesh.Trimesh, opts: FitOptions):
        self.mesh, self.opts = mesh, opts
        self.volume = mesh_volume(mesh)  # m^3
        self.origin = mesh.bounds.mean(axis=0)
        self.scale = float(np.linalg.norm(np.ptp(mesh.bounds, axis=0)))
        if not self.scale > 0:
            raise FitError("collision geometry has zero extent")

        def norm(points: np.ndarray) -> np.ndarray:
            return (np.asarray(points) - self.origin) / self.scale

        self.targets = norm(sample_points(mesh, opts.fit_surface_points, opts.fit_grid_points, opts.seed))
        surface, _ = trimesh.sample.sample_surface(mesh, opts.fit_surface_points, seed=opts.seed)
        self.surface = norm(surface)
        pad = 0.15 * self.scale  # the objective only sees excess volume within `pad` of the mesh
        grid, step = centred_grid(mesh.bounds[0] - pad, mesh.bounds[1] + pad, opts.outside_grid_points)
        grid = grid[~inside(mesh, grid)]
        self.outside = norm(grid[surface_distance(mesh, grid) <= pad])
        self.cell = (step / self.scale) ** 3
        self.gap = opts.gap / self.scale
        self.covers: list[tuple[list[Sphere], float]] = []  # covers[k - 1]: (normalised spheres, volume m^3)

    def best(self, k: int) -> tuple[list[Sphere], float]:
        """Best cover found with at most ``k`` spheres: (spheres in the link frame, union volume m^3)."""
        while len(self.covers) < k:
            self.covers.append(self._search(len(self.covers) + 1))
        spheres, volume = self.covers[k - 1]
        return [Sphere(s.center * self.scale + self.origin, s.radius * self.scale) for s in spheres], volume

    def _search(self, k: int) -> tuple[list[Sphere], float]:
        """Best normalised cover with at most ``k`` spheres and its union volume (m^3)."""
        rng = np.random.default_rng([self.opts.seed, k])
        starts = [spheres_around(self.targets, kmeans(self.surface, k, rng)) for _ in range(self.opts.restarts)]
        if self.covers:
            starts.append(split_largest(self.targets, self.covers[-1][0], rng))
        results = [self.covers[-1]] if self.covers else []
        for start in starts:
            spheres = drop_redundant(self.targets, repair(self.targets, self._optimise(start)))
            shrunk = shrink(spheres, self.gap, MIN_RADIUS / self.scale)
            results.append((spheres, union_volume(shrunk, 100_000) * self.scale ** 3))
        return min(results, key=lambda item: (item[1], len(item[0])))

    def _optimise(self, spheres: list[Sphere]) -> list[Sphere]:
        """Minimise :class:`UnionObjective` from ``spheres`` (normalised) over ``PENALTY_STAGES``."""
        k = len(spheres)
        x = np.concatenate([np.array([s.center for s in spheres]).ravel(), [s.radius for s in spheres]])
        objective = UnionObjective(self.targets, self.outside, self.cell, self.opts.tau, self.gap)
        for mu in PENALTY_STAGES:
            objective.mu = mu
            x = minimize(objective, x, jac=True, method="L-BFGS-B",
                         options={"maxiter": self.opts.iterations}).x
        return [Sphere(x[3 * j:3 * j + 3].copy(), abs(float(x[3 * k + j]))) for j in range(k)]


def shrink(spheres: Sequence[Sphere], gap: float, least: float) -> list[Sphere]:
    """The spheres of a cover with their radii less ``gap``, none below ``least`` (the units of the input)."""
    return [Sphere(s.center, max(s.radius - gap, least)) for s in spheres]


def union_volume(spheres: Sequence[Sphere], count: int = 400_000) -> float:
    """Volume of the union of spheres (units of the input cubed), counted on a centred grid of ~``count``."""
    centers = np.array([s.center for s in spheres])
    radii = np.array([s.radius for s in spheres])
    grid, step = centred_grid((centers - radii[:, None]).min(axis=0), (centers + radii[:, None]).max(axis=0),
                              count)
    return float(np.count_nonzero(excess(grid, spheres) <= 0.0) * step ** 3)


def mesh_volume(mesh: trimesh.Trimesh, count: int = 200_000) -> float:
    """Enclosed volume (m^3): exact for a watertight mesh, else counted on a grid by winding number."""
    if mesh.is_watertight:
        return float(abs(mesh.volume))
    grid, step = centred_grid(mesh.bounds[0], mesh.bounds[1], count)
    return float(np.count_nonzero(inside(mesh, grid)) * step ** 3)


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (n, 3) (golden-angle spiral)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def max_protrusion(mesh: trimesh.Trimesh, spheres: Sequence[Sphere], per_sphere: int = 600) -> float:
    """Largest distance (m) from a point of the union's boundary that lies outside the mesh to the mesh."""
    unit = fibonacci_sphere(per_sphere)
    boundary = np.vstack([s.center + s.radius * unit for s in spheres])
    boundary = boundary[excess(boundary, spheres) > -1e-9]
    outside = boundary[~inside(mesh, boundary)]
    return float(surface_distance(mesh, outside).max()) if len(outside) else 0.0


def rounded(spheres: Sequence[Sphere]) -> list[Sphere]:
    """Round centres to ``DECIMALS`` and radii outwards so the rounded sphere contains the original."""
    unit = 10.0 ** -DECIMALS
    out = []
    for s in spheres:
        center = np.round(s.center, DECIMALS)
        radius = s.radius + float(np.linalg.norm(center - s.center))
        out.append(Sphere(center, math.ceil(radius / unit - 1e-9) * unit))
    return out


def finish_link(name: str, mesh: trimesh.Trimesh, spheres: list[Sphere], opts: FitOptions,
                volume: float | None = None) -> LinkFit:
    """Add the margin, repair against a dense sample, take off the gap, round, and measure on an independent
    sample (``spheres``: the cover, before the gap is taken off; ``volume``: the mesh volume in m^3 when
    already known)."""
    spheres = [Sphere(s.center, s.radius + opts.margin) for s in spheres]
    dense = sample_points(mesh, opts.check_surface_points, opts.check_grid_points, opts.seed + 1)
    spheres = rounded(shrink(repair(dense, spheres), opts.gap, MIN_RADIUS))
    check = sample_points(mesh, opts.check_surface_points, opts.check_grid_points, opts.seed + 2)
    report = LinkReport(
        link=name,
        spheres=len(spheres),
        max_uncovered=float(max(0.0, excess(check, spheres).max())),
        max_uncovered_vertices=float(max(0.0, excess(np.asarray(mesh.vertices), spheres).max())),
        mesh_volume=mesh_volume(mesh) if volume is None else volume,
        union_volume=union_volume(spheres),
        max_protrusion=max_protrusion(mesh, spheres),
        checked_points=len(check),
    )
    return LinkFit(name, spheres, report)


def allocate(fitters: dict[str, LinkFitter], opts: FitOptions, log=None) -> dict[str, int]:
    """Sphere budget per link: start at one each, then repeatedly give one more sphere to the link whose
    union volume drops most, while the drop is at least ``opts.min_gain`` times the total mesh volume, no
    link exceeds ``opts.max_per_link`` and the total stays within ``opts.max_total``."""
    budget = {name: 1 for name in fitters}
    threshold = opts.min_gain * sum(f.volume for f in fitters.values())
    while sum(budget.values()) < opts.max_total:
        gains = {name: f.best(budget[name])[1] - f.best(budget[name] + 1)[1]
                 for name, f in fitters.items() if budget[name] < opts.max_per_link}
        if not gains:
            break
        name = max(gains, key=lambda n: (gains[n], n))
        if gains[name] < threshold:
            break
        budget[name] += 1
        if log:
            log(f"  +1 sphere on {name} (now {budget[name]}): union volume -{1e6 * gains[name]:.1f} cm3")
    return budget


def fit_robot(meshes: dict[str, trimesh.Trimesh], opts: FitOptions, log=None) -> list[LinkFit]:
    """Fit every link of ``meshes`` (``{link: mesh in link frame}``) under the budgets of ``opts``."""
    if (opts.margin < 0 or opts.gap < 0 or opts.max_per_link < 1 or opts.max_total < 1 or opts.min_gain < 0
            or opts.tau <= 0):
        raise FitError("need --margin >= 0, --gap >= 0, --max-per-link >= 1, --max-total >= 1, --min-gain >= 0, "
                       "--tau > 0")
    if len(meshes) > opts.max_total:
        raise FitError(f"{len(meshes)} links need at least {len(meshes)} spheres > --max-total {opts.max_total}")
    fitters = {}
    for name, mesh in meshes.items():
        try:
            fitters[name] = LinkFitter(mesh, opts)
        except FitError as exc:
            raise FitError(f"link {name!r}: {exc}") from exc
    budget = allocate(fitters, opts, log)
    return [finish_link(name, meshes[name], fitters[name].best(budget[name])[0], opts, fitters[name].volume)
            for name in meshes]


# ------------------------------------------------------------------------------------------------ output


def spheres_json(fits: Sequence[LinkFit], comment: str | None = None) -> str:
    """The sphere file text: ``{"comment": ..., "spheres": [{"link", "center" [x, y, z], "radius"}, ...]}``,
    centres in metres in the link frame, radii in metres, one sphere per line (``comment`` only if given)."""
    rows = [json.dumps({"link": fit.link, "center": [round(float(v), DECIMALS) for v in s.center],
                        "radius": round(float(s.radius), DECIMALS)})
            for fit in fits for s in fit.spheres]
    head = f"  \"comment\": {json.dumps(comment)},\n" if comment else ""
    return "{\n" + head + "  \"spheres\": [\n    " + ",\n    ".join(rows) + "\n  ]\n}\n"


def load_spheres_json(path: str | Path) -> dict[str, list[Sphere]]:
    """Read a sphere file written by :func:`spheres_json` into ``{link: [Sphere]}`` (file order kept)."""
    data = json.loads(Path(path).read_text())
    result: dict[str, list[Sphere]] = {}
    for entry in data["spheres"]:
        result.setdefault(entry["link"], []).append(
            Sphere(np.asarray(entry["center"], dtype=float), float(entry["radius"])))
    return result


def coverage(mesh: trimesh.Trimesh, spheres: Sequence[Sphere], surface_points: int, grid_points: int,
             seed: int) -> float:
    """Largest uncovered distance (m, >= 0) of a sample of ``mesh`` (vertices, surface, interior)."""
    points = sample_points(mesh, surface_points, grid_points, seed)
    return float(max(0.0, excess(points, spheres).max()))


def report_table(fits: Sequence[LinkFit]) -> str:
    """Human-readable per-link report (mm, cm^3) with totals."""
    lines = [f"{'link':<20}{'n':>4}{'uncov mm':>10}{'vert mm':>9}{'mesh cm3':>10}"
             f"{'union cm3':>11}{'ratio':>7}{'protr mm':>10}"]
    for fit in fits:
        r = fit.report
        lines.append(f"{r.link:<20}{r.spheres:>4}{1000 * r.max_uncovered:>10.3f}"
                     f"{1000 * r.max_uncovered_vertices:>9.3f}{1e6 * r.mesh_volume:>10.1f}"
                     f"{1e6 * r.union_volume:>11.1f}{r.volume_ratio:>7.2f}{1000 * r.max_protrusion:>10.1f}")
    mesh_total = sum(f.report.mesh_volume for f in fits)
    union_total = sum(f.report.union_volume for f in fits)
    lines.append(f"{'total':<20}{sum(f.report.spheres for f in fits):>4}"
                 f"{1000 * max(f.report.max_uncovered for f in fits):>10.3f}"
                 f"{1000 * max(f.report.max_uncovered_vertices for f in fits):>9.3f}{1e6 * mesh_total:>10.1f}"
                 f"{1e6 * union_total:>11.1f}{union_total / mesh_total:>7.2f}"
                 f"{1000 * max(f.report.max_protrusion for f in fits):>10.1f}")
    return "\n".join(lines)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="fit_spheres", description=__doc__.split("\n\n")[0],
        epilog="Writes {\"spheres\": [{\"link\", \"center\", \"radius\"}]} (metres, URDF link frames).")
    parser.add_argument("urdf", type=Path, help="URDF whose links have collision geometry")
    parser.add_argument("--mesh-dir", type=Path, default=None,
                        help="directory package:// and relative mesh paths resolve against (default: URDF dir)")
    parser.add_argument("--out", type=Path, default=None, help="output JSON (default: stdout)")
    parser.add_argument("--report", type=Path, default=None, help="also write the per-link report as JSON")
    parser.add_argument("--links", nargs="+", default=None, help="links to fit (default: all with collision)")
    parser.add_argument("--margin", type=float, default=FitOptions.margin,
                        help="metres added to every radius before the repair step (default %(default)s)")
    parser.add_argument("--gap", type=float, default=FitOptions.gap,
                        help="distance in m by which the spheres may miss the mesh: the cover is fitted, then "
                             "its radii shrink by this much (default %(default)s: every point covered)")
    parser.add_argument("--max-per-link", type=int, default=FitOptions.max_per_link,
                        help="most spheres on one link (default %(default)s)")
    parser.add_argument("--max-total", type=int, default=FitOptions.max_total,
                        help="most spheres in all (default %(default)s)")
    parser.add_argument("--min-gain", type=float, default=FitOptions.min_gain,
                        help="smallest union-volume drop, as a fraction of the total mesh volume, worth one "
                             "more sphere (default %(default)s)")
    parser.add_argument("--restarts", type=int, default=FitOptions.restarts,
                        help="k-means starts per sphere count (default %(default)s)")
    parser.add_argument("--tau", type=float, default=FitOptions.tau,
                        help="soft union width, fraction of a link's bounding-box diagonal (default %(default)s)")
    parser.add_argument("--iterations", type=int, default=FitOptions.iterations,
                        help="L-BFGS-B iterations per penalty stage (default %(default)s)")
    parser.add_argument("--seed", type=int, default=FitOptions.seed, help="random seed (default %(default)s)")
    parser.add_argument("--fit-surface-points", type=int, default=FitOptions.fit_surface_points)
    parser.add_argument("--fit-grid-points", type=int, default=FitOptions.fit_grid_points)
    parser.add_argument("--outside-grid-points", type=int, default=FitOptions.outside_grid_points)
    parser.add_argument("--check-surface-points", type=int, default=FitOptions.check_surface_points)
    parser.add_argument("--check-grid-points", type=int, default=FitOptions.check_grid_points)
    parser.add_argument("--quiet", action="store_true", help="no progress or report on stderr")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit status (2 on a :class:`FitError`)."""
    args = parse_args(argv)
    log = None if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    counts = (args.fit_surface_points, args.fit_grid_points, args.outside_grid_points, args.check_surface_points,
              args.check_grid_points, args.restarts, args.iterations)
    if min(counts) < 1:
        print("fit_spheres: error: point counts, --restarts and --iterations must be >= 1", file=sys.stderr)
        return 2
    opts = FitOptions(margin=args.margin, gap=args.gap, max_per_link=args.max_per_link, max_total=args.max_total,
                      min_gain=args.min_gain, restarts=args.restarts, tau=args.tau, iterations=args.iterations,
                      seed=args.seed, fit_surface_points=args.fit_surface_points,
                      fit_grid_points=args.fit_grid_points, outside_grid_points=args.outside_grid_points,
                      check_surface_points=args.check_surface_points, check_grid_points=args.check_grid_points)
    try:
        meshes = load_link_meshes(args.urdf, args.mesh_dir, args.links)
        fits = fit_robot(meshes, opts, log)
    except FitError as exc:
        print(f"fit_spheres: error: {exc}", file=sys.stderr)
        return 2
    settings = ", ".join(f"{name}={value}" for name, value in vars(opts).items())
    source = f"{args.urdf.resolve().parent.name}/{args.urdf.name}"
    worst = max(fit.report.max_uncovered for fit in fits)
    held = ("Every mesh vertex lies inside its link's spheres" if opts.gap == 0 else
            f"Every mesh vertex lies within {1000 * opts.gap:g} mm of its link's spheres")
    text = spheres_json(fits, f"Fitted by tools/fit_spheres.py to the collision geometry of {source} "
                              f"({settings}). {held}; largest miss on an independent dense sample "
                              f"{1000 * worst:.2f} mm. Centres in metres in the URDF link frames, radii in metres.")
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    if args.report is not None:
        rows = [dict(vars(f.report), volume_ratio=f.report.volume_ratio) for f in fits]
        args.report.write_text(json.dumps(rows, indent=1) + "\n")
    if log:
        log(report_table(fits))
    return 0


if __name__ == "__main__":
    sys.exit(main())
