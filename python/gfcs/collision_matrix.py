"""The collision matrix MoveIt Setup Assistant writes into an SRDF, for a robot that has no MoveIt
configuration: which link pairs never need a collision check.

A URDF alone leaves every link pair enabled. Links that touch by construction (a joint's two links, a
finger against its palm) then collide at every configuration, and conservative collision spheres of links
that never meet overlap at many: such a robot cannot be planned for, nor validated, until those pairs are
disabled. :func:`collision_matrix` samples the configuration space as Setup Assistant does and gives each
disabled pair its reason:

* ``"Adjacent"``: a joint joins the two links (links without collision geometry are skipped, so a link is
  adjacent to its nearest ancestor with geometry);
* ``"Default"``: the pair touches at the default configuration (every joint at 0, clamped into its limits);
* ``"Always"``: the pair touches in at least ``always`` (0.95) of the sampled configurations;
* ``"Never"``: the pair touches in none of ``samples`` (10,000) configurations drawn uniformly within the
  joint limits (a continuous joint within the core's [−2π, 2π], :mod:`gfcs.joints`).

Every other pair stays enabled. "Touches" means the collision meshes and primitives of the two links come
within ``contact`` (0 m: in contact) of each other, measured by :class:`gfcs.MeshChecker`. Like Setup
Assistant's, the result is statistical: a pair that touches only in a small region of the configuration
space that no sample hit is disabled as "Never". Links joined by fixed joints (one rigid body) that are
not adjacent are not measured: gfcs never checks them, and a pair of them that touches would touch at every
configuration. Pairs on two bodies that a movable joint joins, which gfcs's planner leaves out, are measured
on the first :data:`ADJACENT_SAMPLES` samples.

Command line: ``gfcs collision-matrix robot.urdf -o robot.srdf`` (``--srdf`` adds the pairs to an SRDF that
has the groups).
"""

from __future__ import annotations

import argparse
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError
from gfcs.srdf_groups import PathOrXml, UrdfTree, collision_links, read_urdf_tree, read_xml

__all__ = ["ADJACENT_SAMPLES", "DisabledPair", "REASONS", "adjacent_pairs", "adjacent_body_pairs", "movable_joints",
           "collision_matrix", "srdf_with_pairs", "register_cli"]

#: The reasons of Setup Assistant's matrix, in the order they are decided.
REASONS = ("Adjacent", "Default", "Always", "Never")
#: The adjacent-body pairs are measured one configuration at a time, on this many of the samples at most
#: (their mesh distances, of links that meet at a joint, take about 2.5 ms per configuration on the Fetch).
ADJACENT_SAMPLES = 1000
PathLike = PathOrXml


@dataclass(frozen=True)
class DisabledPair:
    """A link pair whose collision check the SRDF disables, and why (one of :data:`REASONS`)."""

    link1: str
    link2: str
    reason: str


def adjacent_pairs(urdf: PathLike) -> List[Tuple[str, str]]:
    """(parent, child) of every pair of links with collision geometry that the kinematic tree of ``urdf``
    joins directly, links without geometry skipped (Setup Assistant's "Adjacent"); sorted by child."""
    return _adjacent_pairs(read_urdf_tree(urdf), collision_links(urdf))


def adjacent_body_pairs(urdf: PathLike) -> List[Tuple[str, str]]:
    """The pairs of links with collision geometry on two rigid bodies that one movable joint joins (links
    joined by fixed joints form one body), sorted: the pairs gfcs's self-collision model leaves out as
    adjacent, a superset of :func:`adjacent_pairs` (a link fixed to its parent's body and a sibling on a
    joint of that body, say)."""
    return _adjacent_body_pairs(read_urdf_tree(urdf), collision_links(urdf))


def movable_joints(urdf: PathLike) -> List[str]:
    """The joints of ``urdf`` that move on their own (revolute, continuous, prismatic; not mimic joints),
    in tree order: the configuration space the matrix samples."""
    return _movable_joints(read_urdf_tree(urdf))


def _adjacent_pairs(tree: UrdfTree, solid_links: Sequence[str]) -> List[Tuple[str, str]]:
    """:func:`adjacent_pairs` of a parsed tree and its links with collision geometry."""
    solid = set(solid_links)

    def solid_parent(link: str) -> Optional[str]:
        return next((a for a in tree.ancestors(link) if a in solid), None)

    return [(p, link) for link in sorted(solid) if (p := solid_parent(link)) is not None]


