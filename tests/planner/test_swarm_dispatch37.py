"""Round 37V (issue 37: "the same seed gives the same plan on any machine"): numpy picks its SIMD kernels at run
time, and a float made through them may differ in its last bits from one set of kernels to another (rounds 37S,
37U: the tracking bound, 5.5e-15 m on a keep-out's w between the AVX-512 and the AVX2 kernels, flipped a right
angle's cosine in timing.corners and parted pillar-256 by type). A test cannot switch the kernels once numpy is
imported, but a child python started with ``NPY_DISABLE_CPU_FEATURES`` can: the child here runs without the
highest group of kernels this machine has (the AVX-512 ones where present, else AVX2 / FMA3) and must give

- the same tracking bounds and keep-outs, bit for bit (the bound is rounded up where it is made,
  :data:`proxplan.planner.swarm.tracking_bound.TRACKING_BOUND_RESOLUTION_M`), on pillar-8 (three types);
- the same two-way lane plans (:func:`proxplan.planner.swarm.lanes.lanes_stage`: lane routes with right-angle
  corners, offsets built from the keep-outs' w) on pillar-8 and circle-24, digest of the grid tracks to 1e-6 m;
- the digests recorded in ``test_swarm_speed28_split.PLANS`` for corridor-12 (prioritised) and grid-16 (stacked);
- (round 37W) the same deflection allowance, bit for bit, of a plan that fails verify: scenarios/swap_8.yaml
  planned "no-downwash" (separation only; 7 violations), the verifier's deflections made into the allowance as
  ``pipeline._until_verified`` does after a failed verify (it grows the re-plan's keep-outs). The allowance is
  rounded up where it is made (:data:`proxplan.planner.metrics.DEFLECTION_RESOLUTION_M`); the raw deflections
  differ between the AVX-512 and the AVX2 kernels in 6 of 8 vehicles (cf7: 0x1.1322c9d5bbae2p-6 vs
  0x1.1322c9d5bbb03p-6 m).

What it guards, measured on an AVX-512 machine (round 37V): with the rounding of the bound undone, the keep-outs
differ between the two kernels (the first assertion fails); with that and round 37U's rounding of the right
angle's cosine undone, the lane plans part too: pillar-8 5.275 s (AVX-512) vs 5.375 s (AVX2), circle-24
6.9 s vs 6.275 s."""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from proxplan.planfile import load_scenario, scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.metrics import DEFLECTION_DT_S, DEFLECTION_RESOLUTION_M, deflection_allowance
from proxplan.planner.pipeline import plan_scenario
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.lanes import lanes_stage
from proxplan.planner.swarm.plan import swarm_timed
from proxplan.planner.swarm.problem import tracking_growth_m
from proxplan.planner.swarm.tracking_bound import TRACKING_BOUND_RESOLUTION_M
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.ties import rounded_up
from proxplan.planner.timing.profile import rest_to_rest
from proxplan.verify import verify_with_deflections

from .test_swarm_speed28_split import FLAT_LEVELS, PLANS, _digest

try:  # numpy >= 2
    _umath = importlib.import_module("numpy._core._multiarray_umath")
except ImportError:  # numpy 1.x
    _umath = importlib.import_module("numpy.core._multiarray_umath")

ENV = "NPY_DISABLE_CPU_FEATURES"
KEEPOUT_CASE = ("pillar", 8)  # three vehicle types: nine keep-outs
LANE_CASES = [("pillar", 8), ("circle", 24)]
PLAN_CASES = [("corridor", 12, "fixed"), ("grid", 16, "fixed")]
DEFLECTION_CASE = ("swap_8", "no-downwash")  # scenarios/<name>.yaml and the method of a plan that fails verify
REPORT_TAG = "DISPATCH37:"  # the child's report line on stdout
CHILD_TIMEOUT_S = 300.0  # s; the child takes about 10 s on a loaded 2-core machine


