"""The vehicle parameters refitted exactly beside a candidate (variable projection, issue 35).

A library effect's shape (:func:`proxplan.identify.effect_candidates.fit_shape`) and its delay
(:func:`proxplan.identify.delay_profile.profiled_objective`) are both judged on the residual the
calibration would leave WITH the effect: for every trial, the steps of the calibrated vehicle parameters
(their tangent columns, with their priors as a ridge) are refitted by linear least squares. The tangents'
weighted Gram matrix and their projection of the data are the same for every trial, so they are formed
once here (one (P, 4 N) product per trial instead of the (P, P) Gram over 4 N rows).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from proxplan.identify.crossval import Ridge
from proxplan.identify.design import SelectionSet

GRAM_JITTER = 1e-9
"""Relative jitter on the Gram matrix's diagonal, -: keeps the normal equations solvable when a tangent
column is all zero on the train rows (a parameter no train row informs), far below any data term."""


@dataclass(frozen=True)
class TangentProjection:
    """The selection set's train rows, the vehicle parameters' ``tangents`` (N, 4, P) and their priors, on
    the ``channels`` (indices of F_z and the three torques) a candidate is judged on; everything in noise
    units, the data term over the residual's correlation time tau."""

    tangents: np.ndarray  # (N, 4, P), noise units per unit of each parameter's step
    weight: np.ndarray  # (N * 4,) sample weight on the train rows and chosen channels, else 0
    y: np.ndarray  # (N * 4,) the reference model's residual, noise units
    weighted_t: np.ndarray  # (P, N * 4): tangents^T W / tau
    gram: np.ndarray  # (P, P): tangents^T W tangents / tau
    t_y: np.ndarray  # (P,): tangents^T W y / tau
    y_y: float  # y^T W y / tau
    lhs: np.ndarray  # (P, P) the tangents' normal matrix with their prior precision
    precision: np.ndarray  # (P,) prior precision of each step
    center: np.ndarray  # (P,) prior mean of each step
    tau: float  # integrated autocorrelation time of the residual, samples

    @staticmethod
    def of(
        sel: SelectionSet, tangents: np.ndarray, ridge: Ridge, channels: Sequence[int] = (0, 1, 2, 3)
    ) -> TangentProjection:
        """The projection on ``sel``'s train rows; ``ridge`` holds the tangents' priors first (P entries)."""
        n_t = tangents.shape[2]
        mask = np.zeros(4)
        mask[list(channels)] = 1.0
        train = ~sel.plan.held_out_only[sel.group]
        weight = ((sel.weight * train)[:, None] * mask[None, :]).reshape(-1)
        t_flat = tangents.reshape(len(sel.weight) * 4, n_t)
        weighted_t = (t_flat * weight[:, None]).T / sel.tau
        gram = weighted_t @ t_flat
        precision, center = ridge.precision[:n_t], ridge.center[:n_t]
        lhs = gram + np.diag(precision + GRAM_JITTER * np.maximum(np.diag(gram), 1e-300))
        y = sel.residual.reshape(-1)
        return TangentProjection(tangents, weight, y, weighted_t, gram, weighted_t @ y,
                                 float(np.sum(weight * y * y)) / sel.tau, lhs, precision, center, float(sel.tau))  # fmt: skip

    @property
    def n_params(self) -> int:
        return self.tangents.shape[2]

    def step(self, z: np.ndarray) -> np.ndarray:
        """(P,) the MAP steps of the vehicle parameters fitted to the residual ``z`` (N, 4) (noise units)."""
        if not self.n_params:
            return np.zeros(0)
        return np.linalg.solve(self.lhs, self.weighted_t @ z.reshape(-1) + self.precision * self.center)

    def residual_vector(self, columns: np.ndarray) -> np.ndarray:
        """The stacked whitened residual of the MAP objective with the candidate's ``columns`` (N, 4) at
        fixed strength and the steps refitted (data rows, then one prior row per step): its squared sum is
        tau times the objective (for a least-squares solver, the noise scale sqrt(tau))."""
        z = self.y.reshape(columns.shape) - columns
        step = self.step(z)
        data = np.sqrt(self.weight) * (z - self.tangents @ step).reshape(-1)
        prior = np.sqrt(self.tau * self.precision) * (step - self.center)
        return np.concatenate([data, prior])

    def profiled_objective(self, columns: Sequence[np.ndarray]) -> float:
        """The MAP objective, -, with ``columns`` (each (N, 4), noise units; their strengths free, no prior)
        and the steps fitted jointly: the weighted squared residual over tau (from the normal equations'
        sums, so no residual over the 4 N rows is formed) plus the steps' prior penalty."""
        return self._profiled(columns)[0]

    def profiled_strengths(self, columns: Sequence[np.ndarray]) -> np.ndarray:
        """(k,) the strengths of ``columns`` (each (N, 4), noise units, per unit of strength) at the minimum of
        :meth:`profiled_objective`: fitted jointly with the vehicle parameters' steps, unbounded."""
        return self._profiled(columns)[1][self.n_params :]

    def _profiled(self, columns: Sequence[np.ndarray]) -> tuple[float, np.ndarray]:
        """The objective of :meth:`profiled_objective` and the (P + k,) solution (steps, then strengths)."""
        n_t = self.n_params
        c = np.stack([col.reshape(-1) for col in columns], axis=1)  # (4 N, k)
        wc = c * (self.weight / self.tau)[:, None]
        t_flat = self.tangents.reshape(len(self.y), n_t)
        cross = wc.T @ t_flat  # (k, P)
        gram_c = wc.T @ c
        lhs = np.block(
            [[self.lhs, cross.T], [cross, gram_c + np.diag(GRAM_JITTER * np.maximum(np.diag(gram_c), 1e-300))]]
        )
        c_y = wc.T @ self.y
        rhs = np.concatenate([self.t_y + self.precision * self.center, c_y])
        beta = np.linalg.solve(lhs, rhs)
        # the weighted squared residual from the normal equations' sums: y'Wy - 2 beta'X'Wy + beta'X'WX beta
        gram = np.block([[self.gram, cross.T], [cross, gram_c]])
        sse = self.y_y - 2.0 * beta @ np.concatenate([self.t_y, c_y]) + beta @ gram @ beta
        return float(sse + np.sum(self.precision * (beta[:n_t] - self.center) ** 2)), beta
