"""Statistics of the residual disturbance the model does not explain, measured on real logs; they
set :class:`proxplan.certify.draws.NoiseSpec`'s residual process (``python -m proxplan.certify.residuals``).

Method: the Neural-Swarm single-vehicle flights (``takeoff_s``, ``takeoff_l``: no other vehicle, so
the base model predicts zero) are measured with :func:`proxplan.identify.measure_log` (S0-11 with the logged
motor forces). Samples count when the vehicle is at least ``min_height_m`` above the ground plane
(out of ground effect: > 8 rotor diameters for both vehicles) and slower than ``max_speed_mps`` (a
hover). Per flight, the mean force is removed (a thrust-calibration bias, which ``identify``
calibrates as ``thrust_bias``); what is left is the residual. Reported per vehicle type: the
residual std along z and along x/y as a fraction of the weight, and the correlation time: the lag
where the autocorrelation of the z residual over the longest contiguous hover stretch first drops
below 1/e (the Ornstein-Uhlenbeck time constant).

The residual includes the measurement's own noise (accelerometer, motor-force model), so it
over- rather than under-states the unexplained force: a conservative choice for certification.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from proxplan.identify import measure_log, read_log
from proxplan.physics import BUILTIN_VEHICLES

DEFAULT_ROOT = Path(__file__).resolve().parents[2] / "shared" / "data" / "neural-swarm"
FLIGHTS = {"takeoff_s": "crazyflie-2.1", "takeoff_l": "crazyflie-parrot"}
GROUND_Z_M = {"takeoff_s": 0.05, "takeoff_l": 0.06}  # ground plane height in the mocap frame (data README)


@dataclass(frozen=True)
class ResidualStats:
    vehicle_type: str
    flights: int
    samples: int
    std_z_weight: float  # residual force std along z / weight, -
    std_xy_weight: float  # residual force std along x and y (pooled) / weight, -
    tau_s: float  # median 1/e correlation time of the z residual, s


def _acf_time_s(x: np.ndarray, dt_s: float) -> float:
    x = x - x.mean()
    acf = np.correlate(x, x, "full")[x.size - 1 :] / float(x @ x)
    below = np.flatnonzero(acf < np.exp(-1.0))
    return float(below[0] * dt_s) if below.size else float("nan")


def residual_statistics(
    root: str | Path = DEFAULT_ROOT, *, min_height_m: float = 0.35, max_speed_mps: float = 0.2
) -> dict[str, ResidualStats]:
    """:class:`ResidualStats` per vehicle type from the single-vehicle flights under ``root``."""
    out = {}
    for folder, type_name in FLIGHTS.items():
        veh = BUILTIN_VEHICLES[type_name]
        z_res, xy_res, taus = [], [], []
        files = sorted((Path(root) / folder).glob("*.csv.gz"))
        for path in files:
            log = read_log(path)
            log = log.take(np.all(np.isfinite(log.position_m), axis=1) & np.all(np.isfinite(log.accel_mps2), axis=1))
            force = measure_log(veh, log).force_N
            hover = (log.position_m[:, 2] - GROUND_Z_M[folder] > min_height_m) & (
                np.linalg.norm(log.velocity_mps, axis=1) < max_speed_mps
            )
            if hover.sum() < 50:
                continue
            f = force[hover] - force[hover].mean(axis=0)
            z_res.append(f[:, 2])
            xy_res.append(f[:, :2].ravel())
            idx = np.flatnonzero(hover)
            runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
            longest = max(runs, key=len)
            taus.append(_acf_time_s(force[longest, 2], float(np.median(np.diff(log.t_s)))))
        if not z_res:
            continue
        z = np.concatenate(z_res)
        out[type_name] = ResidualStats(
            vehicle_type=type_name,
            flights=len(z_res),
            samples=int(z.size),
            std_z_weight=float(z.std() / veh.weight_N),
            std_xy_weight=float(np.concatenate(xy_res).std() / veh.weight_N),
            tau_s=float(np.nanmedian(taus)),
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="residual disturbance statistics of the Neural-Swarm hover logs")
    parser.add_argument("--root", default=str(DEFAULT_ROOT), help="neural-swarm data folder")
    args = parser.parse_args(argv)
    stats = residual_statistics(args.root)
    print(json.dumps({k: asdict(v) for k, v in stats.items()}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
