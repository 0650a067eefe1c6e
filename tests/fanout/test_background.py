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


def _total(parts: list[tuple[int, int]], extra: dict[str, tuple[int, int]]) -> int:
    return sum(s for _, s in parts) + extra["k"][1]


class _Counter:
    """A shared value that tasks cache on (a setup every task of a worker needs)."""

    def __init__(self) -> None:
        self.calls = 0


def _count(counter: _Counter) -> tuple[int, int]:
    counter.calls += 1
    return os.getpid(), counter.calls


@pytest.mark.parametrize("workers", [0, 1, 2])
def test_a_stage_given_other_stages_runs_on_their_results(workers: int):
    with background(workers) as side:
        parts = [side.submit(f"part {k}", _pid_and_sum, k, b=1) for k in range(4)]
        total = side.submit("the total", _total, parts, {"k": side.submit("k", _pid_and_sum, 10)})
        assert total.result() == (1 + 2 + 3 + 4) + 10
        assert [p.result()[1] for p in parts] == [1, 2, 3, 4]
        done = list(side.as_completed(parts))
        assert sorted(t.label for t in done) == [p.label for p in parts]


@pytest.mark.parametrize("workers", [0, 1])
def test_a_shared_value_is_one_object_for_every_stage_of_a_worker(workers: int):
    with background(workers) as side:
        counter = _Counter()
        shared = side.share(counter)
        seen = [side.submit(f"count {k}", _count, shared).result() for k in range(3)]
    assert [n for _, n in seen] == [1, 2, 3]  # each stage saw what the one before left on the object
    assert (counter.calls == 3) == (workers == 0)  # with workers the caller's object is a copy's source only
    assert len({pid for pid, _ in seen}) == 1
