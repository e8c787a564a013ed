#!/usr/bin/env python3
"""Inscribed spheres that fill the gaps between a robot's collision spheres and its collision meshes.

A hand-made sphere model (MotionBenchMaker's ``panda_spherized.urdf``) may leave parts of the collision
meshes outside every sphere: up to 62 mm on the MBM Panda's link5, so a fabric that avoids obstacles with
those spheres can drive the mesh into them. Covering spheres (``tools/fit_spheres.py``) close the gaps but
reach beyond the mesh and block goals placed close to obstacles. This tool adds spheres *inside* the meshes
instead: a configuration whose meshes are clear stays clear for the added spheres, and every gap shrinks.

Per link with a collision mesh (convex or not; an open or self-overlapping mesh is read through its
generalised winding number):

1. Gap: for a seeded area-uniform surface sample plus the vertices (link frame, URDF ``<origin>`` and
   ``scale`` applied), the distance outside the union of the link's existing spheres.
2. Candidates: the points of a 4 mm grid inside the mesh (winding number ≥ 1/2) and at least 5 mm from its
   surface, each with the radius of its largest inscribed sphere (the exact distance to the surface)
   less ``--slack``. The sphere lies inside the mesh, by ``--slack`` at its closest.
3. Greedy: add the candidate that removes the most summed gap, recompute the gap, and repeat while the
   largest gap exceeds ``--target`` and the link has fewer than ``--per-link`` added spheres.

Output (``--out``, JSON, the form of ``Robot.from_urdf(spheres=...)`` files): ``{"for_spheres", "spheres": [{"link",
"center", "radius"}, ...]}``, centres in metres in the link frame, radii in metres, rounded inwards to 1
micrometre; ``for_spheres`` is the ``gfcs.problems.sphere_fingerprint`` of the existing spheres, so that
``gfcs.problems.with_gap_spheres`` adds these to that model only.
The per-link gap before and after goes to stderr. Seeded (``--seed``): the same input gives the same output.

Example (the spheres :func:`gfcs.problems.mbm_panda` adds)::

    python tools/fill_sphere_gaps.py ../shared/robots/mbm_panda/panda.urdf \\
        ../shared/robots/mbm_panda/panda_spherized.urdf --exclude panda_link0 \
        --out python/gfcs/data/mbm_panda_gap_spheres.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

import gfcs
from gfcs.problems import sphere_fingerprint

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fit_spheres import Sphere, excess, inside, surface_distance  # noqa: E402  (the sibling tool's geometry)


def link_mesh(geometry: dict) -> trimesh.Trimesh:
    """The collision mesh of one URDF ``<collision>`` element in its link frame."""
    mesh = trimesh.load(geometry["path"], force="mesh")
    scale = np.asarray(geometry["scale"]) if geometry["scale"] is not None else np.ones(3)
    origin = np.asarray(geometry["origin"])
    vertices = (np.asarray(mesh.vertices) * scale) @ origin[:3, :3].T + origin[:3, 3]
    return trimesh.Trimesh(vertices, mesh.faces, process=False)


def fill(mesh: trimesh.Trimesh, centers: np.ndarray, radii: np.ndarray, args: argparse.Namespace,
         rng: np.random.Generator) -> tuple[list, float, float]:
    """Greedy inscribed spheres for one link: (added [(centre, radius)], gap before, gap after) in m."""
    hull = ConvexHull(mesh.vertices)
    points = np.vstack([trimesh.sample.sample_surface(mesh, args.samples, seed=int(rng.integers(2**31)))[0],
                        mesh.vertices])
    gap = np.maximum(excess(points, [Sphere(c, r) for c, r in zip(centers, radii)]), 0.0)
    before = float(gap.max())
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    axes = [np.arange(a, b, args.grid) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    # The hull bounds the depth from above (cheap cull); the exact depth of a point inside the mesh is
    # its distance to the surface (equal to the hull's for a convex mesh).
    grid = grid[-(grid @ hull.equations[:, :3].T + hull.equations[:, 3]).max(axis=1) >= args.min_depth]
    grid = grid[inside(mesh, grid)]
    depth = surface_distance(mesh, grid)
    keep = depth >= args.min_depth
    grid, rho = grid[keep], depth[keep] - args.slack
    added: list = []
    while len(added) < args.per_link and gap.max() > args.target and len(grid):
        gain = np.empty(len(grid))
        for k in range(0, len(grid), 1024):
            d = np.linalg.norm(points[None] - grid[k:k + 1024, None], axis=2) - rho[k:k + 1024, None]
            gain[k:k + 1024] = np.sum(gap[None] - np.minimum(gap[None], np.maximum(d, 0.0)), axis=1)
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        gap = np.minimum(gap, np.maximum(np.linalg.norm(points - grid[best], axis=1) - rho[best], 0.0))
        added.append((grid[best], float(rho[best])))
    return added, before, float(gap.max())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh_urdf", type=Path, help="URDF whose collision elements are the meshes")
    ap.add_argument("sphere_urdf", type=Path, help="URDF (or any robot file) with the existing spheres")
    ap.add_argument("--out", type=Path, required=True, help="output JSON file")
    ap.add_argument("--target", type=float, default=0.015, help="stop when every gap is below this (m)")
    ap.add_argument("--per-link", type=int, default=4, help="at most this many spheres per link")
    ap.add_argument("--slack", type=float, default=0.001, help="inscribed radius reduction (m)")
    ap.add_argument("--grid", type=float, default=0.004, help="candidate grid spacing (m)")
    ap.add_argument("--min-depth", type=float, default=0.005, help="least candidate depth inside the hull (m)")
    ap.add_argument("--samples", type=int, default=6000, help="surface samples per link")
    ap.add_argument("--exclude", action="append", default=[], metavar="LINK",
                    help="leave this link as it is (repeatable), e.g. a base fixed to the world")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    root = args.mesh_urdf.resolve().parent
    meshes = gfcs.Robot.from_urdf(str(args.mesh_urdf), mesh_dir=str(root))
    spheres = gfcs.Robot.from_urdf(str(args.sphere_urdf), mesh_dir=str(root))
    links = list(spheres.sphere_links)
    centers, radii = np.asarray(spheres.sphere_centers_local), np.asarray(spheres.sphere_radii)
    rng = np.random.default_rng(args.seed)
    out = []
    for geometry in meshes.collision_geometry():
        if geometry["type"] != "mesh":
            continue
        name = geometry["link"]
        if name in args.exclude:
            continue
        mesh = link_mesh(geometry)
        own = [i for i, link in enumerate(links) if link == name]
        added, before, after = fill(mesh, centers[own], radii[own], args, rng)
        for c, r in added:
            out.append({"link": name, "center": [round(float(x), 6) for x in c],
                        "radius": math.floor(r * 1e6) / 1e6})
        print(f"{name:18s} largest gap {before * 1e3:5.1f} -> {after * 1e3:5.1f} mm, {len(added)} spheres",
              file=sys.stderr)
    made_for = sphere_fingerprint(spheres)
    args.out.write_text(json.dumps({"for_spheres": made_for, "spheres": out}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