def highest_group() -> list[str]:
    """The names to give ``NPY_DISABLE_CPU_FEATURES`` to switch off the highest group of SIMD kernels numpy
    dispatches to on this machine: among numpy's dispatch targets (``__cpu_dispatch__``, the only names it
    accepts; baseline ones raise, others are ignored with a warning) those enabled now, the AVX-512 ones if any
    (numpy 2: X86_V4, AVX512_ICL, AVX512_SPR; 1.x: AVX512F, AVX512_SKX, ...), else the AVX2 / FMA3 ones
    (X86_V3; 1.x: AVX2, FMA3). Empty when there is none (not x86, or a build without them)."""
    if platform.machine().lower() not in ("x86_64", "amd64", "x86", "i386", "i686"):
        return []
    enabled = [f for f in _umath.__cpu_dispatch__ if _umath.__cpu_features__.get(f)]
    avx512 = [f for f in enabled if f.startswith("AVX512") or f == "X86_V4"]
    return avx512 or [f for f in enabled if f in ("X86_V3", "AVX2", "FMA3")]


def _lane_digest(tracks) -> str:
    """Each grid track's arrival step and positions rounded to 1e-6 m (as ``_digest`` rounds), by agent."""
    h = hashlib.sha256()
    for tr in sorted(tracks, key=lambda t: t.agent):
        h.update(np.array([tr.agent, tr.arrival_step], dtype=np.int64).tobytes())
        h.update((np.round(np.asarray(tr.positions_m), 6) + 0.0).tobytes())  # + 0.0: -0.0 hashed as 0.0
    return h.hexdigest()[:16]


def _keepout_bytes(keepouts) -> str:
    """Every field of every keep-out, raw bytes (floats by ``float.hex``): equal only if bit-identical."""
    h = hashlib.sha256()
    for key in sorted(keepouts):
        for f in dataclasses.fields(keepouts[key]):
            x = getattr(keepouts[key], f.name)
            h.update(np.ascontiguousarray(x).tobytes() if isinstance(x, np.ndarray) else repr(x).encode())
    return h.hexdigest()[:16]


def report(plans: bool = True) -> dict:
    """What this process computes (under whatever kernels it got): the state of numpy's dispatch targets, the
    tracking bounds (hex) and keep-outs of ``KEEPOUT_CASE``, the lane plans of ``LANE_CASES`` (digest, arrival
    step), and with ``plans`` the plans of ``PLAN_CASES`` (stage, ``_digest``; the default kernels' are
    ``PLANS``, checked by test_swarm_speed28_split)."""
    out: dict = {"features": {f: bool(_umath.__cpu_features__.get(f)) for f in _umath.__cpu_dispatch__}}
    layout, n = KEEPOUT_CASE
    scenario = scenario_from_dict(LAYOUTS[layout](n), label="test")
    out["bounds_m"] = {k: float(v).hex() for k, v in sorted(tracking_growth_m(scenario).items())}
    out["keepouts"] = _keepout_bytes(swarm_problem(scenario).keepouts)
    for layout, n in LANE_CASES:
        problem = swarm_problem(scenario_from_dict(LAYOUTS[layout](n), label="test"))
        flights_m = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
        lower_s = max(rest_to_rest(float(d), lim, GRID_DT_S).duration_s for d, lim in zip(flights_m, problem.limits))
        stage = lanes_stage(problem, lower_s, {})
        assert stage is not None
        out[f"lanes {layout}-{n}"] = [_lane_digest(stage.tracks), max(tr.arrival_step for tr in stage.tracks)]
    name, method = DEFLECTION_CASE
    scenario = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" / f"{name}.yaml")
    plan = plan_scenario(scenario, method=method, seed=0)
    bad, deflections = verify_with_deflections(plan, scenario, dt_fine_s=DEFLECTION_DT_S)
    allowance = deflection_allowance(plan, scenario, deflections=deflections or None)  # as pipeline._until_verified
    out["deflection case"] = [len(bad), {k: v.hex() for k, v in sorted(allowance.items())}]
    for layout, n, _ in PLAN_CASES if plans else []:
        timed, info = swarm_timed(scenario_from_dict(LAYOUTS[layout](n), label="test"), FLAT_LEVELS)
        out[f"plan {layout}-{n}"] = [info.stage, _digest(timed, info)]
    return out


@pytest.fixture(scope="module")
def group() -> list[str]:
    names = highest_group()
    if not names:
        pytest.skip("no SIMD dispatch group of numpy to disable on this machine (not x86, or none enabled)")
    return names


