"""`proxplan vehicles` and `proxplan wrench` through the installed console script."""

import json
import subprocess
import sys

import pytest

KEYS = {"force_N", "torque_Nm", "components", "valid", "authority_usage"}


def run(*args):
    return subprocess.run([sys.executable, "-m", "proxplan.cli", *args], capture_output=True, text=True, timeout=60)


def test_wrench_json_contract():
    out = run("wrench", "--source", "small-quad", "--target", "large-quad", "--offset", "0", "0.1", "-1.5", "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert set(data) == KEYS
    assert set(data["components"]) == {"drag", "thrust_change"}
    for part in data["components"].values():
        assert set(part) == {"force_N", "torque_Nm"}
    total = [
        a + b for a, b in zip(data["components"]["drag"]["force_N"], data["components"]["thrust_change"]["force_N"])
    ]
    assert total == pytest.approx(data["force_N"])
    assert data["valid"] is True and data["force_N"][2] < 0 and 0 < data["authority_usage"] < 1


def test_vehicles_json_lists_builtins():
    out = run("vehicles", "--json")
    assert out.returncode == 0
    names = set(json.loads(out.stdout)["vehicles"])
    assert {"small-quad", "large-quad", "crazyflie-2.1", "crazyflie-parrot"} <= names


@pytest.mark.parametrize(
    "args, message",
    [
        (["--source", "nope", "--target", "large-quad", "--offset", "0", "0", "-1"], "unknown vehicle type 'nope'"),
        (
            ["--source", "small-quad", "--target", "large-quad", "--offset", "0", "inf", "-1"],
            "--offset DY: expected a finite number",
        ),
        (
            ["--source", "small-quad", "--target", "large-quad", "--offset", "0", "x", "-1"],
            "--offset DY: expected a number",
        ),
    ],
)
def test_bad_input_is_one_line_exit_2(args, message):
    out = run("wrench", *args)
    assert out.returncode == 2
    assert message in out.stderr and "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_bad_vehicle_file(tmp_path):
    bad = tmp_path / "v.yaml"
    bad.write_text("vehicles:\n  v: {base: small-quad, propeller: {diameter_m: 0}}\n")
    out = run(
        "wrench", "--vehicle-file", str(bad), "--source", "v", "--target", "large-quad", "--offset", "0", "0", "-1"
    )
    assert out.returncode == 2 and "propeller.diameter_m: expected a positive number" in out.stderr
    assert "Traceback" not in out.stderr