def _adjacent_body_pairs(tree: UrdfTree, solid: Sequence[str]) -> List[Tuple[str, str]]:
    """:func:`adjacent_body_pairs` of a parsed tree and its links with collision geometry."""
    body = {link: link for link in tree.links}
    for j in tree.joints:  # tree order: a parent's body is settled before its children's
        if j.type == "fixed":
            body[j.child] = body[j.parent]
    joined = {frozenset((body[j.parent], body[j.child])) for j in tree.joints if j.type != "fixed"}
    return sorted((a, b) for a in solid for b in solid if a < b and frozenset((body[a], body[b])) in joined)


def _movable_joints(tree: UrdfTree) -> List[str]:
    """:func:`movable_joints` of a parsed tree."""
    return [j.name for j in tree.joints if j.active]


def _link_contacts(checker: Any, q: np.ndarray, contact: float, threads: Optional[int],
                   adjacent_bodies: Sequence[Tuple[str, str]]) -> Dict[Tuple[str, str], np.ndarray]:
    """Link pair (sorted names) -> (T,) bool: its shapes come within ``contact`` m at each configuration of
    q (T, dof); the checker's self pairs (batched) and ``adjacent_bodies`` (one configuration at a time)."""
    # verdicts only: two meshes in contact read 0, without parry's penetration depth (which costs most of
    # the matrix's time on links that overlap at their joint)
    d = np.atleast_2d(checker.pair_clearances(q, threads=threads, cutoff=contact, depth=False))
    out: Dict[Tuple[str, str], np.ndarray] = {}
    for k, (a, b) in enumerate(checker.self_pair_links):
        key = (a, b) if a <= b else (b, a)
        hit = d[:, k] <= contact
        out[key] = out[key] | hit if key in out else hit
    if adjacent_bodies:
        for key in adjacent_bodies:
            out.setdefault(key, np.zeros(len(q), dtype=bool))
        for t, row in enumerate(q):
            for a, b, _ in checker.adjacent_contacts(row, within=contact, depth=False):
                key = (a, b) if a <= b else (b, a)
                if key in out:
                    out[key][t] = True
    return out


def collision_matrix(urdf: PathLike, mesh_dir: Optional[PathLike] = None, samples: int = 10000, seed: int = 0,
                     always: float = 0.95, contact: float = 0.0, threads: Optional[int] = None,
                     progress: bool = False) -> List[DisabledPair]:
    """The link pairs of ``urdf`` that Setup Assistant's collision matrix disables (module docstring), sorted
    by link names. ``mesh_dir`` resolves ``package://`` mesh paths; ``samples`` configurations (≥ 1) drawn
    with ``seed``; ``always`` in (0, 1]; ``contact`` [m, ≥ 0]. Raises InvalidValueError for bad arguments, a
    URDF without collision geometry; gfcs.IoError / gfcs.FormatError for one that cannot be read."""
    import gfcs

    tree, solid = read_urdf_tree(urdf), collision_links(urdf)  # each file read once
    joints = _movable_joints(tree)
    if not joints:
        raise InvalidValueError(f"{urdf}: no movable joint (revolute, continuous or prismatic) to sample")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise InvalidValueError(f"samples must be an integer >= 1, got {samples!r}")
    if not 0.0 < float(always) <= 1.0:
        raise InvalidValueError(f"always must be in (0, 1], got {always!r}")
    if not (np.isfinite(contact) and contact >= 0.0):
        raise InvalidValueError(f"contact must be a finite distance >= 0 [m], got {contact!r}")
    # an SRDF that disables nothing: the checker then reports the adjacent-body pairs too
    # (MeshChecker.adjacent_contacts), which MoveIt checks unless the matrix disables them
    with tempfile.TemporaryDirectory() as tmp:
        bare = Path(tmp) / "bare.srdf"
        bare.write_text('<robot name="robot"/>')
        robot = gfcs.Robot.from_urdf(str(urdf), mesh_dir=None if mesh_dir is None else str(mesh_dir),
                                     active_joints=joints, srdf=str(bare))
    checker = gfcs.MeshChecker(robot)
    adjacent_bodies = _adjacent_body_pairs(tree, solid)
    pairs: List[DisabledPair] = [DisabledPair(*sorted(p), "Adjacent") for p in _adjacent_pairs(tree, solid)]
    decided = {(p.link1, p.link2) for p in pairs}
    # the core's box of each joint (a continuous joint's is [−2π, 2π]: every angle, twice)
    lower, upper = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    default = np.clip(np.zeros(robot.dof), lower, upper)
    for key, hit in sorted(_link_contacts(checker, default[None, :], contact, threads, adjacent_bodies).items()):
        if key not in decided and hit[0]:
            pairs.append(DisabledPair(*key, "Default"))
            decided.add(key)
    rng = np.random.default_rng(seed)
    counts: Dict[Tuple[str, str], int] = {}
    totals: Dict[Tuple[str, str], int] = {}
    chunk = ADJACENT_SAMPLES  # the first chunk measures the adjacent-body pairs too
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=int(samples), desc="collision matrix", unit="configuration")
    for start in range(0, int(samples), chunk):
        n = min(chunk, int(samples) - start)
        measured = adjacent_bodies if start < ADJACENT_SAMPLES else ()
        q = rng.uniform(lower, upper, size=(n, robot.dof))
        for key, hit in _link_contacts(checker, q, contact, threads, measured).items():
            counts[key] = counts.get(key, 0) + int(hit.sum())
            totals[key] = totals.get(key, 0) + n
        if bar is not None:
            bar.update(n)
    if bar is not None:
        bar.close()
    for key in sorted(counts):
        if key in decided:
            continue
        if counts[key] >= always * totals[key]:
            pairs.append(DisabledPair(*key, "Always"))
        elif counts[key] == 0:
            pairs.append(DisabledPair(*key, "Never"))
    return sorted(pairs, key=lambda p: (p.link1, p.link2))


