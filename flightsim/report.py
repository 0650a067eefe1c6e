"""Metrics of a simulated flight and a PNG of the tracking errors over time.

Per vehicle, over the whole record (the plan plus the settle time after it):
position error |p - p_ref| (max, RMS), altitude error |z - z_ref| (max, RMS), m; time with any
motor command clipped (physics-step resolution), s; the largest authority usage (DESIGN.md
section 3, proxplan.physics.authority) of the disturbance wrench actually applied; the largest motor usage
actually commanded (thrust change from hover over the headroom in that direction, tracking
included: 1 = a motor at its limit); the time spent below another vehicle inside its invalid zone
(dz <= 3 L with overlapping footprints, S0 II-A: the verifier's test), where the applied model
value is an extrapolation. Next to the flown authority usage and invalid-zone time stand what the
plan predicted: the usage of the plan's predicted disturbance (its feed-forward fields, or the
verifier's model) and the same invalid-zone test on the plan's positions. The tracking error is
also split by what the plan predicts: how far the vehicle's closed loop along the plan takes it off
its plan beyond the tube (``proxplan.verify.predicted_tube_growth``: its tracking error along its own
reference, the deviation the jets drive and the growth of a deviation within the tube, the hold after the plan's end; part of the
vehicle's tube where it applies, as the verifier counts it), the largest error where the plan predicts no disturbance (its
predicted force below :data:`UNDISTURBED_FORCE_SHARE` of the vehicle's weight and |d| <=
:data:`UNDISTURBED_M`), and the largest error beyond |d| (to hold within the tube).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from proxplan.fileio import save_figure
from proxplan.physics import authority_usage

USAGE_RATIO_FLOOR = 1e-3  # predicted usage below which a flown/predicted ratio means nothing, -
UNDISTURBED_M = 0.001  # predicted deflection up to which the plan predicts "no disturbance", m
UNDISTURBED_FORCE_SHARE = 0.005  # predicted force (share of the weight) up to which it does, -


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
    predicted_max_authority_usage: float  # of the plan's predicted disturbance (model at the plan), -
    predicted_time_in_invalid_zone_s: float  # the same invalid-zone test on the plan's positions, s
    usage_ratio_flown_to_predicted: float | None  # max flown / max predicted (None: predicted < 1e-3)
    predicted_max_deflection_m: float = 0.0  # largest predicted tube growth in the jets (verify's), m
    max_error_undisturbed_m: float = 0.0  # largest position error where |d| <= UNDISTURBED_M, m
    max_error_beyond_deflection_m: float = 0.0  # largest (position error - |d|), m
    tube_m: float = 0.0  # the tube the verifier granted (limits.tracking_margin_m; else the type's), m
    left_tube_by_m: float = 0.0  # largest (position error - |d| - tube), >= 0: the tube failed, m


def motor_usage(vehicle, cmd_motor_thrust_N: np.ndarray) -> np.ndarray:
    """Commanded motor usage (M,): max over motors of the thrust change from hover divided by the
    headroom in that direction (up to f_max, down to f_min), -."""
    hover = vehicle.hover_thrust_per_rotor_N
    up = vehicle.max_thrust_per_rotor_N - hover
    down = hover - vehicle.min_motor_thrust_N
    change = cmd_motor_thrust_N - hover
    return np.where(change > 0, change / up, -change / down).max(axis=1)


def invalid_zone_mask(result, name: str, *, planned: bool = False) -> np.ndarray:
    """(M,) True where ``name`` flies in another vehicle's invalid zone (dz <= 3 L with
    overlapping footprints, proxplan.physics.invalid_zone_mask: the verifier's test), flown or, with
    ``planned``, on the plan's reference positions. The simulator applies the model's
    (extrapolated) value there."""
    from proxplan.physics import invalid_zone_mask as zone

    key = "ref_position_m" if planned else "position_m"
    rec = result.records[name]
    bad = np.zeros(rec.t_s.size, dtype=bool)
    for other, orec in result.records.items():
        if other != name:
            bad |= zone(orec.vehicle, rec.vehicle, getattr(rec, key) - getattr(orec, key))
    return bad


def invalid_zone_time_s(result, name: str, *, planned: bool = False) -> float:
    """Time (log resolution) ``name`` spends in another vehicle's invalid zone (flown or planned), s."""
    return float(invalid_zone_mask(result, name, planned=planned).sum() * result.options.log_dt_s)


def vehicle_metrics(
    record, saturation_time_s: float, invalid_s: float = 0.0, predicted_invalid_s: float = 0.0
) -> VehicleMetrics:
    err = record.position_m - record.ref_position_m
    pos = np.linalg.norm(err, axis=1)
    alt = np.abs(err[:, 2])
    usage = authority_usage(record.vehicle, record.applied_force_N, record.applied_torque_Nm)
    predicted = 0.0
    if record.predicted_force_N is not None and record.predicted_torque_Nm is not None:
        predicted = max(
            0.0, float(authority_usage(record.vehicle, record.predicted_force_N, record.predicted_torque_Nm).max())
        )
    flown = max(0.0, float(usage.max()))  # (-0.0 of a vehicle nothing acts on)
    defl = predicted_deflection_m(record)
    calm = undisturbed(record, defl)
    return VehicleMetrics(
        type=record.type_name,
        max_position_error_m=float(pos.max()),
        rms_position_error_m=float(np.sqrt(np.mean(pos**2))),
        max_altitude_error_m=float(alt.max()),
        rms_altitude_error_m=float(np.sqrt(np.mean(alt**2))),
        motor_saturation_time_s=float(saturation_time_s),
        max_authority_usage=flown,
        max_motor_usage=float(motor_usage(record.vehicle, record.cmd_motor_thrust_N).max()),
        max_disturbance_force_N=float(np.linalg.norm(record.applied_force_N, axis=1).max()),
        time_in_invalid_zone_s=float(invalid_s),
        predicted_max_authority_usage=predicted,
        predicted_time_in_invalid_zone_s=float(predicted_invalid_s),
        usage_ratio_flown_to_predicted=flown / predicted if predicted > USAGE_RATIO_FLOOR else None,
        predicted_max_deflection_m=float(defl[np.isfinite(defl)].max(initial=0.0)),
        max_error_undisturbed_m=float(pos[calm].max()) if calm.any() else 0.0,
        max_error_beyond_deflection_m=float((pos - defl).max()),
        tube_m=record_tube_m(record),
        left_tube_by_m=max(0.0, float((pos - defl).max()) - record_tube_m(record)),
    )


