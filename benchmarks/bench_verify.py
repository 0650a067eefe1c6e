"""Speed of ``proxplan verify`` (and of the plan's metrics and plot) at swarm scale (issue 30).

A test plan of N vehicles without any planner: a formation of ``proxplan.planner.formations.LAYOUTS``
(default the pillar formation change) flown on straight, synchronised rest-to-rest lines (every
vehicle leaves at t = 0 and arrives together, one Ruckig segment each, ``straight_line_plan``). Such a
plan has violations (paths cross each other, the pillar, the jets): that is fine for timing.

Usage:
    python benchmarks/bench_verify.py [--layout pillar] [--n 32 64 128 256] [--baseline-python PATH]
        [--baseline-timeout 600] [--metrics] [--keep DIR]

Per N it prints the whole-process wall time and peak memory (``resource`` rusage of the child, MB) of
``proxplan verify plan.json --json`` with this interpreter, and, with ``--baseline-python`` (an
interpreter whose ``proxplan`` is the code to compare with, e.g. a venv of a worktree at an older
commit), the same for that one in the same run, their ratio and whether both report the same
violations. ``--metrics`` also times ``finish_metrics`` and ``plot_plan`` in-process.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def straight_line_plan(doc: dict, *, model=None):
    """(scenario, plan) of scenario mapping ``doc`` (with the calibrated ``model``, if any) where
    every vehicle flies one straight rest-to-rest Ruckig segment from its start to its goal (a
    hovering one stays put), all leaving at t = 0 and arriving together (the slowest vehicle's
    minimum time); no planner, no checks."""
    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.timing import TimedPath, assemble_plan, min_segment_duration_s, ruckig_segment

    import numpy as np

    sc = scenario_from_dict(doc, model=model)
    legs = {}
    for name, task in sc.vehicles.items():
        goal = task.goal_m if task.goal_m is not None else task.start_m
        legs[name] = (task.start_m, goal, task.kinematic_limits)
    duration = max(min_segment_duration_s(float(np.linalg.norm(g - s)), lim) for s, g, lim in legs.values())
    timed = {}
    for name, (s, g, lim) in legs.items():
        if float(np.linalg.norm(g - s)) < 1e-9:
            timed[name] = TimedPath(np.array([0.0, duration]), np.array([s, g]), [None])
            continue
        traj = ruckig_segment(s, g, lim, minimum_duration_s=duration)
        timed[name] = TimedPath(np.array([0.0, float(traj.duration)]), np.array([s, g]), [traj])
    return sc, assemble_plan(sc, timed, method="straight-lines", notes=["benchmark: straight synchronised lines"])
