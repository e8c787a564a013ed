"""Playback of solved motion problems in rerun (``.rrd`` recordings) and the ``gfcs view`` command.

:func:`record` writes one recording with every method of a problem side by side, as the GFCS paper's
Fig. 1 shows a solution: the robot moving over time, the obstacles, the end-effector (EE) path, the EE
positions of the command states q_g¹..q_gⁿ (GFCS eq. 4) as red spheres and the goal as a green sphere,
plus time series of the joint speed ‖q̇‖, the fabric energy and the minimum clearance. :func:`view`
opens a recording in the rerun viewer.

Entity layout (world frame = robot base frame, metres; one timeline ``"time"`` in seconds from the start
of each trajectory):

``/world/obstacles/<name>``                 static obstacles (boxes, cylinders, capsules, spheres, half
                                            spaces; meshes and point clouds as surface points)
``/world/start``, ``/world/goal``           EE position of q₀ (white) and of the goal q_g (green)
``/methods/<label>/robot/links/<link>``     per-step link pose (Transform3D) + static link meshes below
``/methods/<label>/robot/spheres``          or, without meshes, the per-step collision spheres
``/methods/<label>/ee``                     per-step EE position
``/methods/<label>/ee_path``                the whole EE path (LineStrips3D)
``/methods/<label>/commands``               EE positions of the commands (red spheres)
``/methods/<label>/metrics/<series>``       Scalars: ``joint_speed`` [rad/s], ``clearance`` and
                                            ``self_clearance`` [m], ``energy`` L̃_e, ``potential`` ψ,
                                            ``lyapunov`` L̃_e + ψ (GF Thm IV.4)
``/methods/<label>/summary``                a text summary (success, cost, lengths)

``<label>`` is ``gf`` (local fabric), ``gfcs`` (command sequence with the uniform sampler) or
``gfcs_learned`` (command sequence warm-started by a learned sampler), with ``_2``, ``_3``... appended
to repeated labels, unless the caller names the results (a ``{label: result}`` mapping).

``rerun`` is imported by this module only: ``import gfcs`` works without the ``viz`` extra.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from gfcs import metrics as _metrics
from gfcs.errors import InvalidValueError, MissingFileError
from gfcs.pose_goal import (
    quaternion_xyzw as rotation_to_quaternion,  # (..., 3, 3) -> (..., 4) [x, y, z, w]
)
from gfcs.results import planned_robot

__all__ = [
    "record",
    "view",
    "register_cli",
    "method_labels",
    "TIMELINE",
    "SERIES",
    "rotation_to_quaternion",
    "has_display",
    "viewer_command",
]

#: Name of the timeline (seconds since the start of each trajectory).
TIMELINE = "time"

#: Time series logged under ``/methods/<label>/metrics/``: name -> (view title, unit).
SERIES: Dict[str, Tuple[str, str]] = {
    "joint_speed": ("joint speed ‖q̇‖", "rad/s"),
    "clearance": ("min clearance to obstacles", "m"),
    "self_clearance": ("min self clearance", "m"),
    "energy": ("fabric energy L̃_e = ½ q̇ᵀM̃q̇", ""),
    "potential": ("forcing potential ψ", ""),
    "lyapunov": ("L̃_e + ψ (GF Thm IV.4 Lyapunov function)", ""),
}

_METHOD_COLORS = {
    "gf": (31, 119, 180),
    "gfcs": (255, 127, 14),
    "gfcs_learned": (148, 103, 189),
}
_PALETTE = [(31, 119, 180), (255, 127, 14), (148, 103, 189), (140, 86, 75), (227, 119, 194),
            (23, 190, 207), (188, 189, 34), (127, 127, 127)]
_RED = (220, 30, 30)
_GREEN = (30, 190, 60)
_OBSTACLE_COLOR = (150, 150, 160, 170)
_SURFACE_SPACING = 0.02  # m, surface sampling of mesh obstacles
_HALF_SPACE_EXTENT = 2.0  # m, half edge of the square drawn for a half-space


# ------------------------------------------------------------------------------------ small helpers
def _part(name: Any) -> str:
    """One entity-path part for an arbitrary name (escaped; "_" for an empty one)."""
    text = str(name)
    return rr.escape_entity_path_part(text) if text else "_"


def _label_of(result: Any) -> str:
    method = str(getattr(result, "method", "") or "result")
    sampler = str((getattr(result, "settings", None) or {}).get("sampler", "") or "")
    if method == "gfcs" and sampler == "EBMSampler":
        return "gfcs_learned"
    return re.sub(r"[^A-Za-z0-9_]+", "_", method)


def method_labels(results: Sequence[Any]) -> List[str]:
    """Entity labels of ``results`` (see the module docstring), unique: ``gf``, ``gfcs``, ``gfcs_2``..."""
    seen: Dict[str, int] = {}
    labels = []
    for r in results:
        base = _label_of(r)
        seen[base] = seen.get(base, 0) + 1
        labels.append(base if seen[base] == 1 else f"{base}_{seen[base]}")
    return labels


def _normalise_results(results: Any) -> List[Tuple[str, Any]]:
    if isinstance(results, Mapping):
        items = [(re.sub(r"[^A-Za-z0-9_]+", "_", str(k)) or "result", v) for k, v in results.items()]
        if len({k for k, _ in items}) != len(items):
            raise InvalidValueError(f"results: labels must stay distinct after sanitising, got {list(results)}")
    else:
        seq = list(results) if isinstance(results, (list, tuple)) else [results]
        items = list(zip(method_labels(seq), seq))
    if not items:
        raise InvalidValueError("results: expected at least one SolveResult")
    for label, r in items:
        traj = getattr(r, "trajectory", None)
        if traj is None or not hasattr(traj, "q"):
            raise InvalidValueError(f"results[{label!r}]: expected a gfcs.results.SolveResult, got {type(r).__name__}")
        if len(traj.t) == 0:
            raise InvalidValueError(f"results[{label!r}]: the trajectory is empty (a result loaded from JSON "
                                    "written with --no-trajectory?)")
    return items


def _color(label: str, index: int) -> Tuple[int, int, int]:
    """Fixed colours for the standard labels, a palette by position otherwise."""
    return _METHOD_COLORS.get(label, _PALETTE[index % len(_PALETTE)])


# ------------------------------------------------------------------------------------- link geometry
@dataclass
class _LinkMesh:
    """A triangle mesh in its link frame: vertices (V, 3) m, triangles (F, 3), vertex normals (V, 3)."""

    link: str
    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray


def _primitive_mesh(kind: str, size: Sequence[float]) -> Any:
    import trimesh

    if kind == "box":
        return trimesh.creation.box(extents=np.asarray(size, dtype=np.float64))
    if kind == "cylinder":
        return trimesh.creation.cylinder(radius=float(size[1]), height=float(size[0]))
    if kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=2, radius=float(size[0]))
    raise InvalidValueError(f"unknown geometry type {kind!r}")


def _to_link_mesh(link: str, mesh: Any, origin: Optional[np.ndarray], scale: Optional[Any]) -> _LinkMesh:
    v = np.asarray(mesh.vertices, dtype=np.float64)
    n = np.asarray(mesh.vertex_normals, dtype=np.float64)
    if scale is not None:
        s = np.broadcast_to(np.asarray(scale, dtype=np.float64).reshape(-1), (3,))
        v = v * s
        # normals transform with the inverse transpose of the scaling, then are renormalised
        n = n / np.where(s == 0.0, 1.0, s)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    if origin is not None:
        t = np.asarray(origin, dtype=np.float64)
        v = v @ t[:3, :3].T + t[:3, 3]
        n = n @ t[:3, :3].T
    return _LinkMesh(link, v, np.asarray(mesh.faces, dtype=np.uint32), n)


class _MeshLoadError(Exception):
    """A mesh file trimesh could not turn into triangles (the link is then drawn without it)."""


def _load_mesh_file(path: str) -> Any:
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as e:  # trimesh raises many types (missing loader plugin, parse errors, I/O)
        raise _MeshLoadError(f"{path}: {type(e).__name__}: {e}") from e
    if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
        raise _MeshLoadError(f"{path}: no triangles")
    return mesh


def _urdf_visual_meshes(urdf: Union[str, os.PathLike], mesh_dir: Optional[str], links: Sequence[str]
                        ) -> List[_LinkMesh]:
    """``<visual>`` geometry of a URDF file (yourdfpy parses it, trimesh loads the meshes)."""
    import yourdfpy

    kwargs: Dict[str, Any] = dict(load_meshes=False, build_scene_graph=False,
                                  build_collision_scene_graph=False, load_collision_meshes=False)
    if mesh_dir:
        kwargs["mesh_dir"] = str(mesh_dir)
    model = yourdfpy.URDF.load(str(urdf), **kwargs)
    wanted = set(links)
    out: List[_LinkMesh] = []
    for link in model.robot.links:
        if link.name not in wanted:
            continue
        for vis in link.visuals:
            g = vis.geometry
            try:
                if g.mesh is not None:
                    mesh = _load_mesh_file(model._filename_handler(g.mesh.filename))
                    out.append(_to_link_mesh(link.name, mesh, vis.origin, g.mesh.scale))
                elif g.box is not None:
                    out.append(_to_link_mesh(link.name, _primitive_mesh("box", g.box.size), vis.origin, None))
                elif g.cylinder is not None:
                    out.append(_to_link_mesh(link.name, _primitive_mesh(
                        "cylinder", [g.cylinder.length, g.cylinder.radius]), vis.origin, None))
                elif g.sphere is not None:
                    out.append(_to_link_mesh(link.name, _primitive_mesh("sphere", [g.sphere.radius]),
                                             vis.origin, None))
            except _MeshLoadError as e:
                warnings.warn(f"gfcs.viz: skipping a visual of link {link.name}: {e}", stacklevel=3)
    return out


def _collision_mesh_files(robot: Any) -> List[Dict[str, Any]]:
    """The robot's URDF ``<collision>`` elements that are mesh files found on disk."""
    return [g for g in robot.collision_geometry() if g.get("type") == "mesh" and g.get("path") and g.get("exists")]


