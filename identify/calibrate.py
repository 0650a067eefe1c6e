"""Calibration of declared model parameters with ``scipy.optimize.least_squares``.

:func:`fit_parameters` is the generic bounded nonlinear least-squares fit with a one-sigma
uncertainty from the Jacobian at the solution, cov = s^2 (J^T J)^+ with s^2 = 2 cost / (m - p)
(the usual Gauss-Newton estimate). That estimate assumes independent residuals; flight samples a
fraction of a second apart are not, so the standard deviations are widened by the AR(1) variance
factor sqrt((1 + rho) / (1 - rho)) of the residual's lag-1 autocorrelation rho in sample order (rows
of one flight are in time order; rho = 0 leaves them as they are). Parameters that end on a
bound are flagged (``at_bound``) and held fixed in the covariance.

:func:`apply_vehicle_parameters` puts calibrated values into a :class:`Vehicle` with
``dataclasses.replace`` — downwash (c_ax, z0_m, c_rad of S0-1, S0-2) and the propeller's measured
b_v (S0-5) — so every prediction still runs through :mod:`proxplan.physics.disturbance`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from proxplan.physics import DownwashSpec, Vehicle

VEHICLE_PARAMETERS = ("c_ax", "z0_m", "c_rad", "b_v")
"""Vehicle parameters that :func:`apply_vehicle_parameters` understands (units: -, m, -,
N m^-1 rad^-2 s^3)."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter to fit: start value and bounds, in the parameter's own unit."""

    name: str
    initial: float
    lower: float
    upper: float


@dataclass(frozen=True)
class CalibrationResult:
    names: tuple[str, ...]
    values: np.ndarray  # (p,)
    std: np.ndarray  # (p,) one-sigma from the Jacobian (inf where not identifiable)
    rmse: float  # RMSE of the residual vector at the solution (its unit)
    n_residuals: int
    success: bool
    message: str
    at_bound: tuple[bool, ...] = ()  # per parameter: ended on a bound (its std is then not meaningful)
    std_inflation: float = 1.0  # AR(1) factor the Jacobian's std were widened by (residual autocorrelation), -

    def interval_excludes(self, name: str, value: float = 0.0, *, z: float = 2.0) -> bool:
        """Whether the parameter ``name``'s z-sigma interval excludes ``value`` (a parameter pinned on a
        bound other than ``value`` does: the data push it out of its range, away from ``value``)."""
        k = self.names.index(name)
        v = float(self.values[k])
        if self.at_bound and self.at_bound[k]:
            return not np.isclose(v, value)
        return bool(np.isfinite(self.std[k]) and abs(v - value) > z * float(self.std[k]))

    def as_dict(self) -> dict[str, float]:
        return dict(zip(self.names, (float(v) for v in self.values)))

    def to_json(self) -> dict[str, dict[str, float | bool | None]]:
        bounds = self.at_bound or (False,) * len(self.names)
        return {n: {"value": float(v), "std": float(s) if np.isfinite(s) else None, "at_bound": bool(b)}
                for n, v, s, b in zip(self.names, self.values, self.std, bounds)}  # fmt: skip


