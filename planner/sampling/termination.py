"""Deterministic termination and seeding of OMPL: a solve ends after a fixed number of RRT
iterations (CPU time only as a safety net) and OMPL's global RNG is seeded once per process, so a
``proxplan plan`` run is reproducible for a given ``--seed`` whatever the machine's load."""

from __future__ import annotations


class IterationBudget:
    """Planner termination after ``max_calls`` iterations (deterministic, keeps ``--seed``
    reproducible) or, as a safety net only, ``max_wall_s`` seconds of this process's CPU time (not
    wall time, which depends on the machine's load)."""

    def __init__(self, max_calls: int, max_wall_s: float):
        import time

        self.max_calls = max_calls
        self.deadline = time.process_time() + max_wall_s
        self.calls = 0
        self._clock = time.process_time

    def __call__(self) -> bool:
        self.calls += 1
        if self.calls > self.max_calls:
            return True
        return (self.calls & 255) == 0 and self._clock() > self.deadline


_SEEDED: list[int] = []


def seed_ompl_once(seed: int) -> bool:
    """Seed OMPL's global RNG (possible once per process, before any sampling); True if applied.

    Later planners in the same process draw from the continuing seeded sequence, so a whole
    ``proxplan plan`` run is reproducible for a given ``--seed``.
    """
    from ompl import util as ou

    if _SEEDED:
        return _SEEDED[0] == int(seed)
    ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)  # OMPL takes a positive 32-bit seed
    _SEEDED.append(int(seed))
    return True
