"""How far a robot's collision meshes stick out of its collision spheres, sphere by sphere.

A sphere model made by hand or by a spherization tool (MotionBenchMaker's ``*_spherized.urdf``) leaves parts
of the collision meshes outside every sphere: 10-57 mm on the MotionBenchMaker Fetch's links, 3-29 mm on the
UR5's. A fabric that keeps its spheres a few millimetres from obstacles can then bring those parts into
contact, and a mesh validator rejects the motion. :func:`sphere_deficits` measures, for each sphere, how far
the mesh points nearest to it lie outside it; the ``MeshCover`` retry policy
(:mod:`gfcs.planning.policies`) keeps each sphere that much farther from obstacles.

Mesh points: every vertex of each link's collision elements (meshes with their ``scale``, boxes,
cylinders, spheres) placed by the element's ``<origin>``, and a seeded area-uniform sample of their
surfaces, in the link frame. Each point belongs to the sphere of its link whose surface is nearest, and a
sphere's deficit is the largest distance of its points outside it (0 when they all lie inside).

Where the description itself models a part by a sphere (:func:`element_spheres`), the planning model can
carry that sphere exactly (:func:`with_element_spheres`, used by :func:`gfcs.planning.models.models_for`).
"""

from __future__ import annotations

import functools
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

__all__ = ["sphere_deficits", "element_spheres", "with_element_spheres", "SURFACE_SAMPLES"]

#: Surface points sampled per collision element (seeded), besides its vertices.
SURFACE_SAMPLES = 2000


def _element_points(element: Dict[str, Any]) -> np.ndarray:
    """(N, 3) points of one collision element of ``Robot.collision_geometry()`` in its link's frame."""
    import trimesh

    kind = element["type"]
    if kind == "mesh":
        if not element.get("exists", True) or element.get("path") is None:
            return np.zeros((0, 3))
        mesh = trimesh.load(element["path"], force="mesh")
        if element.get("scale") is not None:
            mesh.apply_scale(np.asarray(element["scale"], dtype=np.float64))
    elif kind == "box":
        mesh = trimesh.creation.box(extents=np.asarray(element["size"], dtype=np.float64))
    elif kind in ("cylinder", "capsule"):
        length, radius = (float(x) for x in element["size"])
        make = trimesh.creation.cylinder if kind == "cylinder" else trimesh.creation.capsule
        mesh = make(radius=radius, height=length)
    elif kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=float(element["size"][0]))
    else:
        return np.zeros((0, 3))
    mesh.apply_transform(np.asarray(element["origin"], dtype=np.float64))
    points = [np.asarray(mesh.vertices, dtype=np.float64)]
    if len(mesh.faces):
        points.append(np.asarray(trimesh.sample.sample_surface(mesh, SURFACE_SAMPLES, seed=0)[0]))
    return np.vstack(points)


@functools.lru_cache(maxsize=16)
def _link_points(geometry: Tuple[Tuple[Any, ...], ...]) -> Dict[str, np.ndarray]:
    """{link: (N, 3) mesh points} for a robot's collision geometry given as :func:`_key` tuples, cached by
    it (the same meshes are read once per process)."""
    out: Dict[str, List[np.ndarray]] = {}
    for link, kind, path, size, scale, origin in geometry:
        element = {"type": kind, "path": path, "size": size, "scale": scale,
                   "origin": np.asarray(origin).reshape(4, 4)}
        out.setdefault(link, []).append(_element_points(element))
    return {link: np.vstack(parts) for link, parts in out.items()}


def _key(element: Dict[str, Any]) -> Tuple[Any, ...]:
    """One collision element of ``Robot.collision_geometry()`` as a hashable tuple (link, type, mesh path or
    None, sizes, scale, origin), numbers as tuples of floats."""
    def values(x: Any) -> Optional[Tuple[float, ...]]:
        return None if x is None else tuple(float(v) for v in np.asarray(x, dtype=np.float64).ravel())

    path = element.get("path") if element.get("exists", True) else None
    return (str(element["link"]), str(element["type"]), path, values(element.get("size")),
            values(element.get("scale")), values(element["origin"]))


