"""One BLAS thread for a stage made of many small matrix products (:func:`one_blas_thread`).

OpenBLAS hands every product, however small, to all its threads, and after it the threads spin for a
while waiting for the next one. The identification pipeline is tens of thousands of products of a few
thousand rows by a few columns: there the hand-offs cost more than the products, and on a machine whose
cores are shared (the team's 2-core host with other processes running) each hand-off also waits for a
core. Measured on the synthetic logs of tests/identify/test_discovery.py (docs/identify.md, "Suite
speed, tenth round (10C)"): 101 s wall / 21.5 s CPU with the default threads against 49 s / 4.4 s with
one. Matrix products are the same to the bit (OpenBLAS splits their output among its threads, not the
sums that make each element); a long 1-D dot product (over ~20 000 elements) is not: threaded, each
thread sums a part, so its last bits depended on the thread count. On the shipped manifest the kept
effects and terms are the same; the nonlinear fits carry that last-bit change to their tolerance (the
calibration moves by <= 6.3e-8 relative, the test errors by <= 6.3e-10).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

_P = ParamSpec("_P")
_R = TypeVar("_R")

BLAS_THREADS = 1  # threads of the BLAS inside a stage wrapped by one_blas_thread (module docstring), -


def one_blas_thread(fn: Callable[_P, _R]) -> Callable[_P, _R]:
    """``fn`` run with the BLAS limited to :data:`BLAS_THREADS` thread(s), the previous limit restored after
    (also on an exception; nested calls keep the limit)."""

    @functools.wraps(fn)
    def wrapped(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapped
