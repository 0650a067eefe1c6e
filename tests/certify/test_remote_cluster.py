"""Certification through a real Dask cluster: a ``dask scheduler`` and two ``dask worker``
processes on 127.0.0.1, started here; the result equals the local cluster's."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import REPO

DASK = [sys.executable, "-m", "dask", "scheduler"]  # the `dask scheduler` command of this Python
WORKER = [sys.executable, "-m", "dask", "worker"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def dask_cluster(tmp_path: Path):
    """Address of a scheduler with two single-threaded workers, all on 127.0.0.1; stopped after."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    logs = [open(tmp_path / f"dask_{i}.log", "w") for i in range(3)]  # noqa: SIM115 - closed below
    procs = [
        subprocess.Popen(
            [*DASK, "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            env=env,
            stdout=logs[0],
            stderr=subprocess.STDOUT,
            cwd=tmp_path,
        )  # fmt: skip
    ]
    try:
        time.sleep(2.0)
        for i in (1, 2):
            procs.append(
                subprocess.Popen(
                    [
                        *WORKER,
                        address,
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                        "--host",
                        "127.0.0.1",
                        "--name",
                        f"w{i}",
                        "--local-directory",
                        str(tmp_path / f"w{i}"),
                    ],
                    env=env,
                    stdout=logs[i],
                    stderr=subprocess.STDOUT,
                    cwd=tmp_path,
                )  # fmt: skip
            )
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in reversed(procs):
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
        for log in logs:
            log.close()


@pytest.mark.slow
def test_certify_through_a_real_scheduler_equals_the_local_result(dask_cluster, proxplan, battery_swap_plan, tmp_path):
    remote = proxplan("certify", battery_swap_plan, "--runs", 6, "--seed", 9, "--scheduler", dask_cluster,
                      "--out", tmp_path / "remote", "--json")  # fmt: skip
    assert remote.returncode == 0, remote.stderr
    execution = json.loads(remote.stdout)["execution"]
    assert execution["workers"] == 2 and execution["scheduler"] == dask_cluster
    local = proxplan("certify", battery_swap_plan, "--runs", 6, "--seed", 9, "--workers", 1,
                     "--out", tmp_path / "local", "--json")  # fmt: skip
    assert local.returncode == 0, local.stderr
    assert (tmp_path / "remote" / "certify.json").read_bytes() == (tmp_path / "local" / "certify.json").read_bytes()
    assert (tmp_path / "remote" / "runs.jsonl").read_bytes() == (tmp_path / "local" / "runs.jsonl").read_bytes()
