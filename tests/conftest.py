"""Shared paths and builders for the test suite.

Fixtures: ``proxplan`` runs the command line in a fresh process (exit code, stdout, stderr);
``battery_swap_plan`` is the shipped battery swap planned once per session (sampling method, seed 0,
in a fresh process); ``write_yaml`` writes a mapping as a YAML file.
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
def battery_swap_plan(tmp_path_factory) -> Path:
    """Folder holding plan.json of the shipped battery swap (sampling, seed 0)."""
    out = tmp_path_factory.mktemp("battery_swap_plan")
    res = run_proxplan("plan", SCENARIOS / "battery_swap.yaml", "--out", out, "--method", "sampling", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["verify"]["passed"]
    return out


@pytest.fixture
def write_yaml(tmp_path: Path) -> Callable[..., Path]:
    def write(doc: Any, name: str = "file.yaml") -> Path:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        return path

    return write