def _collision_meshes(robot: Any) -> List[_LinkMesh]:
    """Mesh elements of the robot's URDF ``<collision>`` geometry that load with trimesh."""
    out: List[_LinkMesh] = []
    for g in _collision_mesh_files(robot):
        try:
            mesh = _load_mesh_file(str(g["path"]))
        except _MeshLoadError as e:
            warnings.warn(f"gfcs.viz: skipping a collision mesh of link {g['link']}: {e}", stacklevel=3)
            continue
        out.append(_to_link_mesh(str(g["link"]), mesh, g.get("origin"), g.get("scale")))
    return out


def _robot_meshes(robot: Any, geometry: str, urdf: Optional[Any], mesh_dir: Optional[str]) -> List[_LinkMesh]:
    if geometry == "spheres":
        return []
    if geometry == "auto" and urdf is None and not _collision_mesh_files(robot):
        return []  # nothing to load (the shipped Panda): spare the import of trimesh, ~0.8 s
    try:
        import trimesh  # noqa: F401
    except ImportError:
        if geometry in ("meshes", "both"):
            raise
        return []
    meshes = _urdf_visual_meshes(urdf, mesh_dir, robot.link_names) if urdf is not None else []
    if not meshes:
        meshes = _collision_meshes(robot)
    if geometry in ("meshes", "both") and not meshes:
        raise InvalidValueError("robot_geometry='meshes': no link mesh could be loaded (pass urdf= with visual "
                                "meshes, or use 'auto' / 'spheres')")
    return meshes