def sphere_deficits(robot: Any, mesh_robot: Any) -> np.ndarray:
    """(S,) how far [m, ≥ 0] the collision meshes of ``mesh_robot`` stick out of each collision sphere of
    ``robot`` (see the module docstring); spheres on links without mesh geometry get 0.

    Args:
        robot: the :class:`gfcs.Robot` whose spheres plan (``sphere_links``, ``sphere_centers_local``,
            ``sphere_radii``).
        mesh_robot: a robot with the same links whose ``collision_geometry()`` holds the meshes (e.g. a
            :class:`gfcs.MeshChecker`'s ``robot``).
    """
    points = _link_points(tuple(_key(e) for e in mesh_robot.collision_geometry()))
    links = np.asarray(robot.sphere_links)
    centres = np.asarray(robot.sphere_centers_local, dtype=np.float64).reshape(-1, 3)
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    deficit = np.zeros(radii.shape[0])
    for link, pts in points.items():
        on = np.flatnonzero(links == link)
        if on.size == 0 or pts.shape[0] == 0:
            continue
        outside = np.linalg.norm(pts[:, None, :] - centres[on][None], axis=2) - radii[on][None]
        nearest = np.argmin(outside, axis=1)
        for k, i in enumerate(on):
            mine = outside[nearest == k, k]
            if mine.size:
                deficit[i] = max(0.0, float(mine.max()))
    return deficit


def element_spheres(mesh_robot: Any) -> List[Tuple[str, List[float], float]]:
    """The collision elements of ``mesh_robot`` that are spheres, as ``Robot.with_spheres`` takes them: (link,
    centre in the link frame [m], radius [m]), in the order of ``collision_geometry()``. A robot description
    may model a part by a sphere (a head, a sensor dome); the validator then judges that sphere exactly."""
    return [(str(e["link"]), [float(x) for x in np.asarray(e["origin"], dtype=np.float64)[:3, 3]],
             float(e["size"][0]))
            for e in mesh_robot.collision_geometry() if e["type"] == "sphere"]


def with_element_spheres(robot: Any, spheres: Sequence[Tuple[str, Sequence[float], float]]) -> Any:
    """``robot`` with the collision spheres ``spheres`` ((link, centre m, radius m), e.g.
    :func:`element_spheres` of its validator's robot) added and each of its own spheres that lies inside one
    of them on the same link (redundant) removed; ``robot`` itself when that changes nothing. Spheres on
    links ``robot`` does not have are left out.

    A sphere model made by a spherization tool approximates a collision sphere of the description by
    smaller ones and leaves most of it uncovered (the MotionBenchMaker Fetch's head: 28 spheres inside a
    0.2 m collision sphere, 95 mm of it outside all of them); planning on the element itself leaves no gap."""
    known = set(robot.link_names)
    exact = [(str(link), np.asarray(c, dtype=np.float64), float(r)) for link, c, r in spheres if link in known]
    if not exact:  # the common case (descriptions without sphere elements): nothing to compare
        return robot
    own = list(zip(robot.sphere_links, np.asarray(robot.sphere_centers_local, dtype=np.float64).reshape(-1, 3),
                   np.asarray(robot.sphere_radii, dtype=np.float64)))

    def inside(link: str, c: np.ndarray, r: float) -> bool:
        return any(link == e_link and np.linalg.norm(c - e_c) + r <= e_r + 1e-9 for e_link, e_c, e_r in exact)

    def key(sphere: Tuple[str, np.ndarray, float]) -> Tuple[Any, ...]:
        return (sphere[0], *np.round(sphere[1], 9), round(sphere[2], 9))

    merged = [s for s in own if not inside(*s)] + exact
    if sorted(map(key, merged)) == sorted(map(key, own)):
        return robot
    return robot.with_spheres([(link, [float(x) for x in c], r) for link, c, r in merged])
