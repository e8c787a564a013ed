"""The time budget of a solve (``time_limit``): deadlines for the optimiser, the candidate selection and the
start of a new attempt.

A solve must end within its budget (plus at most 10 %), whatever the robot. The Rust batch evaluation
cannot be interrupted, so the budget is kept by not starting work that will not fit: the optimiser stops
between CMA-ES batches and cuts its last batch to the candidates that fit (:func:`gfcs.planning.gfcop.solve_gfcop`),
the selection judges no further candidate past its deadline, and no attempt starts unless a first batch and
a first verdict of its selection, as long as the longest measured so far, fit in what is left. The first
attempt always runs: a solve returns a motion.

**Selection share.** Judging candidates on detailed meshes can take a second each, and an attempt's
candidates, drawn from one converged search distribution, tend to fail on the same contact; a selection
allowed to run to the end of the budget then leaves nothing for the retry policies, which change what the
search sees (more commands, margins). So while another attempt would still fit after it, a selection may
spend only a ``share`` of the time left (:meth:`Budget.selection_deadline`).
"""

from __future__ import annotations

import time
from typing import Optional

__all__ = ["Budget"]

#: Share of the budget kept for a selection's first verdict until one was measured.
_FIRST_VERDICT_SHARE = 0.05


class Budget:
    """Deadlines of one solve with ``limit`` seconds (None: no limit; every deadline is then None).

    The clock starts at construction (``time.perf_counter``).
    """

    def __init__(self, limit: Optional[float]) -> None:
        self.limit = limit
        self.start = time.perf_counter()
        self.end = None if limit is None else self.start + float(limit)
        self._selection = 0.0 if limit is None else _FIRST_VERDICT_SHARE * float(limit)
        self._first_batch = 0.0

    def remaining(self) -> float:
        """Seconds left (inf without a limit)."""
        return float("inf") if self.end is None else self.end - time.perf_counter()

    def optimiser_deadline(self) -> Optional[float]:
        """When CMA-ES must stop: the end, less the time the selection's first verdict is expected to take."""
        return None if self.end is None else self.end - self._selection

    def selection_deadline(self, share: float = 1.0) -> Optional[float]:
        """After this, the selection judges no further candidate: ``share`` (in (0, 1]) of the time left from
        now when another attempt (its first batch and first verdict) would still fit after that, else the
        end (a last attempt's selection may use all of it)."""
        if self.end is None:
            return None
        now = time.perf_counter()
        cut = now + float(share) * max(0.0, self.end - now)
        return cut if self.end - cut > self._first_batch + self._selection else self.end

    def observe_selection(self, seconds: float) -> None:
        """Record how long a selection took to its first verdict (the rollout, finishing and judgement of the
        first candidate, which every selection makes); the reserve becomes the longest seen."""
        self._selection = max(self._selection, float(seconds))

    def observe_first_batch(self, seconds: float) -> None:
        """Record how long an attempt's first batch took."""
        self._first_batch = max(self._first_batch, float(seconds))

    def exclude(self, seconds: float) -> None:
        """Move the end ``seconds`` later: work done for measurement only (``record_first_batch``) does not
        count against the budget."""
        if self.end is not None:
            self.end += float(seconds)

    def allows_attempt(self) -> bool:
        """Whether another attempt fits: its first batch and its selection's first verdict, as long as the
        longest seen."""
        return self.end is None or self.remaining() > self._first_batch + self._selection
