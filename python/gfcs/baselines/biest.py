"""Bi-EST: the bidirectional expansive-space-tree planner of OMPL (``ompl::geometric::BiEST``, Hsu, Latombe
and Motwani 1999, as OMPL implements it), in numpy.

The ``ompl`` 2.0 wheels from PyPI compile BiEST into their library but bind no Python class for it, so the
planner runs here, on the same collision checks (:class:`gfcs.baselines.validity.SphereValidity`) and the
same parameters as OMPL's, and its path is then simplified by OMPL's own ``PathSimplifier``
(:mod:`gfcs.baselines.ompl_planner`). The algorithm, per iteration, on one of the two trees (start, goal),
the other tree's turn coming after each segment check (a failed sample or a rejected state tries the same
tree again):

1. pick a node of the tree with probability proportional to its weight 1 / (1 + n), n the number of nodes of
   that tree within the neighbourhood radius r_n when it was added or since (OMPL's PDF update w → w/(w+1));
2. sample a valid state uniformly in the box of half-width ``range`` around it, clipped to the bounds (OMPL's
   ``UniformValidStateSampler::sampleNear``, up to 100 attempts);
3. with k ≥ 1 tree nodes within r_n of that state, drop it with probability 1 − 1/k (density rejection);
4. if the segment from the node to the state is valid, add the state; then try to connect it to each node
   of the other tree within ``range``, nearest first: the first valid segment joins the trees.

Parameters as OMPL sets them: ``range`` = 0.2 × the space's maximum extent (``SelfConfig``), r_n = range / 3.
"""

from __future__ import annotations

import time
from typing import List, Optional, Tuple

import numpy as np

from gfcs.baselines.validity import SphereValidity

__all__ = ["BiEST", "RANGE_FRACTION", "SAMPLE_ATTEMPTS"]

#: OMPL's default planner range as a fraction of the space's maximum extent
#: (``magic::MAX_MOTION_LENGTH_AS_SPACE_EXTENT_FRACTION``).
RANGE_FRACTION = 0.2
#: Attempts of OMPL's ``UniformValidStateSampler`` to find a valid state near another.
SAMPLE_ATTEMPTS = 100
#: Candidates drawn (and checked in one batch) per round of the near-sampler's attempts.
_SAMPLE_BATCH = 10


class _Tree:
    """Nodes (states), parents and EST weights of one tree, in growable arrays."""

    def __init__(self, root: np.ndarray) -> None:
        self.states = np.empty((64, root.shape[0]))
        self.parent = np.empty(64, dtype=np.int64)
        self.weight = np.empty(64)
        self.n = 0
        self.add(root, -1, np.zeros(0, dtype=np.int64))

    def within(self, q: np.ndarray, radius: float) -> Tuple[np.ndarray, np.ndarray]:
        """(indices, distances) of the nodes within ``radius`` of ``q``, nearest first."""
        d = np.linalg.norm(self.states[:self.n] - q, axis=1)
        idx = np.flatnonzero(d <= radius)
        order = np.argsort(d[idx], kind="stable")
        return idx[order], d[idx[order]]

    def add(self, q: np.ndarray, parent: int, neighbours: np.ndarray) -> int:
        if self.n == self.states.shape[0]:
            self.states = np.vstack([self.states, np.empty_like(self.states)])
            self.parent = np.concatenate([self.parent, np.empty_like(self.parent)])
            self.weight = np.concatenate([self.weight, np.empty_like(self.weight)])
        w = self.weight[neighbours]
        self.weight[neighbours] = w / (w + 1.0)
        self.states[self.n], self.parent[self.n] = q, parent
        self.weight[self.n] = 1.0 / (len(neighbours) + 1.0)
        self.n += 1
        return self.n - 1

    def pick(self, rng: np.random.Generator) -> int:
        c = np.cumsum(self.weight[:self.n])
        return int(min(np.searchsorted(c, rng.random() * c[-1], side="right"), self.n - 1))

    def branch(self, i: int) -> List[np.ndarray]:
        """States from node ``i`` back to the root."""
        out = []
        while i >= 0:
            out.append(self.states[i].copy())
            i = int(self.parent[i])
        return out


class BiEST:
    """OMPL's BiEST on a :class:`SphereValidity` (see the module docstring).

    Args:
        validity: the collision checks (its ``lower``/``upper`` are the sampling bounds).
        extent: the state space's maximum extent [rad] (OMPL's ``getMaximumExtent``: the diagonal of the
            bounds box), from which ``range`` follows.
    """

    def __init__(self, validity: SphereValidity, extent: float) -> None:
        self.validity = validity
        self.range = RANGE_FRACTION * float(extent)
        self.radius = self.range / 3.0
        self.nodes = 0

    def _sample_near(self, q: np.ndarray, rng: np.random.Generator) -> Optional[np.ndarray]:
        lo = np.maximum(self.validity.lower, q - self.range)
        hi = np.minimum(self.validity.upper, q + self.range)
        for _ in range(SAMPLE_ATTEMPTS // _SAMPLE_BATCH):
            cand = lo + rng.random((_SAMPLE_BATCH, q.shape[0])) * (hi - lo)
            ok = np.flatnonzero(self.validity.valid(cand))
            if ok.size:
                return cand[ok[0]]
        return None

    def solve(self, start: np.ndarray, goal: np.ndarray, rng: np.random.Generator,
              deadline: float) -> Optional[List[np.ndarray]]:
        """A path of states from ``start`` to ``goal`` (both valid), or None when ``time.perf_counter()``
        passes ``deadline`` first."""
        trees = (_Tree(np.asarray(start, dtype=np.float64)), _Tree(np.asarray(goal, dtype=np.float64)))
        grow = 0
        try:
            while time.perf_counter() < deadline:
                tree, other = trees[grow], trees[1 - grow]
                existing = tree.pick(rng)
                x = self._sample_near(tree.states[existing], rng)
                if x is None:  # as in OMPL, a failed sample or a rejection grows the same tree again
                    continue
                near, _ = tree.within(x, self.radius)
                if len(near) and rng.random() < 1.0 - 1.0 / len(near):
                    continue
                grow = 1 - grow
                if not self.validity.segment_valid(tree.states[existing], x):
                    continue
                new = tree.add(x, existing, near)
                for j in other.within(x, self.range)[0]:
                    if self.validity.segment_valid(x, other.states[j]):
                        mine, theirs = tree.branch(new), other.branch(int(j))
                        from_start = mine if tree is trees[0] else theirs
                        to_goal = theirs if tree is trees[0] else mine
                        return from_start[::-1] + to_goal
            return None
        finally:
            self.nodes = trees[0].n + trees[1].n
