"""The idle-motor check of a log of COMMANDED thrust judges the thrust the motors deliver (stop 64)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from proxplan.identify.log_checks import QualityOptions, check_log
from proxplan.identify.vehicle_log import VehicleLog
from proxplan.physics import BUILTIN_VEHICLES

PARROT = BUILTIN_VEHICLES["crazyflie-parrot"]


def _hover_with_dip(dip_samples: int, n: int = 400) -> VehicleLog:
    """Hovering 0.7 m up at 100 Hz; the command drops to zero for ``dip_samples`` samples at sample 200 (a swing
    of a command through the motors' lag: what a controller asks while a neighbour passes close)."""
    t = 0.01 * np.arange(n)
    thrust = np.full((n, 4), PARROT.hover_thrust_per_rotor_N)
    thrust[200 : 200 + dip_samples] = 0.0
    return VehicleLog(
        t_s=t,
        position_m=np.column_stack([0 * t, 0 * t, 0.7 + 0 * t]),
        velocity_mps=np.zeros((n, 3)),
        accel_mps2=np.tile([0.0, 0.0, 9.81], (n, 1)),
        quat_xyzw=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
        motor_thrust_N=thrust,
        gyro_radps=np.zeros((n, 3)),
    )


def test_a_command_dip_shorter_than_the_lag_is_no_idle_motor() -> None:
    """One 10 ms command at zero, 0.7 m up: as delivered thrust it is idle (one sample dropped, the log split);
    through the Parrot's 72 ms lag the motors never fall below the idle share (30 % of W), nothing is dropped."""
    tau = PARROT.motor_time_constant_s
    log = _hover_with_dip(1)
    delivered, ex_d = check_log(log, weight_N=PARROT.weight_N)
    assert ex_d.ground_samples == 1 and len(np.unique(delivered.segment)) == 2
    commanded, ex_c = check_log(log, weight_N=PARROT.weight_N, motor_time_constant_s=tau)
    assert ex_c.ground_samples == 0 and len(commanded) == len(log) and len(np.unique(commanded.segment)) == 1


def test_motors_idle_for_longer_than_the_lag_are_still_idle() -> None:
    """A command at zero for 0.5 s (7 lags): the delivered thrust falls below the idle share within ~1.2 lags
    (0.3 = exp(-t / tau)), so the whole stretch is idle in both readings, from its first sample (a cut to land)."""
    log = _hover_with_dip(50)
    _, ex_d = check_log(log, weight_N=PARROT.weight_N)
    _, ex_c = check_log(log, weight_N=PARROT.weight_N, motor_time_constant_s=PARROT.motor_time_constant_s)
    assert ex_d.ground_samples == 50 and ex_c.ground_samples == 50


def test_on_the_ground_is_ground_whatever_the_motors() -> None:
    """Ground contact is judged by height, with or without a lag."""
    log = _hover_with_dip(0)
    pos = log.position_m.copy()
    pos[:100, 2] = 0.01
    grounded = replace(log, position_m=pos)
    _, ex = check_log(grounded, weight_N=PARROT.weight_N, motor_time_constant_s=PARROT.motor_time_constant_s)
    assert ex.ground_samples == 100 and QualityOptions().ground_clearance_m > 0.01
