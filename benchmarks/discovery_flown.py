"""The FLOWN world of the discovery benchmark (``bench_discovery.py --world closed-loop``): the draws of
:mod:`discovery_world` (vehicles, motions, effect) flown closed loop in :mod:`proxplan.flightsim`, the effect a
residual wrench the simulator evaluates on the vehicles' own states (:func:`make_set_closed_loop`), and what a
vehicle can fly (:func:`_under_control`, :data:`MOTION_REDRAWS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from discovery_world import DT_S, SetSpec, _flight_motions, hidden_wrench, motion_inputs

MOTION_REDRAWS = 8
"""Draws of a flight's motions the closed-loop world tries before it calls the set not flyable: a flight whose
clean flown twin leaves a vehicle not under control (:func:`_under_control`) is drawn again (``spec.redraws``),
as a pilot would not fly it; the effect set flies the same draws. A count, not a threshold, -."""
UNDER_CONTROL_SATURATED_SHARE = 0.5
"""A flown vehicle whose motors sit at a limit on more than this share of its samples is not under control:
its controller's demand goes unmet most of the time (the majority rule, as selection's other 1/2s). A set
holding such a flight is not flyable (``most_saturated_share``): the scripted motions put a light vehicle in a
heavy one's jet that it cannot hold against (draw 81002: a 67 g vehicle under a 650 g one, saturated on 84 % of
its samples and 145 m off its path), which no real log would hold, -."""
CLOSED_LOOP_CONTROLLER = "rotorpy"
"""The tracking law of the closed-loop world (:data:`proxplan.flightsim.CONTROLLERS`): RotorPy's SE(3)
controller, whose gains follow each vehicle's mass and inertia. The Mellinger law carries the Crazyflie
firmware's gains: on these motions the 145 g small-quad saturates its motors with them (1400 of 10 000 physics
steps) and ends metres off its path, which is a controller the vehicle would not fly with."""


def _motion_plan(spec: SetSpec, vehicles: dict[str, Any], motions: dict[str, np.ndarray], t: np.ndarray):
    """The flight's scripted motions (m, world, on clock ``t`` s) as a plan the simulated vehicles track."""
    from proxplan.planfile import Plan, VehicleTrajectory

    trajs = {}
    for name, pos in motions.items():
        vel = np.gradient(pos, t, axis=0)
        trajs[name] = VehicleTrajectory(
            name, spec.types[name], vehicles[name], t, pos, vel, np.gradient(vel, t, axis=0)
        )
    return Plan(f"discovery-{spec.seed}", DT_S, trajs, method="synthetic")


