"""Shared paths and builders for the test suite.

Fixtures: ``proxplan`` runs the command line in a fresh process (exit code, stdout, stderr);
``battery_swap_plan`` is the shipped battery swap planned once per session (sampling method, seed 0,
in a fresh process; ``battery_swap_planned`` the same run with its finished process); ``shipped_plans`` every
shipped scenario planned so, once per session; ``write_yaml`` writes a mapping as a YAML file.

Parallel runs (README's ``-n auto --dist loadgroup``, pytest-xdist): each test is marked
``xdist_group`` with its module, so a module's tests and its module fixtures stay on one worker; the
modules that read one of the costly session fixtures (``SESSION_GROUPS``) share one group, so the
fixture is built once in the run, not once per worker.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"
SHARED = REPO.parent / "shared"

# session fixture -> the xdist group of every module whose tests read it (directly or through another
# fixture). Each is a planner or identify run in fresh processes (shipped_plans ~90 s loaded, the battery
# swap ~10 s, discovery_clean ~40 s): built once per worker that runs a reader, so the readers share a worker.
SESSION_GROUPS = {
    "battery_swap_planned": "shipped_plans",
    "battery_swap_plan": "shipped_plans",
    "shipped_plans": "shipped_plans",
    "discovery_clean": "discovery_clean",  # tests/identify/conftest.py
}


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the marks (it appends the group to the node id)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test ``xdist_group``: its module's path, or the ``SESSION_GROUPS`` group of a session
    fixture that a test of its module reads (one group for a module that reads two). Without
    ``--dist loadgroup`` the marks do nothing."""
    groups: dict[Path, str] = {}
    for item in items:
        readers = sorted({SESSION_GROUPS[name] for name in item.fixturenames if name in SESSION_GROUPS})
        if readers:
            groups[item.path] = "+".join(sorted({*readers, *groups.get(item.path, "").split("+")} - {""}))
    for item in items:
        item.add_marker(pytest.mark.xdist_group(groups.get(item.path) or item.path.relative_to(REPO).as_posix()))


def run_proxplan(*args: Any, timeout: float = 300.0, cwd: Path = REPO) -> subprocess.CompletedProcess:
    """``proxplan ARGS`` in a fresh Python process (OMPL's seed is per process)."""
    return subprocess.run(
        [sys.executable, "-m", "proxplan.cli", *map(str, args)],
        capture_output=True, text=True, timeout=timeout, cwd=cwd,
    )  # fmt: skip


@pytest.fixture(scope="session")
def proxplan() -> Callable[..., subprocess.CompletedProcess]:
    return run_proxplan


@pytest.fixture(scope="session")
def battery_swap_planned(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """``proxplan plan scenarios/battery_swap.yaml --method sampling --json`` (seed 0, with plots) run once
    in a fresh process: (the --out folder, the finished process with its JSON report on stdout)."""
    out = tmp_path_factory.mktemp("battery_swap_plan")
    res = run_proxplan("plan", SCENARIOS / "battery_swap.yaml", "--out", out, "--method", "sampling", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["verify"]["passed"]
    return out, res


@pytest.fixture(scope="session")
def battery_swap_plan(battery_swap_planned) -> Path:
    """Folder holding plan.json of the shipped battery swap (sampling, seed 0)."""
    return battery_swap_planned[0]


@pytest.fixture(scope="session")
def shipped_plans(tmp_path_factory, battery_swap_plan: Path) -> dict[str, Path]:
    """Every shipped scenario planned once per session by ``proxplan plan --method sampling --json`` (seed 0,
    a fresh process each; the battery swap is ``battery_swap_plan``, the others with --no-plot): scenario
    stem -> the --out folder holding plan.json. Read-only: tests write their own copies."""
    out = {}
    for path in sorted(SCENARIOS.glob("*.yaml")):
        if path.stem == "battery_swap":
            out[path.stem] = battery_swap_plan
            continue
        folder = tmp_path_factory.mktemp(f"shipped_{path.stem}")
        res = run_proxplan("plan", path, "--out", folder, "--method", "sampling", "--no-plot", "--json")
        assert res.returncode == 0, res.stderr
        out[path.stem] = folder
    return out


@pytest.fixture
def write_yaml(tmp_path: Path) -> Callable[..., Path]:
    def write(doc: Any, name: str = "file.yaml") -> Path:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        return path

    return write
