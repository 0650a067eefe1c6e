"""Deterministic termination and seeding of OMPL: a solve ends after a fixed number of RRT
iterations (CPU time only as a safety net), and every search seeds the random generators it creates
from its own seed (:func:`seed_search`), so a plan depends on the scenario and ``--seed`` only:
not on the machine's load, nor on what the same process planned before."""

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


def seed_search(seed: int) -> None:
    """Seed the random generators of the OMPL objects a search creates from now on with ``seed``.

    OMPL gives every generator it creates (a planner's, its state sampler's, a path simplifier's)
    a seed drawn from one process-wide seed sequence; ``ompl.util.RNG.setSeed`` restarts that
    sequence. Called at the start of every search, before it creates any OMPL object, it makes
    the search's draws a function of ``seed`` alone (OMPL logs an error when the sequence is
    restarted after a first use: silenced here, the restart is the point)."""
    from ompl import util as ou

    level = ou.getLogLevel()
    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    try:
        ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)  # OMPL takes a positive 32-bit seed
    finally:
        ou.setLogLevel(level)
