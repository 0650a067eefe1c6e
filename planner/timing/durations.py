"""Time-optimal rest-to-rest durations over straight distances, tabulated with Ruckig (cached per
limits): the lower bounds and edge times of the planners' searches."""

from __future__ import annotations

import math

from proxplan.physics import KinematicLimits


class DurationTable:
    """Time-optimal rest-to-rest duration over a straight distance, tabulated with Ruckig.

    ``duration_s(d)`` returns the tabulated duration at the next grid distance above ``d`` (m),
    so it is never shorter than the optimum and Ruckig can always meet it as a minimum duration.
    """

    def __init__(self, limits: KinematicLimits, *, max_distance_m: float = 20.0, step_m: float = 0.01):
        from ruckig import InputParameter, Ruckig, Trajectory

        self.step_m = step_m
        n = int(math.ceil(max_distance_m / step_m)) + 1
        otg, inp, traj = Ruckig(1), InputParameter(1), Trajectory(1)
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = (
            [limits.max_speed_mps],
            [limits.max_accel_mps2],
            [limits.max_jerk_mps3],
        )
        table = [0.0]
        for k in range(1, n):
            inp.current_position, inp.target_position = [0.0], [k * step_m]
            otg.calculate(inp, traj)
            table.append(float(traj.duration) * 1.0005 + 1e-6)
        self.table = table

    def duration_s(self, distance_m: float) -> float:
        if distance_m <= 0.0:
            return 0.0
        k = int(math.ceil(distance_m / self.step_m))
        if k >= len(self.table):
            return self.table[-1] * distance_m / ((len(self.table) - 1) * self.step_m)
        return self.table[k]


def min_segment_duration_s(distance_m: float, limits: KinematicLimits) -> float:
    """Time-optimal rest-to-rest duration over ``distance_m`` (m) for the norm limits, s."""
    return duration_table(limits).duration_s(distance_m)


_TABLES: dict[KinematicLimits, DurationTable] = {}


def duration_table(limits: KinematicLimits) -> DurationTable:
    """The (cached) :class:`DurationTable` of ``limits``."""
    if limits not in _TABLES:
        _TABLES[limits] = DurationTable(limits)
    return _TABLES[limits]
