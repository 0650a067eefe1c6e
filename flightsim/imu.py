"""IMU model: the equations of RotorPy's ``rotorpy.sensors.imu.Imu.measurement`` (IMU at the centre
of mass, sensor axes = body axes), vectorised over samples, with white noise and constant bias.

    accel = R^T (a_world - g_world) + bias_a + noise_a     (specific force, body frame, m/s^2)
    gyro  = w_body + bias_g + noise_g                       (body frame, rad/s)

with g_world = (0, 0, -9.81) m/s^2, so a hovering vehicle reads about +9.81 on body z.
Calling RotorPy's ``Imu`` per sample costs ~0.1 ms (and uses numpy's global random state); tests
check these equations against it with noise off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

GRAVITY_WORLD_MPS2 = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class ImuOptions:
    """Noise of the logged IMU samples (one sample per log step). Defaults: the sample-to-sample
    spread of the Neural-Swarm Crazyflie hover logs at 100 Hz (about 0.1 m/s^2 and 0.015 rad/s,
    ``diff / sqrt 2`` of ``swap_ss`` and ``takeoff_s`` hover stretches)."""

    accel_noise_std_mps2: float = 0.1  # white noise per sample, each axis, m/s^2
    gyro_noise_std_radps: float = 0.015  # white noise per sample, each axis, rad/s
    accel_bias_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)  # constant bias, body frame, m/s^2
    gyro_bias_radps: tuple[float, float, float] = (0.0, 0.0, 0.0)  # constant bias, body frame, rad/s


def imu_samples(
    q_xyzw: np.ndarray,
    w_body_radps: np.ndarray,
    accel_world_mps2: np.ndarray,
    *,
    options: ImuOptions = ImuOptions(),
    rng: np.random.Generator | None = None,
    with_noise: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Accelerometer (M, 3) m/s^2 and gyro (M, 3) rad/s, body frame, for attitudes (M, 4)
    [x, y, z, w], body rates (M, 3) rad/s and true accelerations (M, 3) m/s^2, world frame."""
    rot = Rotation.from_quat(q_xyzw)
    accel = rot.inv().apply(accel_world_mps2 - GRAVITY_WORLD_MPS2) + np.asarray(options.accel_bias_mps2)
    gyro = np.asarray(w_body_radps, dtype=float) + np.asarray(options.gyro_bias_radps)
    if with_noise:
        rng = np.random.default_rng() if rng is None else rng
        accel = accel + rng.normal(scale=options.accel_noise_std_mps2, size=accel.shape)
        gyro = gyro + rng.normal(scale=options.gyro_noise_std_radps, size=gyro.shape)
    return accel, gyro
