"""Tests of proxplan.planner.compare and the method comparison claims of issue 5.

Claims (each asserted on the shipped scenarios, planned for real and checked by proxplan.verify.checks):
* ``optimized`` passes verify and is no slower than ``sampling`` on the battery swap and on the
  8-vehicle swap (about 15 s, marked slow);
* ``no-downwash`` breaks the authority limit on at least one shipped scenario;
* ``ellipsoid`` is violated or slower than ``optimized`` on at least one shipped scenario.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from proxplan.planfile import load_scenario
from proxplan.planner.compare import ComparisonRow, main, run_one, to_markdown, write_outputs

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
# cheapest first: the loops below stop at the first scenario that shows the claim
# the optimiser's wall-clock budget in these tests, s: 10x the CLI's default (60 s) and some 40x what swap_8 takes
# on a quiet 2-core machine (about 15 s), so a loaded CI machine never decides the claim (a run that hit the
# default once fell back to the sampling plan at load 7-8)
OPTIMIZER_BUDGET_S = 600.0
BASELINE_ORDER = ("swap_8.yaml", "corridor_stack.yaml", "battery_swap.yaml", "package_handoff.yaml", "crossing_4.yaml")


def _scenario_path(name: str) -> Path:
    path = SCENARIOS / name
    if not path.exists():
        pytest.skip(f"scenario {name} is not shipped")
    return path


def _check_optimized_vs_sampling(name: str) -> None:
    path = _scenario_path(name)
    scenario = load_scenario(path)
    optimized = run_one(path, "optimized", time_budget_s=OPTIMIZER_BUDGET_S)
    sampling = run_one(path, "sampling")
    assert optimized.feasible and sampling.feasible
    assert optimized.verify_passed, optimized.violations
    assert optimized.note == "", optimized.note  # the optimiser ran and was kept (no fall-back)
    assert optimized.makespan_s <= sampling.makespan_s + 1e-9
    assert optimized.max_authority_usage <= scenario.limits.authority_fraction + 1e-3


def test_optimized_battery_swap_passes_verify_and_is_not_slower_than_sampling():
    _check_optimized_vs_sampling("battery_swap.yaml")


def test_optimized_swap_8_passes_verify_and_is_not_slower_than_sampling():  # about 15 s
    _check_optimized_vs_sampling("swap_8.yaml")


def test_no_downwash_baseline_breaks_the_authority_limit_somewhere():
    seen = []
    for name in BASELINE_ORDER:
        if not (SCENARIOS / name).exists():
            continue
        row = run_one(SCENARIOS / name, "no-downwash")
        seen.append((name, row.violations))
        if row.feasible and any(v.startswith("authority") for v in row.violations):
            assert row.max_authority_usage > row.authority_fraction
            return
    pytest.fail(f"no-downwash kept the authority limit on every scenario: {seen}")


def test_ellipsoid_baseline_is_violated_or_slower_than_optimized_somewhere():
    seen = []
    for name in BASELINE_ORDER:
        if not (SCENARIOS / name).exists():
            continue
        ell = run_one(SCENARIOS / name, "ellipsoid")
        if ell.feasible and not ell.verify_passed:
            return
        opt = run_one(SCENARIOS / name, "optimized")
        if opt.feasible and opt.verify_passed and (not ell.feasible or ell.makespan_s > opt.makespan_s):
            return
        seen.append((name, ell.violations, ell.makespan_s, opt.makespan_s))
    pytest.fail(f"ellipsoid was valid and as fast as optimized everywhere: {seen}")


def _rows() -> list[ComparisonRow]:
    return [
        ComparisonRow("s1", "optimized", True, 2.5, 3.0, 0.05, 0.15, 0.4, True, (), 1.2),
        ComparisonRow("s1", "no-downwash", True, 2.0, 2.8, 0.31, 0.15, 0.3, False, ("authority x2",), 0.1),
        ComparisonRow(
            "s1", "ellipsoid", False, None, None, None, 0.15, None, None, (), 0.5, "infeasible: a: ellipsoid of b"
        ),
    ]


def test_markdown_table_has_every_row_and_the_verify_result():
    md = to_markdown(_rows())
    lines = [line for line in md.splitlines() if line.startswith("| s1")]
    assert len(lines) == 3
    assert "FAIL: authority x2" in lines[1]
    assert "no plan" in lines[2] and "infeasible: a: ellipsoid of b" in lines[2]
    assert "0.310 / 0.15" in lines[1]


def test_write_outputs_and_main(tmp_path):
    out = write_outputs(_rows(), tmp_path / "a")
    assert out["png"].stat().st_size > 1000
    assert json.loads(out["json"].read_text())[1]["violations"] == ["authority x2"]
    assert not list((tmp_path / "a").glob(".*tmp*"))  # no temporary files left behind
    rc = main(
        ["--out", str(tmp_path / "b"), "--scenarios", str(SCENARIOS / "battery_swap.yaml"), "--methods", "sampling"]
    )
    assert rc == 0
    rows = json.loads((tmp_path / "b" / "comparison.json").read_text())
    assert [(r["scenario"], r["method"]) for r in rows] == [("battery-swap", "sampling")]
    assert rows[0]["verify_passed"] is True
