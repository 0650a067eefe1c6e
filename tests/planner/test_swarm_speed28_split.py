"""Round 28B (issue 37): ``planner/swarm/plan.py`` split into modules with one job each (entry points;
what a plan hands on; the stages in order; the re-timing and repair stages; what the stages give). The
same plans: each case's digest (stage, makespan, every vehicle's knots and positions sampled every
10 ms, rounded to 1e-6) was recorded on main 8cfd46f before the split, for :func:`swarm_timed` and for
:func:`swarm_again` from its hand-on (the re-timed-again path)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import SwarmOptions
from proxplan.planner.swarm import plan as plan_module
from proxplan.planner.swarm.hand_on import level_stacking
from proxplan.planner.swarm.plan import swarm_again, swarm_timed
from proxplan.planner.swarm.retime_stage import HORIZON_MARGIN_S, retime_stage
from proxplan.planner.swarm.stages import level_options

# (layout, vehicles, goals) -> (stage, digest of swarm_timed's plan, of swarm_again's), main 8cfd46f
PLANS = {
    # round 35A: the digest blind to the sign of zero (see circle-16) re-hashes the same plans of two cases, each
    # checked to give its old digest (in the comment) on the same code just before: corridor-12 dce9a4e801defc31,
    # grid-32 db04b66a397f3de8 (grid-16 and the others have no -0.0 and kept theirs)
    ("corridor", 12, "fixed"): ("prioritised", "f02e55d2b5dc673d", "f02e55d2b5dc673d"),
    ("grid", 16, "fixed"): ("stacked", "992d856974eae234", "992d856974eae234"),
    # recorded 26d43be78b7e2a4a on main 8cfd46f's machine; the same code gives e373fcd75be511dc on a fresh machine of
    # stop 70 (AMD EPYC, AVX2; packages installed fresh from the registry; numpy's SIMD and OpenBLAS's kernel
    # switched off give the same e373...: not traced further). Two of its types have two assignments of equal cost,
    # a likely place for such a split. Its plan is not a machine-independent figure, so only what holds on any
    # machine is checked: the stage, and the re-timed-again path giving the same plan.
    # Round 34W: not the goal assignment (swarm_timed does not assign: the flag only steers the stages) nor a float
    # key of a choice (none within 1e-9 on this case; every such key now goes through planner.ties). Probes on the
    # stop-72 machine, all e373fcd75be511dc: OPENBLAS_NUM_THREADS=1 and 2; NPY_DISABLE_CPU_FEATURES=AVX2,FMA3,AVX512*;
    # numpy's sqrt, sin/cos/arctan2/hypot and exp/log/power each 1 ulp up. One that parts it: np.linalg.norm 1 ulp up
    # (non-zero values) in straight.own_straight_track alone -> adc0ab3f46fa848c, with the same step count (92) and
    # the profile's arc moved by 4e-16 m: a comparison downstream is decided at the last bit of a track's position
    # (Ruckig's profile, a compiled library, is such a last bit). Not traced further: still unchecked.
    # Round 35A: no comparison parts it; the plans are the same (positions within 9e-16 m, the same knots): this
    # digest hashed np.round(x, 6)'s bytes, and a position of 0 computed as -2.2e-16 on one machine and 0 on
    # another rounds to -0.0 against 0.0. Flipping the sign of the one zero of v000's x at t = 1.60 s in this
    # machine's digest gives exactly 26d43be78b7e2a4a (8cfd46f's machine), of v014's x at 1.15 s adc0ab3f46fa848c
    # (the norm probe). The digest now adds 0.0 after rounding (-0.0 -> 0.0): corridor-12 and grid-32 re-hashed (above).
    ("circle", 16, "by_type"): ("prioritised", "fe57c25503c9fbb2", "fe57c25503c9fbb2"),
    ("grid", 32, "fixed"): ("stacked", "e90b1e3708cf4277", "e90b1e3708cf4277"),
}


# the digests were recorded before round 29A's routes raised over the others on a level of the stacked plan
# (swarm.raised), which change these plans by design: the split is checked without them
FLAT_LEVELS = SwarmOptions(raised_routes=False)


def _digest(timed, info) -> str:
    """The plan's stage, makespan, knots and positions every 10 ms, each rounded to 1e-6 (s, m) before hashing:
    a different plan moves them by far more, and a BLAS build that rounds the last bit differently does not."""
    h = hashlib.sha256()
    h.update(info.stage.encode())
    h.update(f"{info.makespan_s:.6f}".encode())
    for name in sorted(timed):
        path = timed[name]
        h.update(name.encode())
        h.update((np.round(np.asarray(path.knot_t_s), 6) + 0.0).tobytes())  # + 0.0: -0.0 hashed as 0.0 (round 35A)
        t = np.arange(0.0, path.duration_s + 0.1, 0.01)
        h.update((np.round(np.ascontiguousarray(path.sample(t)[0]), 6) + 0.0).tobytes())
    return h.hexdigest()[:16]


@pytest.mark.parametrize("case", sorted(PLANS), ids=lambda c: f"{c[0]}-{c[1]}-{c[2]}")
def test_the_split_plans_as_main_did(case):
    layout, n, goals = case
    doc = LAYOUTS[layout](n)
    if goals == "by_type":
        doc["assign_goals"] = "by_type"
    sc = scenario_from_dict(doc, label="test")
    timed, info = swarm_timed(sc, FLAT_LEVELS)
    stage, first, again = PLANS[case]
    assert info.stage == stage
    digest = _digest(timed, info)
    assert _digest(*swarm_again(sc, info.hand_on, info.hand_on.options)) == (digest if again is None else again)
    if first is not None:
        assert digest == first


def test_the_names_imported_from_plan_are_the_stages_themselves():
    """refine_repair and benchmarks/why_128.py import these from plan.py: the same objects, not copies."""
    assert plan_module.HORIZON_MARGIN_S == HORIZON_MARGIN_S
    assert plan_module._retime_stage is retime_stage
    assert plan_module._level_options is level_options
    assert plan_module._stacking is level_stacking
