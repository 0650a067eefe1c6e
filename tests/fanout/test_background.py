"""Stages run beside the caller (proxplan.fanout.background): in a worker process, or in this process
when asked for, with the same results either way."""

from __future__ import annotations

import os

import pytest

from proxplan.fanout import background


def _pid_and_sum(a: int, b: int = 0) -> tuple[int, int]:
    return os.getpid(), a + b


def _environ() -> tuple[str | None, str | None]:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OPENBLAS_NUM_THREADS")


def _fails(message: str) -> None:
    raise ValueError(message)


def test_a_stage_runs_in_a_worker_process_while_the_caller_goes_on():
    with background(1) as side:
        assert side.workers == 1
        task = side.submit("a sum", _pid_and_sum, 2, b=3)
        pid, total = task.result()
    assert total == 5 and pid != os.getpid()
    assert task.seconds >= 0.0


def test_workers_run_with_the_callers_malloc_and_one_blas_thread():
    with background(1) as side:
        trim, blas = side.submit("the environment", _environ).result()
    assert trim == os.environ.get("MALLOC_TRIM_THRESHOLD_") and blas == "1"  # glibc's defaults, as here


def test_without_workers_a_stage_runs_here_when_its_result_is_asked_for():
    calls: list[int] = []

    def record(x: int) -> int:
        calls.append(x)
        return 2 * x

    with background(0) as side:
        assert side.workers == 0
        task = side.submit("double", record, 4)
        assert calls == []  # nothing ran yet: the serial order is the order results are used
        assert task.result() == 8 and task.result() == 8
    assert calls == [4]


@pytest.mark.parametrize("workers", [0, 1])
def test_a_stage_that_raises_raises_where_its_result_is_asked_for(workers: int):
    with background(workers) as side:
        task = side.submit("a failing stage", _fails, "no data")
        with pytest.raises(ValueError, match="no data"):
            task.result()


def test_a_negative_count_is_refused():
    with pytest.raises(ValueError, match="workers"):
        with background(-1):
            pass


def _size(values: list[int], *, extra: list[int]) -> int:
    return len(values) + len(extra)


@pytest.mark.parametrize("workers", [0, 1])
def test_a_shared_value_reaches_the_stage_as_the_value(workers: int):
    with background(workers) as side:
        big = side.share(list(range(100_000)))
        assert side.submit("sizes", _size, big, extra=side.share([1, 2])).result() == 100_002
