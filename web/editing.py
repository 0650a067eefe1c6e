"""Editing a goal or dock offset with a transform gizmo, and re-planning in the background.

A mixin of :class:`proxplan.web.app.ReviewApp`: it uses the app's ``server``, ``loaded``, ``edit_vehicle``,
``edit_note``, ``progress``, ``_gizmo``, ``_lock``, ``_jobs`` and ``_guard``. Positions are world
frame, m; a dock offset is relative to the partner's final position.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from proxplan.web.replan import with_dock_offset, with_goal


class GoalEditing:
    """Gizmo editing of goals / dock offsets and the background re-plan of the edited scenario."""

    # provided by ReviewApp (declared for the type checker)
    server: Any
    loaded: Any
    edit_vehicle: Any
    edit_note: Any
    progress: Any
    _gizmo: Any
    _lock: Any
    _jobs: Any

    def _guard(self, fn: Any) -> Any: ...  # ReviewApp._guard

    def _editable(self, name: str) -> bool:
        d = self.loaded.data if self.loaded else None
        if d is None or d.scenario is None:
            return False
        v = d.vehicles[name]
        return v.goal_m is not None or (v.dock_with is not None and v.dock_offset_m is not None)

    def _gizmo_anchor(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(origin the edited vector is relative to, current end point), world frame, m."""
        d = self.loaded.data
        v = d.vehicles[name]
        if v.dock_with is not None and v.dock_offset_m is not None and v.dock_with in d.vehicles:
            partner_end = d.vehicles[v.dock_with].position_m[-1]
            return partner_end, partner_end + v.dock_offset_m
        return np.zeros(3), np.asarray(v.goal_m, float)

    def _remove_gizmo(self) -> None:
        if self._gizmo is not None:
            self._gizmo.remove()
            self._gizmo = None

    def _rebuild_gizmo(self) -> None:
        with self._lock:
            self._remove_gizmo()
            name = self.edit_vehicle.value
            if self.loaded is None or name not in self.loaded.data.vehicles or not self._editable(name):
                self.edit_note.content = (
                    ""
                    if self.loaded is None or self.loaded.data.scenario is not None
                    else "editing needs the scenario (plan.json without one, or no planner)"
                )
                return
            _, end = self._gizmo_anchor(name)
            self._gizmo = self.server.scene.add_transform_controls(
                "/edit/target", scale=0.4, disable_rotations=True, position=tuple(end)
            )
            what = "dock offset" if self.loaded.data.vehicles[name].dock_with else "goal"
            self.edit_note.content = f"drag the gizmo to move the {what} of **{name}**, then press re-plan"
            self._gizmo.on_update(self._guard(lambda _e: self._gizmo_moved(name, what)))

    def _gizmo_moved(self, name: str, what: str) -> None:
        if self._gizmo is None or self.loaded is None:
            return
        origin, _ = self._gizmo_anchor(name)
        value = np.asarray(self._gizmo.position, float) - (origin if what == "dock offset" else 0.0)
        self.edit_note.content = (
            f"new {what} of **{name}**: [{value[0]:.2f}, {value[1]:.2f}, {value[2]:.2f}] m — press re-plan"
        )

    def edited_scenario(self) -> Any:
        """The scenario with the gizmo's goal or dock offset applied (None when nothing is edited)."""
        name = self.edit_vehicle.value
        if self.loaded is None or self._gizmo is None or name not in self.loaded.data.vehicles:
            return None
        d = self.loaded.data
        v = d.vehicles[name]
        origin, _ = self._gizmo_anchor(name)
        pos = np.asarray(self._gizmo.position, float)
        if v.dock_with is not None and v.dock_offset_m is not None:
            return with_dock_offset(d.scenario, name, pos - origin)
        return with_goal(d.scenario, name, pos)

    def replan(self, *, client: Any = None) -> bool:
        """Re-plan the edited scenario in the background; False when nothing to do or busy."""
        scenario = self.edited_scenario()
        if scenario is None:
            msg = "select a vehicle under 'goal / dock of' and move its gizmo first"
        elif not self._jobs.submit(scenario):
            msg = "a plan is already running"
        else:
            self.progress.visible = True
            self.progress.value = 0.0
            self.edit_note.content = "planning …"
            return True
        if client is not None:
            client.add_notification("proxplan", msg, auto_close_seconds=6.0)
        self.edit_note.content = msg
        return False

    def wait_idle(self, timeout_s: float | None = None) -> None:
        """Block until the background load / re-plan finishes (tests, CLI export)."""
        self._jobs.join(timeout_s)
