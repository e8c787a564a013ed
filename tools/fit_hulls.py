#!/usr/bin/env python3
"""Fit a bounding convex polytope to each link's collision geometry in a URDF, for mesh-based validation.

For every link with collision geometry, its vertices (read by ``fit_spheres.load_link_meshes``: each element's
``<origin>`` and ``scale`` applied, in metres in the URDF link frame) are bounded by the half-spaces ``d_i . x <= h_i``, with ``h_i`` the
largest ``d_i . v`` over the vertices (the support function). The directions ``d_i`` are the 26 of the axes, face
diagonals and cube diagonals, and ``--planes`` more: the centres of a seeded spherical k-means of the outward
normals of the vertices' convex hull, each facet weighted by its area, so that the planes follow the flat parts
of the mesh. The intersection of those half-spaces is a convex polytope that contains the link's mesh (every
mesh point is a convex combination of its vertices, and every vertex satisfies every inequality), so a state
whose polytopes clear an obstacle by ``m`` leaves the meshes at least ``m`` clear too. It exceeds the mesh's
convex hull by the report's ``excess`` (the Hausdorff distance between the two convex sets, from their support
functions on 20,000 seeded random directions). The k-means runs with ``--seeds`` seeds (default 8) and the
polytope with the smallest excess is kept: with the default 120 planes, 0.8-2.7 mm on the Panda's links (0 for
a link whose hull has fewer facet directions than that) with 18-253 vertices per link (one seed: 0.9-3.2 mm); a Fibonacci
sphere of 2048 directions instead came to 0.7-3.6 mm with 223-1325 vertices (the meshes' sharp edges need
many directions when they are not chosen from the mesh).

The polytope's vertices (the half-space intersection, by qhull) and its faces (the convex hull of those vertices,
triangulated, counter-clockwise seen from outside) are written
as ``<out_dir>/<link>.obj``, in metres in the link frame to 1e-12 m (qhull's triangulation keeps slivers only
0.1 micrometre high inside flat faces, whose normals coarser rounding would turn). The vertices are intersections of the chosen planes, not points of the input
meshes. Deterministic: the same input gives the same files.

Example (the shipped Panda's collision polytopes, ``gfcs.problems.shipped_panda_checker``)::

    python tools/fit_hulls.py ../shared/robots/mbm_panda/panda.urdf --out-dir python/gfcs/data/panda_hulls
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np
from scipy.spatial import ConvexHull, HalfspaceIntersection

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fit_spheres import load_link_meshes  # noqa: E402  (the sibling tool's URDF reader)

def link_points(urdf: Path) -> Dict[str, np.ndarray]:
    """{link: (V, 3) collision-geometry vertices in the link frame, m} for every link with collision geometry,
    as the sibling sphere fitter reads them (``fit_spheres.load_link_meshes``: origins, scales, package
    paths, duplicate vertices merged)."""
    return {name: np.asarray(mesh.vertices, dtype=np.float64) for name, mesh in load_link_meshes(urdf).items()}


def directions(points: np.ndarray, planes: int, seed: int = 0, iterations: int = 50) -> np.ndarray:
    """(26 + k, 3) unit vectors: axes, face and cube diagonals, then k <= ``planes`` centres of a spherical
    k-means of the outward facet normals of the points' convex hull, weighted by facet area (seeded). The
    hull's triangles are taken sorted by normal and area (to 1e-9), so that the result does not depend on the
    order of the points (qhull lists its facets in an order that does)."""
    fixed = np.array([c for c in itertools.product((-1, 0, 1), repeat=3) if any(c)], dtype=np.float64)
    fixed /= np.linalg.norm(fixed, axis=1, keepdims=True)
    hull = ConvexHull(points)
    a, b, c = (points[hull.simplices[:, i]] for i in range(3))
    areas = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    key = np.round(np.column_stack([hull.equations[:, :3], areas]), 9)
    order = np.lexsort(key.T[::-1])
    normals, weights = hull.equations[order, :3], areas[order]
    rng = np.random.default_rng(seed)
    k = min(planes, len(normals))
    centres = normals[rng.choice(len(normals), size=k, replace=False, p=weights / weights.sum())]
    for _ in range(iterations):
        label = (normals @ centres.T).argmax(axis=1)
        for j in range(k):
            mine = label == j
            if mine.any():
                total = (normals[mine] * weights[mine, None]).sum(axis=0)
                centres[j] = total / np.linalg.norm(total)
    dirs = np.vstack([fixed, centres])
    _, first = np.unique(np.round(dirs, 12), axis=0, return_index=True)  # a plane once (empty clusters)
    return dirs[np.sort(first)]


def polytope(points: np.ndarray, dirs: np.ndarray) -> Tuple[np.ndarray, List[List[int]]]:
    """The polytope {x : dirs . x <= max over points of dirs . p}: (V, 3) vertices (the half-space
    intersection's, by qhull) and triangles, counter-clockwise seen from outside."""
    h = (points @ dirs.T).max(axis=0)
    inner = HalfspaceIntersection(np.hstack([dirs, -h[:, None]]), points.mean(axis=0)).intersections
    hull = ConvexHull(inner)
    verts = inner[hull.vertices]
    index = {int(v): i for i, v in enumerate(hull.vertices)}
    faces: List[List[int]] = []
    for tri, eq in zip(hull.simplices, hull.equations):
        a, b, c = (inner[v] for v in tri)
        tri = [index[int(v)] for v in tri]
        faces.append(tri if np.dot(np.cross(b - a, c - a), eq[:3]) > 0 else tri[::-1])
    return verts, faces


def excess(points: np.ndarray, verts: np.ndarray, samples: int = 20000) -> float:
    """Hausdorff distance between the polytope (its vertices) and the points' convex hull, m: the largest
    difference of their support functions over seeded random unit directions."""
    u = np.random.default_rng(0).normal(size=(samples, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return float(((verts @ u.T).max(axis=0) - (points @ u.T).max(axis=0)).max())


def write_obj(path: Path, verts: np.ndarray, faces: List[List[int]], header: str) -> None:
    lines = [f"# {header}"] + [f"v {x:.12f} {y:.12f} {z:.12f}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def main(argv: List[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("urdf", type=Path, help="URDF whose links have collision geometry")
    p.add_argument("--out-dir", type=Path, required=True, help="folder for <link>.obj")
    p.add_argument("--planes", type=int, default=120, help="planes fitted to the hull's facets besides the 26 "
                   "fixed ones (default 120)")
    p.add_argument("--seeds", type=int, default=8, help="k-means seeds tried per link; the polytope with the "
                   "smallest excess over the hull is kept (default 8)")
    p.add_argument("--report", type=Path, help="JSON file for the per-link report")
    args = p.parse_args(argv)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    report = {}
    for link, pts in link_points(args.urdf).items():
        fits = []
        for seed in range(max(1, args.seeds)):
            dirs = directions(pts, args.planes, seed)
            verts, faces = polytope(pts, dirs)
            fits.append((excess(pts, verts), len(verts), seed, dirs, verts, faces))
        _, _, _, dirs, verts, faces = min(fits, key=lambda fit: fit[:3])
        header = (f"bounding polytope of {link}'s collision meshes in {args.urdf.name}: {len(dirs)} planes "
                  f"(tools/fit_hulls.py), m, link frame")
        write_obj(args.out_dir / f"{link}.obj", verts, faces, header)
        report[link] = {"vertices": len(verts), "faces": len(faces), "excess_m": excess(pts, verts)}
        print(f"{link}: {len(verts)} vertices, {len(faces)} triangles, excess over the hull "
              f"{report[link]['excess_m'] * 1000:.2f} mm", file=sys.stderr)
    if args.report:
        args.report.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
