"""proxplan.physics.blas_threads: a wrapped stage runs on one BLAS thread, gives the same products, and
leaves the thread count as it found it."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from proxplan.physics import one_blas_thread
from proxplan.physics.blas_threads import BLAS_THREADS


def _blas_threads() -> list[int]:
    return [int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]


def test_one_blas_thread_inside_restored_after() -> None:
    if not _blas_threads():
        pytest.skip("numpy without a BLAS threadpoolctl can see")
    with threadpool_limits(limits=2, user_api="blas"):
        outside = _blas_threads()

        @one_blas_thread
        def inside() -> list[int]:
            return _blas_threads()

        assert inside() == [BLAS_THREADS] * len(outside)
        assert _blas_threads() == outside

        @one_blas_thread
        def fails() -> None:
            raise RuntimeError("boom")

        with pytest.raises(RuntimeError):
            fails()
        assert _blas_threads() == outside


def test_products_equal_bit_for_bit() -> None:
    # the shapes of the identification's products (docs/identify.md, "Suite speed, tenth round"): tall
    # matrices of a few columns, their Gram matrices, matrix-vector products. Not a long 1-D dot product:
    # threaded OpenBLAS sums its parts per thread, so its last bits depend on the thread count
    rng = np.random.default_rng(5)
    a, b, v = rng.normal(size=(40000, 7)), rng.normal(size=(40000, 3)), rng.normal(size=40000)

    def products() -> list[np.ndarray]:
        return [a.T @ a, a.T @ b, a.T @ v, b.T @ b, a @ np.arange(7.0)]

    with threadpool_limits(limits=2, user_api="blas"):
        threaded = products()
    single = one_blas_thread(products)()
    for x, y in zip(threaded, single):
        assert np.array_equal(x, y)
