"""Run every planning method on every shipped scenario and tabulate the results (markdown + PNG).

    python -m proxplan.planner.compare --out DIR [--scenarios a.yaml b.yaml] [--methods optimized sampling]

Writes ``DIR/comparison.md``, ``DIR/comparison.png`` and ``DIR/comparison.json``. Columns: makespan
(s, last time any vehicle moves), total path length (m, all vehicles), max authority usage (-, with
the scenario's limit), min separation (m, non-dock pairs), verify result (``proxplan.verify.checks``: the
disturbance model evaluated directly, so the baselines' violations show) and planning time (s,
whole ``proxplan plan`` process, which runs in a fresh process per plan so that every method starts
from the same seeded sampling stage).
A method that finds no plan gets a row saying why (``InfeasibleError``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
METHOD_ORDER = ("optimized", "sampling", "no-downwash", "ellipsoid")


@dataclass(frozen=True)
class ComparisonRow:
    """One (scenario, method) result; numbers are None when no plan was found."""

    scenario: str
    method: str
    feasible: bool
    makespan_s: float | None
    path_length_m: float | None  # sum over vehicles, m
    max_authority_usage: float | None  # -
    authority_fraction: float  # the scenario's limit, -
    min_separation_m: float | None
    verify_passed: bool | None
    violations: tuple[str, ...]  # "kind x count" summaries
    planning_time_s: float
    note: str = ""  # method actually used (e.g. optimiser fall-back) or why it failed


def run_one(scenario_path: Path, method: str, *, seed: int = 0, time_budget_s: float | None = None) -> ComparisonRow:
    """Plan the scenario with ``method`` in a fresh ``proxplan plan`` process, verify, summarise.
    ``time_budget_s``: the optimiser's wall-clock budget (``--time-budget``; None: the CLI's default), s.

    Every search seeds its own OMPL generators, so ``optimized`` refines exactly the plan that
    ``sampling`` reports in any process; a fresh process per run makes the planning time the
    whole-process time a user sees.
    """
    import subprocess
    import tempfile

    from proxplan.planfile import load_scenario, read_plan
    from proxplan.verify import verify_plan

    scenario = load_scenario(scenario_path)
    fraction = float(scenario.limits.authority_fraction)
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "proxplan.cli", "plan", str(scenario_path), "--out", out,
               "--method", method, "--seed", str(seed), "--json", "--no-plot"]  # fmt: skip
        if time_budget_s is not None:
            cmd += ["--time-budget", f"{time_budget_s:g}"]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600 + (time_budget_s or 0.0))
        elapsed = time.perf_counter() - t0
        if proc.returncode == 1 and '"feasible": false' in proc.stdout:
            info = json.loads(proc.stdout)
            return ComparisonRow(scenario.name, method, False, None, None, None, fraction, None, None, (),
                                 elapsed, f"infeasible: {info['vehicle']}: {info['constraint']}")  # fmt: skip
        if proc.returncode not in (0, 1):
            last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            raise RuntimeError(f"proxplan plan {scenario_path} --method {method} failed: {last}")
        plan = read_plan(Path(out) / "plan.json")
    violations = verify_plan(plan, scenario)
    kinds: dict[str, int] = {}
    for v in violations:
        kinds[v.kind] = kinds.get(v.kind, 0) + 1
    m = plan.metrics
    lengths = m.get("path_length_m") or {}
    return ComparisonRow(
        scenario=scenario.name,
        method=method,
        feasible=True,
        makespan_s=float(m["makespan_s"]),
        path_length_m=float(sum(lengths.values())),
        max_authority_usage=float(m["max_authority_usage"]),
        authority_fraction=fraction,
        min_separation_m=None if m.get("min_separation_m") is None else float(m["min_separation_m"]),
        verify_passed=not violations,
        violations=tuple(f"{k} x{c}" for k, c in sorted(kinds.items())),
        planning_time_s=elapsed,
        note="" if plan.method == method else f"ran as {plan.method}",
    )


def compare(
    scenario_paths: list[Path], methods: tuple[str, ...] = METHOD_ORDER, *, seed: int = 0, progress=None
) -> list[ComparisonRow]:
    """Every method on every scenario; ``progress(message)`` is called before each run."""
    rows = []
    for path in scenario_paths:
        for method in methods:
            if progress is not None:
                progress(f"{Path(path).stem}: {method}")
            rows.append(run_one(Path(path), method, seed=seed))
    return rows


def _f(value, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def _cells(row: ComparisonRow) -> list[str]:
    if not row.feasible:
        verify = "no plan"
    elif row.verify_passed:
        verify = "pass"
    else:
        verify = "FAIL: " + ", ".join(row.violations)
    usage = "-" if row.max_authority_usage is None else f"{row.max_authority_usage:.3f} / {row.authority_fraction:g}"
    return [
        row.scenario,
        row.method,
        _f(row.makespan_s, ".2f"),
        _f(row.path_length_m, ".2f"),
        usage,
        _f(row.min_separation_m, ".3f"),
        verify,
        f"{row.planning_time_s:.2f}",
        row.note,
    ]


HEADER = [
    "scenario",
    "method",
    "makespan (s)",
    "path length (m)",
    "max authority usage / limit",
    "min separation (m)",
    "verify",
    "planning time (s)",
    "note",
]


def to_markdown(rows: list[ComparisonRow]) -> str:
    """The comparison as a markdown table with a short legend."""
    lines = [
        "| " + " | ".join(HEADER) + " |",
        "|" + "|".join("---" for _ in HEADER) + "|",
    ]
    lines += ["| " + " | ".join(_cells(r)) + " |" for r in rows]
    legend = (
        "\nMakespan: last time any vehicle moves. Path length: all vehicles together. Authority usage: "
        "the worst vehicle's, from the disturbance model evaluated directly (DESIGN.md s. 3), against "
        "the scenario's `limits.authority_fraction`. Min separation: centre distance over non-dock pairs. "
        "Verify: `proxplan verify` checks (model numbers, separation, invalid zone, limits, goals). "
        "Planning time: whole `proxplan plan` process (one fresh process per plan, same seed). "
        "Regenerate with `python -m proxplan.planner.compare --out docs`.\n"
    )
    return "\n".join(lines) + "\n" + legend


def to_png(rows: list[ComparisonRow], path: Path) -> Path:
    """A rendered table (failed verifications in red, passes in green)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cells = [_cells(r)[:-1] for r in rows]
    fig_h = 0.8 + 0.32 * (len(rows) + 1)
    fig, ax = plt.subplots(figsize=(15, fig_h))
    ax.axis("off")
    table = ax.table(cellText=cells, colLabels=HEADER[:-1], loc="center", cellLoc="left")
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.auto_set_column_width(list(range(len(HEADER) - 1)))
    for i, row in enumerate(rows, start=1):
        colour = "#d8f0d8" if row.verify_passed else "#f6d0d0"
        table[i, 6].set_facecolor(colour)
    ax.set_title("proxplan: every method on every shipped scenario", fontsize=10)
    fig.tight_layout()
    from proxplan.fileio import save_figure

    return save_figure(fig, path, dpi=130, bbox_inches="tight")


