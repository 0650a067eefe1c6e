"""The flight as the unit (issue 35, stop 71): samples of one flight are not independent, so what the residual
does from flight to flight is judged over flights.

* :func:`ratio_mean` is the one estimator used for both: the ratio mean p = sum_i y_i / sum_i n_i of k
  clusters (cluster i: a total y_i over a size n_i) and its variance by linearisation,

      Var(p) = k / (k - 1) sum_i (y_i - p n_i)^2 / (sum_i n_i)^2,

  the ratio estimator of cluster sampling (Cochran, *Sampling Techniques*, 3rd ed. 1977, sections 6.2-6.4
  and 9A.4; the same as a cluster-robust sandwich variance of a weighted mean). It assumes nothing about how
  the samples inside a cluster are correlated: only the clusters are taken as independent.
* :func:`log_offset` is a vehicle log's mean residual and that mean's own variance. Inside a log the samples
  are correlated (the slow part of the residual), so the variance is taken by batch means (Flegal & Jones,
  "Batch means and spectral variance estimators in Markov chain Monte Carlo", Ann. Statist. 38, 2010): the
  log in time order cut into b = floor(sqrt(n)) contiguous batches of equal count (their batch size
  n^(1/2), :data:`MIN_BATCHES` at least), each batch a cluster of :func:`ratio_mean`.
* :func:`between_log_variance` is the variance of the per-log constant between the logs of one vehicle type:
  a one-way random-effects model m_i = b_i + e_i (b_i the log's constant, variance sigma_flight^2; e_i the
  error of the log's mean, variance v_i from :func:`log_offset`), estimated by the method of moments about
  zero, sigma_flight^2 = max(0, mean_i(m_i^2 - v_i)): the unweighted moment estimator of a random-effects
  variance (Hedges & Olkin, *Statistical Methods for Meta-Analysis*, 1985; DerSimonian & Laird, Control.
  Clin. Trials 7, 1986, with equal weights) with the mean taken as zero, not fitted: the interval is
  centred on the prediction, so a bias common to the type is part of what a new flight's constant can be.
* :func:`new_flight_quantile` is the interval's multiplier for a NEW flight: its residual is a constant b
  plus the within-log part e, b from the random-effects predictive law b = sigma_flight T_k (T_k Student's t
  with k degrees of freedom, k the type's logs: the law of a new draw over a scale estimated from k draws of
  known zero mean), e taken as the held-out samples' own within-log parts. The multiplier q solves
  mean_j w_j P(|b + e_j| <= q sigma_total_j) = 0.9 (Brent's method; the probability rises with q).
* :func:`coverage_interval` is the coverage's confidence interval with flights as the clusters: p +- t
  sqrt(Var(p)), t the Student quantile at k - 1 degrees of freedom (few flights: the variance itself is
  estimated from k of them), :data:`COVERAGE_LEVEL`; and the design effect Var(p) / (p (1 - p) / N) against
  N independent samples (Kish, *Survey Sampling*, 1965).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import stdtr
from scipy.stats import t as student_t

COVERAGE_LEVEL = 0.95
"""Two-sided confidence level of a set's coverage interval (the usual convention; not tuned)."""
MIN_BATCHES = 2
"""Fewest batches of a log's batch-means variance: two are needed for a spread between batches."""


def ratio_mean(totals: Sequence[float], sizes: Sequence[float]) -> tuple[float, float]:
    """(p, Var(p)) of k clusters with totals y_i and sizes n_i (module docstring); Var = inf below 2 clusters,
    p = nan when the sizes sum to zero."""
    y, n = np.asarray(totals, dtype=float), np.asarray(sizes, dtype=float)
    total_n = float(n.sum())
    if total_n <= 0.0:
        return float("nan"), float("inf")
    p = float(y.sum()) / total_n
    k = y.size
    if k < 2:
        return p, float("inf")
    return p, float(k / (k - 1) * np.sum((y - p * n) ** 2) / total_n**2)