# -------------------------------------------------------------------------------------- the scene
def _log_pose(rec: Any, path: str, pose: np.ndarray) -> None:
    rec.log(path, rr.Transform3D(translation=pose[:3, 3], quaternion=rotation_to_quaternion(pose[:3, :3])),
            static=True)


def _single_obstacle_points(scene: Any, obstacle_id: int, spacing: float) -> np.ndarray:
    """Surface points of one obstacle: the scene copy keeps only that obstacle."""
    alone = scene.copy()
    for other in alone.ids():
        if other != obstacle_id:
            alone.remove(other)
    return np.asarray(alone.surface_points(spacing), dtype=np.float64).reshape(-1, 3)


def _log_obstacles(rec: Any, scene: Any) -> List[str]:
    """Log every obstacle of ``scene`` (static, world frame); returns their entity paths."""
    paths: List[str] = []
    color = [_OBSTACLE_COLOR]
    for ob in scene.obstacles():
        kind = str(ob["type"])
        name = ob.get("name")
        path = f"/world/obstacles/{_part(name if name else ob['id'])}"
        if path in paths:  # names need not be unique: the id disambiguates
            path = f"{path}_{ob['id']}"
        pose = np.asarray(ob["pose"], dtype=np.float64)
        size = np.asarray(ob["size"], dtype=np.float64).reshape(-1)
        if kind in ("mesh", "point_cloud"):
            pts = _single_obstacle_points(scene, int(ob["id"]), _SURFACE_SPACING)
            radius = max(float(size[1]) if kind == "point_cloud" and size.size > 1 else 0.0, 0.004)
            rec.log(path, rr.Points3D(pts, radii=radius, colors=color), static=True)
            paths.append(path)
            continue
        _log_pose(rec, path, pose)
        if kind == "box":
            shape = rr.Boxes3D(half_sizes=[size[:3] / 2.0], colors=color, fill_mode="solid")
        elif kind == "sphere":
            shape = rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=color, fill_mode="solid")
        elif kind == "cylinder":
            shape = rr.Cylinders3D(lengths=[size[0]], radii=[size[1]], centers=[[0.0, 0.0, 0.0]], colors=color,
                                   fill_mode="solid")
        elif kind == "capsule":
            # rerun's capsule runs from the origin along +z; ours is centred on the pose origin
            shape = rr.Capsules3D(lengths=[size[0]], radii=[size[1]], translations=[[0.0, 0.0, -size[0] / 2.0]],
                                  colors=color, fill_mode="solid")
        elif kind == "half_space":
            # the solid is z <= 0 of the pose: draw a thin square under the plane, centred below the
            # world origin's projection onto the plane
            local = pose[:3, :3].T @ (-pose[:3, 3])
            e = _HALF_SPACE_EXTENT
            shape = rr.Boxes3D(half_sizes=[[e, e, 0.005]], centers=[[local[0], local[1], -0.005]],
                               colors=color, fill_mode="solid")
        else:
            warnings.warn(f"gfcs.viz: obstacle {ob.get('name')!r} of unknown type {kind!r} not drawn", stacklevel=3)
            continue
        rec.log(path, shape, static=True)
        paths.append(path)
    return paths