def write_outputs(rows: list[ComparisonRow], out_dir: Path) -> dict[str, Path]:
    """Write comparison.md / .png / .json into ``out_dir`` (each atomically)."""
    from proxplan.fileio import atomic_write_text

    out_dir.mkdir(parents=True, exist_ok=True)
    md = atomic_write_text(out_dir / "comparison.md", "# Planner comparison\n\n" + to_markdown(rows))
    js = atomic_write_text(out_dir / "comparison.json", json.dumps([asdict(r) for r in rows], indent=1))
    png = to_png(rows, out_dir / "comparison.png")
    return {"markdown": md, "png": png, "json": js}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m proxplan.planner.compare",
        description="Run every planning method on every shipped scenario; write a markdown + PNG table.",
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (comparison.md/.png/.json)")
    parser.add_argument("--scenarios", nargs="*", metavar="YAML", help="scenario files (default: scenarios/*.yaml)")
    parser.add_argument("--methods", nargs="*", choices=METHOD_ORDER, default=list(METHOD_ORDER), help="methods to run")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    args = parser.parse_args(argv)
    from proxplan.fileio import UserError

    paths = [Path(p) for p in args.scenarios] if args.scenarios else sorted(SCENARIO_DIR.glob("*.yaml"))
    if not paths:
        print(f"proxplan.planner.compare: error: no scenario files found in {SCENARIO_DIR}", file=sys.stderr)
        return 2
    try:
        from tqdm import tqdm

        jobs = len(paths) * len(args.methods)
        with tqdm(total=jobs, file=sys.stderr, desc="compare", unit="plan") as bar:

            def progress(msg: str) -> None:
                bar.set_postfix_str(msg)
                bar.update(0)

            rows = []
            for path in paths:
                part = compare([path], tuple(args.methods), seed=args.seed, progress=progress)
                rows.extend(part)
                bar.update(len(part))
    except UserError as err:
        print(f"proxplan.planner.compare: error: {err}", file=sys.stderr)
        return 2
    out = write_outputs(rows, Path(args.out))
    print(to_markdown(rows))
    print(f"wrote {out['markdown']}, {out['png']}, {out['json']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
