"""Calibration of declared model parameters with ``scipy.optimize.least_squares``, and the pipeline's
calibration stage (:func:`calibrate_model`: the MAP fit of the vehicles' parameters on train flights).

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

from proxplan.identify.data import IdentifyOptions, Model, Unit, predict
from proxplan.identify.delayed import delayed_units, with_rows
from proxplan.identify.noise import NoiseLevel
from proxplan.identify.priors import INFORMED_RATIO, MOVE_SIGMAS, STACK_SHIELDING_PRIOR, Prior, vehicle_priors
from proxplan.identify.strata import MIN_STACK_SAMPLES, stacked_samples, stratified_sample
from proxplan.physics import MAX_STACK_SHIELDING, DownwashSpec, Vehicle

VEHICLE_PARAMETERS = ("c_ax", "z0_m", "c_rad", "b_v")
"""Vehicle parameters that :func:`apply_vehicle_parameters` understands (units: -, m, -,
N m^-1 rad^-2 s^3)."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter to fit: start value and bounds, in the parameter's own unit, and its prior (MAP
    fit; None: plain least squares, :func:`fit_parameters`)."""

    name: str
    initial: float
    lower: float
    upper: float
    prior: Prior | None = None


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
    priors: tuple[Prior | None, ...] = ()  # per parameter, its prior (MAP fit), or None

    def prior_report(self) -> dict[str, dict[str, float | bool | None]]:
        """Per parameter with a prior: its prior center and sigma, how far it moved (prior sigmas,
        signed), its posterior over prior sigma, and whether the data informed it
        (:data:`proxplan.identify.priors.INFORMED_RATIO`) or moved it suspiciously far
        (:data:`proxplan.identify.priors.MOVE_SIGMAS`: a sign of a missing effect)."""
        out: dict[str, dict[str, float | bool | None]] = {}
        for k, (name, prior) in enumerate(zip(self.names, self.priors)):
            if prior is None or prior.sigma <= 0.0:
                continue
            value, std = float(self.values[k]), float(self.std[k])
            ratio = prior.relative_std(value, std) if np.isfinite(std) else None
            move = prior.z(value)
            out[name] = {"prior_center": prior.center, "prior_sigma": prior.sigma, "prior_log": prior.log,
                         "move_sigmas": move, "posterior_over_prior": ratio,
                         "informed": ratio is not None and ratio <= INFORMED_RATIO,
                         "large_move": abs(move) >= MOVE_SIGMAS}  # fmt: skip
        return out

    def large_moves(self) -> list[str]:
        """Names of the parameters the data moved by at least MOVE_SIGMAS prior sigmas."""
        return [k for k, d in self.prior_report().items() if d["large_move"]]

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
    noise_sigma: float | None = None,
) -> CalibrationResult:
    """Minimise ||residual_fn(theta)||^2 over bounded ``theta`` (p,), with uncertainty.

    ``residual_fn`` maps a (p,) vector (``specs`` order) to an (m,) residual vector.

    MAP fit (``noise_sigma`` given, in the residual's unit): the objective is
    ||residual / noise_sigma||^2 + sum_k z_k^2, z_k the standardised distance of parameter k from
    its :attr:`ParamSpec.prior` (:class:`proxplan.identify.priors.Prior`; none: no term). ``noise_sigma``
    is the noise of ONE independent sample of the residual vector (the caller folds in the residual's
    autocorrelation: :func:`integrated_autocorrelation_time`), so the posterior covariance is
    (J^T J)^-1 of the augmented, standardised residual, not widened again. A prior of sigma 0 holds
    its parameter at the prior's center.
    """
    if noise_sigma is not None:
        return _fit_map(residual_fn, specs, max_nfev=max_nfev, noise_sigma=noise_sigma)
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


def _fit_map(
    residual_fn: Callable[[np.ndarray], np.ndarray],
    specs: Sequence[ParamSpec],
    *,
    max_nfev: int | None,
    noise_sigma: float,
) -> CalibrationResult:
    """The MAP fit of :func:`fit_parameters` (parameters held by a zero-sigma prior are not fitted)."""
    names = tuple(s.name for s in specs)
    held = [s.prior is not None and s.prior.sigma <= 0.0 for s in specs]
    free_idx = [k for k, h in enumerate(held) if not h]
    full0 = np.array([s.prior.center if h and s.prior is not None else s.initial for s, h in zip(specs, held)])
    lo = np.array([specs[k].lower for k in free_idx], dtype=float)
    hi = np.array([specs[k].upper for k in free_idx], dtype=float)
    priors = [specs[k].prior for k in free_idx]

    def full(x: np.ndarray) -> np.ndarray:
        theta = full0.copy()
        theta[free_idx] = x
        return theta

    def augmented(x: np.ndarray) -> np.ndarray:
        data = np.asarray(residual_fn(full(x)), dtype=float) / noise_sigma
        prior = np.array([0.0 if p is None else p.z(float(v)) for p, v in zip(priors, x)])
        return np.concatenate([data, prior])

    if not free_idx:
        r = np.asarray(residual_fn(full0), dtype=float)
        return CalibrationResult(names, full0, np.zeros(len(specs)), float(np.sqrt(np.mean(r**2))) if r.size else 0.0,
                                 r.size, True, "every parameter held", tuple(False for _ in specs), 1.0,
                                 tuple(s.prior for s in specs))  # fmt: skip
    x0 = np.clip(full0[free_idx], lo, hi)
    sol = least_squares(augmented, x0, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev)
    jac = np.atleast_2d(sol.jac)
    at_b = np.isclose(sol.x, lo, rtol=1e-6, atol=1e-12) | np.isclose(sol.x, hi, rtol=1e-6, atol=1e-12)
    col = np.linalg.norm(jac, axis=0)
    ok = (~at_b) & (col > 0.0)
    std_free = np.full(len(free_idx), np.inf)
    if ok.any():
        js = jac[:, ok] / col[ok]
        std_free[ok] = np.sqrt(np.clip(np.diag(np.linalg.pinv(js.T @ js)), 0.0, None)) / col[ok]
    std = np.zeros(len(specs))
    std[free_idx] = std_free
    at_bound = np.zeros(len(specs), dtype=bool)
    at_bound[free_idx] = at_b
    data = np.asarray(residual_fn(full(sol.x)), dtype=float)
    return CalibrationResult(
        names=names,
        values=full(sol.x),
        std=std,
        rmse=float(np.sqrt(np.mean(data**2))) if data.size else 0.0,
        n_residuals=data.size,
        success=bool(sol.success),
        message=str(sol.message),
        at_bound=tuple(bool(b) for b in at_bound),
        std_inflation=1.0,
        priors=tuple(s.prior for s in specs),
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
    """The declared parameters of ``vehicle`` (names ``prefix + param``) with their priors
    (:func:`proxplan.identify.priors.vehicle_priors`) and physical bounds.

    Source parameters (c_ax, z0_m, c_rad) when it produces downwash in the data, b_v when it
    receives it. The bounds only keep the model physical (factors of 5, +-2 L); the priors say how far
    the data must push a parameter to move it.
    """
    d, L = vehicle.downwash, vehicle.size_m
    pri = vehicle_priors(vehicle, as_source=as_source, as_target=as_target)
    out = []
    if as_source:
        out += [
            ParamSpec(prefix + "c_ax", d.c_ax, d.c_ax / 5.0, d.c_ax * 5.0, pri["c_ax"]),
            ParamSpec(prefix + "z0_m", d.z0_m, -2.0 * L, 2.0 * L, pri["z0_m"]),
            ParamSpec(prefix + "c_rad", d.c_rad, d.c_rad / 5.0, d.c_rad * 5.0, pri["c_rad"]),
        ]
    if as_target:
        out.append(ParamSpec(prefix + "b_v", vehicle.b_v, vehicle.b_v / 5.0, vehicle.b_v * 5.0, pri["b_v"]))
    return out


# ------------------------------------------------------------------------------ the calibration stage


def _roles(units: Sequence[Unit]) -> tuple[set[str], set[str], list[str]]:
    sources = {t for u in units for t in u.source_types}
    targets = {u.type for u in units if u.source_types}
    types = sorted({u.type for u in units})
    return sources, targets, types


STACK_PARAMETER = "model.stack_shielding"
"""Name of the stack shielding eta among the calibrated parameters."""


def model_specs(units: Sequence[Unit], model: Model, held: frozenset[str] = frozenset()) -> list[ParamSpec]:
    """The declared parameters the data can inform, with their priors: c_ax, z0_m, c_rad of every type
    that is a source in ``units``, b_v of every type that receives a downwash, every type's thrust scale
    (names ``TYPE.param``; :func:`proxplan.identify.calibrate.vehicle_param_specs`), and the stack shielding
    eta where the units hold at least :data:`MIN_STACK_SAMPLES` samples with two or more sources overhead;
    none named in ``held`` (held at the model's value: :mod:`proxplan.identify.earned`)."""
    sources, targets, types = _roles(units)
    specs: list[ParamSpec] = []
    n_stacked = sum(int(np.sum(stacked_samples(u, model))) for u in units)
    if n_stacked >= MIN_STACK_SAMPLES:
        specs.append(ParamSpec(STACK_PARAMETER, model.options.stack_shielding, 0.0, MAX_STACK_SHIELDING,
                               STACK_SHIELDING_PRIOR))  # fmt: skip
    for t in types:
        specs += vehicle_param_specs(model.vehicles[t], f"{t}.", as_source=t in sources, as_target=t in targets)
        specs.append(ParamSpec(f"{t}.thrust_scale", model.thrust_scale.get(t, 1.0), 0.7, 1.3,
                               vehicle_priors(model.vehicles[t], as_source=False, as_target=False)["thrust_scale"]))  # fmt: skip
    return [s for s in specs if s.name not in held]


def parameter_value(model: Model, name: str) -> float:
    """The value of calibrated parameter ``name`` (``TYPE.c_ax``, ``TYPE.thrust_scale``,
    ``model.stack_shielding``, ...: :func:`model_specs`) in ``model``, in its own unit."""
    vtype, key = name.rsplit(".", 1)
    if key == "stack_shielding":
        return float(model.options.stack_shielding)
    if key == "thrust_scale":
        return float(model.thrust_scale.get(vtype, 1.0))
    veh = model.vehicles[vtype]
    return float({"c_ax": veh.downwash.c_ax, "z0_m": veh.downwash.z0_m, "c_rad": veh.downwash.c_rad,
                  "b_v": veh.b_v}[key])  # fmt: skip


def calibrate_model(
    units: Sequence[Unit],
    model: Model,
    *,
    options: IdentifyOptions,
    noise: NoiseLevel,
    start: Model | None = None,
    held: frozenset[str] = frozenset(),
) -> tuple[Model, CalibrationResult, Model]:
    """MAP fit of c_ax, z0_m, c_rad (source types), b_v (target types) and thrust scales (all types) on F_z,
    on a stratified, weighted sample of ``units`` (:func:`proxplan.identify.strata.stratified_sample`),
    with the priors of :mod:`proxplan.identify.priors`. The data term is in units of the F_z noise of one
    independent sample: each type's F_z noise unit times sqrt(tau) (:func:`proxplan.identify.noise.noise_level`).
    The thrust scales are nuisance parameters: the model is returned with them at 1 (and ``fitted``, the
    model with them, is what the measurement noise is judged on). The priors and bounds are ``model``'s;
    with ``start`` (a model with effects, e.g. after selection) the fit starts from its values and predicts
    with its effects and options (the effects held as they are; a delayed one on each sample's delayed
    state, :func:`proxplan.identify.delayed.delayed_unit`). Parameters named in ``held`` are not fitted:
    they keep ``start``'s value (else ``model``'s)."""
    sources = with_rows([u for u in units if len(u)])
    fit_units = stratified_sample(sources, options.max_fit_samples, model.vehicles)
    sw = np.sqrt(np.concatenate([u.weight for u in fit_units])) / noise.rows(fit_units)[:, 0]
    specs = model_specs(fit_units, model, held)
    if start is not None:
        specs = [replace(s, initial=float(np.clip(parameter_value(start, s.name), s.lower, s.upper))) for s in specs]
    y = np.concatenate([u.force_N[:, 2] for u in fit_units])
    origin = model if start is None else start
    delayed = delayed_units(fit_units, sources, sorted({e.lag_s for e in origin.effects}))

    def model_of(theta: np.ndarray) -> Model:
        per_type: dict[str, dict[str, float]] = {}
        options = origin.options
        for spec, val in zip(specs, theta):
            if spec.name == STACK_PARAMETER:
                options = replace(options, stack_shielding=float(val))
                continue
            t, key = spec.name.rsplit(".", 1)
            per_type.setdefault(t, {})[key] = float(val)
        vehicles = dict(origin.vehicles)
        scales = dict(origin.thrust_scale)
        for t, vals in per_type.items():
            scales[t] = vals.pop("thrust_scale", 1.0)
            vehicles[t] = apply_vehicle_parameters(origin.vehicles[t], **vals)
        return replace(origin, vehicles=vehicles, thrust_scale=scales, options=options)

    def residual(theta: np.ndarray) -> np.ndarray:
        m = model_of(theta)
        return sw * (np.concatenate([predict(u, m, delayed=d)[0][:, 2] for u, d in zip(fit_units, delayed)]) - y)

    result = fit_parameters(residual, specs, max_nfev=60 + 10 * len(specs), noise_sigma=float(np.sqrt(noise.tau)))
    # the thrust scales are nuisance parameters (so a thrust-calibration error does not distort the
    # aerodynamic ones); selection refits them beside every candidate (thrust_bias)
    calibrated = model_of(result.values)
    return replace(calibrated, thrust_scale=dict(model.thrust_scale)), result, calibrated
