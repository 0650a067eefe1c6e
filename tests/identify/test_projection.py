"""The variable projection shared by the effect shape fit and the delay profile (identify/projection.py):
its objective, formed from the normal equations' sums, equals the MAP objective computed directly."""

from types import SimpleNamespace

import numpy as np
from scipy.optimize import minimize_scalar

from proxplan.identify.crossval import Ridge
from proxplan.identify.projection import TangentProjection


def _selection(rng: np.random.Generator, n: int = 400, n_t: int = 3):
    tangents = rng.normal(size=(n, 4, n_t))
    truth = rng.normal(size=(n, 4))
    residual = truth + tangents @ np.array([0.3, -0.2, 0.1]) + 0.1 * rng.normal(size=(n, 4))
    group = rng.integers(0, 5, size=n)
    plan = SimpleNamespace(held_out_only=np.array([False, False, False, False, True]))
    sel = SimpleNamespace(plan=plan, group=group, weight=rng.uniform(0.5, 2.0, size=n), residual=residual, tau=3.0)
    ridge = Ridge(precision=np.array([4.0, 0.0, 1.0]), center=np.array([0.05, 0.0, -0.1]))
    return sel, tangents, ridge, truth


def _direct_objective(sel, tangents, ridge, columns, channels) -> float:
    """min over steps and strengths of sum W r^2 / tau + prior, by least squares on the whitened rows."""
    mask = np.zeros(4)
    mask[list(channels)] = 1.0
    train = ~sel.plan.held_out_only[sel.group]
    w = ((sel.weight * train)[:, None] * mask[None, :]).reshape(-1) / sel.tau
    x = np.concatenate([tangents, np.stack(columns, axis=2)], axis=2).reshape(len(sel.weight) * 4, -1)
    n_t, k = tangents.shape[2], len(columns)
    prec = np.concatenate([ridge.precision, np.zeros(k)])
    center = np.concatenate([ridge.center, np.zeros(k)])
    a = np.vstack([x * np.sqrt(w)[:, None], np.diag(np.sqrt(prec))])
    b = np.concatenate([sel.residual.reshape(-1) * np.sqrt(w), np.sqrt(prec) * center])
    beta = np.linalg.lstsq(a, b, rcond=None)[0]
    assert beta.shape == (n_t + k,)
    return float(np.sum((a @ beta - b) ** 2))


def test_profiled_objective_equals_the_direct_map_objective():
    rng = np.random.default_rng(3)
    sel, tangents, ridge, truth = _selection(rng)
    columns = [truth, rng.normal(size=truth.shape)]
    for channels in [(0, 1, 2, 3), (0, 3)]:
        got = TangentProjection.of(sel, tangents, ridge, channels).profiled_objective(columns)
        want = _direct_objective(sel, tangents, ridge, columns, channels)
        assert abs(got - want) <= 1e-6 * want


def test_residual_vector_squares_to_tau_times_the_objective_at_the_best_strength():
    rng = np.random.default_rng(4)
    sel, tangents, ridge, truth = _selection(rng)
    proj = TangentProjection.of(sel, tangents, ridge)
    found = minimize_scalar(lambda s: float(np.sum(proj.residual_vector(s * truth) ** 2)), bounds=(0.0, 2.0),
                            method="bounded", options={"xatol": 1e-9})  # fmt: skip
    assert abs(found.x - 1.0) < 0.05
    assert abs(found.fun - sel.tau * proj.profiled_objective([truth])) <= 1e-6 * found.fun
