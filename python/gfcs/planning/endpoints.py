"""The start and goal of a problem, judged on the collision meshes before any planning.

MoveIt refuses a request whose start state is in collision, and a goal in collision cannot be reached by a
collision-free motion. A validator that checks every state of a returned motion against the meshes rejects
each motion of such a problem, so :func:`gfcs.planning.solve` checks both states first
(:func:`check_endpoints`) and raises :class:`gfcs.CollisionError` naming the links in contact instead of
spending its time budget. ``solve(..., endpoint_check=False)`` plans anyway.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gfcs.errors import CollisionError

__all__ = ["check_endpoints", "check_held_links", "endpoint_grazes"]


def _depth(distance: float) -> str:
    """How deep a contact of (signed) ``distance`` [m, ≤ 0] is, for messages."""
    return f"{max(0.0, -distance) * 1000:.3g} mm deep"


def check_held_links(checker: Any, q: Any, what: str) -> None:
    """Raise :class:`gfcs.CollisionError` (its message starting with ``what``) when two links that joints
    outside the robot's active joints hold still relative to each other touch at their held values
    (:meth:`gfcs.MeshChecker.held_contacts` at q (dof,)): MoveIt checks such a pair like any other, and no
    motion of the active joints moves it apart, so every state is in collision."""
    contacts = checker.held_contacts(np.asarray(q, dtype=np.float64), 0.0)
    if contacts:
        a, b, depth = contacts[0]
        more = f" (and {len(contacts) - 1} more pair(s))" if len(contacts) > 1 else ""
        held = ", ".join(sorted(checker.robot.locked_positions)[:4])
        raise CollisionError(f"{what}: links '{a}' and '{b}' touch ({_depth(depth)}){more} at the held "
                             f"values of the joints the group does not move ({held}, ...), so every state of "
                             "every motion is in collision; hold those joints elsewhere (the request's start state) "
                             "or disable the pair in the SRDF")


def check_endpoints(problem: Any) -> None:
    """Raise :class:`gfcs.CollisionError` when the start ``problem.q0`` or the goal ``problem.goal`` puts the
    collision meshes of ``problem.mesh_checker`` in contact (distance ≤ 0) with the scene or with each other
    (the SRDF's enabled link pairs, adjacent links included), or when links held still by the joints outside
    the group touch (:func:`check_held_links`); the message names the problem, the state, the links and the
    depth.
    Nothing is checked for a problem without a :class:`gfcs.MeshChecker` (the sphere model is conservative by
    design; a duck-typed stand-in checker is not asked, so that it sees only the motions)."""
    from gfcs._core import MeshChecker

    checker = getattr(problem, "mesh_checker", None)
    if not isinstance(checker, MeshChecker):
        return
    check_held_links(checker, problem.q0, f"problem '{problem.name}'")
    for state, q in (("start", problem.q0), ("goal", problem.goal)):
        q = np.asarray(q, dtype=np.float64)
        contacts = checker.self_contacts(q, 0.0)
        if contacts:
            a, b, depth = contacts[0]
            more = f" (and {len(contacts) - 1} more pair(s))" if len(contacts) > 1 else ""
            raise CollisionError(f"problem '{problem.name}': the {state} state is in collision: the meshes of "
                                 f"links '{a}' and '{b}' touch ({_depth(depth)}){more}; "
                                 f"MoveIt refuses such a request (endpoint_check=False plans anyway)")
        contacts = checker.adjacent_contacts(q, 0.0)
        if contacts:
            a, b, depth = contacts[0]
            raise CollisionError(f"problem '{problem.name}': the {state} state is in collision: the meshes of "
                                 f"adjacent links '{a}' and '{b}' touch ({_depth(depth)}) and the SRDF "
                                 "leaves the pair enabled, so MoveIt checks it (MoveIt Setup Assistant disables "
                                 f'adjacent links: <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/>; '
                                 "`gfcs collision-matrix` writes its whole matrix)")
        # distances up to a micrometre are measured exactly; nearer than 0 is contact
        clearance = float(checker.min_clearance(problem.scene, q, cutoff=1e-6))
        if clearance <= 0.0:
            raise CollisionError(f"problem '{problem.name}': the {state} state is in collision: the meshes "
                                 f"touch an obstacle ({_depth(clearance)}); MoveIt refuses such a "
                                 f"request (endpoint_check=False plans anyway)")


def endpoint_grazes(problem: Any, margin: float) -> bool:
    """Whether the start or the goal keeps its collision meshes within ``margin`` +
    :data:`gfcs.metrics.INTERPOLATION_ALLOWANCE` [m] of the scene or of each other: every motion of the
    problem then passes that near, so the continuous check must certify each candidate's path there, and no
    candidate certifies faster than another. False without a :class:`gfcs.MeshChecker`."""
    from gfcs._core import MeshChecker
    from gfcs.metrics import INTERPOLATION_ALLOWANCE

    checker = getattr(problem, "mesh_checker", None)
    if not isinstance(checker, MeshChecker):
        return False
    near = float(margin) + INTERPOLATION_ALLOWANCE
    q = np.asarray([problem.q0, problem.goal], dtype=np.float64)
    return min(float(checker.min_clearance(problem.scene, q, cutoff=near)),
               float(checker.min_self_clearance(q, cutoff=near))) <= near