def log_offset(residual: np.ndarray, weight: np.ndarray, t_s: np.ndarray) -> tuple[float, float]:
    """(m, v): the weighted mean of one vehicle log's residual (N,) (weights (N,), clock (N,) s) and the
    batch-means variance of that mean (module docstring), in the residual's unit and its square."""
    order = np.argsort(np.asarray(t_s), kind="stable")
    r, w = np.asarray(residual, dtype=float)[order], np.asarray(weight, dtype=float)[order]
    batches = max(int(np.sqrt(r.size)), MIN_BATCHES)
    cuts = np.array_split(np.arange(r.size), batches)
    return ratio_mean([float(np.sum(w[c] * r[c])) for c in cuts], [float(np.sum(w[c])) for c in cuts])


def between_log_variance(means: Sequence[float], mean_variances: Sequence[float]) -> float:
    """sigma_flight^2 of one vehicle type from its logs' mean residuals m_i and their variances v_i (module
    docstring); a log whose v_i is not finite (too few samples) counts with v_i = 0 (its m_i^2 is all
    offset then: the estimate leans wide, not narrow)."""
    m, v = np.asarray(means, dtype=float), np.asarray(mean_variances, dtype=float)
    if m.size == 0:
        return 0.0
    v = np.where(np.isfinite(v), v, 0.0)
    return float(max(np.mean(m**2 - v), 0.0))


QUANTILE_XTOL = 1e-9
"""Absolute tolerance of the multiplier in :func:`new_flight_quantile` (-): far below the quantile's own sampling
error (a multiplier near 1.6 known to a few per cent from the held-out samples)."""


def new_flight_quantile(
    within: np.ndarray, place_N: np.ndarray, flight_N: np.ndarray, dof: np.ndarray, weight: np.ndarray, level: float
) -> float:
    """The multiplier q (-) of the interval |r| <= q sqrt(place_N^2 + flight_N^2) that holds a new flight's
    residual with probability ``level`` (module docstring), from each sample's within-log residual (N,) N, its
    place sigma (N,) N, its type's flight sigma (N,) N and logs k (N,), and weights (N,)."""
    total = np.sqrt(place_N**2 + flight_N**2)
    w = np.asarray(weight, dtype=float) / float(np.sum(weight))
    has = flight_N > 0.0
    safe = np.where(has, flight_N, 1.0)
    k = np.maximum(dof, 1.0)

    def cover(q: float) -> float:
        half = q * total
        p = np.where(has, stdtr(k, (half - within) / safe) - stdtr(k, (-half - within) / safe),
                     np.abs(within) <= half)  # fmt: skip
        return float(np.sum(w * p))

    if cover(0.0) >= level:  # residuals that are zero (exactly) at the level asked: no width needed
        return 0.0
    lo, hi = 0.0, 1.0
    while cover(hi) < level and hi < 1e6:
        lo, hi = hi, 2.0 * hi
    return float(brentq(lambda q: cover(q) - level, lo, hi, xtol=QUANTILE_XTOL))


@dataclass(frozen=True)
class CoverageInterval:
    """A coverage with flights as the unit: the share ``coverage`` (-), its :data:`COVERAGE_LEVEL` interval
    ``low``..``high`` (-), the number of ``flights`` and the ``design_effect`` (-; nan when not defined)."""

    coverage: float
    low: float
    high: float
    flights: int
    design_effect: float

    def holds(self, target: float) -> bool:
        """Whether ``target`` (e.g. 0.9) lies inside the interval: a set that misses it by less is no miss."""
        return self.low <= target <= self.high


def coverage_interval(inside: Sequence[float], sizes: Sequence[float]) -> CoverageInterval:
    """The coverage of flights with ``inside`` samples inside the interval out of ``sizes`` each (module
    docstring); one flight: the interval is 0..1 (one flight says nothing of the next)."""
    p, var = ratio_mean(inside, sizes)
    k, total_n = len(sizes), float(np.sum(sizes))
    if not np.isfinite(var):
        return CoverageInterval(p, 0.0, 1.0, k, float("nan"))
    half = float(student_t.ppf(0.5 + 0.5 * COVERAGE_LEVEL, k - 1)) * float(np.sqrt(var))
    binomial = p * (1.0 - p) / total_n
    deff = var / binomial if binomial > 0.0 else float("nan")
    return CoverageInterval(p, max(p - half, 0.0), min(p + half, 1.0), k, deff)
