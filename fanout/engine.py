"""One small interface over ``dask.distributed``: ``fan_out(fn, items)`` runs ``fn(item)`` for every
item on a cluster and returns the results in item order.

* ``scheduler=None``: an embedded ``LocalCluster`` of worker processes on 127.0.0.1 (one per core
  by default), started for the call and closed after it;
* ``scheduler="tcp://HOST:PORT"``: the same tasks on an existing cluster (``dask scheduler`` and
  ``dask worker`` processes); an unreachable scheduler is a one-line UserError within
  ``connect_timeout_s``.

Determinism is the caller's: a task must depend on its item only (e.g. seed it from the item), so
results do not depend on which worker ran it. A task whose worker dies is run again elsewhere by
Dask's scheduler (up to its ``allowed-failures``); how many were resubmitted is reported
(``FanoutResult.retried``), and a task that kills every worker it runs on is a one-line error. A
task raising an exception is retried ``retries`` times. A remote scheduler without any worker is a
one-line error after ``connect_timeout_s`` (not a hang).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from proxplan.fileio import UserError

_ADDRESS = re.compile(r"^(tcp|tls)://[^\s/:]+:\d+$")


@dataclass(frozen=True)
class FanoutResult:
    """Results in the order of the items; ``retried`` tasks had to run again (a worker was lost)."""

    results: list[Any]
    retried: int
    workers: int  # workers the cluster had when the tasks were submitted
    scheduler: str  # address of the scheduler used


def connect(
    scheduler: str | None, n_workers: int | None, connect_timeout_s: float, *, environ: dict[str, Any] | None = None
):
    """A client of ``scheduler``, or of a new local cluster of ``n_workers`` single-threaded worker processes
    (default one per core) with ``environ`` changing the environment variables Dask starts them with
    (``distributed.nanny.pre-spawn-environ``; a value None removes that variable: the worker inherits the
    caller's); returns (client, the local cluster or None)."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler is None:
        n = n_workers or os.cpu_count() or 1
        spawn = dict(dask.config.get("distributed.nanny.pre-spawn-environ")) | dict(environ or {})
        spawn = {k: v for k, v in spawn.items() if v is not None}
        with dask.config.set({"distributed.nanny.pre-spawn-environ": spawn}):
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=None, silence_logs=50,
            )  # fmt: skip
        return Client(cluster), cluster
    if not _ADDRESS.match(scheduler):
        raise UserError(f"--scheduler {scheduler}: expected tcp://HOST:PORT (or tls://HOST:PORT) of a 'dask scheduler'")
    try:
        client = Client(scheduler, timeout=f"{connect_timeout_s}s")
    except (OSError, TimeoutError) as err:
        raise UserError(
            f"--scheduler {scheduler}: cannot reach a Dask scheduler there within {connect_timeout_s:g} s "
            f"({type(err).__name__}); expected tcp://HOST:PORT of a running 'dask scheduler'"
        ) from None
    try:  # a scheduler without workers would leave every task pending forever
        client.wait_for_workers(1, timeout=connect_timeout_s)
    except TimeoutError:
        client.close()
        raise UserError(
            f"--scheduler {scheduler}: the scheduler has no workers after {connect_timeout_s:g} s; "
            "start some with 'dask worker " + scheduler + "'"
        ) from None
    return client, None


def fan_out(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    *,
    scheduler: str | None = None,
    n_workers: int | None = None,
    retries: int = 2,
    connect_timeout_s: float = 10.0,
    progress: Callable[[int, int], None] | None = None,
) -> FanoutResult:
    """Run ``fn(item)`` for every item; ``progress(done, total)`` is called as tasks finish."""
    from distributed import as_completed

    if not items:
        return FanoutResult([], 0, 0, scheduler or "")
    client, cluster = connect(scheduler, n_workers, connect_timeout_s)
    try:
        workers = len(client.scheduler_info().get("workers", {}))
        futures = client.map(fn, list(items), pure=False, retries=retries)
        index = {f.key: i for i, f in enumerate(futures)}
        results: list[Any] = [None] * len(futures)
        done = 0
        for future in as_completed(futures):
            results[index[future.key]] = future_result(future, f"task {index[future.key]}")
            done += 1
            if progress is not None:
                progress(done, len(futures))
        retried = _retried_tasks(client, [f.key for f in futures])
        return FanoutResult(results, retried, workers, client.scheduler.address)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def future_result(future, label: str) -> Any:
    """``future.result()``; a task that took down every worker it was tried on is a one-line UserError
    naming ``label`` (its exception, if it raised one, propagates as raised)."""
    from distributed.scheduler import KilledWorker

    try:
        return future.result()
    except KilledWorker as err:
        raise UserError(
            f"{label} was lost: each worker that ran it died (Dask's allowed-failures; "
            f"out of memory or a crash in the task): {err}"
        ) from None


def _count_suspicious(dask_scheduler, keys: list) -> int:
    """On the scheduler: tasks of ``keys`` that were running on a worker that died (Dask's
    ``TaskState.suspicious`` counter); the scheduler re-ran them elsewhere."""
    return sum(1 for key in keys if (ts := dask_scheduler.tasks.get(key)) is not None and ts.suspicious > 0)


def _retried_tasks(client, keys: list) -> int:
    """How many of ``keys`` had to run again because their worker was lost (futures still held)."""
    return int(client.run_on_scheduler(_count_suspicious, keys=keys))