def srdf_with_pairs(pairs: Sequence[DisabledPair], robot_name: str, srdf: Optional[PathLike] = None) -> str:
    """SRDF text: ``srdf`` (its groups and other elements kept; a new ``<robot name=robot_name>`` when None)
    with a ``<disable_collisions>`` for each of ``pairs`` that it does not disable already."""
    root = ET.Element("robot", name=robot_name) if srdf is None else read_xml(srdf, "SRDF")[0]
    have = {frozenset((e.get("link1"), e.get("link2"))) for e in root.iter("disable_collisions")}
    for p in pairs:
        if frozenset((p.link1, p.link2)) not in have:
            ET.SubElement(root, "disable_collisions", link1=p.link1, link2=p.link2, reason=p.reason)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _cmd(args: argparse.Namespace) -> int:
    import json
    import sys

    from gfcs.cli import _writable_file

    _writable_file(args.out, "-o")  # before sampling, so that a long run does not end in a write error
    pairs = collision_matrix(args.urdf, mesh_dir=args.mesh_dir, samples=args.samples, seed=args.seed,
                             always=args.always, contact=args.contact, threads=args.threads,
                             progress=not args.no_progress)
    counts = {r: sum(p.reason == r for p in pairs) for r in REASONS}
    name = read_xml(args.urdf, "URDF")[0].get("name") or Path(args.urdf).stem
    text = srdf_with_pairs(pairs, name, args.srdf)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        print(json.dumps({"urdf": str(args.urdf), "samples": args.samples, "seed": args.seed,
                          "counts": counts, "pairs": [p.__dict__ for p in pairs]}))
    elif not args.out:
        sys.stdout.write(text)
    summary = ", ".join(f"{counts[r]} {r}" for r in REASONS)
    print(f"gfcs: {len(pairs)} link pairs disabled ({summary})" + (f"; wrote {args.out}" if args.out else ""),
          file=sys.stderr)
    return 0


def register_cli(sub: Any) -> argparse.ArgumentParser:
    """Register ``gfcs collision-matrix``."""
    p = sub.add_parser(
        "collision-matrix", help="write the SRDF collision matrix MoveIt Setup Assistant would (for a URDF "
                                 "without a MoveIt configuration)",
        description="Disable the link pairs MoveIt Setup Assistant would, each with its reason: Adjacent (a joint "
                    "joins them), Default (in contact at the default configuration), Always (in contact in at least "
                    "--always of --samples random configurations), Never (in none of them); every other pair stays "
                    "enabled. Contact is measured on the URDF's collision meshes and primitives. Writes the SRDF "
                    "(stdout unless -o) and a summary on stderr.")
    p.add_argument("urdf", help="robot URDF with collision geometry")
    p.add_argument("--mesh-dir", help="directory resolving package:// mesh paths")
    p.add_argument("--srdf", help="SRDF to add the pairs to (its groups kept; default: a new one)")
    p.add_argument("-o", "--out", help="SRDF file to write")
    p.add_argument("--samples", type=int, default=10000, help="random configurations (default 10000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the samples (default 0)")
    p.add_argument("--always", type=float, default=0.95,
                   help="share of samples in contact from which a pair is 'Always' (default 0.95)")
    p.add_argument("--contact", type=float, default=0.0,
                   help="distance [m] at or below which two links touch (default 0)")
    p.add_argument("--threads", type=int, help="worker threads (default: all cores)")
    p.add_argument("--json", action="store_true", help="print the pairs and counts as JSON on stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd)
    return p
