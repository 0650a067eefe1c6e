"""The delay of a library effect (issue 35: "a lag on any effect"; :data:`proxplan.physics.LAG_PARAM`): the
profile of the MAP objective over a grid of delays, its refinement, and the channels a delay is judged on.
Used by :mod:`proxplan.identify.effect_selection`; the inputs of a delay at the fits' sparse rows come from
:mod:`proxplan.identify.delayed`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from proxplan.identify.crossval import Ridge
from proxplan.identify.design import LagInputs, SelectionSet, effect_columns, lag_inputs
from proxplan.identify.projection import TangentProjection
from proxplan.physics import LAG_BOUNDS_S, LAGS_S, Effect

LAG_GRID_S = (0.0, *LAGS_S)
"""Delays every library effect of a NEIGHBOUR is profiled over, s (:data:`proxplan.physics.LAG_PARAM`): at
once, and the temporal features' geometric grid (:data:`proxplan.physics.LAGS_S`, 0.05-0.85 s, ratio 1.5:
any delay in range within 25 % of one). Another vehicle's disturbance may reach the target late (its wake
travels down, the target's rotors take time to respond), and an effect tried only at once is then
rejected or leaves most of itself behind. The target's own effects
(:data:`proxplan.physics.TARGET_ONLY_EFFECTS`) are tried at once only: no wake carries them, and a delayed
own speed is a stand-in for a place (on a periodic path the speed a quarter period late IS the position:
with delays, own_velocity stood in for a wall's suction in tests/identify/test_discovery_wide.py)."""
DELAY_CHANNELS = (0, 3)
"""Channels a delay is chosen on (of F_z, torque x, y, z): F_z and yaw. The measured roll and pitch torques
hold R J omega_dot, the vehicle's own rotation, which follows any roll or pitch disturbance through its
attitude loop, late; an error in that term (the Savitzky-Golay derivative's attenuation, the inertia) is a
delayed image of the disturbance, so a delay chosen there fits the measurement, not the air: on
closed-loop simulator logs with NO effect (tests/identify/test_identify.py), the roll residual follows the
derivative of the body rate (49 % of its variance), and thrust_quadratic 35 ms late, chosen on every
channel, halved the held-out torque error; chosen on these two channels but tested on all, 58 ms late it
still passed (+0.71 +- 0.12) on the logs with a constant force hidden. So a delayed effect's held-out gain
is tested on these channels too (:attr:`proxplan.identify.effect_candidates.EffectCandidate.judged_channels`).
Its shape AND its strength are fitted on all four, and saved, it acts on all four: fitted on F_z and yaw alone,
the F_z of an effect near its source trades with the vehicle parameters' tangents (a jet's decay and virtual
origin), and a lagged near field came out at -0.2 to -0.3 of the shape fit's strength on every fold of a set
that holds it (docs/identify.md, "Stop 59")."""
LAG_RESOLUTION_S = 0.002
"""Resolution of a refined delay, s: a fifth of the logs' 10 ms sample step (within it the inputs are
interpolated linearly, and the objective is flat below it)."""


def best_lag(
    sel: SelectionSet,
    effects: Sequence[Effect],
    tangents: np.ndarray,
    ridge: Ridge,
    delayed: dict[float, LagInputs],
    *,
    near: float | None = None,
) -> tuple[float, float]:
    """The delay (s), and the objective there, at which ``effects`` (one column each, their strengths free) leave the lowest
    :meth:`proxplan.identify.projection.TangentProjection.profiled_objective` on :data:`DELAY_CHANNELS`: the best of 0 and the delays of :data:`LAG_GRID_S` in ``delayed`` (at once
    on a tie), chosen on :data:`DELAY_CHANNELS`, then, when that is a delay, refined between its neighbours on
    the grid (bounded Brent, to :data:`LAG_RESOLUTION_S`); with ``near`` (a delay found before), only
    that refinement, around the grid point nearest to it, kept if it beats ``near``. The refined delay's
    inputs are added to ``delayed``."""

    projection = TangentProjection.of(sel, tangents, ridge, DELAY_CHANNELS)

    def score(lag: float) -> float:
        if lag not in delayed:
            delayed[lag] = lag_inputs(sel, lag)
        return projection.profiled_objective([effect_columns(sel, e, delayed[lag]) for e in effects])

    grid = [lag for lag in LAG_GRID_S if lag in delayed]
    if len(grid) == 1:
        return 0.0, score(0.0)
    if near is not None:
        k = max(1, int(np.argmin([abs(g - near) for g in grid])))
        best = score(near)
    else:
        listed = [score(lag) for lag in grid]
        k = int(np.argmin(listed))
        best = listed[k]
        if k == 0:
            return 0.0, best
    upper = grid[k + 1] if k + 1 < len(grid) else min(grid[k] * LAG_GRID_S[2] / LAG_GRID_S[1], LAG_BOUNDS_S[1])
    found = minimize_scalar(lambda x: score(round(float(x), 3)), bounds=(grid[k - 1], upper),
                            method="bounded", options={"xatol": LAG_RESOLUTION_S})  # fmt: skip
    lag = round(float(found.x), 3)
    refined = score(lag)
    if refined < best:
        return lag, refined
    return (near if near is not None else float(grid[k])), best
