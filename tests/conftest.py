"""Shared paths and builders for the test suite.

Fixtures: ``proxplan`` runs the command line in a fresh process (exit code, stdout, stderr);
``battery_swap_plan`` is the shipped battery swap planned once per session (sampling method, seed 0,
in a fresh process; ``battery_swap_planned`` the same run with its finished process); ``shipped_plans`` every
shipped scenario planned so, once per session; ``write_yaml`` writes a mapping as a YAML file.

Parallel runs (README's ``-n auto --dist loadgroup``, pytest-xdist): each test is marked
``xdist_group`` with its module, so a module's tests and its module fixtures stay on one worker. The
planned scenarios (``battery_swap_planned``, ``shipped_plans``) are files: the first worker that needs
them plans them under a lock in the folder every worker of the run shares (:func:`once_per_run`), the
others wait for it and read the same folders, so their readers spread over the workers. A fixture that
returns Python objects (``discovery_clean``) cannot be shared so: the modules that read it share one
group (``SESSION_GROUPS``), so it is built once in the run, not once per worker.
"""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"
SHARED = REPO.parent / "shared"

# session fixture -> the xdist group of every module whose tests read it (directly or through another
# fixture): an identify run (discovery_clean ~40 s loaded) whose result is Python objects, built once per
# worker that runs a reader, so the readers share a worker. The planned scenarios are shared as files instead
# (once_per_run), so their readers need no common group.
SESSION_GROUPS = {
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


@contextmanager
def once_per_run(tmp_path_factory: pytest.TempPathFactory, name: str) -> Iterator[Path]:
    """The folder ``name`` in the folder every pytest-xdist worker of this run shares (the parent of the
    workers' base temporary folders; the base folder itself without xdist), held under an exclusive lock
    (``fcntl.flock`` on ``name.lock`` beside it) while the caller builds or reads it: the first caller builds
    it and writes its ``done.json`` last, every later caller (any worker) finds that file and reads. A build
    that fails leaves no ``done.json``, so the next caller builds again and fails the same way."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, also on an exception
        folder = root / name
        folder.mkdir(exist_ok=True)
        yield folder


@pytest.fixture(scope="session")
def battery_swap_planned(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """``proxplan plan scenarios/battery_swap.yaml --method sampling --json`` (seed 0, with plots) run once
    per test run (:func:`once_per_run`) in a fresh process: (the --out folder, the finished process with its
    JSON report on stdout)."""
    with once_per_run(tmp_path_factory, "battery_swap_plan") as out:
        done = out / "done.json"
        if not done.exists():
            res = run_proxplan("plan", SCENARIOS / "battery_swap.yaml", "--out", out, "--method", "sampling", "--json")
            assert res.returncode == 0, res.stderr
            assert json.loads(res.stdout)["verify"]["passed"]
            done.write_text(json.dumps({"args": res.args, "stdout": res.stdout, "stderr": res.stderr}))
        run = json.loads(done.read_text())
    return out, subprocess.CompletedProcess(run["args"], 0, run["stdout"], run["stderr"])


@pytest.fixture(scope="session")
def battery_swap_plan(battery_swap_planned) -> Path:
    """Folder holding plan.json of the shipped battery swap (sampling, seed 0)."""
    return battery_swap_planned[0]


@pytest.fixture(scope="session")
def shipped_plans(tmp_path_factory, battery_swap_plan: Path) -> dict[str, Path]:
    """Every shipped scenario planned once per test run (:func:`once_per_run`) by ``proxplan plan --method
    sampling --json`` (seed 0, a fresh process each; the battery swap is ``battery_swap_plan``, the others with
    --no-plot): scenario stem -> the --out folder holding plan.json. Read-only: tests write their own copies."""
    out = {}
    with once_per_run(tmp_path_factory, "shipped_plans") as root:
        done = root / "done.json"
        for path in sorted(SCENARIOS.glob("*.yaml")):
            if path.stem == "battery_swap":
                out[path.stem] = battery_swap_plan
                continue
            folder = root / path.stem
            if not done.exists():
                folder.mkdir(exist_ok=True)
                res = run_proxplan("plan", path, "--out", folder, "--method", "sampling", "--no-plot", "--json")
                assert res.returncode == 0, res.stderr
            out[path.stem] = folder
        done.write_text(json.dumps(sorted(out)))
    return out


@pytest.fixture
def write_yaml(tmp_path: Path) -> Callable[..., Path]:
    def write(doc: Any, name: str = "file.yaml") -> Path:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        return path

    return write
