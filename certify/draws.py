"""Per-run random draws of a certification: what differs between the planned and the flown world.

Every run ``k`` of a certification with seed ``S`` draws from its own generator
``numpy.random.default_rng(SeedSequence(S, spawn_key=(k,)))`` — the same stream as
``SeedSequence(S).spawn(N)[k]`` — so a run's draws depend on (S, k) only, never on which worker,
process or machine flies it, nor on how many runs there are.

One run draws (all documented in docs/certify.md):

* **model parameters** of every vehicle type in the plan, Gaussian around the plan's values:
  ``c_ax``, ``z0_m``, ``c_rad`` (S0-1, S0-2) and ``b_v`` (S0-5). Spreads (1 sigma) come from a
  saved model's ``uncertainty: {param: std}`` (key ``TYPE.PARAM`` or ``PARAM`` for every type;
  absolute, in the parameter's unit) and otherwise from :data:`DEFAULT_RELATIVE_SPREADS`;
* a **residual disturbance force** per vehicle beyond the model: an Ornstein-Uhlenbeck process
  (exact AR(1) on a ``residual_dt_s`` grid) per world axis with the std (fraction of the vehicle's
  weight) and correlation time measured on Neural-Swarm logs (:mod:`proxplan.certify.residuals`);
* **sensor noise**: errors of the position / velocity estimate the controller uses (OU processes);
* **start-position** (Gaussian per axis) and **timing** errors (Gaussian start delay per vehicle).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from proxplan.identify import VEHICLE_PARAMETERS
from proxplan.physics import Vehicle

MODEL_PARAMETERS = VEHICLE_PARAMETERS
"""Model parameters drawn per vehicle type: c_ax, z0_m, c_rad, b_v (the ones ``proxplan identify``
calibrates; a drawn set is applied with ``proxplan.identify.apply_vehicle_parameters``)."""

DEFAULT_RELATIVE_SPREADS = {"c_ax": 0.10, "z0_m": 0.0, "c_rad": 0.15, "b_v": 0.20}
"""Default 1-sigma spreads as a fraction of the value, used when no saved uncertainty is given.
c_ax: the seed's two fits of it differ by ~4 % (4.7-4.9, S0 IV-B) and round-jet decay constants in
its ref [13] by ~10 %; c_rad: 15 % (the Gaussian width is the least constrained shape parameter of
the fits); b_v: 20 % (measured for one propeller only, blade-element values for the others,
DESIGN.md s. 2). z0_m: absolute spread :data:`DEFAULT_Z0_SPREAD_L` x L instead (z0 can be ~0)."""

DEFAULT_Z0_SPREAD_L = 0.25
"""Default 1-sigma spread of the virtual origin z0, in units of the source size L, -."""


@dataclass(frozen=True)
class NoiseSpec:
    """Everything but the model parameters that a run draws; SI units in the names.

    Residual force: measured on the Neural-Swarm single-vehicle hover segments
    (``python -m proxplan.certify.residuals``, docs/certify.md): z std 2.2 % (Crazyflie, 3 flights) and
    1.9 % (Parrot frame, 1 flight) of the weight, x/y std 0.66 % and 0.47 %, 1/e correlation times
    0.13 s and 0.06 s; defaults: z 2.1 %, x/y 0.6 %, 0.10 s. Estimate errors: motion-capture +
    onboard EKF class figures (2 mm, 2 cm/s), not measured here.
    """

    residual_std_z_weight: float = 0.021  # residual force std along z / weight, -
    residual_std_xy_weight: float = 0.006  # residual force std along x and y / weight, -
    residual_tau_s: float = 0.10  # correlation time of the residual force, s
    residual_dt_s: float = 0.01  # grid of the drawn residual (the logs' 100 Hz), s
    estimate_std_m: float = 0.002  # position-estimate error std per axis, m
    estimate_std_mps: float = 0.02  # velocity-estimate error std per axis, m/s
    estimate_tau_s: float = 0.05  # correlation time of the estimate errors, s
    start_std_m: float = 0.02  # start-position error std per axis, m
    timing_std_s: float = 0.02  # start delay std per vehicle, s


@dataclass(frozen=True)
class Spreads:
    """1-sigma model-parameter spreads: absolute values from a saved model (``TYPE.PARAM`` or
    ``PARAM`` keys), else the defaults. ``from_model`` says which were used."""

    absolute: Mapping[str, float] = field(default_factory=dict)
    from_model: bool = False

    def sigma(self, type_name: str, vehicle: Vehicle, param: str) -> float:
        for key in (f"{type_name}.{param}", param):
            if key in self.absolute:
                return float(self.absolute[key])
        if param == "z0_m":
            return DEFAULT_Z0_SPREAD_L * vehicle.size_m
        return DEFAULT_RELATIVE_SPREADS[param] * abs(_value(vehicle, param))


def _value(vehicle: Vehicle, param: str) -> float:
    if param == "b_v":
        return float(vehicle.b_v)
    return float(getattr(vehicle.downwash, param))


def run_rng(seed: int, index: int) -> np.random.Generator:
    """The generator of run ``index``: ``SeedSequence(seed).spawn(...)[index]``'s stream."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))