@pytest.fixture(scope="module")
def child(group) -> dict:
    """:func:`report` from a child python with ``group`` disabled (added to any ``NPY_DISABLE_CPU_FEATURES``
    this process was given)."""
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ)
    env[ENV] = " ".join([*env.get(ENV, "").split(), *group])
    env["PYTHONPATH"] = os.pathsep.join([str(root), *filter(None, [env.get("PYTHONPATH")])])
    code = f"import json, {__name__} as m; print({REPORT_TAG!r} + json.dumps(m.report()))"
    run = subprocess.run(
        [sys.executable, "-c", code],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=CHILD_TIMEOUT_S,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    lines = [ln for ln in run.stdout.splitlines() if ln.startswith(REPORT_TAG)]
    assert len(lines) == 1, run.stdout[-3000:]
    return json.loads(lines[0][len(REPORT_TAG) :])


@pytest.fixture(scope="module")
def here() -> dict:
    return report(plans=False)


def test_the_child_runs_without_the_highest_kernels(group, child, here):
    assert all(here["features"][f] for f in group)
    assert not any(child["features"][f] for f in group), child["features"]  # numpy took the names


def test_tracking_bounds_and_keepouts_are_bit_identical_under_both_kernels(child, here):
    assert child["bounds_m"] == here["bounds_m"]
    assert child["keepouts"] == here["keepouts"]


def test_lane_plans_and_recorded_plans_are_the_same_under_both_kernels(child, here):
    for layout, n in LANE_CASES:
        assert child[f"lanes {layout}-{n}"] == here[f"lanes {layout}-{n}"], (layout, n)
    for case in PLAN_CASES:
        layout, n, _ = case
        stage, digest, _ = PLANS[case]
        assert child[f"plan {layout}-{n}"] == [stage, digest], case


def test_the_deflection_allowance_of_a_failed_plan_is_bit_identical_under_both_kernels(child, here):
    """Round 37W: after a failed verify the allowance grows the re-plan's keep-outs; it must be one float per
    vehicle on both kernels (the plan does fail verify, and some vehicle is pushed, so the test is not vacuous)."""
    violations, allowance = here["deflection case"]
    assert violations > 0 and allowance
    assert child["deflection case"] == here["deflection case"]


def test_the_two_kernels_deflections_round_up_to_one_float():
    """Runs on any machine: cf7's raw deflection in the failed swap_8 plan under the AVX-512 and the AVX2 kernels
    (round 37W, 1.1e-16 m apart), rounded up as the allowance is, are one float, above both by less than the
    resolution."""
    avx512, avx2 = float.fromhex("0x1.1322c9d5bbae2p-6"), float.fromhex("0x1.1322c9d5bbb03p-6")
    assert avx512 != avx2
    up = rounded_up(avx512, DEFLECTION_RESOLUTION_M)
    assert up == rounded_up(avx2, DEFLECTION_RESOLUTION_M)
    assert 0.0 < up - max(avx512, avx2) < DEFLECTION_RESOLUTION_M


def test_the_two_kernels_bounds_round_up_to_one_float():
    """Runs on any machine: the Crazyflie 2.1's raw bound under the AVX-512 and the AVX2 kernels (round 37V, pillar-256
    by type, 6.0e-15 m apart), rounded up, are one float, a multiple of the resolution, above both by less than it."""
    avx512, avx2 = float.fromhex("0x1.895ca311a8199p-6"), float.fromhex("0x1.895ca311a885fp-6")
    assert avx512 != avx2
    up = rounded_up(avx512, TRACKING_BOUND_RESOLUTION_M)
    assert up == rounded_up(avx2, TRACKING_BOUND_RESOLUTION_M)
    assert 0.0 < up - max(avx512, avx2) < TRACKING_BOUND_RESOLUTION_M
    assert up == round(up / TRACKING_BOUND_RESOLUTION_M) * TRACKING_BOUND_RESOLUTION_M
    for exact in (0.0, 0.024, 1.0):  # a multiple stays itself; a float of a multiple is never rounded below
        assert rounded_up(exact, TRACKING_BOUND_RESOLUTION_M) >= exact
        assert rounded_up(exact, TRACKING_BOUND_RESOLUTION_M) - exact < 1e-15