# ------------------------------------------------------------------------------------ one method
def _active_commands(t: np.ndarray, t_stars: np.ndarray, n_segments: int) -> np.ndarray:
    """Index (T,) of the command steering each sample (GFCS eq. 5-7): command i runs for t_i*, so sample k
    (time t_k, uniform step) belongs to segment i when Σ_{j<i} t_j* ≤ t_k − t_0 < Σ_{j≤i} t_j*; the sample
    where a segment ends starts the next one (its acceleration is the next command's)."""
    n = t.shape[0]
    if n < 2 or n_segments < 2:
        return np.zeros(n, dtype=np.int64)
    dt = (t[-1] - t[0]) / (n - 1)
    k = np.rint((t - t[0]) / dt).astype(np.int64)
    ends = np.rint(np.cumsum(np.asarray(t_stars, dtype=np.float64).reshape(-1))[: n_segments - 1] / dt)
    idx = np.searchsorted(ends.astype(np.int64), k, side="right")
    return np.clip(idx, 0, n_segments - 1)


def _fabric_series(problem: Any, result: Any, q: np.ndarray, qd: np.ndarray, t: np.ndarray
                   ) -> Optional[Dict[str, np.ndarray]]:
    """Fabric energy L̃_e = ½ q̇ᵀM̃q̇, forcing potential ψ and their sum (the Lyapunov function of GF
    Thm IV.4) along the trajectory, from ``Fabric.diagnostics``; None when unavailable."""
    import gfcs

    try:
        fabric = gfcs.Fabric(planned_robot(result, problem), problem.scene, getattr(result, "fabric_config", None))
    except gfcs.GfcsError as e:
        warnings.warn(f"gfcs.viz: fabric energy not logged ({e})", stacklevel=3)
        return None
    goal = np.asarray(result.goal, dtype=np.float64).reshape(1, -1)
    cmds = np.vstack([np.asarray(result.commands, dtype=np.float64).reshape(-1, goal.shape[1]), goal])
    active = _active_commands(t, np.asarray(result.t_stars), cmds.shape[0])
    energy = np.full(t.shape[0], math.nan)
    potential = np.full(t.shape[0], math.nan)
    for k in range(t.shape[0]):
        fabric.acceleration(q[k], qd[k], cmds[active[k]])
        d = fabric.diagnostics()
        if d is None:
            return None
        energy[k] = float(d.get("energy", math.nan))
        potential[k] = float(d.get("potential", math.nan))
    return {"energy": energy, "potential": potential, "lyapunov": energy + potential}


