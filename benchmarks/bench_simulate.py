"""Speed of the closed-loop simulation: two vehicles, 500 Hz physics, downwash every step.

Prints real-time factors (simulated s per wall-clock s) of
  * baseline: RotorPy's own classes stepped per vehicle (SE3Control.update + Multirotor.step via
    scipy solve_ivp, the external wrench from proxplan.physics.effects.total_wrench at every step),
  * proxplan.flightsim.simulate_plan with the wrench evaluated every step (horizon 1) and batched over
    10 steps at predicted positions (the default), with no truth effects and with all of them,
and their ratios to the baseline measured in the same run; then 8 vehicles (4 swapping pairs). Optionally (``--plans``) flies the
battery-swap plans of the planner (sampling, no-downwash, optimized) and prints the carrier's max
altitude error.

Run: python benchmarks/bench_simulate.py [--seconds 4] [--plans]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from proxplan.flightsim import load_truth_file, simulate_plan, swap_plan
from proxplan.flightsim.vehicle_params import quad_params
from proxplan.physics import BUILTIN_VEHICLES, EffectInputs, SourceSample, total_wrench

REPO = Path(__file__).resolve().parents[1]


def baseline_rtf(sim_s: float) -> float:
    """RotorPy's classes, one vehicle at a time, 500 Hz, wrench every step (hover stack)."""
    from rotorpy.controllers.quadrotor_control import SE3Control

    from proxplan.flightsim.dynamics import ExternalWrenchMultirotor

    vehs = [BUILTIN_VEHICLES["crazyflie-2.1"], BUILTIN_VEHICLES["crazyflie-parrot"]]
    pos = [np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, 1.0])]
    models, ctrls, states = [], [], []
    for v, p0 in zip(vehs, pos):
        p = quad_params(v)
        models.append(ExternalWrenchMultirotor(p, aero=True))
        ctrls.append(SE3Control(p))
        w = np.sqrt(v.hover_thrust_per_rotor_N / p["k_eta"])
        states.append(
            {
                "x": p0.copy(),
                "v": np.zeros(3),
                "q": np.array([0, 0, 0, 1.0]),
                "w": np.zeros(3),
                "wind": np.zeros(3),
                "rotor_speeds": np.full(4, w),
            }
        )
    dt = 0.002
    n = int(round(sim_s / dt))
    t0 = time.perf_counter()
    for _ in range(n):
        for i in range(2):
            j = 1 - i
            inp = EffectInputs(
                vehs[i],
                np.array([states[i]["x"][2]]),
                states[i]["v"][None],
                (SourceSample(vehs[j], (states[i]["x"] - states[j]["x"])[None]),),
            )
            f, t = total_wrench(inp)
            models[i].ext_force_N = f[0]
            models[i].ext_torque_Nm = t[0]
            flat = {
                "x": pos[i],
                "x_dot": np.zeros(3),
                "x_ddot": np.zeros(3),
                "x_dddot": np.zeros(3),
                "x_ddddot": np.zeros(3),
                "yaw": 0.0,
                "yaw_dot": 0.0,
            }
            cmd = ctrls[i].update(0.0, states[i], flat)
            states[i] = models[i].step(states[i], cmd, dt)
    return sim_s / (time.perf_counter() - t0)


def ours_rtf(plan, **kw) -> float:
    simulate_plan(plan, settle_s=0.0, **kw)  # compile the stepper once
    return simulate_plan(plan, settle_s=0.0, **kw).real_time_factor


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated time per measurement, s")
    ap.add_argument("--plans", action="store_true", help="also fly the planner's battery-swap plans")
    args = ap.parse_args()
    base = baseline_rtf(min(args.seconds, 1.0))
    print(f"baseline (RotorPy step + SE3Control per vehicle): {base:6.2f}x real time")
    plan = swap_plan(vertical_gap_m=0.4, swap_s=max(args.seconds - 1.0, 1.0) / 1, n_swaps=1, hold_s=0.5)
    truth = load_truth_file(REPO / "examples" / "truth" / "all_effects.yaml")
    for label, kw in (
        ("flightsim, wrench every step (horizon 1)", {"wrench_horizon_steps": 1}),
        ("flightsim, default (horizon 10)", {}),
        ("flightsim, default + all truth effects", {"truth": truth}),
    ):
        rtf = ours_rtf(plan, **kw)
        print(f"{label:<44}: {rtf:6.1f}x real time  ({rtf / base:5.1f}x baseline)")
    eight = eight_vehicle_plan(swap_s=max(args.seconds - 1.0, 1.0))
    rtf8 = ours_rtf(eight)
    print(f"{'flightsim, 8 vehicles (4 swapping pairs)':<44}: {rtf8:6.1f}x real time")
    if args.plans:
        fly_planner_plans()


def eight_vehicle_plan(*, swap_s: float):
    """Four Neural-Swarm-like swapping pairs side by side, 1 m apart (8 vehicles)."""
    from proxplan.planfile import Plan

    vehicles = {}
    for k in range(4):
        pair = swap_plan(vertical_gap_m=0.4, swap_s=swap_s, n_swaps=1, hold_s=0.5, centre_m=(1.0 * k, 0.0, 1.0))
        for name, tr in pair.vehicles.items():
            vehicles[f"{name}{k}"] = type(tr)(
                f"{name}{k}", tr.type_name, tr.vehicle, tr.t_s, tr.position_m, tr.velocity_mps, tr.acceleration_mps2
            )
    return Plan("eight", pair.dt_s, vehicles)


def fly_planner_plans() -> None:
    import subprocess
    import tempfile

    scen = REPO / "scenarios" / "battery_swap.yaml"
    with tempfile.TemporaryDirectory() as tmp:
        for method in ("optimized", "sampling", "no-downwash"):
            out = Path(tmp) / method
            proc = subprocess.run(
                ["proxplan", "plan", str(scen), "--out", str(out), "--method", method, "--json"],
                capture_output=True,
                text=True,
                timeout=600,
            )
            if proc.returncode != 0:
                print(f"battery swap, {method}: planner failed ({proc.stderr.strip().splitlines()[-1:]})")
                continue
            res = simulate_plan(out / "plan.json", imu_noise=False)
            for name, rec in res.records.items():
                alt = np.abs(rec.position_m[:, 2] - rec.ref_position_m[:, 2])
                print(
                    f"battery swap, {method:<12} {name:<8}: max altitude error {100 * alt.max():5.2f} cm, "
                    f"max |F| {np.linalg.norm(rec.applied_force_N, axis=1).max():.3f} N"
                )


if __name__ == "__main__":
    main()
