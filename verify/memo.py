"""The verifier's answer for the plan it checked last, given back when asked about the same plan again
(:func:`proxplan.verify.verify_with_deflections`).

The swarm layer's guard of the makespan repair on the stacked plan
(:class:`proxplan.planner.swarm.verify_guard.VerifyGuard`) verifies the whole repaired plan, and the
pipeline's verification policy then verifies the very same plan again (grid-256: 20-25 s of CPU for
the same answer; stop 61 round 23A). The verifier is a function of what it reads: the scenario, the
fine step, and per vehicle its name, type, parameters and sampled trajectory (times, positions,
velocities, accelerations, predicted disturbances), the plan's step and whether it is a predicted
flight read back. :class:`VerifyMemo` keys the last answer on exactly those (the scenario by
identity, held so that its id cannot be reused, and by a digest of what the verifier reads of it, in
case it was changed in place; the arrays by a BLAKE2b digest of their bytes, dtypes and shapes) and hands out copies, so a caller that changes what it got cannot change what the next
one gets. One slot: the plan asked twice in a row is the case it serves.
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from proxplan.planfile import PREDICTED_FLIGHT_KEY, Plan, Scenario

# digest size of the plan's arrays, bytes (BLAKE2b's largest: a collision is not a practical concern)
DIGEST_BYTES = 64

__all__ = ["DIGEST_BYTES", "VerifyMemo", "plan_key", "scenario_key"]

Answer = tuple[list, dict[str, np.ndarray]]


def plan_key(plan: Plan, dt_fine_s: float) -> tuple:
    """What the verifier reads of ``plan`` (checked at ``dt_fine_s``, s) besides the scenario: the
    vehicles in order (name, type name, parameters) and a digest of every sampled array."""
    h = hashlib.blake2b(digest_size=DIGEST_BYTES)
    heads = []
    for name, tr in plan.vehicles.items():
        heads.append((name, tr.type_name, tr.vehicle))
        for arr in (
            tr.t_s,
            tr.position_m,
            tr.velocity_mps,
            tr.acceleration_mps2,
            tr.disturbance_force_N,
            tr.disturbance_torque_Nm,
        ):
            if arr is None:
                h.update(b"none")
                continue
            a = np.ascontiguousarray(arr)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
    flight = bool(plan.metrics.get(PREDICTED_FLIGHT_KEY))
    return (float(dt_fine_s), float(plan.dt_s), flight, tuple(heads), h.digest())


def scenario_key(scenario: Scenario) -> bytes:
    """A digest of what the verifier reads of ``scenario`` (workspace, obstacles, limits, the vehicles'
    tasks in order, the model's options and effects): a scenario held by the memo and changed in place
    since (its ``vehicles`` dict, its arrays) is not the one answered for."""
    parts = (
        np.asarray(scenario.workspace_min_m).tolist(),
        np.asarray(scenario.workspace_max_m).tolist(),
        scenario.obstacles,
        scenario.limits,
        tuple(scenario.vehicles.items()),
        scenario.field_form,
        scenario.effects,
        scenario.stack_shielding,
    )
    with np.printoptions(threshold=sys.maxsize, precision=17):
        text = repr(parts)
    return hashlib.blake2b(text.encode(), digest_size=DIGEST_BYTES).digest()


@dataclass
class VerifyMemo:
    """The last (scenario, plan key) -> answer (violations, deflections per vehicle); counts the
    answers given back (``hits``) and computed (``misses``)."""

    _scenario: Scenario | None = None
    _key: tuple | None = None
    _answer: Answer | None = None
    hits: int = 0
    misses: int = 0

    def get(self, plan: Plan, scenario: Scenario, dt_fine_s: float, verify: Callable[[], Answer]) -> Answer:
        """The answer of ``verify()`` for ``plan`` on ``scenario`` at ``dt_fine_s``: the one kept when
        the last plan asked was the same, else computed and kept (copies either way)."""
        key = (plan_key(plan, dt_fine_s), scenario_key(scenario))
        if self._answer is not None and self._scenario is scenario and self._key == key:
            self.hits += 1
        else:
            self.misses += 1
            out, loops = verify()
            self._scenario, self._key, self._answer = scenario, key, (list(out), dict(loops))
        out, loops = self._answer
        return list(out), {n: d.copy() for n, d in loops.items()}
