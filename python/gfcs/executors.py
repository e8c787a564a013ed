"""Executors: run one task function over many inputs, in this process or on a Ray cluster, and stream each
task's outcome as it finishes.

``gfcs bench`` runs one task per problem (:func:`gfcs.bench.run_bench`) and ``gfcs train`` one task per
solve of a training round (:func:`gfcs.learning.train.train`). Both take an executor:

* :class:`LocalExecutor` (the default) calls the task function in this process, one input after the other,
  in order; it needs nothing beyond gfcs.
* :class:`RayExecutor` submits each input as a Ray task (the extra ``ray``: ``pip install "gfcs[ray]"``).
  Each task reserves ``threads`` CPUs of the cluster and runs its solve on that many Rayon threads, so a
  cluster of C CPUs runs C / threads tasks at once. A task whose worker process dies (killed, out of
  memory, node lost) is run again, up to ``max_retries`` times; its outcome is reported once, by the run
  that finished. Outcomes arrive in the order the tasks finish, not the order they were submitted.

A task function is ``fn(shared, *args) -> value``: ``shared`` is the same for every task of a run (the
problem suite's recipe, the solve options, the sampler's weights) and is sent to the cluster once; ``args``
are the task's own (a problem's name and seed). On Ray, ``fn`` and ``shared`` must pickle (Ray uses
cloudpickle): compiled objects such as :class:`gfcs.Robot` do not, so tasks rebuild them on the worker
(see :class:`gfcs.bench.Suite`).
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator, Optional, Tuple

__all__ = ["Done", "Executor", "LocalExecutor", "RayExecutor", "make_executor", "add_executor_options",
           "executor_from_args", "EXECUTORS"]

#: Names accepted by :func:`make_executor` and ``--executor``.
EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class Done:
    """The outcome of one task: ``key`` as submitted; ``value`` the task function's return value, or
    ``error`` (a one-line message) when the task could not be completed (Ray: its worker died more often
    than the retries allow, or the function raised)."""

    key: Any
    value: Any = None
    error: Optional[str] = None


class Executor:
    """Runs ``fn(shared, *args)`` for each ``(key, args)`` of ``tasks`` and yields a :class:`Done` per task
    as it finishes. ``workers``: how many tasks run at once; ``threads``: Rayon threads of each task's
    solve (None: the solve's default, every core)."""

    name = "executor"
    workers = 1
    threads: Optional[int] = None

    def run(self, fn: Callable[..., Any], shared: Any, tasks: Iterable[Tuple[Any, Tuple[Any, ...]]]) -> Iterator[Done]:
        raise NotImplementedError

    def close(self) -> None:
        """Release what the executor started (a local Ray instance)."""

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class LocalExecutor(Executor):
    """Tasks in this process, one after the other, in submission order. An exception raised by the task
    function propagates (as a direct call would)."""

    name = "local"

    def __init__(self, threads: Optional[int] = None) -> None:
        self.threads = threads

    def run(self, fn: Callable[..., Any], shared: Any, tasks: Iterable[Tuple[Any, Tuple[Any, ...]]]) -> Iterator[Done]:
        for key, args in tasks:
            yield Done(key, fn(shared, *args))


def _call(fn: Callable[..., Any], shared: Any, *args: Any) -> Any:
    """The body of every Ray task: the task function on the worker."""
    return fn(shared, *args)


class RayExecutor(Executor):
    """Tasks as Ray tasks on the cluster at ``address`` (None: a Ray instance already initialised in this
    process, else a new local one with ``workers x threads`` CPUs).

    Args:
        address: Ray cluster address (``ray://host:10001``, ``host:6379`` or ``auto``); None: local.
        workers: tasks at once (default: the cluster's CPUs // ``threads``).
        threads: CPUs each task reserves and Rayon threads of its solve (default 1).
        max_retries: runs of a task after its worker died before it is reported as an error (default 3).
    """

    name = "ray"

    def __init__(self, address: Optional[str] = None, workers: Optional[int] = None, threads: Optional[int] = None,
                 max_retries: int = 3) -> None:
        from gfcs.errors import InvalidValueError

        for value, what in ((workers, "workers"), (threads, "threads")):
            if value is not None and (not isinstance(value, int) or value < 1):
                raise InvalidValueError(f"RayExecutor {what}: expected an integer >= 1, got {value!r}")
        if not isinstance(max_retries, int) or max_retries < 0:
            raise InvalidValueError(f"RayExecutor max_retries: expected an integer >= 0, got {max_retries!r}")
        try:
            import ray
        except ImportError as e:
            raise InvalidValueError(f"executor 'ray' needs the 'ray' extra (pip install 'gfcs[ray]'): {e}") from e
        self._ray = ray
        self.threads = threads or 1
        self.max_retries = max_retries
        self._started = False
        if not ray.is_initialized():
            cpus = None if address is not None or workers is None else workers * self.threads
            ray.init(address=address, num_cpus=cpus, include_dashboard=False, log_to_driver=True,
                     configure_logging=False, runtime_env=_runtime_env(address))
            self._started = True
        total = int(ray.cluster_resources().get("CPU", 1))
        self.workers = workers or max(1, total // self.threads)

    def run(self, fn: Callable[..., Any], shared: Any, tasks: Iterable[Tuple[Any, Tuple[Any, ...]]]) -> Iterator[Done]:
        ray = self._ray
        remote = ray.remote(_call).options(num_cpus=self.threads, max_retries=self.max_retries,
                                           retry_exceptions=False)
        shared_ref = ray.put(shared)
        waiting = list(tasks)[::-1]
        running = {}
        try:
            while waiting or running:
                while waiting and len(running) < 2 * self.workers:  # a short queue: the rest is not yet sent
                    key, args = waiting.pop()
                    running[remote.remote(fn, shared_ref, *args)] = key
                ready, _ = ray.wait(list(running), num_returns=1)
                key = running.pop(ready[0])
                try:
                    value = ray.get(ready[0])
                except ray.exceptions.RayError as e:
                    yield Done(key, error=_ray_message(e))
                else:
                    yield Done(key, value)
        finally:  # the caller stopped early (an error, Ctrl-C): the tasks still running are cancelled
            for ref in running:
                ray.cancel(ref, force=True)

    def close(self) -> None:
        if self._started and self._ray.is_initialized():
            self._ray.shutdown()
        self._started = False


def _runtime_env(address: Optional[str]) -> Optional[dict]:
    """Workers of a local Ray import gfcs and the task functions' modules as this process does: the
    ``PYTHONPATH`` and ``sys.path`` folders outside the interpreter's installation (a source checkout, a
    test folder). A remote cluster's nodes must have gfcs installed themselves."""
    if address is not None:
        return None
    import sys

    import gfcs

    def own(path: str) -> bool:  # a folder of this process's path outside the interpreter's installation
        full = os.path.abspath(path)
        return os.path.isdir(full) and not any(full.startswith(os.path.abspath(prefix) + os.sep)
                                               for prefix in {sys.prefix, sys.base_prefix})

    root = os.path.dirname(os.path.dirname(os.path.abspath(gfcs.__file__)))
    paths = [p for p in [root, *os.environ.get("PYTHONPATH", "").split(os.pathsep), *sys.path] if p and own(p)]
    if not paths:  # gfcs installed with the interpreter: workers find it as this process does
        return None
    return {"env_vars": {"PYTHONPATH": os.pathsep.join(dict.fromkeys(os.path.abspath(p) for p in paths))}}


def _ray_message(e: BaseException) -> str:
    """One line for a task Ray could not complete."""
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[-1] if text else ''}".strip()


def make_executor(name: str = "local", address: Optional[str] = None, workers: Optional[int] = None,
                  threads: Optional[int] = None, max_retries: int = 3) -> Executor:
    """The executor called ``name`` (:data:`EXECUTORS`); ``address``/``workers``/``max_retries`` are Ray's
    (an address with ``local`` is an error), ``threads`` the Rayon threads of each task."""
    from gfcs.errors import InvalidValueError

    if name == "local":
        if address is not None or workers is not None:
            raise InvalidValueError("--ray-address and --workers need --executor ray")
        return LocalExecutor(threads)
    if name == "ray":
        return RayExecutor(address, workers, threads, max_retries)
    raise InvalidValueError(f"executor: expected one of {', '.join(EXECUTORS)}, got {name!r}")


def add_executor_options(p: argparse.ArgumentParser) -> None:
    """The ``--executor`` options of ``gfcs bench`` and ``gfcs train``."""
    from gfcs.cli import _integer

    g = p.add_argument_group("executor (where the solves run; docs/scaleout.md)")
    g.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="local: one solve after the other in this process (default); ray: every problem's "
                        "solve a Ray task (the 'ray' extra), on a local Ray or the cluster at --ray-address")
    g.add_argument("--ray-address", metavar="ADDR",
                   help="Ray cluster to join (ray://HOST:10001, HOST:6379 or auto; default: start a local Ray)")
    g.add_argument("--workers", type=_integer(1), metavar="N",
                   help="Ray: solves at once (default: the cluster's CPUs / --threads; a local Ray gets "
                        "N x --threads CPUs)")
    g.add_argument("--max-retries", type=_integer(0), default=3, metavar="N",
                   help="Ray: runs of a solve again after its worker died (default 3)")


def executor_from_args(args: argparse.Namespace) -> Executor:
    """The executor of the command-line options of :func:`add_executor_options` (``--threads``: the Rayon
    threads of each task; a Ray task reserves that many CPUs, 1 when not given)."""
    return make_executor(args.executor, args.ray_address, args.workers, getattr(args, "threads", None),
                         args.max_retries)


def describe(executor: Executor) -> str:
    """``local`` or ``ray (N workers x T threads)``, for progress bars and logs."""
    if isinstance(executor, RayExecutor):
        return f"ray ({executor.workers} workers x {executor.threads} threads)"
    return executor.name
