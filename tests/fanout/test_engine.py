"""The fan-out engine: results in item order from a local Dask cluster; clear error for a
scheduler that is not there."""

from __future__ import annotations

import time

import pytest

from fanout import fan_out
from fileio import UserError


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