def _wrench_on_flown(spec: SetSpec, result: Any, amplitude: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The hidden effect's wrench at ``amplitude`` on each vehicle of a simulated flight, on its recorded (true)
    states: force (N, 3) N and torque (N, 3) N m, world."""
    recs = result.records
    t = next(iter(recs.values())).t_s
    inputs = motion_inputs({n: r.vehicle for n, r in recs.items()}, {n: r.position_m for n, r in recs.items()}, t,
                           {n: r.velocity_mps for n, r in recs.items()},
                           {n: r.acceleration_mps2 for n, r in recs.items()})  # fmt: skip
    wrenches = {n: hidden_wrench(spec.effect, x) for n, x in inputs.items()}
    return {n: (amplitude * force_N, amplitude * torque_Nm) for n, (force_N, torque_Nm) in wrenches.items()}


def _max_lag_s(desc: dict[str, Any]) -> float:
    """The longest delay (s) of effect ``desc`` (0 without one)."""
    if desc["family"] == "mix":
        return max(_max_lag_s(p) for p in desc["parts"])
    return float(desc.get("lag_s", 0.0))


@dataclass
class _HiddenWrench:
    """The hidden effect at ``amplitude`` as :attr:`proxplan.flightsim.Perturbation.wrench_of_state`: its force and
    torque, evaluated by :func:`hidden_wrench` on the states the simulator predicts over each wrench horizon (a few
    milliseconds), with the flight's own past for a delay (the state at each earlier horizon's start, kept for the
    effect's longest delay). ``vehicles``: name -> :class:`proxplan.physics.Vehicle` in the plan's order."""

    effect: dict[str, Any]
    vehicles: dict[str, Any]
    amplitude: float
    past: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)

    def __call__(
        self, t: np.ndarray, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        keep_s = _max_lag_s(self.effect) + 2.0 * float(t[-1] - t[0] + 1e-9)
        self.past = [p for p in self.past if p[0] >= t[0] - keep_s]
        times = np.array([p[0] for p in self.past] + list(t))
        stacked = [np.concatenate([np.array([p[i] for p in self.past]).reshape(-1, *pos.shape[1:]), x])
                   for i, x in ((1, pos), (2, vel), (3, acc))]  # fmt: skip
        self.past.append((float(t[0]), pos[0], vel[0], acc[0]))
        names = list(self.vehicles)
        inputs = motion_inputs(self.vehicles, {n: stacked[0][:, i] for i, n in enumerate(names)}, times,
                               {n: stacked[1][:, i] for i, n in enumerate(names)},
                               {n: stacked[2][:, i] for i, n in enumerate(names)})  # fmt: skip
        force_N, torque_Nm = np.zeros_like(pos), np.zeros_like(pos)
        for i, n in enumerate(names):
            f, tq = hidden_wrench(self.effect, inputs[n])
            force_N[:, i], torque_Nm[:, i] = self.amplitude * f[-len(t) :], self.amplitude * tq[-len(t) :]
        return force_N, torque_Nm


def make_set_closed_loop(spec: SetSpec, root: Path, amplitude: float | None) -> tuple[Path, dict[str, Any]]:
    """The set flown CLOSED LOOP (:func:`proxplan.flightsim.simulate_plan`: RotorPy dynamics under
    :data:`CLOSED_LOOP_CONTROLLER`, motor dynamics and IMU noise), clean when ``amplitude`` is None: each flight's
    scripted motions (:func:`_flight_motions`) become a plan the vehicles track, and the world's downwash is
    the base model's. The effect (``spec.effect``, force and torque as drawn) is a residual wrench the simulator
    evaluates on the vehicles' own states as it flies them (:class:`_HiddenWrench`, with their past for a
    delay). The logs are what :func:`proxplan.flightsim.write_flight_logs` writes (commanded or delivered
    thrust as ``spec.commanded``); unlike :func:`discovery_world.make_set` they hold no thrust-map error
    (``spec.thrust_error`` is not applied). Returns the manifest and ``{"applied_mismatch": RMS of the force
    applied minus the effect's on the recorded states, over the effect's RMS, every vehicle and flight pooled (the
    horizon's prediction and the past's sampling), -; "applied_torque_mismatch": the same for the torque (0 for an
    effect without one), -; "most_saturated_share": the largest share of samples any
    vehicle of any flight spent with a motor at a limit, -; "flyable": every vehicle of every flight under control
    (:func:`_under_control`); "redraws": per flight, the draw of its motions flown (:data:`MOTION_REDRAWS`: the
    clean set chooses them, the effect set is given them in ``spec.redraws``)}``."""
    from proxplan.flightsim import Perturbation, simulate_plan, write_flight_logs
    from proxplan.physics import BUILTIN_VEHICLES

    vehicles = {n: BUILTIN_VEHICLES[t] for n, t in spec.types.items()}
    sizes = {n: v.size_m for n, v in vehicles.items()}
    t = np.arange(0.0, spec.duration_s, DT_S)
    logged = "commanded" if spec.commanded else "actual"
    manifest = root / "manifest.yaml"
    left, size = np.zeros(2), np.zeros(2)  # squared mismatch and effect: force N^2, torque (N m)^2
    saturated, redraws, flyable = 0.0, list(spec.redraws), True
    root.mkdir(parents=True, exist_ok=True)
    for k in range(spec.n_train + 1):
        tries = [redraws[k]] if k < len(redraws) else range(MOTION_REDRAWS)
        for redraw in tries:  # the first draw of the flight's motions a vehicle can fly
            here = replace(spec, redraws=(*redraws[:k], redraw))
            motions, noise_seed = _flight_motions(here, k, sizes, t)
            plan = _motion_plan(spec, vehicles, motions, t)
            flown = simulate_plan(plan, seed=noise_seed, controller=CLOSED_LOOP_CONTROLLER)
            if _under_control(flown):
                break
        redraws[k:] = [redraw]
        flyable = flyable and _under_control(flown)
        if amplitude is not None:
            hidden = _HiddenWrench(spec.effect, dict(zip(plan.vehicles, vehicles.values())), amplitude)
            flown = simulate_plan(plan, seed=noise_seed, controller=CLOSED_LOOP_CONTROLLER,
                                  perturbation=Perturbation(wrench_of_state=hidden))  # fmt: skip
            felt = _wrench_on_flown(spec, flown, amplitude)
            for n, r in flown.records.items():
                applied = (r.applied_force_N - r.model_force_N, r.applied_torque_Nm - r.model_torque_Nm)
                for i in range(2):
                    left[i] += float(np.sum((felt[n][i] - applied[i]) ** 2))
                    size[i] += float(np.sum(felt[n][i] ** 2))
            flyable = flyable and _under_control(flown)
        saturated = max([saturated] + [float(np.mean(r.saturated)) for r in flown.records.values()])
        manifest = write_flight_logs(flown, root, flight_name=f"f{k}", split="test" if k == spec.n_train else "train",
                                     seed=noise_seed, logged_thrust=logged)  # fmt: skip
    force_mis, torque_mis = (float(np.sqrt(left[i] / size[i])) if size[i] > 0.0 else 0.0 for i in range(2))
    return manifest, {"applied_mismatch": force_mis, "applied_torque_mismatch": torque_mis,
                      "most_saturated_share": saturated, "flyable": flyable, "redraws": redraws}  # fmt: skip


def _under_control(result: Any) -> bool:
    """Whether every vehicle of a simulated flight flew it to the end with its motors at a limit on at most
    :data:`UNDER_CONTROL_SATURATED_SHARE` of its samples."""
    from proxplan.flightsim import SimulationStatus

    return result.status == SimulationStatus.COMPLETE and all(
        float(np.mean(r.saturated)) <= UNDER_CONTROL_SATURATED_SHARE for r in result.records.values()
    )
