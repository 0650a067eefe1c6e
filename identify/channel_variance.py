"""Each channel's error variance as the delivered fit weighs it: measurement noise plus what the model leaves
unexplained (issue 35, harm from an effect nothing keeps).

Selection measures every channel in its noise unit (:mod:`proxplan.identify.noise`: the residual's spread at
one correlation time, where slow structure cancels). That unit is right for TESTS (a gain is judged against
the noise), but as the weight of a FIT it claims that every channel is predicted to its noise, which is false
where an effect nothing keeps sits in the channel: a kernel torque on a large quad that no term explains is
then fitted as if it were signal, and the vehicle parameters' tangents bend to it (stop 61: the small quad's
thrust scale moved 0.9937 -> 0.9802 through its jet's torque on the large quad, and the small quad, which
nothing affects, ended at 6.4x its clean error).

The variance-components model: a channel c of vehicle type t has error variance
sigma^2_tc = noise^2_tc * max(m_tc, 1), with m_tc the HELD-OUT mean squared residual in noise units (each
train sample predicted by the fit that left its flight out, with everything selection kept). The first
factor is the measurement noise; the second the unexplained structure, which cannot be negative, so a
held-out MSE below one noise unit (sampling spread) never weighs a channel above its noise. Weighting each
row and channel by 1 / sqrt(max(m_tc, 1)) in noise units is the feasible generalised least-squares fit of
that model (one iteration: the weights from the fit judged, as in the usual two-step FGLS; Greene,
Econometric Analysis, ch. 9). Where the model explains a channel (m near 1) nothing changes; where a
channel holds what nothing explains, it informs the shared parameters only as far as its error allows.
No constant is set here: the floor at one noise unit is the definition of the noise.
"""

from __future__ import annotations

import numpy as np


def structural_row_weight(
    residual: np.ndarray, types: np.ndarray, train_weight: np.ndarray
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Row and channel weights of the variance-components model (module docstring).

    ``residual`` (N, C): each row's held-out residual in noise units (NaN or inf where a channel has no
    weight); ``types`` (N,) each row's vehicle type; ``train_weight`` (N,) each row's weight in the fit (0 on
    rows the fit does not use). Returns the (N, C) factor 1 / sqrt(max(m_tc, 1)) to multiply the rows'
    columns and target by, and each type's m_tc (C,) (the held-out MSE per channel, noise units; NaN where a
    type has no train row of that channel)."""
    r = np.where(np.isfinite(residual), residual, np.nan)
    factor = np.ones_like(r)
    mse: dict[str, np.ndarray] = {}
    for vtype in sorted(set(types.tolist())):
        rows = types == vtype
        w = train_weight[rows][:, None] * np.isfinite(r[rows])
        total = w.sum(axis=0)
        m = np.where(total > 0, np.nansum(w * np.nan_to_num(r[rows]) ** 2, axis=0) / np.where(total > 0, total, 1.0),
                     np.nan)  # fmt: skip
        mse[str(vtype)] = m
        factor[rows] = 1.0 / np.sqrt(np.maximum(np.where(np.isfinite(m), m, 1.0), 1.0))[None, :]
    return factor, mse
