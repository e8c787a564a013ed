"""Solution buffer ``D^buffer`` of Algorithm 2 (GFCS Sec. IV-C): positives for the InfoNCE loss.

Policy (``MaintainBuffer`` of Alg. 2, with the paper's figures, GFCS Sec. V):

* :meth:`SolutionBuffer.insert` takes the solutions of one ``SolveGFCOP`` call, sorts them by cost
  (ascending, stable) and appends the best ``top_m`` (paper: 4) in that order; candidates with a
  non-finite cost, or a cost above ``max_cost`` when one is given, are skipped;
* the buffer keeps at most ``max_size`` entries (paper: 200): when full, the oldest entries are dropped
  first (FIFO).

Each entry holds the problem name, the context ``x^c`` ``(C,)`` (normalised, see
:mod:`gfcs.learning.encoding`), the target ``y`` ``(D,)`` in joint units (rad; ``D = n_free · dof``, the
concatenated free commands) and its GFCOP cost (s, GFCS eq. 4). The buffer is serialisable
(:meth:`state_dict` / :meth:`from_state_dict`, :meth:`save` / :meth:`load` as ``.npz``).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Deque, Dict, List, Optional, Sequence, Union

import numpy as np

from ._validate import ConfigError, as_float_array, check_positive_int

__all__ = ["BufferEntry", "SolutionBuffer"]


@dataclass(frozen=True)
class BufferEntry:
    """One positive example: ``problem`` name, ``context`` ``(C,)``, ``target`` ``(D,)`` rad, ``cost`` s."""

    problem: str
    context: np.ndarray
    target: np.ndarray
    cost: float


class SolutionBuffer:
    """FIFO buffer of the top-``top_m`` solutions of every solved problem, at most ``max_size`` entries."""

    def __init__(self, max_size: int = 200, top_m: int = 4) -> None:
        self.max_size = check_positive_int("buffer max_size", max_size)
        self.top_m = check_positive_int("top_m", top_m)
        self._entries: Deque[BufferEntry] = deque()

    def __len__(self) -> int:
        return len(self._entries)

    def __iter__(self):
        return iter(list(self._entries))

    @property
    def entries(self) -> List[BufferEntry]:
        """Entries from oldest to newest."""
        return list(self._entries)

    def insert(self, problem: str, context, candidates, costs, max_cost: Optional[float] = None) -> int:
        """Insert the best ``top_m`` of one problem's solutions; returns how many were inserted.

        ``context``: ``(C,)``; ``candidates``: ``(M, D)`` (or a sequence of ``(D,)``); ``costs``: ``(M,)``.
        Context and target lengths must match the entries already in the buffer.
        """
        ctx = as_float_array("context", context, (None,))
        cand = np.asarray(candidates, dtype=np.float64)
        if cand.ndim == 1 and cand.size == 0:
            cand = cand.reshape(0, 0)
        cand = as_float_array("candidates", cand, (None, None))
        cost = np.asarray(costs, dtype=np.float64)
        if cost.shape != (cand.shape[0],):
            raise ConfigError(f"costs: expected shape ({cand.shape[0]},), got {cost.shape}")
        if self._entries:
            first = self._entries[0]
            if ctx.shape != first.context.shape:
                raise ConfigError(f"context: expected shape {first.context.shape}, got {ctx.shape}")
            if cand.shape[0] and cand.shape[1:] != first.target.shape:
                raise ConfigError(f"candidates: expected shape (M, {first.target.shape[0]}), got {cand.shape}")
        keep = np.isfinite(cost)
        if max_cost is not None:
            keep &= cost <= float(max_cost)
        idx = np.flatnonzero(keep)
        idx = idx[np.argsort(cost[idx], kind="stable")][: self.top_m]
        for i in idx:
            self._entries.append(BufferEntry(str(problem), ctx.copy(), cand[i].copy(), float(cost[i])))
        while len(self._entries) > self.max_size:
            self._entries.popleft()
        return int(idx.size)

    def contexts(self) -> np.ndarray:
        """``(N, C)`` contexts, oldest first (``(0, 0)`` when empty)."""
        return np.stack([e.context for e in self._entries]) if self._entries else np.zeros((0, 0))

    def targets(self) -> np.ndarray:
        """``(N, D)`` targets in rad, oldest first (``(0, 0)`` when empty)."""
        return np.stack([e.target for e in self._entries]) if self._entries else np.zeros((0, 0))

    def costs(self) -> np.ndarray:
        """``(N,)`` costs, oldest first."""
        return np.array([e.cost for e in self._entries], dtype=np.float64)

    def problems(self) -> List[str]:
        """Problem names, oldest first."""
        return [e.problem for e in self._entries]

    def state_dict(self) -> Dict[str, Any]:
        """Arrays and settings: ``max_size``, ``top_m``, ``problems`` (list), ``contexts`` ``(N, C)``,
        ``targets`` ``(N, D)``, ``costs`` ``(N,)``."""
        return {"max_size": self.max_size, "top_m": self.top_m, "problems": self.problems(),
                "contexts": self.contexts(), "targets": self.targets(), "costs": self.costs()}

    @classmethod
    def from_state_dict(cls, state: Dict[str, Any]) -> "SolutionBuffer":
        """Inverse of :meth:`state_dict` (accepts numpy arrays, tensors or nested lists)."""
        buf = cls(int(state["max_size"]), int(state["top_m"]))
        names: Sequence[str] = list(state["problems"])
        n = len(names)
        ctx = np.asarray(state["contexts"], dtype=np.float64).reshape(n, -1) if n else np.zeros((0, 0))
        tgt = np.asarray(state["targets"], dtype=np.float64).reshape(n, -1) if n else np.zeros((0, 0))
        cost = np.asarray(state["costs"], dtype=np.float64).reshape(n)
        if n > buf.max_size:
            raise ConfigError(f"buffer state: {n} entries exceed max_size {buf.max_size}")
        for i in range(n):
            buf._entries.append(BufferEntry(str(names[i]), ctx[i].copy(), tgt[i].copy(), float(cost[i])))
        return buf

    def save(self, path: Union[str, Path]) -> None:
        """Write :meth:`state_dict` to an ``.npz`` file."""
        s = self.state_dict()
        np.savez(path, max_size=s["max_size"], top_m=s["top_m"], problems=np.array(s["problems"], dtype=str),
                 contexts=s["contexts"], targets=s["targets"], costs=s["costs"])

    @classmethod
    def load(cls, path: Union[str, Path]) -> "SolutionBuffer":
        """Read a buffer written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as z:
            return cls.from_state_dict({
                "max_size": int(z["max_size"]), "top_m": int(z["top_m"]),
                "problems": z["problems"].tolist(), "contexts": z["contexts"],
                "targets": z["targets"], "costs": z["costs"],
            })
