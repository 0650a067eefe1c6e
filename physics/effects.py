"""Shared library of aerodynamic effects beyond the base downwash model (DESIGN.md section 6).

One implementation serves two users: the closed-loop simulator adds chosen effects to the world as
"truth" (so plans are stress-tested against a world that differs from the planner's model), and the
identification stage tries them as candidate explanations of the residual in flight data.

Frames and conventions: world frame, z up. The target hovers (approximately) level with its body
axes aligned to the world axes, as in :mod:`proxplan.physics.disturbance`; forces are in N, torques in N m
about the target's centre of mass, both expressed in the world frame. ``offsets_m`` are
``p_target - p_source`` (N, 3), m; dz = -offset_z is positive when the target is below the source.

Every :func:`effect_wrench` returns the ADDITIONAL wrench of one effect beyond the base model
(:func:`proxplan.physics.disturbance.disturbance_wrench` summed over the sources); :func:`total_wrench`
returns base + effects. Each effect's parameters, with units in their names, default values and
fit bounds, are listed in :data:`PARAMETERS`; parameters left out of an :class:`Effect` take their
defaults.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.physics.disturbance import (
    oncoming_speed_per_rotor_mps,
    vertical_point_wrench,
)
from proxplan.physics.effect_inputs import (
    BaseCache,
    EffectInputs,
    SourceSample,
    base_source_wrench,
    sum_base,
    zeros_wrench,
)
from proxplan.physics.feature_terms import parse_term_key, term_scale, term_type, weight_scaled
from proxplan.physics.features import CHANNELS, feature_matrix
from proxplan.physics.time_copies import lagged
from proxplan.physics.velocity_field import axial_distance_m

EFFECT_NAMES = (
    "thrust_bias",
    "ground_effect",
    "near_field",
    "wake_swirl",
    "wake_advection",
    "own_velocity",
    "thrust_quadratic",
    "ground_jet",
    "climb_inflow",
    "floor_stagnation",
    "wake_memory",
)

PARAMETERS: dict[str, dict[str, tuple[float, float, float]]] = {
    # param name -> (default, lower bound, upper bound)
    "thrust_bias": {"force_z_N": (0.0, -5.0, 5.0)},
    "ground_effect": {"gain_k": (1.0, 0.0, 4.0)},
    "near_field": {"amplitude": (0.5, 0.0, 5.0), "decay_L": (3.0, 0.2, 30.0)},
    "wake_swirl": {"yaw_per_force_m": (0.02, -0.2, 0.2)},
    "wake_advection": {
        "wind_x_mps": (0.0, -10.0, 10.0),
        "wind_y_mps": (0.0, -10.0, 10.0),
        "convection_speed_mps": (2.0, 0.2, 20.0),
    },
    "own_velocity": {
        "c_w_spm": (0.05, -0.5, 0.5),
        "c_mu_spm": (0.0, -0.5, 0.5),
        "c_mu2_s2pm2": (0.01, -0.2, 0.2),
    },
    "thrust_quadratic": {"b_q_rel_spm": (0.1, -1.0, 1.0)},
    "ground_jet": {"amplitude_1": (0.5, 0.0, 1.0), "decay_L": (2.0, 0.2, 20.0)},
    "climb_inflow": {"gain_1": (1.0, 0.0, 3.0)},
    "floor_stagnation": {"amplitude_1": (1.0, 0.0, 1.0), "decay_widths": (1.0, 0.1, 10.0)},
    "wake_memory": {"share_1": (0.3, -1.0, 1.0)},
}

EFFECT_STRENGTHS: dict[str, tuple[str, ...]] = {
    "thrust_bias": ("force_z_N",),
    "ground_effect": ("gain_k",),
    "near_field": ("amplitude", "decay_L"),
    "wake_swirl": ("yaw_per_force_m",),
    "wake_advection": ("wind_x_mps", "wind_y_mps"),
    "own_velocity": ("c_w_spm", "c_mu_spm", "c_mu2_s2pm2"),
    "thrust_quadratic": ("b_q_rel_spm",),
    "ground_jet": ("amplitude_1", "decay_L"),
    "climb_inflow": ("gain_1",),
    "floor_stagnation": ("amplitude_1", "decay_widths"),
    "wake_memory": ("share_1",),
}
"""Per effect, the parameters whose value 0 switches it off (a decay length of 0 too: the effect then
vanishes at any distance; every other parameter then does nothing): an effect is identified by data
when the interval of at least one of them excludes zero (proxplan.identify.effect_selection)."""

LAG_PARAM = "lag_s"
"""Optional parameter of every library effect: the effect acts ``lag_s`` seconds after its cause (a wake
travelling down, a rotor spinning up; issue 35's "a lag on any effect"). The effect's wrench at time t is
its wrench on the inputs of time t - lag_s (:func:`effect_wrench`), so it needs the inputs' clock
(``EffectInputs.time_s``); a steady state (cost maps, one simulator step, no clock) is the same with or
without a lag. Left out: 0. Not a key of :data:`PARAMETERS` (no shape fit moves it: identification profiles
it over a grid, :mod:`proxplan.identify.effect_selection`)."""
LAG_BOUNDS_S = (0.0, 2.0)
"""Allowed range of :data:`LAG_PARAM`, s: no effect before its cause; the upper end only bounds what a model
file may declare (identification searches :data:`proxplan.physics.time_copies.LAGS_S`, up to 0.85 s)."""

DISCOVERED_PREFIX = "discovered:"
"""Name prefix of a term found by sparse regression (proxplan.identify.discovery): its parameters are named
``"<channel>*<feature>"`` (:mod:`proxplan.physics.features`) and are the coefficients of a linear combination
of features, in channel units per feature unit."""

TARGET_ONLY_EFFECTS = ("thrust_bias", "ground_effect", "own_velocity", "climb_inflow")
"""Effects that depend on the target alone (counted once, whatever the sources); every other effect
is a sum over the sources, and like the base model is zero for a source not above the target."""

MAX_GROUND_EFFECT_RATIO = 2.0
"""Cap on T_IGE / T_OGE: the Cheeseman-Bennett form diverges as the rotor nears the ground, -."""


@dataclass(frozen=True)
class Effect:
    """One named effect with its parameters (missing ones take :data:`PARAMETERS` defaults)."""

    name: str  # one of EFFECT_NAMES, or DISCOVERED_PREFIX + a label (a term of proxplan.physics.features)
    params: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name.startswith(DISCOVERED_PREFIX):
            for key, value in self.params.items():
                parse_term_key(key)
                if not np.isfinite(float(value)):
                    raise ValueError(f"effect {self.name!r}: parameter {key} must be finite")
            return
        if self.name not in PARAMETERS:
            raise ValueError(f"unknown effect {self.name!r}; expected one of {', '.join(EFFECT_NAMES)}")
        unknown = sorted(set(self.params) - set(PARAMETERS[self.name]) - {LAG_PARAM})
        if unknown:
            raise ValueError(
                f"effect {self.name!r}: unknown parameter(s) {', '.join(unknown)}; "
                f"expected {', '.join(PARAMETERS[self.name])} (and optionally {LAG_PARAM})"
            )
        for key, value in self.params.items():
            if not np.isfinite(float(value)):
                raise ValueError(f"effect {self.name!r}: parameter {key} must be finite")
        lag = float(self.params.get(LAG_PARAM, 0.0))
        if not LAG_BOUNDS_S[0] <= lag <= LAG_BOUNDS_S[1]:
            raise ValueError(
                f"effect {self.name!r}: {LAG_PARAM} must be in [{LAG_BOUNDS_S[0]:g}, {LAG_BOUNDS_S[1]:g}] s"
            )

    @property
    def lag_s(self) -> float:
        """Delay of the effect behind its cause, s (:data:`LAG_PARAM`; 0 when not given)."""
        return float(self.params.get(LAG_PARAM, 0.0)) if not self.name.startswith(DISCOVERED_PREFIX) else 0.0

    def without_lag(self) -> Effect:
        """The same effect acting at once (its parameters without :data:`LAG_PARAM`)."""
        return Effect(self.name, {k: v for k, v in self.params.items() if k != LAG_PARAM})

    @property
    def features(self) -> tuple[str, ...]:
        """Features of :mod:`proxplan.physics.features` a discovered term uses (empty for library effects)."""
        if not self.name.startswith(DISCOVERED_PREFIX):
            return ()
        return tuple(dict.fromkeys(parse_term_key(k)[1] for k in self.params))

    def full_params(self) -> dict[str, float]:
        """All parameters of this effect, defaults filled in (:data:`LAG_PARAM` only when given)."""
        if self.name.startswith(DISCOVERED_PREFIX):
            return {k: float(v) for k, v in self.params.items()}
        out = {k: spec[0] for k, spec in PARAMETERS[self.name].items()}
        out.update({k: float(v) for k, v in self.params.items()})
        return out


def default_effect(name: str) -> Effect:
    """The effect ``name`` with its default parameters."""
    return Effect(name, {k: spec[0] for k, spec in PARAMETERS[name].items()})


# --------------------------------------------------------------------------- effects


def _thrust_bias(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """Constant vertical force ``force_z_N`` (N, world z): a thrust-calibration error off by a constant, seen
    by the S0-11 measurement as a steady bias (one force for every vehicle type: what models saved before
    issue 35 hold; identification now fits the error as a per-type scale,
    proxplan.identify.data.Model.thrust_scale, and holds this at 0)."""
    force, torque = zeros_wrench(inputs.n_samples)
    force[:, 2] = p["force_z_N"]
    return force, torque


def _ground_effect(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """Cheeseman-Bennett ground effect: T_IGE / T_OGE = 1 / (1 - k (R / 4h)^2), R rotor radius (m),
    h rotor plane height above ground (m), k = ``gain_k`` (1 in the original method-of-images
    derivation). Applied to the target's hover thrust (its weight, N): Delta F_z = W (ratio - 1),
    capped at ratio <= :data:`MAX_GROUND_EFFECT_RATIO`. No torque (level vehicle, equal heights)."""
    force, torque = zeros_wrench(inputs.n_samples)
    h_m = np.maximum(np.asarray(inputs.height_above_ground_m, dtype=float), 1e-6)
    r_m = inputs.target.propeller.radius_m
    denom = 1.0 - p["gain_k"] * (r_m / (4.0 * h_m)) ** 2
    ratio = np.where(denom > 1.0 / MAX_GROUND_EFFECT_RATIO, 1.0 / np.maximum(denom, 1e-9), MAX_GROUND_EFFECT_RATIO)
    force[:, 2] = inputs.target.weight_N * (ratio - 1.0)
    return force, torque


def _near_field(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """Downwash stronger than the far-field model close to the source (the zone of flow
    establishment, S0 II-A): extra wrench = base source wrench * ``amplitude`` *
    exp(-dz / (``decay_L`` * L_source)) for dz > 0 (target below), zero otherwise; L = 2 x arm (m)."""
    force, torque = zeros_wrench(inputs.n_samples)
    for src, (f, t) in zip(inputs.sources, base.per_source()):
        dz_m = -np.asarray(src.offsets_m, dtype=float).reshape(-1, 3)[:, 2]
        scale = np.where(
            dz_m > 0.0,
            p["amplitude"] * np.exp(-np.maximum(dz_m, 0.0) / (p["decay_L"] * src.vehicle.size_m)),
            0.0,
        )
        force += f * scale[:, None]
        torque += t * scale[:, None]
    return force, torque


def _wake_swirl(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """Yaw torque from the swirl of the source's wake, proportional to the base vertical force it
    causes: tau_z = ``yaw_per_force_m`` * F_z,base (N m; F_z,base < 0 in a downwash, so a positive
    parameter gives a negative, clockwise-from-above torque). No force."""
    force, torque = zeros_wrench(inputs.n_samples)
    for f, _ in base.per_source():
        torque[:, 2] += p["yaw_per_force_m"] * f[:, 2]
    return force, torque


def _wake_advection(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """A steady horizontal wind (``wind_x_mps``, ``wind_y_mps``) carries the wake downstream while
    it descends at ``convection_speed_mps``: at depth dz > 0 the wake axis is displaced by
    wind_xy * dz / convection_speed, so the target sees the base field at the effective offset
    offset_xy - wind_xy * dz / convection_speed. Effect = base(effective) - base(actual)."""
    force, torque = zeros_wrench(inputs.n_samples)
    wind = np.array([p["wind_x_mps"], p["wind_y_mps"]])
    if not np.any(wind):
        return force, torque
    for src, (f0, t0), s in zip(inputs.sources, base.per_source(), base.factors()):
        offsets = np.asarray(src.offsets_m, dtype=float).reshape(-1, 3)
        dz_m = np.maximum(-offsets[:, 2], 0.0)
        shifted = offsets.copy()
        shifted[:, :2] -= wind[None, :] * (dz_m / p["convection_speed_mps"])[:, None]
        f1, t1 = base_source_wrench(SourceSample(src.vehicle, shifted), inputs.target, inputs.options)
        force += f1 * s[:, None] - f0
        torque += t1 * s[:, None] - t0
    return force, torque


def _own_velocity(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """Thrust change of the target with its own motion, after seed 001 eq. 25
    (C_T = C_T0 + C_Tlambda lambda + C_Tmu mu + C_Tw w + C_Tmu2 mu^2, S1-25), written per unit weight:

        Delta F_z = W (-c_w_spm v_z + c_mu_spm |v_xy| + c_mu2_s2pm2 |v_xy|^2),

    W the target's weight (N), v_z its vertical speed (m/s, up positive: climbing raises the inflow
    ratio and lowers thrust for c_w_spm > 0), |v_xy| its horizontal speed (m/s, advance ratio:
    translational lift for positive c_mu). No torque."""
    force, torque = zeros_wrench(inputs.n_samples)
    vel = np.asarray(inputs.velocity_mps, dtype=float).reshape(-1, 3)
    v_xy = np.hypot(vel[:, 0], vel[:, 1])
    force[:, 2] = inputs.target.weight_N * (
        -p["c_w_spm"] * vel[:, 2] + p["c_mu_spm"] * v_xy + p["c_mu2_s2pm2"] * v_xy**2
    )
    return force, torque


def _thrust_quadratic(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """Nonlinear thrust loss in the oncoming downwash, beyond the linear (S0-6):
    Delta f_i = -b_q v_on,i^2 omega_i^2 with b_q = ``b_q_rel_spm`` * b_v of the target
    (b_q in N s^4 m^-2 rad^-2; the parameter, s/m, is the ratio b_q / b_v, so one value suits any
    vehicle), v_on,i the disk-averaged oncoming speed of rotor i (m/s), omega_i^2 the hover value
    (rad^2/s^2). Force and torque via the rotor positions (S0-7, S0-8)."""
    force, torque = zeros_wrench(inputs.n_samples)
    target = inputs.target
    b_q = p["b_q_rel_spm"] * target.b_v
    for src, s in zip(inputs.sources, base.factors()):
        v_on = oncoming_speed_per_rotor_mps(src.vehicle, target, src.offsets_m, inputs.options)
        delta_f = -b_q * v_on**2 * target.hover_omega_sq_rad2ps2 * s[:, None]  # shielded like the base
        f, t = vertical_point_wrench(target.rotor_positions_m, delta_f)
        force += f
        torque += t
    return force, torque


def _ground_jet(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """A source's jet meeting the ground: below the target the jet runs into the floor, stagnates
    and spreads sideways, so at the target (height h above the floor) the axial velocity is below
    the free jet's. Impinging-jet form: v / v_free = 1 - a exp(-h / (lambda L_s)), a =
    ``amplitude_1`` (-), lambda = ``decay_L`` (the stagnation layer's thickness in units of the
    source's size L_s, m); the wrench scales with v^2 (S0-3..S0-6), so the extra wrench is
    base_s * ((1 - a exp(-h / (lambda L_s)))^2 - 1) per source above the target."""
    force, torque = zeros_wrench(inputs.n_samples)
    h_m = np.maximum(np.asarray(inputs.height_above_ground_m, dtype=float), 0.0)
    for src, (f, t) in zip(inputs.sources, base.per_source()):
        ratio = 1.0 - p["amplitude_1"] * np.exp(-h_m / (p["decay_L"] * src.vehicle.size_m))
        scale = ratio**2 - 1.0
        force += f * scale[:, None]
        torque += t * scale[:, None]
    return force, torque


def _floor_stagnation(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """A source's jet stopped by the floor near a target pushed down close to it. An impinging jet
    slows down over a layer above the wall whose thickness scales with the jet's own width there, not
    with the source's size: at the target's height h above the floor the axial speed is
    v / v_free = 1 - a exp(-h / (lambda w)), w = (dz - z0) / sqrt(c_rad) the e-folding radius of the
    S0-2 Gaussian profile at the target's depth (m), a = ``amplitude_1`` (1: the jet stops at the
    floor), lambda = ``decay_widths`` (the layer's thickness in jet widths, -). The wrench scales with
    v^2 (S0-3..S0-6): extra wrench base_s ((1 - a exp(-h / (lambda w)))^2 - 1) per source above the
    target. (The earlier ``ground_jet`` scales the layer with the source's size instead.)"""
    force, torque = zeros_wrench(inputs.n_samples)
    h_m = np.maximum(np.asarray(inputs.height_above_ground_m, dtype=float), 0.0)
    for src, (f, t) in zip(inputs.sources, base.per_source()):
        dz_m = -np.asarray(src.offsets_m, dtype=float).reshape(-1, 3)[:, 2]
        width_m = axial_distance_m(src.vehicle, dz_m) / np.sqrt(src.vehicle.downwash.c_rad)
        ratio = 1.0 - p["amplitude_1"] * np.exp(-h_m / (p["decay_widths"] * width_m))
        scale = ratio**2 - 1.0
        force += f * scale[:, None]
        torque += t * scale[:, None]
    return force, torque


def _climb_inflow(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """The target's own climb in its rotors' oncoming flow. (S0-5, S0-6) take the thrust loss of a rotor
    in an oncoming stream as Delta f_i = -b_v v_on omega_i^2, with v_on the jet's speed; the stream the
    rotor meets is the air RELATIVE to it, so a rotor climbing at v_z meets v_z more (the inflow ratio
    lambda = (w + v_i) / (omega R) of S1-2 / S1-32, its thrust change C_Tw w of S1-25): per rotor
    Delta f_i = -g b_v v_z omega_i^2 with omega_i^2 = f_i / k1, so summed over the rotors

        Delta F_z = -g (b_v / k1) v_z T,

    T the target's collective thrust along world z (N; its weight when unknown), v_z its vertical
    speed (m/s, up positive), g = ``gain_1`` (1: the S0-6 coefficient as calibrated, nothing new fitted).
    A vehicle falling at 1 m/s with its motors near their ceiling (the loss-of-authority regime) gains
    b_v / k1 ~ 7 % of its thrust, one hovering in a climb loses as much. No torque."""
    force, torque = zeros_wrench(inputs.n_samples)
    target = inputs.target
    vel = np.asarray(inputs.velocity_mps, dtype=float).reshape(-1, 3)
    thrust = target.weight_N if inputs.thrust_z_N is None else np.asarray(inputs.thrust_z_N, dtype=float)
    force[:, 2] = -p["gain_1"] * (target.b_v / target.propeller.k1_Ns2prad2) * vel[:, 2] * thrust
    return force, torque


def _wake_memory(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """A share of the downwash felt late: the wake remembers where its source was (Vendruscolo et al., "Wake Up
    to the Past", arXiv 2603.22472: wake memory and a transport delay). Extra wrench = ``share_1`` x the base
    wrench of every source (S0-3..S0-8, shielded as the base), meant with a delay (:data:`LAG_PARAM`): then
    it is the base wrench of ``lag_s`` earlier. At once it is only a rescaling of the base model (its steady
    state: a hover under a source feels 1 + share_1 of the base), which the calibration's parameters
    already hold; identification keeps it only with a delay."""
    force, torque = zeros_wrench(inputs.n_samples)
    for f, t in base.per_source():
        force += p["share_1"] * f
        torque += p["share_1"] * t
    return force, torque


_EFFECT_FUNCTIONS = {
    "thrust_bias": _thrust_bias,
    "ground_effect": _ground_effect,
    "near_field": _near_field,
    "wake_swirl": _wake_swirl,
    "wake_advection": _wake_advection,
    "own_velocity": _own_velocity,
    "thrust_quadratic": _thrust_quadratic,
    "ground_jet": _ground_jet,
    "climb_inflow": _climb_inflow,
    "floor_stagnation": _floor_stagnation,
    "wake_memory": _wake_memory,
}


def _discovered(p: dict[str, float], inputs: EffectInputs, base: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """A discovered term: wrench channel c = sum_j params["c*feature_j"] * feature_j (a weight-scaled key
    ``"c*W*feature_j"`` also times :func:`proxplan.physics.feature_terms.term_scale` of the target; a key ending
    in ``"@<type>"`` only where the target's ``name`` is that type), the features of
    :func:`proxplan.physics.features.feature_matrix` (pairwise ones vanish far from every source)."""
    wrench = np.zeros((inputs.n_samples, 6))
    p = {k: v for k, v in p.items() if term_type(k) in (None, inputs.target.name)}
    if p:
        names = list(dict.fromkeys(parse_term_key(k)[1] for k in p))
        x = feature_matrix(inputs, base.per_source(), names)
        for key, coef in p.items():
            channel, feature = parse_term_key(key)
            scale = term_scale(channel, inputs.target) if weight_scaled(key) else 1.0
            wrench[:, CHANNELS.index(channel)] += coef * scale * x[:, names.index(feature)]
    return wrench[:, :3], wrench[:, 3:]


def _function(name: str):
    return _discovered if name.startswith(DISCOVERED_PREFIX) else _EFFECT_FUNCTIONS[name]


def _apply(effect: Effect, inputs: EffectInputs, cache: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """The wrench of ``effect`` on ``inputs``, delayed by its :data:`LAG_PARAM` along ``inputs.time_s``."""
    params = effect.full_params()
    lag = float(params.pop(LAG_PARAM, 0.0))
    force, torque = _function(effect.name)(params, inputs, cache)
    if lag > 0.0 and inputs.time_s is not None:
        t = np.asarray(inputs.time_s, dtype=float)
        force = np.column_stack([lagged(force[:, k], t, lag) for k in range(3)])
        torque = np.column_stack([lagged(torque[:, k], t, lag) for k in range(3)])
    return force, torque


def effect_wrench(
    effect: Effect, inputs: EffectInputs, *, cache: BaseCache | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """ADDITIONAL force (N, 3), N, and torque (N, 3), N m, of ``effect`` beyond the base model,
    world frame, for the N samples of ``inputs``. ``cache`` (a :class:`BaseCache` of the same
    ``inputs``) reuses the sources' base wrenches across calls (a fit evaluating one effect many times).
    An effect with a :data:`LAG_PARAM` is its wrench on the inputs of ``lag_s`` earlier: the samples must then
    follow each other in time (a full-rate or uniformly strided series; ``time_s`` runs as in
    :func:`proxplan.physics.time_copies.lagged`)."""
    return _apply(effect, inputs, cache if cache is not None else BaseCache(inputs))


def total_wrench(inputs: EffectInputs, effects: Sequence[Effect] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Base model summed over all sources plus every effect in ``effects``: force (N, 3), N, and
    torque (N, 3), N m, world frame."""
    cache = BaseCache(inputs)
    force, torque = sum_base(inputs, cache)
    for effect in effects:
        f, t = _apply(effect, inputs, cache)
        force += f
        torque += t
    return force, torque