def _summary_markdown(label: str, result: Any) -> str:
    m = getattr(result, "metrics", {}) or {}

    def f(key: str, unit: str = "") -> str:
        v = m.get(key)
        return "NA" if v is None or not isinstance(v, (int, float)) or not math.isfinite(v) else f"{v:.3g}{unit}"

    t_stars = " + ".join(f"{x:.2f}" for x in np.asarray(result.t_stars).reshape(-1))
    return "\n".join([
        f"## {label}",
        f"- success: **{bool(result.success)}**, goal reached: {bool(result.reached)}",
        f"- cost (GFCS eq. 4): {float(result.cost):.3g} s (t* = {t_stars} s)",
        f"- commands: {int(np.asarray(result.commands).reshape(-1, len(result.goal)).shape[0])} free",
        f"- EE length {f('ee_length', ' m')}, C-space length {f('cspace_length', ' rad')}",
        f"- EE-LDJ {f('ee_ldj')}, C-space-LDJ {f('cspace_ldj')}",
        f"- min clearance {f('min_clearance', ' m')}, self {f('min_self_clearance', ' m')}",
        f"- solve time {float(getattr(result, 'solve_time', math.nan)):.3g} s",
    ])


@dataclass
class _MethodData:
    """Everything logged for one method, computed before logging (the blueprint needs the series).

    Shapes: ``t`` (T,) s; ``q`` (T, dof); ``ee`` (T, 3) m; ``link_poses`` (T, L, 4, 4) or None;
    ``sphere_centers`` (T, S, 3) m or None; ``command_ee`` (n, 3) m; ``series`` name -> (T,) values.
    """

    label: str
    result: Any
    color: Tuple[int, int, int]
    t: np.ndarray
    q: np.ndarray
    ee: np.ndarray
    link_poses: Optional[np.ndarray]
    sphere_centers: Optional[np.ndarray]
    command_ee: np.ndarray
    series: Dict[str, np.ndarray]