def undisturbed(record, deflection_m: np.ndarray) -> np.ndarray:
    """(M,) True where the plan predicts no disturbance on ``record``'s vehicle: its predicted force
    within :data:`UNDISTURBED_FORCE_SHARE` of the weight and its deflection within :data:`UNDISTURBED_M`."""
    calm = deflection_m <= UNDISTURBED_M
    if record.predicted_force_N is not None:
        force = np.linalg.norm(record.predicted_force_N, axis=1)
        calm &= force <= UNDISTURBED_FORCE_SHARE * record.vehicle.weight_N
    return calm


def predicted_deflection_m(record) -> np.ndarray:
    """(M,), m: how far the plan predicts ``record``'s vehicle beyond its tube (its closed loop
    along the plan, its own reference and the jets, ``proxplan.verify.predicted_tube_growth``; zeros without a prediction)."""
    if record.predicted_deflection_m is None:
        return np.zeros(record.t_s.size)
    return np.asarray(record.predicted_deflection_m, dtype=float)


def record_tube_m(record) -> float:
    """The tube ``record``'s vehicle was granted, m: the verifier's (``limits.tracking_margin_m``),
    else its type's measured tube."""
    return float(record.tube_m) if record.tube_m is not None else float(record.vehicle.tracking_tube_m)


def simulation_metrics(result) -> dict[str, VehicleMetrics]:
    """:class:`VehicleMetrics` of every vehicle of a :class:`proxplan.flightsim.simulate.SimulationResult`."""
    return {
        n: vehicle_metrics(
            r,
            result.saturation_time_s[n],
            invalid_zone_time_s(result, n),
            invalid_zone_time_s(result, n, planned=True),
        )
        for n, r in result.records.items()
    }


def summary_dict(
    result, *, plan_path: str | None = None, plot_path: str | None = None, manifest_path: str | None = None
) -> dict:
    """The JSON summary of ``proxplan simulate`` (a vehicle that left its tube + predicted
    deflection is named in the notes: the tube is a planning allowance that failed)."""
    metrics = simulation_metrics(result)
    left = [
        f"{n}: its closed loop is not damped in the jet where it holds at the end (verify: jet-loop), nothing "
        "bounds its flight after the plan's end"
        for n, r in result.records.items()
        if r.predicted_deflection_m is not None and np.isinf(r.predicted_deflection_m).any()
    ]
    left += [
        f"{n} left its tube ({100 * m.tube_m:.1f} cm + its predicted deflection, up to {100 * m.predicted_max_deflection_m:.1f} cm) "
        f"by up to {100 * m.left_tube_by_m:.1f} cm"
        for n, m in metrics.items()
        if m.left_tube_by_m > 0.0
    ]
    return {
        "scenario": result.scenario,
        "status": result.status.value,
        "status_detail": result.status_detail,
        "plan": plan_path,
        "truth": result.truth.to_dict(),
        "controller": result.options.controller,
        "drag_compensation": result.options.drag_compensation,
        "max_setpoint_lead_m": dict(result.max_lead_m),
        "physics_dt_s": result.options.physics_dt_s,
        "log_dt_s": result.options.log_dt_s,
        "plan_duration_s": result.plan_duration_s,
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "real_time_factor": result.real_time_factor,
        "vehicles": {n: asdict(m) for n, m in metrics.items()},
        "plot": plot_path,
        "logs_manifest": manifest_path,
        "notes": list(result.notes) + left,
    }


def feedforward_comparison(without, with_ff) -> dict:
    """Tracking errors of the same flight without and with feed-forward of the predicted
    disturbance: per vehicle ``{"without": {...}, "with": {...}, "altitude_error_factor",
    "position_error_factor"}`` (factor = without / with, None when "with" is 0) and the most disturbed
    vehicle: the one receiving the largest disturbance (max authority usage of the applied wrench
    without feed-forward; ties and undisturbed flights: the largest max altitude error). Not the
    largest altitude error alone: with the rate feed-forward a vehicle's own climbs and descents
    (rotor drag, induced inflow) can out-weigh the downwash another one receives."""
    keys = ("max_position_error_m", "rms_position_error_m", "max_altitude_error_m", "rms_altitude_error_m")
    a, b = simulation_metrics(without), simulation_metrics(with_ff)
    vehicles = {}
    for name in a:
        wo = {k: getattr(a[name], k) for k in keys}
        wi = {k: getattr(b[name], k) for k in keys}
        vehicles[name] = {
            "without": wo,
            "with": wi,
            "altitude_error_factor": _ratio(wo["max_altitude_error_m"], wi["max_altitude_error_m"]),
            "position_error_factor": _ratio(wo["max_position_error_m"], wi["max_position_error_m"]),
        }
    worst = max(a, key=lambda n: (a[n].max_authority_usage, a[n].max_altitude_error_m)) if a else None
    return {"vehicles": vehicles, "most_disturbed": worst}


def _ratio(num: float, den: float) -> float | None:
    return num / den if den > 1e-12 else None


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
