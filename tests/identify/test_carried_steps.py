"""The delivered joint fit carries the vehicle parameters' steps onto the torque channels
(:func:`proxplan.identify.crossval.solve_carried`, used by :func:`proxplan.identify.selection.joint_model`;
docs/identify.md, "Stop 73 (lead)"): a step fitted on F_z alone but applied on every channel must not be
counted a second time by a torque term (bench draw 29001: the term came out 2.1x its value)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.crossval import GroupSums, Ridge, solve, solve_carried

N_PER_GROUP = 400
N_GROUPS = 4
CHANNELS = 2  # F_z and one torque channel


def _design(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rows (M = groups x samples x channels): a vehicle parameter's tangent on F_z and on the torque channel,
    a torque term (zero on F_z) correlated with the tangent's torque part, and the cell index of each row."""
    rng = np.random.default_rng(seed)
    m = N_GROUPS * N_PER_GROUP
    tangent = rng.normal(size=(m, CHANNELS))
    term = np.zeros((m, CHANNELS))
    term[:, 1] = 0.8 * tangent[:, 1] + 0.6 * rng.normal(size=m)  # the term overlaps the step's torque part
    group = np.repeat(np.arange(N_GROUPS), N_PER_GROUP)
    cell = (group[:, None] * CHANNELS + np.arange(CHANNELS)[None, :]).reshape(-1)
    return tangent, term, cell, group


def _sums(tangent: np.ndarray, term: np.ndarray, y: np.ndarray, cell: np.ndarray) -> GroupSums:
    fz_part = np.zeros_like(tangent)
    fz_part[:, 0] = tangent[:, 0]
    torque_part = tangent - fz_part
    x = np.column_stack([fz_part.reshape(-1), term.reshape(-1), torque_part.reshape(-1)])
    return GroupSums.build(x, y.reshape(-1), np.ones(x.shape[0]), cell, N_GROUPS, ["step", "term", "step|torque"],
                           n_channels=CHANNELS)  # fmt: skip


def test_a_torque_term_is_fitted_to_what_the_carried_step_leaves() -> None:
    tangent, term, cell, _ = _design(0)
    step, coef = 0.7, 0.3
    y = step * tangent + coef * term  # noise-free: the step acts on both channels, the term on the torque
    sums = _sums(tangent, term, y, cell)
    ridge = Ridge(np.zeros(3), np.zeros(3))
    cols = np.array([0, 1])
    train = np.ones(N_GROUPS)
    carried = solve_carried(sums, cols, np.array([2, -1]), train, ridge, 1.0)
    np.testing.assert_allclose(carried, [step, coef], rtol=1e-6)
    # the F_z-only fit without carrying counts the step's torque twice: the term absorbs 0.8 x 0.7 of it
    plain = solve(sums, cols, train, ridge, 1.0)
    assert abs(plain[1] - coef) > 0.3


def test_the_carried_solution_is_the_fixed_point_of_the_plain_fit() -> None:
    """With noise and a prior: ``solve`` against the target less the carried part at the returned coefficients
    gives the same coefficients back."""
    tangent, term, cell, _ = _design(1)
    rng = np.random.default_rng(2)
    y = 0.4 * tangent + 0.2 * term + 0.5 * rng.normal(size=tangent.shape)
    sums = _sums(tangent, term, y, cell)
    ridge = Ridge(np.array([50.0, 0.0, 0.0]), np.array([0.1, 0.0, 0.0]))
    train = np.array([1.0, 1.0, 0.0, 1.0])  # one group never fitted
    beta = solve_carried(sums, np.array([0, 1]), np.array([2, -1]), train, ridge, 2.0)
    torque_part = tangent.copy()
    torque_part[:, 0] = 0.0
    again = _sums(tangent, term, y - beta[0] * torque_part, cell)
    np.testing.assert_allclose(solve(again, np.array([0, 1]), train, ridge, 2.0), beta, rtol=1e-9, atol=1e-12)


def test_nothing_carried_is_the_plain_fit() -> None:
    tangent, term, cell, _ = _design(3)
    y = 0.5 * tangent + np.random.default_rng(4).normal(size=tangent.shape)
    sums = _sums(tangent, term, y, cell)
    ridge = Ridge(np.array([3.0, 0.0, 0.0]), np.zeros(3))
    train = np.ones(N_GROUPS)
    np.testing.assert_array_equal(
        solve_carried(sums, np.array([0, 1]), np.array([-1, -1]), train, ridge, 1.0),
        solve(sums, np.array([0, 1]), train, ridge, 1.0),
    )