def _prepare_method(problem: Any, label: str, result: Any, color: Tuple[int, int, int], meshes: bool,
                    spheres: bool, energy: bool) -> _MethodData:
    robot = planned_robot(result, problem)
    traj = result.trajectory
    t = np.asarray(traj.t, dtype=np.float64).reshape(-1)
    n = t.shape[0]
    q = np.asarray(traj.q, dtype=np.float64).reshape(n, -1)
    qd = np.asarray(traj.qd, dtype=np.float64).reshape(n, -1)
    if q.shape[1] != robot.dof:
        raise InvalidValueError(f"results[{label!r}]: trajectory has {q.shape[1]} joints, the robot {robot.dof}")
    cmds = np.asarray(result.commands, dtype=np.float64).reshape(-1, q.shape[1])
    series: Dict[str, np.ndarray] = {
        "joint_speed": np.linalg.norm(qd, axis=1),
        "clearance": _metrics.obstacle_clearance(robot, problem.scene, q),
        "self_clearance": _metrics.self_clearance(robot, q),
    }
    if energy:
        series.update(_fabric_series(problem, result, q, qd, t) or {})
    return _MethodData(
        label=label,
        result=result,
        color=color,
        t=t,
        q=q,
        ee=np.asarray(robot.ee_position(q), dtype=np.float64).reshape(n, 3),
        link_poses=np.asarray(robot.link_poses(q), dtype=np.float64).reshape(n, -1, 4, 4) if meshes else None,
        sphere_centers=(np.asarray(robot.sphere_centers(q), dtype=np.float64).reshape(n, -1, 3)
                        if spheres else None),
        command_ee=(np.asarray(robot.ee_position(cmds), dtype=np.float64).reshape(-1, 3) if cmds.shape[0]
                    else np.zeros((0, 3))),
        series={k: np.asarray(v, dtype=np.float64) for k, v in series.items()
                if np.any(np.isfinite(np.asarray(v, dtype=np.float64)))},
    )


def _log_method(rec: Any, robot: Any, d: _MethodData, meshes: List[_LinkMesh]) -> None:
    """Log one method under ``/methods/<label>`` (per-step data on the ``time`` timeline)."""
    base = f"/methods/{d.label}"
    n = d.t.shape[0]
    time = [rr.TimeColumn(TIMELINE, duration=d.t)]

    if d.link_poses is not None:
        index = {name: i for i, name in enumerate(robot.link_names)}
        counts: Dict[str, int] = {}
        for m in meshes:
            if m.link not in index:
                continue
            link_path = f"{base}/robot/links/{_part(m.link)}"
            k = counts.get(m.link, 0)
            counts[m.link] = k + 1
            if k == 0:
                p = d.link_poses[:, index[m.link]]
                rec.send_columns(link_path, indexes=time, columns=rr.Transform3D.columns(
                    translation=p[:, :3, 3], quaternion=rotation_to_quaternion(p[:, :3, :3])))
            rec.log(f"{link_path}/visual_{k}",
                    rr.Mesh3D(vertex_positions=m.vertices, triangle_indices=m.triangles, vertex_normals=m.normals,
                              albedo_factor=d.color),
                    static=True)
    if d.sphere_centers is not None and d.sphere_centers.shape[1] > 0:
        s = d.sphere_centers.shape[1]
        radii = np.asarray(robot.sphere_radii, dtype=np.float64).reshape(-1)
        path = f"{base}/robot/spheres"
        rec.log(path, rr.Points3D.from_fields(colors=[(*d.color, 200)]), static=True)
        rec.send_columns(path, indexes=time, columns=rr.Points3D.columns(
            positions=d.sphere_centers.reshape(n * s, 3), radii=np.tile(radii, n)).partition([s] * n))

    rec.log(f"{base}/ee", rr.Points3D.from_fields(colors=[d.color], radii=[0.015]), static=True)
    rec.send_columns(f"{base}/ee", indexes=time, columns=rr.Points3D.columns(positions=d.ee).partition([1] * n))
    rec.log(f"{base}/ee_path", rr.LineStrips3D([d.ee], colors=[d.color], radii=[0.004]), static=True)
    if d.command_ee.shape[0]:
        rec.log(f"{base}/commands",
                rr.Points3D(d.command_ee, radii=0.03, colors=[_RED],
                            labels=[f"{d.label} q_g^{i + 1}" for i in range(d.command_ee.shape[0])]),
                static=True)
    rec.log(f"{base}/summary", rr.TextDocument(_summary_markdown(d.label, d.result),
                                               media_type=rr.MediaType.MARKDOWN), static=True)
    for name, values in d.series.items():
        path = f"{base}/metrics/{name}"
        ok = np.isfinite(values)
        rec.log(path, rr.SeriesLines(colors=[d.color], names=[f"{d.label}"], widths=[1.5]), static=True)
        rec.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=d.t[ok])],
                         columns=rr.Scalars.columns(scalars=values[ok]))


