"""Re-plan in a background thread so the page stays responsive; failures keep the old plan.

The scenario edits are plain functions over the planner's frozen dataclasses (``Scenario``,
``VehicleTask``): a new goal (world frame, m) or a new dock offset (relative to the vehicle docked
with, m) gives a new Scenario; the worker plans it and reports through callbacks.
"""

from __future__ import annotations

import copy
import dataclasses
import sys
import threading
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np


def _edited_spec(scenario: Any, name: str, keys: tuple[str, ...], value: np.ndarray) -> dict:
    """Copy of the scenario's YAML mapping with ``vehicles.<name>.<keys...>`` set to ``value``, so a
    plan written from the edited scenario embeds what was actually planned."""
    spec = copy.deepcopy(getattr(scenario, "spec", None) or {})
    node = spec.setdefault("vehicles", {}).setdefault(name, {})
    for key in keys[:-1]:
        node = node.setdefault(key, {})
    node[keys[-1]] = [float(x) for x in value]
    return spec


def with_goal(scenario: Any, name: str, goal_m: np.ndarray) -> Any:
    """Copy of ``scenario`` where vehicle ``name`` flies to ``goal_m`` (3,), world frame, m."""
    goal = np.asarray(goal_m, dtype=float).reshape(3)
    task = dataclasses.replace(scenario.vehicles[name], goal_m=goal)
    return dataclasses.replace(
        scenario, vehicles={**scenario.vehicles, name: task}, spec=_edited_spec(scenario, name, ("goal",), goal)
    )


def with_dock_offset(scenario: Any, name: str, offset_m: np.ndarray) -> Any:
    """Copy of ``scenario`` where vehicle ``name`` docks at ``offset_m`` (3,) from its partner, m."""
    offset = np.asarray(offset_m, dtype=float).reshape(3)
    task = dataclasses.replace(scenario.vehicles[name], dock_offset_m=offset)
    return dataclasses.replace(
        scenario,
        vehicles={**scenario.vehicles, name: task},
        spec=_edited_spec(scenario, name, ("dock", "offset"), offset),
    )


class Replanner:
    """Runs ``plan_fn(scenario, progress=...)`` on one worker thread at a time.

    Callbacks run on the worker thread: ``on_progress(stage, fraction 0..1)``, ``on_done(scenario,
    plan)`` and ``on_error(scenario, message)``; the caller's current plan is never touched here.
    """

    def __init__(
        self,
        plan_fn: Callable[..., Any],
        *,
        on_progress: Callable[[str, float], None],
        on_done: Callable[[Any, Any], None],
        on_error: Callable[[Any, str], None],
    ) -> None:
        self._plan_fn = plan_fn
        self._on_progress = on_progress
        self._on_done = on_done
        self._on_error = on_error
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    @property
    def busy(self) -> bool:
        with self._lock:
            return self._thread is not None and self._thread.is_alive()

    def submit(self, scenario: Any, *, plan_fn: Callable[..., Any] | None = None) -> bool:
        """Start planning ``scenario`` (with ``plan_fn`` instead of the default one, if given);
        False (and nothing started) while a plan is running."""
        with self._lock:
            if self._thread is not None and self._thread.is_alive():
                return False
            fn = plan_fn or self._plan_fn
            self._thread = threading.Thread(target=self._run, args=(scenario, fn), name="proxplan-replan", daemon=True)
            self._thread.start()
            return True

    def join(self, timeout_s: float | None = None) -> None:
        """Wait for the running plan (tests and shutdown)."""
        thread = self._thread
        if thread is not None:
            thread.join(timeout_s)

    def _run(self, scenario: Any, plan_fn: Callable[..., Any]) -> None:
        try:
            plan = plan_fn(scenario, progress=self._on_progress)
        except Exception as err:  # noqa: BLE001 - any failure must leave the old plan in place
            from proxplan.fileio import UserError

            kind = type(err).__name__
            if isinstance(err, UserError) or kind == "InfeasibleError":
                message = str(err)
            else:  # a bug somewhere: the page gets one line, the terminal the traceback
                traceback.print_exc(file=sys.stderr)
                message = f"{kind}: {err}"
            try:
                self._on_error(scenario, message)
            except Exception:  # noqa: BLE001
                traceback.print_exc()
            return
        try:
            self._on_done(scenario, plan)
        except Exception as err:  # noqa: BLE001
            try:
                self._on_error(scenario, f"could not show the new plan: {type(err).__name__}: {err}")
            except Exception:  # noqa: BLE001
                traceback.print_exc()
