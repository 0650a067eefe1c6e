"""Stages of one pipeline run beside each other: ``with background(workers) as side: task =
side.submit(fn, *args)`` starts ``fn`` in a worker process of a local Dask cluster (``dask.distributed``,
127.0.0.1) while the caller goes on, and ``task.result()`` waits for it.

Where :func:`proxplan.fanout.fan_out` maps one function over many items, this runs a few DIFFERENT
independent stages of one computation (e.g. ``proxplan identify``'s motor-lag check beside the
calibration, its selection around the prior model beside the one around the calibrated model).

* ``workers=0``: no cluster; a task runs in the calling process when its result is first asked for, so
  the stages run one after the other in the order their results are used (the serial pipeline,
  exactly; library calls, tests and benchmarks that already fan out use this).
* ``workers>=1``: a cluster of that many single-threaded worker processes, started when the ``with``
  block is entered and closed when it is left (also on an exception).

A task's arguments may hold other tasks (anywhere in lists, tuples and dict values): the task then runs
after them, with their results in their place (Dask's dependencies; results move between workers as
needed). ``side.share(value)`` sends a large value once to every worker (Dask's broadcast scatter) and
returns a :class:`Shared` handle to pass instead of the value: every task of one worker then receives
the SAME object, so what a task caches on it (e.g. a setup several tasks need) is there for the next
task of that worker. With 0 workers the handle is the value itself, shared by every task.

Determinism is the caller's: a task must depend on its arguments only (a cache on a shared value must
not change what a later task computes). Its arguments and result are pickled (copied) between
processes, so a task must not rely on mutating an argument the caller reads after. ``task.seconds``
is the wall time the task itself ran, s.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from proxplan.fanout.engine import connect, future_result

_CONNECT_TIMEOUT_S = 10.0
"""Seconds a local cluster may take to start its workers (as :func:`proxplan.fanout.fan_out`'s default)."""
WORKER_ENVIRON: dict[str, Any] = {"MALLOC_TRIM_THRESHOLD_": None}
"""Changes to the environment Dask starts workers with: glibc's malloc left at its own defaults, as in the
caller's process. Dask sets ``MALLOC_TRIM_THRESHOLD_=65536`` (``distributed.nanny.pre-spawn-environ``), and
setting it at all also fixes glibc's mmap threshold at 128 KiB (no longer adaptive), so every numpy array
above it is mapped and unmapped, its pages faulted in anew. Measured on ``proxplan identify
manifests/neural-swarm.yaml``, quiet, stop 70: with the threshold set to 1 GiB (this module's first try) the
selection around the prior model took 128-130 s in a worker (38 s of system CPU in the run) against 77 s in
the caller; with Dask's 64 KiB, about twice its serial time (stop 63, docs/identify.md "Speed")."""


def _timed(fn: Callable[..., Any], args: tuple, kwargs: dict, deps: Sequence[Any] = ()) -> tuple[Any, float]:
    """``fn(*args, **kwargs)`` and the wall time it took, s (runs in the worker); ``deps`` are the values of
    the :class:`_Slot` s in ``args`` and ``kwargs`` (Dask resolved them: a task's (value, seconds), a shared
    value as it is)."""
    args, kwargs = _filled((args, kwargs), lambda slot: deps[slot.index][0] if slot.task else deps[slot.index])
    t0 = time.perf_counter()
    value = fn(*args, **kwargs)
    return value, time.perf_counter() - t0


@dataclass(frozen=True)
class _Slot:
    """Where a task's argument held another task (``task=True``) or a shared value: the ``index``-th dependency."""

    index: int
    task: bool


def _filled(obj: Any, value_of: Callable[[Any], Any]) -> Any:
    """``obj`` with every :class:`Task`, :class:`Shared` or :class:`_Slot` in it (in lists, tuples, dict values)
    replaced by ``value_of(it)``."""
    if isinstance(obj, (Task, Shared, _Slot)):
        return value_of(obj)
    if isinstance(obj, (list, tuple)):
        return type(obj)(_filled(x, value_of) for x in obj)
    if isinstance(obj, dict):
        return {k: _filled(v, value_of) for k, v in obj.items()}
    return obj


class Shared:
    """A value sent once to every worker (:meth:`Background.share`); pass the handle as a task's argument."""

    def __init__(self, value: Any, future: Any | None = None):
        self.value = value
        self._future = future


class Task:
    """One submitted stage: :meth:`result` (waits), :attr:`seconds` (its own wall time, s, once done)."""

    def __init__(self, label: str, run: Callable[[], tuple[Any, float]], future: Any | None = None):
        self.label = label
        self._run = run
        self._future = future
        self._done = False
        self._value: Any = None
        self.seconds = float("nan")

    def result(self) -> Any:
        """The stage's return value (its exception, raised here, if it raised one)."""
        if not self._done:
            self._value, self.seconds = self._run()
            self._done = True
        return self._value


class Background:
    """Submits stages (module docstring); made by :func:`background`."""

    def __init__(self, client: Any | None):
        self._client = client

    @property
    def workers(self) -> int:
        """Worker processes beside the caller (0: stages run in the calling process)."""
        if self._client is None:
            return 0
        return len(self._client.scheduler_info().get("workers", {}))

    def share(self, value: Any) -> Shared:
        """``value`` sent once to every worker (module docstring); with 0 workers, kept as it is."""
        if self._client is None:
            return Shared(value)
        return Shared(value, self._client.scatter(value, broadcast=True, hash=False))

    def submit(self, label: str, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Task:
        """Start ``fn(*args, **kwargs)`` (a module-level function: it is pickled) and return its :class:`Task`;
        ``label`` names it in a lost-worker error. Tasks and :class:`Shared` handles in the arguments are
        replaced by their results and values (module docstring)."""
        if self._client is None:
            return Task(label, lambda: _timed(fn, *_filled((args, kwargs), _lazy_value)))
        deps: list[Any] = []

        def slot(x: Task | Shared) -> _Slot:
            deps.append(x._future)
            return _Slot(len(deps) - 1, isinstance(x, Task))

        args, kwargs = _filled((args, kwargs), slot)
        future = self._client.submit(_timed, fn, args, kwargs, deps, pure=False)
        return Task(label, lambda: future_result(future, label), future)

    def as_completed(self, tasks: Sequence[Task]) -> Iterator[Task]:
        """``tasks`` as each one finishes (with 0 workers: run here one after the other, in the order given)."""
        if self._client is None:
            for task in tasks:
                task.result()
                yield task
            return
        from distributed import as_completed

        futures = [task._future for task in tasks]
        by_key = {f.key: task for f, task in zip(futures, tasks) if f is not None}
        for future in as_completed([f for f in futures if f is not None]):
            yield by_key[future.key]


def _lazy_value(x: Task | Shared) -> Any:
    """A dependency's value in the calling process: a task run now (if not yet), a shared value as it is."""
    return x.result() if isinstance(x, Task) else x.value


@contextmanager
def background(workers: int) -> Iterator[Background]:
    """A :class:`Background` with ``workers`` worker processes (0: none, stages run in this process)."""
    if workers < 0:
        raise ValueError(f"workers must be >= 0, got {workers}")
    if workers == 0:
        yield Background(None)
        return
    client, cluster = connect(None, workers, _CONNECT_TIMEOUT_S, environ=WORKER_ENVIRON)
    try:
        yield Background(client)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