def fit_parameters(
    residual_fn: Callable[[np.ndarray], np.ndarray],
    specs: Sequence[ParamSpec],
    *,
    max_nfev: int | None = 200,
    loss: str = "linear",
) -> CalibrationResult:
    """Minimise ||residual_fn(theta)||^2 over bounded ``theta`` (p,), with uncertainty.

    ``residual_fn`` maps a (p,) vector (``specs`` order) to an (m,) residual vector.
    """
    names = tuple(s.name for s in specs)
    if not specs:
        r = np.asarray(residual_fn(np.zeros(0)))
        return CalibrationResult(
            names,
            np.zeros(0),
            np.zeros(0),
            float(np.sqrt(np.mean(r**2))) if r.size else 0.0,
            r.size,
            True,
            "nothing to fit",
        )
    lo = np.array([s.lower for s in specs], dtype=float)
    hi = np.array([s.upper for s in specs], dtype=float)
    x0 = np.clip(np.array([s.initial for s in specs], dtype=float), lo, hi)
    sol = least_squares(residual_fn, x0, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev, loss=loss)
    m, p = sol.fun.size, len(specs)
    jac = np.atleast_2d(sol.jac)
    at_bound = np.isclose(sol.x, lo, rtol=1e-6, atol=1e-12) | np.isclose(sol.x, hi, rtol=1e-6, atol=1e-12)
    s2 = 2.0 * sol.cost / max(m - p, 1)
    # covariance of the free parameters (those on a bound are held fixed), computed on unit-norm
    # Jacobian columns so that parameters of very different magnitude (b_v ~ 1e-9, c_rad ~ 1e2)
    # do not defeat the pseudo-inverse's cut-off
    col = np.linalg.norm(jac, axis=0)
    free = (~at_bound) & (col > 0.0)
    std = np.full(p, np.inf)
    inflation = _ar1_inflation(sol.fun)
    if free.any():
        js = jac[:, free] / col[free]
        cov_s = s2 * np.linalg.pinv(js.T @ js)
        std[free] = inflation * np.sqrt(np.clip(np.diag(cov_s), 0.0, None)) / col[free]
    return CalibrationResult(
        names=names,
        values=sol.x,
        std=std,
        rmse=float(np.sqrt(np.mean(sol.fun**2))) if m else 0.0,
        n_residuals=m,
        success=bool(sol.success),
        message=str(sol.message),
        at_bound=tuple(bool(b) for b in at_bound),
        std_inflation=inflation,
    )


def _ar1_inflation(r: np.ndarray) -> float:
    """sqrt((1 + rho) / (1 - rho)) of the lag-1 autocorrelation rho of ``r`` (1 when rho <= 0), -."""
    r = np.asarray(r, dtype=float)
    if r.size < 3 or not np.any(r):
        return 1.0
    rho = float(np.dot(r[1:], r[:-1]) / np.dot(r, r))
    rho = min(rho, 0.99)
    return float(np.sqrt((1.0 + rho) / (1.0 - rho))) if rho > 0.0 else 1.0


def apply_vehicle_parameters(vehicle: Vehicle, **values: float) -> Vehicle:
    """``vehicle`` with any of c_ax, z0_m, c_rad (downwash) and b_v (propeller) replaced."""
    unknown = set(values) - set(VEHICLE_PARAMETERS)
    if unknown:
        raise ValueError(f"unknown vehicle parameter(s) {sorted(unknown)}; expected {VEHICLE_PARAMETERS}")
    d = vehicle.downwash
    out = vehicle
    if {"c_ax", "z0_m", "c_rad"} & set(values):
        out = replace(
            out,
            downwash=DownwashSpec(
                c_ax=float(values.get("c_ax", d.c_ax)),
                z0_m=float(values.get("z0_m", d.z0_m)),
                c_rad=float(values.get("c_rad", d.c_rad)),
            ),
        )
    if "b_v" in values:
        out = replace(out, propeller=replace(out.propeller, b_v_measured=float(values["b_v"])))
    return out


def vehicle_param_specs(vehicle: Vehicle, prefix: str, *, as_source: bool, as_target: bool) -> list[ParamSpec]:
    """Default fit ranges of the declared parameters of ``vehicle`` (names ``prefix + param``).

    Source parameters (c_ax, z0_m, c_rad) when it produces downwash in the data, b_v when it
    receives it. Bounds are wide (factors of 3-5 around the prior) so calibration can absorb the
    assumed geometry of :mod:`proxplan.physics.builtin_vehicles`.
    """
    d, L = vehicle.downwash, vehicle.size_m
    out = []
    if as_source:
        out += [
            ParamSpec(prefix + "c_ax", d.c_ax, d.c_ax / 5.0, d.c_ax * 5.0),
            ParamSpec(prefix + "z0_m", d.z0_m, -2.0 * L, 2.0 * L),
            ParamSpec(prefix + "c_rad", d.c_rad, d.c_rad / 5.0, d.c_rad * 5.0),
        ]
    if as_target:
        out.append(ParamSpec(prefix + "b_v", vehicle.b_v, vehicle.b_v / 5.0, vehicle.b_v * 5.0))
    return out
