"""Set-point export for streaming controllers (PX4 offboard ``TrajectorySetpoint``, ROS 2): one CSV
per vehicle with time, position, velocity, acceleration and the predicted downwash force and torque
(feed-forward), sampled from the plan at a fixed rate.

Columns: ``t_s, x_m, y_m, z_m, vx_mps, vy_mps, vz_mps, ax_mps2, ay_mps2, az_mps2, drag_ax_mps2,
drag_ay_mps2, drag_az_mps2, ff_fx_N, ff_fy_N, ff_fz_N, ff_tx_Nm, ff_ty_Nm, ff_tz_Nm``; world frame
(x, y horizontal, z up; convert to PX4's NED when streaming).

* ``a*_mps2`` is the acceleration feed-forward to stream: the plan's acceleration plus, with drag
  compensation (default), the rotor-drag term ``drag_a*_mps2`` = c v (c per axis from the vehicle's
  rotor drag, ``Vehicle.drag_rate_ps``, 1/s; :func:`proxplan.planfile.drag_feedforward_mps2`). A
  controller with acceleration feed-forward then delivers the force that drag takes and tracks the
  plan's positions without the drag lag; the plan's own acceleration is ``a - drag_a``.
* ``ff_*`` is the disturbance wrench the model predicts *on* the vehicle at that set-point (the
  same model as ``proxplan verify``, S0-3..S0-8, summed over the vehicles above it); a controller
  compensates it by subtracting it from its force / moment command.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from proxplan.fileio import atomic_write_text
from proxplan.planfile import Plan, Scenario, drag_feedforward_mps2
from proxplan.verify import wrench_along_plan

SETPOINT_COLUMNS = (
    "t_s", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps", "ax_mps2", "ay_mps2", "az_mps2",
    "drag_ax_mps2", "drag_ay_mps2", "drag_az_mps2", "ff_fx_N", "ff_fy_N", "ff_fz_N", "ff_tx_Nm", "ff_ty_Nm", "ff_tz_Nm",
)  # fmt: skip
DEFAULT_RATE_HZ = 50.0


def setpoint_times(plan: Plan, rate_hz: float) -> np.ndarray:
    """Uniform times (M,), s, from the plan's start to its end (included) at ``rate_hz``, Hz."""
    t0, t1 = float(plan.t_s[0]), float(plan.t_s[-1])
    n = int(np.floor((t1 - t0) * rate_hz + 1e-9)) + 1
    t = t0 + np.arange(n) / rate_hz
    return t if t[-1] >= t1 - 1e-9 else np.append(t, t1)


def feedforward_wrench(plan: Plan, scenario: Scenario, t_s: np.ndarray) -> tuple[dict[str, np.ndarray], str]:
    """Per vehicle the predicted disturbance (force_N (M, 3) | torque_Nm (M, 3)) as (M, 6) at ``t_s``,
    and where it came from (a note): plan.json's stored feed-forward fields (linear between plan
    samples) when every vehicle has them, else recomputed with the verifier's model."""
    if all(tr.has_feedforward for tr in plan.vehicles.values()):
        wrench = {}
        for name, tr in plan.vehicles.items():
            assert tr.disturbance_force_N is not None and tr.disturbance_torque_Nm is not None
            stored = np.hstack([tr.disturbance_force_N, tr.disturbance_torque_Nm])
            wrench[name] = np.column_stack([np.interp(t_s, tr.t_s, stored[:, k]) for k in range(6)])
        return wrench, "feed-forward wrench from plan.json's disturbance_force_N / disturbance_torque_Nm"
    along = wrench_along_plan(plan, scenario, t_s=t_s)
    wrench = {name: np.hstack([w.force_N, w.torque_Nm]) for name, w in along.items()}
    note = (
        "plan.json has no feed-forward fields (older version): feed-forward wrench recomputed with the "
        "verifier's model (proxplan.verify.wrench_along_plan) along the plan"
    )
    return wrench, note


def export_setpoints(
    plan: Plan,
    scenario: Scenario,
    folder: str | Path,
    *,
    rate_hz: float = DEFAULT_RATE_HZ,
    drag_compensation: bool = True,
) -> tuple[dict, list[str]]:
    """Write ``NAME_setpoints.csv`` per vehicle into ``folder``; returns ({vehicle: {file, rows,
    max_drag_accel_mps2}}, notes)."""
    t = setpoint_times(plan, rate_hz)
    wrench, note = feedforward_wrench(plan, scenario, t)
    summary = {}
    for name, tr in plan.vehicles.items():
        p, v, a = tr.sample(t)
        drag = drag_feedforward_mps2(tr, t) if drag_compensation else np.zeros_like(a)
        table = np.hstack([t[:, None], p, v, a + drag, drag, wrench[name]])
        table[np.abs(table) < 1e-12] = 0.0  # no 1e-235 noise in a set-point file
        buf = io.StringIO()
        np.savetxt(buf, table, delimiter=",", header=",".join(SETPOINT_COLUMNS), comments="", fmt="%.9g")
        file = f"{name}_setpoints.csv"
        atomic_write_text(Path(folder) / file, buf.getvalue())
        summary[name] = {
            "file": file,
            "rows": int(t.size),
            "max_deviation_m": 0.0,
            "max_drag_accel_mps2": float(np.linalg.norm(drag, axis=1).max()),
        }
    how = (
        "acceleration columns carry the rotor-drag feed-forward c v (drag_a*_mps2; the plan's acceleration is a - drag_a)"
        if drag_compensation
        else "no drag compensation: acceleration columns are the plan's, drag_a*_mps2 are 0"
    )
    return summary, [note, how]
