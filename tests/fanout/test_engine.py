"""The fan-out engine: results in item order from a local Dask cluster; clear error for a
scheduler that is not there."""

from __future__ import annotations

import time

import pytest

from proxplan.fanout import fan_out
from proxplan.fileio import UserError


def _square_plus(x: int) -> int:
    return x * x + 1


def test_local_cluster_returns_results_in_item_order():
    seen = []
    result = fan_out(
        _square_plus, list(range(12)), n_workers=2, progress=lambda done, total: seen.append((done, total))
    )
    assert result.results == [x * x + 1 for x in range(12)]
    assert result.workers == 2 and result.retried == 0
    assert seen[-1] == (12, 12)


def test_unreachable_scheduler_is_a_user_error_within_the_timeout():
    t0 = time.perf_counter()
    with pytest.raises(UserError, match="cannot reach a Dask scheduler"):
        fan_out(_square_plus, [1], scheduler="tcp://127.0.0.1:9", connect_timeout_s=3.0)
    assert time.perf_counter() - t0 < 10.0


def _dies_once(item: tuple[int, str]) -> int:
    """Kills its worker process the first time item 3 runs (a marker file remembers it)."""
    import os

    i, marker = item
    if i == 3 and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(1)
    time.sleep(0.05)
    return 10 * i


def test_a_worker_dying_mid_run_loses_nothing_and_its_tasks_are_counted(tmp_path):
    marker = str(tmp_path / "died")
    result = fan_out(_dies_once, [(i, marker) for i in range(8)], n_workers=2)
    assert result.results == [10 * i for i in range(8)]
    assert (tmp_path / "died").exists()  # the worker did die
    assert result.retried >= 1


@pytest.mark.parametrize("address", ["foo", "tcp://127.0.0.1:notaport", "http://127.0.0.1:8786"])
def test_malformed_scheduler_address_is_a_user_error(address):
    with pytest.raises(UserError, match="expected tcp://HOST:PORT"):
        fan_out(_square_plus, [1], scheduler=address)


def test_no_items_starts_no_cluster():
    result = fan_out(_square_plus, [], scheduler="tcp://127.0.0.1:9")
    assert result.results == [] and result.retried == 0


@pytest.mark.slow
def test_a_scheduler_without_workers_is_a_user_error_not_a_hang(tmp_path):
    import socket
    import subprocess
    import sys

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(
        [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path,
    )  # fmt: skip
    try:
        time.sleep(3.0)
        t0 = time.perf_counter()
        with pytest.raises(UserError, match="no workers"):
            fan_out(_square_plus, [1, 2], scheduler=f"tcp://127.0.0.1:{port}", connect_timeout_s=3.0)
        assert time.perf_counter() - t0 < 10.0
    finally:
        proc.terminate()
        proc.wait(timeout=15)
