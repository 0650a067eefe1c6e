"""``python -m proxplan`` is the ``proxplan`` command (``proxplan/__main__.py``)."""

from __future__ import annotations

import subprocess
import sys


def test_python_m_proxplan_runs_the_command_line() -> None:
    out = subprocess.run([sys.executable, "-m", "proxplan", "--help"], capture_output=True, text=True, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("usage: proxplan")


def test_python_m_proxplan_exits_2_on_a_user_mistake() -> None:
    out = subprocess.run([sys.executable, "-m", "proxplan", "no-such-command"], capture_output=True, text=True,
                         check=False)  # fmt: skip
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
