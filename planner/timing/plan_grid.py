"""The common time grid of plan.json and the assembly of timed paths into a :class:`Plan`."""

from __future__ import annotations

import numpy as np

from proxplan.planfile import Plan, Scenario, VehicleTrajectory
from proxplan.planner.timing.paths import TimedPath, common_grid

DT_S = 0.05  # common time grid of plan.json, s
DOCK_SPEED_FACTOR = 0.5  # final dock approach at this fraction of the vehicle's limits
MOVING_SPEED_MPS = 1e-4  # a vehicle faster than this on a sample moves (the makespan is when the last stops), m/s


def assemble_plan(scenario: Scenario, timed: dict[str, TimedPath], *, method: str, notes: list[str]) -> Plan:
    """Sample every timed path on one common grid (file order of vehicles) into a Plan."""
    end = max([tp.duration_s for tp in timed.values()] + [DT_S])
    grid = common_grid(end, DT_S)
    vehicles = {}
    for name, task in scenario.vehicles.items():
        p, v, a = timed[name].sample(grid)
        vehicles[name] = VehicleTrajectory(name, task.type_name, task.vehicle, grid.copy(), p, v, a)
    notes = list(notes)
    for name, task in scenario.vehicles.items():
        if task.dock_with is not None:
            a_pt, d_pt = scenario.dock_geometry(name)
            notes.append(
                f"dock {name} -> {task.dock_with}: final approach from {np.round(a_pt, 3).tolist()} to "
                f"{np.round(d_pt, 3).tolist()} at {DOCK_SPEED_FACTOR:g} x speed crosses the model's invalid zone "
                f"(dz <= 3 L, S0 II-A); the cutoff rule is suspended for this pair there and verify checks the "
                f"model's extrapolated usage"
            )
    return Plan(
        scenario=scenario.name,
        dt_s=DT_S,
        vehicles=vehicles,
        metrics={},
        method=method,
        notes=notes,
        scenario_file=scenario.source_path,
        scenario_spec=scenario.to_spec(),
    )


def vehicle_arrival_s(tr: VehicleTrajectory) -> float:
    """The time after which ``tr`` no longer moves, s (0 for a vehicle that never moves)."""
    moving = np.flatnonzero(np.linalg.norm(tr.velocity_mps, axis=1) > MOVING_SPEED_MPS)
    return float(tr.t_s[min(int(moving[-1]) + 1, tr.t_s.size - 1)]) if moving.size else 0.0


def moving_end_s(plan: Plan) -> float:
    """The time after which no vehicle of ``plan`` moves any more (DESIGN.md's makespan), s."""
    return max([vehicle_arrival_s(tr) for tr in plan.vehicles.values()] + [0.0])
