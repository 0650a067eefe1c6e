"""Metrics of a simulated flight and a PNG of the tracking errors over time.

Per vehicle, over the whole record (the plan plus the settle time after it):
position error |p - p_ref| (max, RMS), altitude error |z - z_ref| (max, RMS), m; time with any
motor command clipped (physics-step resolution), s; the largest authority usage (DESIGN.md
section 3, physics.authority) of the disturbance wrench actually applied; the largest motor usage
actually commanded (thrust change from hover over the headroom in that direction, tracking
included: 1 = a motor at its limit); the time spent below another vehicle inside its invalid zone
(dz <= 3 L, S0 II-A), where the applied model value is an extrapolation.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from fileio import save_figure
from physics import authority_usage


@dataclass(frozen=True)
class VehicleMetrics:
    type: str
    max_position_error_m: float
    rms_position_error_m: float
    max_altitude_error_m: float
    rms_altitude_error_m: float
    motor_saturation_time_s: float
    max_authority_usage: float  # of the applied disturbance wrench, -
    max_motor_usage: float  # commanded, tracking included, -
    max_disturbance_force_N: float  # largest |applied external force|, N
    time_in_invalid_zone_s: float  # time below another vehicle within dz <= 3 L of it (S0 II-A), s


def motor_usage(vehicle, cmd_motor_thrust_N: np.ndarray) -> np.ndarray:
    """Commanded motor usage (M,): max over motors of the thrust change from hover divided by the
    headroom in that direction (up to f_max, down to f_min), -."""
    hover = vehicle.hover_thrust_per_rotor_N
    up = vehicle.max_thrust_per_rotor_N - hover
    down = hover - vehicle.min_motor_thrust_N
    change = cmd_motor_thrust_N - hover
    return np.where(change > 0, change / up, -change / down).max(axis=1)


def invalid_zone_mask(result, name: str) -> np.ndarray:
    """(M,) True where ``name`` is below another vehicle inside its invalid zone: 0 < dz <= 3 L of
    that vehicle (S0 II-A), horizontally within half the two sizes plus dz (the wake's spread). The
    simulator still applies the model's (extrapolated) value there."""
    from physics import validity_mask

    rec = result.records[name]
    bad = np.zeros(rec.t_s.size, dtype=bool)
    for other, orec in result.records.items():
        if other == name:
            continue
        offsets = rec.position_m - orec.position_m
        dz = -offsets[:, 2]
        near = np.hypot(offsets[:, 0], offsets[:, 1]) < 0.5 * (rec.vehicle.size_m + orec.vehicle.size_m) + dz
        bad |= (dz > 0) & near & ~validity_mask(orec.vehicle, offsets)
    return bad


def invalid_zone_time_s(result, name: str) -> float:
    """Time (log resolution) ``name`` spends in another vehicle's invalid zone, s."""
    return float(invalid_zone_mask(result, name).sum() * result.options.log_dt_s)


def vehicle_metrics(record, saturation_time_s: float, invalid_s: float = 0.0) -> VehicleMetrics:
    err = record.position_m - record.ref_position_m
    pos = np.linalg.norm(err, axis=1)
    alt = np.abs(err[:, 2])
    usage = authority_usage(record.vehicle, record.applied_force_N, record.applied_torque_Nm)
    return VehicleMetrics(
        type=record.type_name,
        max_position_error_m=float(pos.max()),
        rms_position_error_m=float(np.sqrt(np.mean(pos**2))),
        max_altitude_error_m=float(alt.max()),
        rms_altitude_error_m=float(np.sqrt(np.mean(alt**2))),
        motor_saturation_time_s=float(saturation_time_s),
        max_authority_usage=float(usage.max()),
        max_motor_usage=float(motor_usage(record.vehicle, record.cmd_motor_thrust_N).max()),
        max_disturbance_force_N=float(np.linalg.norm(record.applied_force_N, axis=1).max()),
        time_in_invalid_zone_s=float(invalid_s),
    )


def simulation_metrics(result) -> dict[str, VehicleMetrics]:
    """:class:`VehicleMetrics` of every vehicle of a :class:`flightsim.simulate.SimulationResult`."""
    return {
        n: vehicle_metrics(r, result.saturation_time_s[n], invalid_zone_time_s(result, n))
        for n, r in result.records.items()
    }


def summary_dict(
    result, *, plan_path: str | None = None, plot_path: str | None = None, manifest_path: str | None = None
) -> dict:
    """The JSON summary of ``proxplan simulate``."""
    return {
        "scenario": result.scenario,
        "status": result.status.value,
        "status_detail": result.status_detail,
        "plan": plan_path,
        "truth": result.truth.to_dict(),
        "physics_dt_s": result.options.physics_dt_s,
        "log_dt_s": result.options.log_dt_s,
        "plan_duration_s": result.plan_duration_s,
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "real_time_factor": result.real_time_factor,
        "vehicles": {n: asdict(m) for n, m in simulation_metrics(result).items()},
        "plot": plot_path,
        "logs_manifest": manifest_path,
        "notes": list(result.notes),
    }


def plot_errors(result, path: str | Path) -> Path:
    """PNG of position and altitude error (top) and applied-disturbance authority usage (bottom)
    over time, every vehicle; written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for k, (name, rec) in enumerate(result.records.items()):
        color = f"C{k}"
        err = rec.position_m - rec.ref_position_m
        ax1.plot(rec.t_s, 100 * np.linalg.norm(err, axis=1), color=color, label=f"{name} |position error|")
        ax1.plot(rec.t_s, 100 * err[:, 2], color=color, ls="--", label=f"{name} altitude error")
        usage = authority_usage(rec.vehicle, rec.applied_force_N, rec.applied_torque_Nm)
        ax2.plot(rec.t_s, usage, color=color, label=name)
        bad = invalid_zone_mask(result, name)
        if bad.any():
            ax2.fill_between(
                rec.t_s,
                0,
                1,
                where=bad,
                color=color,
                alpha=0.12,
                lw=0,
                transform=ax2.get_xaxis_transform(),
                label=f"{name} in invalid zone (dz <= 3 L)",
            )
    for ax in (ax1, ax2):
        ax.axvline(result.plan_duration_s, color="0.5", lw=0.8, ls=":")
        ax.grid(alpha=0.3)
    ax1.set_ylabel("tracking error [cm]")
    ax1.legend(fontsize=8, ncol=2)
    ax2.set_ylabel("authority usage of\napplied disturbance [-]")
    ax2.set_xlabel("time since plan start [s] (dotted: plan end)")
    ax2.legend(fontsize=8)
    fig.suptitle(f"{result.scenario}: closed-loop flight ({len(result.records)} vehicles)")
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)