def ou_series(rng: np.random.Generator, n: int, dt_s: float, tau_s: float, std: np.ndarray) -> np.ndarray:
    """Stationary Ornstein-Uhlenbeck samples (n, D) of std ``std`` (D,) and correlation time tau_s,
    exact discretisation x_{k+1} = a x_k + sqrt(1 - a^2) std e_k, a = exp(-dt / tau)."""
    std = np.asarray(std, dtype=float)
    a = float(np.exp(-dt_s / tau_s)) if tau_s > 0 else 0.0
    from scipy.signal import lfilter

    e = rng.standard_normal((n, std.size))
    out = np.empty((n, std.size))
    out[0] = e[0]  # the stationary distribution (unit variance)
    if n > 1:
        b = np.sqrt(1.0 - a * a)
        out[1:] = lfilter([b], [1.0, -a], e[1:], axis=0, zi=a * e[:1])[0]
    return out * std


@dataclass(frozen=True)
class Series:
    """A sampled signal (n, 3) on the grid t = k dt_s (s since the plan start), held between samples."""

    dt_s: float
    values: np.ndarray

    def __call__(self, t_s: np.ndarray) -> np.ndarray:
        k = np.clip(np.floor(np.asarray(t_s) / self.dt_s).astype(int), 0, len(self.values) - 1)
        return self.values[k]


@dataclass(frozen=True)
class RunDraw:
    """Everything run ``index`` of seed ``seed`` draws. Vehicle types map to drawn parameter
    values; per-vehicle maps are keyed by vehicle name."""

    seed: int
    index: int
    parameters: dict[str, dict[str, float]]  # type name -> {param: drawn value}
    start_offset_m: dict[str, tuple[float, float, float]]
    time_offset_s: dict[str, float]
    residual_force_N: dict[str, Series]
    estimate_error_m: dict[str, Series]
    estimate_error_mps: dict[str, Series]
    sim_seed: int  # seed of the simulator's own (logged IMU) noise


def draw_run(
    seed: int,
    index: int,
    vehicles: Mapping[str, tuple[str, Vehicle]],
    duration_s: float,
    *,
    spreads: Spreads = Spreads(),
    noise: NoiseSpec = NoiseSpec(),
) -> RunDraw:
    """Draw run ``index``. ``vehicles`` maps vehicle name -> (type name, Vehicle), in plan order;
    ``duration_s`` covers the flight (plan + settle), s. Draw order is fixed: parameters by sorted
    type, then per vehicle in the given order: start, timing, residual, estimate errors."""
    rng = run_rng(seed, index)
    types: dict[str, Vehicle] = {}
    for type_name, veh in vehicles.values():
        types.setdefault(type_name, veh)
    parameters: dict[str, dict[str, float]] = {}
    for type_name in sorted(types):
        veh = types[type_name]
        values = {}
        for param in MODEL_PARAMETERS:
            nominal = _value(veh, param)
            drawn = nominal + spreads.sigma(type_name, veh, param) * rng.standard_normal()
            if param != "z0_m":  # c_ax, c_rad, b_v are positive: clip the far tail at 10 % of nominal
                drawn = max(drawn, 0.1 * nominal)
            values[param] = float(drawn)
        parameters[type_name] = values
    n = int(np.ceil(duration_s / noise.residual_dt_s)) + 2
    start: dict[str, tuple[float, float, float]] = {}
    timing: dict[str, float] = {}
    residual: dict[str, Series] = {}
    est_m: dict[str, Series] = {}
    est_mps: dict[str, Series] = {}
    for name, (_, veh) in vehicles.items():
        sx, sy, sz = (float(x) for x in noise.start_std_m * rng.standard_normal(3))
        start[name] = (sx, sy, sz)
        timing[name] = float(noise.timing_std_s * rng.standard_normal())
        w = veh.weight_N
        std_f = np.array([noise.residual_std_xy_weight, noise.residual_std_xy_weight, noise.residual_std_z_weight]) * w
        residual[name] = Series(
            noise.residual_dt_s, ou_series(rng, n, noise.residual_dt_s, noise.residual_tau_s, std_f)
        )
        est_m[name] = Series(
            noise.residual_dt_s,
            ou_series(rng, n, noise.residual_dt_s, noise.estimate_tau_s, np.full(3, noise.estimate_std_m)),
        )
        est_mps[name] = Series(
            noise.residual_dt_s,
            ou_series(rng, n, noise.residual_dt_s, noise.estimate_tau_s, np.full(3, noise.estimate_std_mps)),
        )
    sim_seed = int(rng.integers(0, 2**31 - 1))
    return RunDraw(seed, index, parameters, start, timing, residual, est_m, est_mps, sim_seed)
