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

A large argument (e.g. every loaded flight) is better sent with ``side.share(value)`` (Dask's scatter:
pickled once, outside the task graph, so Dask does not warn of a large graph) and the returned
:class:`Shared` handle passed in its place; with 0 workers the handle holds the value itself.

Determinism is the caller's: a task must depend on its arguments only. Its arguments and result are
pickled (copied) between processes, so a task must not rely on mutating an argument the caller
reads after. ``task.seconds`` is the wall time the task itself ran, s.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
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


def _timed(fn: Callable[..., Any], args: tuple, kwargs: dict) -> tuple[Any, float]:
    """``fn(*args, **kwargs)`` and the wall time it took, s (runs in the worker)."""
    t0 = time.perf_counter()
    value = fn(*args, **kwargs)
    return value, time.perf_counter() - t0


class Shared:
    """A value sent to the cluster once (:meth:`Background.share`); pass it as a task's argument (top level)."""

    def __init__(self, value: Any, future: Any | None = None):
        self.value = value
        self.future = future


def _swapped(args: tuple, kwargs: dict, swap: Callable[[Shared], Any]) -> tuple[tuple, dict]:
    """``args`` and ``kwargs`` with each :class:`Shared` replaced by ``swap(it)`` (its value here, or its Dask
    future, which the worker resolves)."""
    return (tuple(swap(a) if isinstance(a, Shared) else a for a in args),
            {k: swap(v) if isinstance(v, Shared) else v for k, v in kwargs.items()})  # fmt: skip


class Task:
    """One submitted stage: :meth:`result` (waits), :attr:`seconds` (its own wall time, s, once done)."""

    def __init__(self, label: str, run: Callable[[], tuple[Any, float]]):
        self.label = label
        self._run = run
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
        """``value`` sent to the cluster once (module docstring); with 0 workers, kept as it is."""
        if self._client is None:
            return Shared(value)
        return Shared(value, self._client.scatter(value, hash=False))

    def submit(self, label: str, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Task:
        """Start ``fn(*args, **kwargs)`` (a module-level function: it is pickled) and return its :class:`Task`;
        ``label`` names it in a lost-worker error."""
        if self._client is None:
            return Task(label, lambda: _timed(fn, *_swapped(args, kwargs, lambda x: x.value)))
        future = self._client.submit(_timed, fn, *_swapped(args, kwargs, lambda x: x.future), pure=False)
        return Task(label, lambda: future_result(future, label))


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
