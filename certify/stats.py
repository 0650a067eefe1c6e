"""Statistics of a certification: probabilities with Wilson 95 % intervals, error percentiles."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (scipy ``binomtest(...).proportion_ci``,
    method ``wilson``); (0, 1) when there are no trials."""
    from scipy.stats import binomtest

    if trials <= 0:
        return (0.0, 1.0)
    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=confidence, method="wilson")
    return (float(ci.low), float(ci.high))


def probability(flags: Sequence[bool]) -> dict[str, float | int | list[float] | None]:
    """{"p", "count", "ci95": [low, high]} of a list of outcomes (p None without runs)."""
    n = len(flags)
    k = int(sum(bool(f) for f in flags))
    low, high = wilson_interval(k, n)
    return {"p": (k / n) if n else None, "count": k, "ci95": [low, high]}


def percentiles(values: Sequence[float]) -> dict[str, float | None]:
    """{"p50", "p95", "max"} of ``values`` (None without values)."""
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if v.size == 0:
        return {"p50": None, "p95": None, "max": None}
    return {"p50": float(np.percentile(v, 50)), "p95": float(np.percentile(v, 95)), "max": float(v.max())}
