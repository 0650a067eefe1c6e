"""The generated world of the discovery benchmark (:mod:`bench_discovery`): a set's vehicles, motions and log
imperfections (:class:`SetSpec`, :func:`draw_spec`), the undeclared effect hidden in it (:func:`draw_effect`,
:func:`hidden_wrench`: force in N and torque in N m, world frame, at unit amplitude), the logs written
(:func:`make_set`) and the effect's size on the test flight (:func:`effect_rms_on_test`). The families and
their ranges are described in :mod:`bench_discovery`'s docstring.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

FAMILIES = ("lag", "kernel", "velocity", "thrust", "mix")
"""Families an undeclared effect is drawn from (a draw's family cycles through them by seed)."""
TYPES = ("small-quad", "large-quad", "crazyflie-2.1", "crazyflie-parrot")
"""Built-in vehicle types a set mixes (145 g to 650 g)."""
LAG_EFFECTS = ("base", "near_field", "thrust_quadratic", "wake_swirl", "ground_jet")
"""What a ``lag`` draw delays: the base downwash or a library effect."""
DT_S = 0.01
"""Sample period of the generated logs, s."""


# ------------------------------------------------------------------------------ the world of a set


@dataclass(frozen=True)
class SetSpec:
    """Everything that makes one generated set (clean and with its effect)."""

    seed: int
    types: dict[str, str]  # vehicle -> type
    n_train: int
    duration_s: float
    commanded: bool  # logs hold commanded thrust through the motor lag
    thrust_error: dict[str, float]  # type -> relative error of the logged thrust
    accel_noise_mps2: float
    family: str
    effect: dict[str, Any]  # the hidden effect's description (family-specific)
    redraws: tuple[int, ...] = ()  # per flight, which draw of its motions (0 where absent: the scripted world's)


MIN_GAP_L = 1.5
"""Vertical gap between two layers: at least this many times the larger vehicle's size (real flights keep
apart: the Neural-Swarm swaps keep 0.1-0.6 m of vertical gap; the model has no meaning inside a frame)."""


def _motions(
    rng: np.random.Generator, names: list[str], t: np.ndarray, low: bool, sizes: dict[str, float]
) -> dict[str, np.ndarray]:
    """Smooth random motions in layers: a random order of the vehicles from the bottom up, each gap
    1.5-4 times the larger size, a slow vertical wobble, and random horizontal paths (sums of sinusoids of
    0.1-0.4 Hz, up to +-0.45 m: speeds up to about 0.8 m/s, like the Neural-Swarm swaps) that pass the
    vehicles under and over each other; with ``low`` the bottom vehicle dips near the ground in the second
    half."""
    order = list(rng.permutation(names))
    z = {order[0]: rng.uniform(0.5, 0.8)}
    for below, above in zip(order[:-1], order[1:]):
        z[above] = z[below] + rng.uniform(MIN_GAP_L, 4.0) * max(sizes[below], sizes[above])
    out = {}
    for name in names:
        pos = np.zeros((len(t), 3))
        for ax in range(2):
            for _ in range(3):
                f = rng.uniform(0.1, 0.4)
                pos[:, ax] += 0.15 * rng.uniform(0.5, 1.0) * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        pos[:, 2] = z[name] + 0.05 * np.sin(2 * np.pi * rng.uniform(0.05, 0.2) * t + rng.uniform(0, 2 * np.pi))
        if low and name == order[0]:
            blend = 0.5 * (1 + np.tanh((t - 0.6 * t[-1]) / 1.0))
            pos[:, 2] = (1 - blend) * pos[:, 2] + blend * (0.12 + 0.08 * np.sin(2 * np.pi * 0.3 * t))
        out[name] = pos
    return out


def draw_spec(seed: int, family: str) -> SetSpec:
    rng = np.random.default_rng(seed)
    n_veh = int(rng.integers(2, 4))
    names = [f"v{k}" for k in range(n_veh)]
    types = {n: str(rng.choice(TYPES)) for n in names}
    effect = draw_effect(rng, family)
    return SetSpec(
        seed=seed, types=types, n_train=int(rng.choice([3, 4, 6])), duration_s=20.0,
        commanded=bool(rng.random() < 0.5),
        thrust_error={t: float(rng.uniform(-0.05, 0.05)) for t in sorted(set(types.values()))},
        accel_noise_mps2=float(rng.uniform(0.02, 0.05)), family=family, effect=effect,
    )  # fmt: skip


def draw_effect(rng: np.random.Generator, family: str) -> dict[str, Any]:
    if family == "mix":
        a, b = rng.choice(FAMILIES[:4], size=2, replace=False)
        return {"parts": [draw_effect(rng, str(a)), draw_effect(rng, str(b))], "family": "mix"}
    if family == "lag":
        return {"family": family, "inner": str(rng.choice(LAG_EFFECTS)), "lag_s": float(rng.uniform(0.05, 1.0))}
    if family == "kernel":
        return {"family": family, "where": str(rng.choice(["above", "beside", "below"])),
                "radial": str(rng.choice(["gauss", "lorentz", "exp"])), "width_L": float(rng.uniform(0.5, 2.0)),
                "decay": str(rng.choice(["exp", "inv", "inv2"])), "decay_L": float(rng.uniform(1.0, 6.0)),
                "sign": float(rng.choice([-1.0, 1.0])), "torque": bool(rng.random() < 0.25)}  # fmt: skip
    if family == "velocity":
        return {"family": family, "form": str(rng.choice(["v_z", "v_z_abs", "v_xy", "v_xy2", "v_z_v_xy", "rel"])),
                "sign": float(rng.choice([-1.0, 1.0]))}  # fmt: skip
    if family == "thrust":
        where = str(rng.choice(["all", "jet", "ground", "speed"]))
        if where == "jet":  # a spreading Gaussian (width w L + s dz) with or without a decay in depth
            return {"family": family, "where": where, "width_L": float(rng.uniform(0.4, 1.0)),
                    "spread": float(rng.uniform(0.05, 0.25)), "decay": str(rng.choice(["none", "exp", "inv"])),
                    "decay_L": float(rng.uniform(1.0, 6.0))}  # fmt: skip
        if where == "ground":
            return {"family": family, "where": where, "form": str(rng.choice(["exp", "inv2"])),
                    "scale_L": float(rng.uniform(0.5, 2.0))}  # fmt: skip
        if where == "speed":
            return {"family": family, "where": where, "power": int(rng.choice([1, 2]))}
        return {"family": family, "where": where}
    raise ValueError(family)


# ------------------------------------------------------------------------------ hidden effects


def _radial(kind: str, x: np.ndarray) -> np.ndarray:
    return {"gauss": np.exp(-(x**2)), "lorentz": 1.0 / (1.0 + x**2), "exp": np.exp(-np.abs(x))}[kind]


def _decay(kind: str, x: np.ndarray) -> np.ndarray:
    x = np.maximum(x, 0.0)
    return {"exp": np.exp(-x), "inv": 1.0 / (1.0 + x), "inv2": 1.0 / (1.0 + x**2)}[kind]


def _shifted(inputs, lag_s: float):
    """``inputs`` with every time series taken ``lag_s`` earlier (held at the start)."""
    from proxplan.physics import SourceSample

    t = np.asarray(inputs.time_s)

    def back(x):
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            return np.interp(t - lag_s, t, x)
        return np.column_stack([np.interp(t - lag_s, t, x[:, k]) for k in range(x.shape[1])])

    srcs = tuple(SourceSample(s.vehicle, back(s.offsets_m), None if s.velocity_mps is None else back(s.velocity_mps))
                 for s in inputs.sources)  # fmt: skip
    return replace(inputs, height_above_ground_m=back(inputs.height_above_ground_m),
                   velocity_mps=back(inputs.velocity_mps), sources=srcs,
                   position_m=None if inputs.position_m is None else back(inputs.position_m),
                   thrust_z_N=None if inputs.thrust_z_N is None else back(inputs.thrust_z_N))  # fmt: skip


def hidden_wrench(desc: dict[str, Any], inputs) -> tuple[np.ndarray, np.ndarray]:
    """The wrench (force (N, 3) N, torque (N, 3) N m, world) of effect ``desc`` at UNIT amplitude (scaled
    later), on one vehicle's inputs."""
    from proxplan.physics import Effect, base_wrench, default_effect, effect_wrench

    n = inputs.n_samples
    force, torque = np.zeros((n, 3)), np.zeros((n, 3))
    fam = desc["family"]
    W = inputs.target.weight_N
    if fam == "mix":
        for part in desc["parts"]:
            f, tq = hidden_wrench(part, inputs)
            scale = part.get("mix_scale", 1.0)
            force, torque = force + scale * f, torque + scale * tq
        return force, torque
    if fam == "lag":
        shifted = _shifted(inputs, desc["lag_s"])
        if desc["inner"] == "base":
            return base_wrench(shifted)
        eff = default_effect(desc["inner"])
        if desc["inner"] == "near_field":
            eff = Effect("near_field", {"amplitude": 1.0, "decay_L": 3.0})
        if desc["inner"] == "thrust_quadratic":
            eff = Effect("thrust_quadratic", {"b_q_rel_spm": 0.5})
        return effect_wrench(eff, shifted)
    if fam == "kernel":
        for src in inputs.sources:
            off = np.asarray(src.offsets_m)
            L = src.vehicle.size_m
            dz = -off[:, 2]  # > 0: the source is above the target
            r = np.hypot(off[:, 0], off[:, 1])
            where = desc["where"]
            if where == "above":
                depth, gate, radial = dz, dz > 0, r
            elif where == "below":
                depth, gate, radial = -dz, dz < 0, r
            else:  # beside: horizontal distance is the depth, height difference the radial coordinate
                depth, gate, radial = r, np.ones(len(r), dtype=bool), np.abs(dz)
            k = np.where(gate, _radial(desc["radial"], radial / (desc["width_L"] * L))
                         * _decay(desc["decay"], depth / (desc["decay_L"] * L)), 0.0)  # fmt: skip
            if desc["torque"]:
                torque[:, 0] += desc["sign"] * 0.02 * W * L * k * np.tanh(off[:, 1] / L)
            else:
                force[:, 2] += desc["sign"] * W * k
        return force, torque
    if fam == "velocity":
        v = np.asarray(inputs.velocity_mps)
        vxy = np.hypot(v[:, 0], v[:, 1])
        form = desc["form"]
        if form == "rel":
            for src in inputs.sources:
                off = np.asarray(src.offsets_m)
                L = src.vehicle.size_m
                vr = v - np.asarray(src.velocity_mps)
                k = np.exp(-((np.hypot(off[:, 0], off[:, 1]) / L) ** 2)) * np.exp(-np.abs(off[:, 2]) / (3 * L))
                force[:, 2] += desc["sign"] * W * k * np.hypot(vr[:, 0], vr[:, 1])
            return force, torque
        g = {"v_z": v[:, 2], "v_z_abs": v[:, 2] * np.abs(v[:, 2]), "v_xy": vxy, "v_xy2": vxy**2,
             "v_z_v_xy": v[:, 2] * vxy}[form]  # fmt: skip
        force[:, 2] = desc["sign"] * W * g
        return force, torque
    if fam == "thrust":
        thrust = np.asarray(inputs.thrust_z_N)
        where = desc["where"]
        if where == "all":
            h = np.ones(n)
        elif where == "ground":
            x = np.maximum(np.asarray(inputs.height_above_ground_m), 0.0) / (desc["scale_L"] * inputs.target.size_m)
            h = np.exp(-x) if desc["form"] == "exp" else 1.0 / (1.0 + x**2)
        elif where == "speed":
            h = np.hypot(np.asarray(inputs.velocity_mps)[:, 0], np.asarray(inputs.velocity_mps)[:, 1]) ** desc["power"]
        else:
            h = np.zeros(n)
            for src in inputs.sources:
                off = np.asarray(src.offsets_m)
                L = src.vehicle.size_m
                dz = -off[:, 2]
                width = desc["width_L"] * L + desc["spread"] * np.maximum(dz, 0.0)
                along = 1.0 if desc["decay"] == "none" else _decay(desc["decay"], dz / (desc["decay_L"] * L))
                h += np.where(dz > 0, np.exp(-0.5 * (np.hypot(off[:, 0], off[:, 1]) / width) ** 2) * along, 0.0)
        force[:, 2] = -thrust * h
        return force, torque
    raise ValueError(fam)


# ------------------------------------------------------------------------------ one set


def _flight_motions(spec: SetSpec, k: int, sizes: dict[str, float], t: np.ndarray) -> tuple[dict[str, np.ndarray], int]:
    """Flight ``k``'s motions (m, world, per vehicle) and its noise seed: the same for every caller (draw
    ``spec.redraws[k]`` of them; the first, 0, is the scripted world's)."""
    redraw = spec.redraws[k] if k < len(spec.redraws) else 0
    rng = np.random.default_rng([spec.seed, k] if redraw == 0 else [spec.seed, k, redraw])
    motions = _motions(rng, list(sizes), t, bool(k % 2), sizes)
    return motions, int(rng.integers(1 << 30))


def make_set(spec: SetSpec, root: Path, amplitude: float | None) -> Path:
    """Write the set (clean when ``amplitude`` is None) under ``root``; returns its manifest."""
    from proxplan.identify import synthetic_logs, write_synthetic_manifest
    from proxplan.physics import BUILTIN_VEHICLES

    vehicles = {n: BUILTIN_VEHICLES[t] for n, t in spec.types.items()}
    t = np.arange(0.0, spec.duration_s, DT_S)
    hidden = None if amplitude is None else (lambda inputs: _scaled(hidden_wrench(spec.effect, inputs), amplitude))
    flights = []
    for k in range(spec.n_train + 1):
        motions, noise_seed = _flight_motions(spec, k, {n: v.size_m for n, v in vehicles.items()}, t)
        taus = {n: (v.motor_time_constant_s if spec.commanded else None) for n, v in vehicles.items()}
        logs = {}
        for tau in set(taus.values()):  # each vehicle's commands through ITS motors' lag (what identify declares)
            made = synthetic_logs(vehicles, motions, t, hidden_wrench=hidden, accel_noise_mps2=spec.accel_noise_mps2,
                                  motor_noise_N=0.002, seed=noise_seed, motor_time_constant_s=tau)  # fmt: skip
            logs |= {n: made[n] for n in vehicles if taus[n] == tau}
        for name, log in logs.items():  # the thrust map's error, per vehicle type
            logs[name] = replace(log, motor_thrust_N=log.motor_thrust_N * (1.0 + spec.thrust_error[spec.types[name]]))
        flights.append((f"f{k}", "test" if k == spec.n_train else "train", logs))
    root.mkdir(parents=True, exist_ok=True)
    return write_synthetic_manifest(root, flights, spec.types,
                                    motor_thrust="commanded" if spec.commanded else "delivered")  # fmt: skip


def _scaled(w: tuple[np.ndarray, np.ndarray], a: float) -> tuple[np.ndarray, np.ndarray]:
    return w[0] * a, w[1] * a


def flight_inputs(spec: SetSpec, k: int) -> dict[str, Any]:
    """Each vehicle's :class:`proxplan.physics.EffectInputs` on flight ``k`` (the exact motions, no noise)."""
    from proxplan.physics import BUILTIN_VEHICLES

    vehicles = {n: BUILTIN_VEHICLES[t] for n, t in spec.types.items()}
    t = np.arange(0.0, spec.duration_s, DT_S)
    motions, _ = _flight_motions(spec, k, {n: v.size_m for n, v in vehicles.items()}, t)
    return motion_inputs(vehicles, motions, t)


def motion_inputs(
    vehicles: dict[str, Any],
    positions_m: dict[str, np.ndarray],
    t_s: np.ndarray,
    velocities_mps: dict[str, np.ndarray] | None = None,
    accelerations_mps2: dict[str, np.ndarray] | None = None,
) -> dict[str, Any]:
    """Each vehicle's :class:`proxplan.physics.EffectInputs` for positions (N, 3) m, world, on the clock ``t_s``
    (N,) s, every other vehicle a source: the height above a floor at z = 0, the velocity (given, m/s, or the
    positions' derivative), the vertical thrust its motion calls for m (g + a_z), N (a_z given, m/s^2, or the
    velocity's derivative)."""
    from proxplan.physics import GRAVITY_MPS2, EffectInputs, SourceSample

    vels = velocities_mps or {n: np.gradient(p, t_s, axis=0) for n, p in positions_m.items()}
    accs = accelerations_mps2 or {n: np.gradient(v, t_s, axis=0) for n, v in vels.items()}
    out = {}
    for name, veh in vehicles.items():
        pos = positions_m[name]
        out[name] = EffectInputs(target=veh, height_above_ground_m=pos[:, 2], velocity_mps=vels[name],
                                 sources=tuple(SourceSample(vehicles[o], pos - positions_m[o], vels[o])
                                               for o in vehicles if o != name),
                                 time_s=t_s, thrust_z_N=veh.mass_kg * (GRAVITY_MPS2 + accs[name][:, 2]),
                                 position_m=pos)  # fmt: skip
    return out


def effect_rms(spec: SetSpec, k: int) -> dict[str, tuple[float, float]]:
    """RMS of the unit-amplitude hidden F_z (N) and of its torque's norm (N m) per vehicle on flight ``k``
    (``spec.n_train``: the test flight)."""
    out = {}
    for name, inputs in flight_inputs(spec, k).items():
        f, tq = hidden_wrench(spec.effect, inputs)
        out[name] = (float(np.sqrt(np.mean(f[:, 2] ** 2))), float(np.sqrt(np.mean(np.sum(tq**2, axis=1)))))
    return out


def flyable_amplitude(spec: SetSpec) -> float:
    """The largest amplitude (-, the factor on :func:`hidden_wrench`) of an effect a hovering vehicle could hold
    against, on every sample of every flight of the set: the (S0-14) mixer's motor thrusts for the hover thrust
    minus the effect's F_z and against its torque stay within [``min_motor_thrust_N``, ``max_thrust_N`` / rotors]
    of the vehicle's type. Affine in the amplitude, so exact; ``inf`` where the effect loads no motor. (Judged at
    hover, not on the flight: the generated motions under another vehicle's jet may already need more than the
    motors give, which is the world's, not the effect's.) A larger effect could not be flown, so its logs could
    not exist; until stop 60 the amplitude was set on the test flight alone, and the tail of a Gaussian there
    asked for 458x the vehicle's weight on a train flight (seed 19001)."""
    from proxplan.physics import mixer_matrix

    bound = np.inf
    for k in range(spec.n_train + 1):
        for inputs in flight_inputs(spec, k).values():
            veh = inputs.target
            f, tq = hidden_wrench(spec.effect, inputs)
            slope = np.linalg.solve(mixer_matrix(veh), np.column_stack([-f[:, 2], -tq]).T).T  # N per unit amplitude
            hover = veh.weight_N / veh.n_rotors
            up, down = veh.max_thrust_N / veh.n_rotors - hover, veh.min_motor_thrust_N - hover
            with np.errstate(divide="ignore"):
                room = np.where(slope > 0, up / slope, np.where(slope < 0, down / slope, np.inf))
            bound = min(bound, float(np.min(room)))
    return bound


def effect_rms_on_test(spec: SetSpec) -> dict[str, tuple[float, float]]:
    """:func:`effect_rms` on the test flight."""
    return effect_rms(spec, spec.n_train)