def _blueprint(methods: Sequence[_MethodData]) -> Any:
    """3D view (world + methods) with the method summaries in tabs below it, beside one time-series
    view per quantity of :data:`SERIES` (each holding every method)."""
    plots = []
    for name, (title, unit) in SERIES.items():
        contents = [f"/methods/{d.label}/metrics/{name}" for d in methods if name in d.series]
        if contents:
            plots.append(rrb.TimeSeriesView(name=f"{title} [{unit}]" if unit else title, origin="/",
                                            contents=contents))
    docs = [rrb.TextDocumentView(name=d.label, origin=f"/methods/{d.label}/summary") for d in methods]
    left = rrb.Vertical(rrb.Spatial3DView(name="scene", origin="/", contents=["/world/**", "/methods/**"]),
                        rrb.Tabs(*docs), row_shares=[4, 1])
    main = rrb.Horizontal(left, rrb.Vertical(*plots), column_shares=[3, 2]) if plots else left
    return rrb.Blueprint(main, collapse_panels=True)


# ------------------------------------------------------------------------------------------ public API
def record(
    problem: Any,
    results: Any,
    path: Optional[Union[str, "os.PathLike[str]"]] = None,
    *,
    spawn: bool = False,
    robot_geometry: str = "auto",
    urdf: Optional[Union[str, "os.PathLike[str]"]] = None,
    mesh_dir: Optional[Union[str, "os.PathLike[str]"]] = None,
    energy: bool = True,
    application_id: str = "gfcs",
) -> Optional[str]:
    """Write a rerun recording of the solutions of one problem (several methods side by side).

    Args:
        problem: the :class:`gfcs.problems.Problem` the results solve (robot, scene, q₀, goal).
        results: a :class:`gfcs.results.SolveResult`, a list of them, or a ``{label: result}`` mapping;
            each needs its trajectory (T ≥ 1 samples). Labels: see the module docstring.
        path: the ``.rrd`` file to write (parent folders are created). None: no file (needs ``spawn``).
        spawn: also stream to a rerun viewer started for the occasion (needs a display).
        robot_geometry: ``"auto"`` (link meshes when some load with trimesh, otherwise the collision
            spheres), ``"meshes"`` (meshes, or an error when none loads), ``"spheres"`` (the collision
            spheres only) or ``"both"``.
        urdf: a URDF file whose ``<visual>`` geometry draws the links (its link names must be the
            robot's); default: the mesh elements of ``robot.collision_geometry()``.
        mesh_dir: folder resolving the URDF's relative / ``package://`` mesh paths.
        energy: log the fabric energy L̃_e, the potential ψ and L̃_e + ψ at every sample
            (``Fabric.diagnostics`` after one ``Fabric.acceleration`` call per sample, with the command
            active at that sample, GFCS eq. 5-7).
        application_id: the rerun application id.

    Returns:
        The path written, as a string (None when ``path`` is None).

    Raises:
        ValueError: no results, an empty trajectory, a trajectory of another robot, neither ``path`` nor
            ``spawn``, an unknown ``robot_geometry``, or ``"meshes"`` with no loadable mesh.
    """
    if path is None and not spawn:
        raise InvalidValueError("record: give a path to write, or spawn=True")
    if robot_geometry not in ("auto", "meshes", "spheres", "both"):
        raise InvalidValueError(f"robot_geometry must be 'auto', 'meshes', 'spheres' or 'both', got {robot_geometry!r}")
    items = _normalise_results(results)
    robot = problem.robot
    meshes = _robot_meshes(robot, robot_geometry, urdf, None if mesh_dir is None else str(mesh_dir))
    spheres = robot_geometry in ("spheres", "both") or not meshes
    methods = [_prepare_method(problem, label, r, _color(label, i), bool(meshes), spheres, energy)
               for i, (label, r) in enumerate(items)]
    blueprint = _blueprint(methods)

    rec = rr.RecordingStream(application_id)
    out_path: Optional[str] = None
    if path is not None:
        target = Path(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        out_path = str(target)
    if out_path is not None and spawn:
        rr.spawn(connect=False)
        rec.set_sinks(rr.FileSink(out_path), rr.GrpcSink(), default_blueprint=blueprint)
    elif out_path is not None:
        rec.save(out_path, default_blueprint=blueprint)
    else:
        rec.spawn(default_blueprint=blueprint)

    rec.send_recording_name(str(problem.name))
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    _log_obstacles(rec, problem.scene)
    goal_ee = np.asarray(robot.ee_position(problem.goal), dtype=np.float64).reshape(1, 3)
    start_ee = np.asarray(robot.ee_position(problem.q0), dtype=np.float64).reshape(1, 3)
    rec.log("/world/goal", rr.Points3D(goal_ee, radii=0.04, colors=[_GREEN], labels=["goal"]), static=True)
    rec.log("/world/start", rr.Points3D(start_ee, radii=0.025, colors=[(240, 240, 240)], labels=["start"]),
            static=True)
    for d in methods:
        _log_method(rec, planned_robot(d.result, problem), d, meshes)
    rec.flush()
    rec.disconnect()  # closes the file sink (writes the footer)
    return out_path


# ------------------------------------------------------------------------------------------- viewer
def has_display() -> bool:
    """Whether a graphical viewer can open here (macOS / Windows, or ``$DISPLAY`` / ``$WAYLAND_DISPLAY``)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def viewer_command() -> List[str]:
    """The command starting the rerun viewer: the ``rerun`` executable of the rerun-sdk wheel when on
    ``PATH``, else ``python -m rerun``."""
    exe = shutil.which("rerun")
    return [exe] if exe else [sys.executable, "-m", "rerun"]


def view(path: Union[str, "os.PathLike[str]"], *, wait: bool = True) -> int:
    """Open a recording in the rerun viewer, or print how to open it when there is no display.

    Args:
        path: the ``.rrd`` file.
        wait: wait for the viewer to close (its exit code is returned); False: return 0 at once.

    Returns:
        The viewer's exit code (0 when it was not started or not waited for).

    Raises:
        FileNotFoundError: ``path`` is not a file.
    """
    p = Path(path)
    if not p.is_file():
        raise MissingFileError(2, "no such recording", str(p))
    cmd = viewer_command() + [str(p)]
    if not has_display():
        print(f"gfcs view: no display here. Open {p} on a machine with one (`pip install rerun-sdk`, then "
              f"`rerun {p.name}`), or serve it to a browser from here: `{' '.join(cmd)} --web-viewer` "
              "(then open the printed http address, forwarding port 9090 and the gRPC port 9876 over ssh "
              "if needed).")
        return 0
    proc = subprocess.Popen(cmd)
    return int(proc.wait()) if wait else 0


def _cmd_view(args: argparse.Namespace) -> int:
    return view(args.path, wait=not args.no_wait)


def register_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``gfcs view REC.rrd`` to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser(
        "view", help="open a rerun recording (.rrd) in the viewer",
        description="Open a recording written by `gfcs solve --rrd` / `gfcs bench --rrd-dir` (or "
                    "gfcs.viz.record) in the rerun viewer shipped with rerun-sdk. Without a display, "
                    "print how to open it elsewhere.",
    )
    p.add_argument("path", metavar="REC.rrd", help="the recording")
    p.add_argument("--no-wait", action="store_true", help="return without waiting for the viewer to close")
    p.set_defaults(func=_cmd_view)
    return p
