"""A hand-made straight-line plan for trying the viewer (and its tests) without running the planner.

The scenario is DESIGN.md section 4's battery swap (carrier hovering, shuttle docking from above,
a third vehicle crossing); trajectories are straight lines at constant speed, sampled every ``dt_s``.
It is not a planned (or safe) plan: it exists to exercise the viewer.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

DEMO_SPEC: dict[str, Any] = {
    "name": "demo-battery-swap",
    "workspace": {"min": [-3.0, -3.0, 0.0], "max": [3.0, 3.0, 4.0]},
    "obstacles": [{"min": [1.0, -0.5, 0.0], "max": [1.5, 0.5, 2.0]}],
    "limits": {"authority_fraction": 0.4, "min_separation_m": 0.3},
    "vehicles": {
        "carrier": {"type": "large-quad", "start": [0.0, 0.0, 1.5], "hover": True},
        "shuttle": {
            "type": "small-quad",
            "start": [2.0, 1.0, 3.5],
            "dock": {"with": "carrier", "offset": [0.0, 0.0, 1.8]},
        },
        "other": {"type": "small-quad", "start": [-2.0, -1.5, 1.0], "goal": [2.0, -1.5, 1.0]},
    },
}


def demo_positions_m(t_s: np.ndarray) -> dict[str, np.ndarray]:
    """Straight-line positions (N, 3), m, of each demo vehicle on the grid ``t_s`` (N,), s."""
    s = np.clip(t_s / t_s[-1], 0.0, 1.0)[:, None]
    v = DEMO_SPEC["vehicles"]
    dock_goal = np.add(v["carrier"]["start"], v["shuttle"]["dock"]["offset"])
    ends = {
        "carrier": (v["carrier"]["start"], v["carrier"]["start"]),
        "shuttle": (v["shuttle"]["start"], dock_goal),
        "other": (v["other"]["start"], v["other"]["goal"]),
    }
    return {n: np.asarray(a, float) + s * (np.asarray(b, float) - np.asarray(a, float)) for n, (a, b) in ends.items()}


def write_demo_plan(out_dir: str | Path, *, duration_s: float = 8.0, dt_s: float = 0.1) -> Path:
    """Write ``out_dir/plan.json`` (with the scenario embedded) and ``out_dir/scenario.yaml``."""
    import yaml

    from proxplan.planfile import Plan, VehicleTrajectory, scenario_from_dict, write_plan

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scenario_path = out_dir / "scenario.yaml"
    scenario_path.write_text(yaml.safe_dump(DEMO_SPEC, sort_keys=False))
    scenario = scenario_from_dict(DEMO_SPEC, source_path=scenario_path)
    t_s = np.arange(0.0, duration_s + 0.5 * dt_s, dt_s)
    vehicles = {}
    for name, pos in demo_positions_m(t_s).items():
        vel = np.gradient(pos, t_s, axis=0)
        task = scenario.vehicles[name]
        vehicles[name] = VehicleTrajectory(
            name, task.type_name, task.vehicle, t_s, pos, vel, np.gradient(vel, t_s, axis=0)
        )
    plan = Plan(
        scenario=DEMO_SPEC["name"],
        dt_s=dt_s,
        vehicles=vehicles,
        metrics={"planning_time_s": 0.0, "makespan_s": float(t_s[-1])},
        method="hand-made straight lines",
        scenario_file=str(scenario_path.resolve()),
        scenario_spec=scenario.to_spec(),
    )
    return write_plan(plan, out_dir)
