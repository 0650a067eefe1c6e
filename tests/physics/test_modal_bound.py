"""The modal bound of a damped loop left to itself (proxplan.physics.modal_bound) and the stepped
recursion (proxplan.physics.discretize.recurrence): the bound holds, does not depend on the basis the
loop is written in (the hover loop's x-y eigenvalue pairs are equal: the old sum over eig's
eigenvectors did), and stays sound for a pair split by rounding; the recursion is stepping."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.stats import ortho_group

from proxplan.physics import BUILTIN_VEHICLES
from proxplan.physics.discretize import expm_stack, recurrence
from proxplan.physics.hover_loop import _live_states, loop_matrices
from proxplan.physics.modal_bound import modal_bound


def _hover_loop(name: str = "small-quad") -> tuple[np.ndarray, np.ndarray]:
    mats = loop_matrices(BUILTIN_VEHICLES[name])
    live = _live_states(mats.a)
    return mats.a[0][np.ix_(live, live)], mats.c[:, live]


def _sup_on_grid(a: np.ndarray, c: np.ndarray, z: np.ndarray, step_s: float, n: int) -> np.ndarray:
    """|C e^{A t} z| on t = k step_s, k < n (by stepping e^{A step})."""
    phi = expm(a * step_s)
    out, x = np.zeros(n), z.copy()
    for k in range(n):
        out[k] = np.linalg.norm(c @ x)
        x = phi @ x
    return out


def test_the_hover_loop_has_equal_x_y_pairs():
    """The premise: without a jet the loop's eigenvalues come in equal pairs (x and y alike)."""
    a, _ = _hover_loop()
    lam = np.linalg.eigvals(a)
    close = np.abs(lam[:, None] - lam[None, :]) < 1e-9 * np.abs(lam).max()
    assert (int(close.sum()) - lam.size) // 2 >= 4  # pairs of equal eigenvalues


def test_the_bound_is_the_same_in_any_basis_and_holds():
    a, c = _hover_loop()
    rng = np.random.default_rng(3)
    z = rng.normal(size=a.shape[0]) * np.abs(np.diag(a)).clip(1.0, None) ** -1  # states of comparable effect
    bound = modal_bound(a, c)
    total = float(bound.weights(z[:, None]).sum())
    for seed in range(4):  # the same loop written in another orthonormal basis: eig returns other pair bases
        q = ortho_group.rvs(a.shape[0], random_state=seed)
        other = modal_bound(q.T @ a @ q, c @ q)
        assert float(other.weights((q.T @ z)[:, None]).sum()) == pytest.approx(total, rel=1e-9)
    seen = _sup_on_grid(a, c, z, 0.01, 3000)
    rate = np.exp(-np.outer(np.arange(3000) * 0.01, bound.rate_ps))  # (T, terms)
    assert np.all(seen <= rate @ bound.weights(z[:, None])[:, 0] * (1.0 + 1e-12))
    assert seen.max() > 0.1 * total  # and not vacuous (0.39 on this loop)


def test_a_pair_split_by_rounding_stays_sound():
    """A nearly defective pair (a Jordan block perturbed by 1e-10): its eigenvectors are nearly
    parallel, the pair is one cluster, and the transient t e^{-t} it rings with is still covered."""
    a = np.array([[-1.0, 1.0, 0.0], [0.0, -1.0 - 1e-10, 0.0], [0.0, 0.0, -3.0]])
    c = np.eye(3)[:1]
    z = np.array([0.0, 1.0, 1.0])
    bound = modal_bound(a, c)
    seen = _sup_on_grid(a, c, z, 0.01, 2000)
    rate = np.exp(-np.outer(np.arange(2000) * 0.01, bound.rate_ps))
    assert np.all(seen <= rate @ bound.weights(z[:, None])[:, 0] * (1.0 + 1e-12))
    assert seen.max() == pytest.approx(np.exp(-1.0), rel=1e-3)  # t e^{-t} at t = 1


def test_a_loop_that_is_not_damped_has_no_bound():
    assert modal_bound(np.array([[0.1, 0.0], [0.0, -1.0]]), np.eye(2)) is None


def test_the_recursion_is_stepping():
    a, _ = _hover_loop()
    phi = expm_stack(a[None] * 0.01)[0]
    rng = np.random.default_rng(5)
    forced = rng.normal(size=(a.shape[0], 2, 777))  # two drives side by side, K not a square
    got = recurrence(phi, forced)
    for d in range(2):
        x = np.zeros(a.shape[0])
        for k in range(forced.shape[-1]):
            x = phi @ x + forced[:, d, k]
            assert np.allclose(got[:, d, k], x, rtol=0.0, atol=1e-11 * (1.0 + np.abs(x).max()))
