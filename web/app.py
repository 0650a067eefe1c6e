"""The review app: a viser server showing a plan, its disturbance layers, plots and a re-plan loop.

All GUI and scene state is shared by every connected browser, so a disconnect or reconnect changes
nothing (a new browser receives the current scene). Every callback is guarded: a failure is shown in
the page and printed on stderr, and the app keeps running with the last good plan.
"""

from __future__ import annotations

import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import proxplan.web.layers as layers
import proxplan.web.plots as plots
import proxplan.web.scene as scene
from proxplan.web.editing import GoalEditing
from proxplan.web.replan import Replanner
from proxplan.web.review_data import ReviewData, load_input, plan_scenario, review_from_plan_result
from proxplan.web.wrench_series import WrenchSeries, wrench_series

PLAY_RATE_HZ = 20.0
PLOT_RATE_HZ = 5.0


@dataclass(frozen=True)
class Loaded:
    """A plan ready to show: its data and every vehicle's predicted disturbance series."""

    data: ReviewData
    series: dict[str, WrenchSeries]


def prepare(data: ReviewData) -> Loaded:
    """Compute the disturbance series of ``data`` (the slow part of showing a plan)."""
    return Loaded(data, wrench_series(data))


def _log(message: str) -> None:
    print(f"proxplan view: {message}", file=sys.stderr, flush=True)


class ReviewApp(GoalEditing):
    """Review GUI on ``server`` for the scenario or plan at ``input_path``.

    Call :meth:`load` (background) or :meth:`show` (foreground) to put a plan on screen.
    """

    def __init__(
        self,
        server: Any,
        input_path: Path | None = None,
        *,
        terminal_progress: Callable[[str, float], None] | None = None,
    ) -> None:
        self.server = server
        self._terminal_progress = terminal_progress
        self.input_path = input_path
        self.loaded: Loaded | None = None
        self.t_s = 0.0
        self._lock = threading.RLock()
        self._handles = scene.SceneHandles()
        self._layer_handles: list[Any] = []
        self._layer_root: Any = None
        self._plot: plots.PlotImage | None = None
        self._last_plot_s = 0.0
        self._gizmo: Any = None
        self._running = True
        self._jobs = Replanner(
            self._replan_job, on_progress=self._on_progress, on_done=self._on_done, on_error=self._on_error
        )
        self._build_gui()
        self._player = threading.Thread(target=self._play_loop, name="proxplan-play", daemon=True)
        self._player.start()

    # ----- GUI ---------------------------------------------------------------------------------
    def _build_gui(self) -> None:
        gui = self.server.gui
        self.status = gui.add_markdown("**proxplan** — loading …")
        self.progress = gui.add_progress_bar(0.0, visible=False, animated=True)
        with gui.add_folder("Time", visible=False) as self._folder_time:
            self.time_slider = gui.add_slider("t [s]", min=0.0, max=1.0, step=0.01, initial_value=0.0)
            self.play = gui.add_checkbox("play", initial_value=False)
            self.speed = gui.add_slider("speed [x]", min=0.1, max=5.0, step=0.1, initial_value=1.0)
        with gui.add_folder("Layers", visible=False) as self._folder_layers:
            self.show_traj = gui.add_checkbox("trajectories", initial_value=True)
            self.show_obst = gui.add_checkbox("obstacles", initial_value=True)
            self.show_iso = gui.add_checkbox("downwash iso-speed", initial_value=True)
            self.show_cut = gui.add_checkbox("cutoff surface", initial_value=True)
            self.source = gui.add_dropdown("downwash source", options=("(none)",), initial_value="(none)")
            self.model_scale = gui.add_slider("model scale [x]", min=1.0, max=20.0, step=0.5, initial_value=1.0)
            self.layer_note = gui.add_markdown("")
            self.legend = gui.add_image(np.full((70, 420, 3), 255, np.uint8), label="usage colours")
        with gui.add_folder("Vehicle plots", visible=False) as self._folder_plots:
            self.plot_vehicle = gui.add_dropdown("vehicle", options=("(none)",), initial_value="(none)")
            self.plot_image = gui.add_image(np.full((420, 420, 3), 255, np.uint8), label="disturbance")
        with gui.add_folder("Edit and re-plan", visible=False) as self._folder_edit:
            self.edit_vehicle = gui.add_dropdown("goal / dock of", options=("(none)",), initial_value="(none)")
            self.replan_button = gui.add_button("re-plan")
            self.edit_note = gui.add_markdown("")
        with gui.add_folder("File"):
            self.reload_button = gui.add_button("reload file")
            self.export_button = gui.add_button("export recording")
        g = self._guard
        self.time_slider.on_update(g(lambda _e: self.set_time(self.time_slider.value)))
        for box in (self.show_traj, self.show_obst, self.show_iso, self.show_cut):
            box.on_update(g(lambda _e: self._apply_visibility()))
        self.source.on_update(g(lambda _e: self._rebuild_layers()))
        self.model_scale.on_update(g(lambda _e: scene.set_model_scale(self._handles, self.model_scale.value)))
        self.plot_vehicle.on_update(g(lambda _e: self._plot_vehicle_changed()))
        self.edit_vehicle.on_update(g(lambda _e: self._rebuild_gizmo()))
        self.replan_button.on_click(g(lambda e: self.replan(client=e.client)))
        self.reload_button.on_click(g(lambda _e: self.load()))
        self.export_button.on_click(g(lambda e: self._export_clicked(e.client)))

    def _guard(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        """Wrap a callback so that an error is reported (page + terminal) instead of raised."""

        def wrapped(*args: Any, **kwargs: Any) -> Any:
            try:
                return fn(*args, **kwargs)
            except Exception as err:  # noqa: BLE001 - the app must keep running
                self._report_error(f"{type(err).__name__}: {err}")
                traceback.print_exc(file=sys.stderr)
                return None

        return wrapped

    def _report_error(self, message: str) -> None:
        _log(f"error: {message}")
        try:
            self.status.content = self._status_text(error=message)
            for client in self.server.get_clients().values():
                client.add_notification("proxplan", message, color="red", auto_close_seconds=15.0)
        except Exception:  # noqa: BLE001 - a closing connection must not turn an error into a crash
            traceback.print_exc(file=sys.stderr)

    def _status_text(self, *, error: str | None = None, note: str | None = None) -> str:
        lines = []
        if self.loaded is not None:
            d = self.loaded.data
            m = d.metrics
            lines.append(
                f"**{d.name}** — {len(d.vehicles)} vehicles, "
                f"{d.t_end_s - d.t_start_s:.1f} s, authority limit {d.authority_fraction:.2f}"
            )
            if m:
                keys = ("max_authority_usage", "min_separation_m", "makespan_s", "planning_time_s")
                lines.append(", ".join(f"{k} = {m[k]:.3g}" for k in keys if isinstance(m.get(k), (int, float))))
        else:
            lines.append(f"**proxplan** — {self.input_path or 'no plan'}")
        if self.loaded is not None and self.loaded.data.note:
            lines.append(f"*{self.loaded.data.note}*")
        if note:
            lines.append(note)
        if error:
            lines.append(f"**Error:** {error}" + (" (the previous plan stays)" if self.loaded else ""))
        return "\n\n".join(lines)

    def _camera_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """(position, look-at) of a camera that frames the workspace from the -x, -y side, m."""
        assert self.loaded is not None
        d = self.loaded.data
        centre = 0.5 * (d.workspace_min_m + d.workspace_max_m)
        span = float(np.max(d.workspace_max_m - d.workspace_min_m))
        return centre + np.array([-0.75, -0.95, 0.65]) * span, centre

    def _frame_client(self, client: Any) -> None:
        """Point an already connected browser's camera at the workspace (new browsers get the
        server's initial camera). Best effort: a client that has not reported its camera yet, or
        that is disconnecting, is left alone."""
        position, look_at = self._camera_pose()
        try:
            client.camera.position = position
            client.camera.look_at = look_at
        except Exception:  # noqa: BLE001 - cosmetic only
            pass

    # ----- loading and showing ---------------------------------------------------------------
    def load(self, path: Path | None = None) -> bool:
        """Load (plan first, for a scenario) ``path`` or the input file in the background."""
        path = path or self.input_path
        if path is None:
            return False
        if self._jobs.busy:
            self.status.content = self._status_text(
                note="busy: a plan is being loaded or planned; try again when it is shown"
            )
            return False
        self.input_path = Path(path)
        self.progress.visible = True
        self.progress.value = 0.0
        self.status.content = self._status_text(note=f"loading {path} …")
        return self._jobs.submit(Path(path), plan_fn=lambda p, progress: prepare(load_input(p, progress=progress)))

    def _replan_job(self, scenario: Any, *, progress: Callable[[str, float], None]) -> Loaded:
        plan = plan_scenario(scenario, progress=progress)
        return prepare(review_from_plan_result(plan, scenario, source_path=self.input_path))

    def _on_progress(self, stage: str, fraction: float) -> None:
        if self._terminal_progress is not None:
            self._terminal_progress(stage, fraction)
        self.progress.visible = True
        self.progress.value = float(np.clip(100.0 * fraction, 0.0, 100.0))
        self.edit_note.content = f"planning: {stage} ({100 * fraction:.0f} %)"

    def _on_done(self, _arg: Any, loaded: Loaded) -> None:
        self.progress.visible = False
        self.edit_note.content = ""
        self.show(loaded)
        _log(f"showing {loaded.data.name} ({len(loaded.data.vehicles)} vehicles)")

    def _on_error(self, arg: Any, message: str) -> None:
        self.progress.visible = False
        what = "loading failed" if isinstance(arg, Path) else "re-planning failed"
        self.edit_note.content = f"{what}; the previous plan stays" if self.loaded else ""
        self._report_error(f"{what}: {message}")

    def show(self, loaded: Loaded) -> None:
        """Replace the scene with ``loaded`` (keeps the time, clamped to the new plan)."""
        d = loaded.data
        with self._lock, self.server.atomic():
            self._remove_gizmo()
            self._layer_handles = []
            if self._layer_root is not None:
                self._layer_root.remove()
                self._layer_root = None
            self._handles.remove()
            usage = {
                name: np.interp(v.t_s, loaded.series[name].t_s, loaded.series[name].usage)
                for name, v in d.vehicles.items()
                if name in loaded.series
            }
            first = self.loaded is None
            self._handles = scene.build_scene(self.server.scene, d, usage=usage, model_scale=self.model_scale.value)
            self.loaded = loaded
            if first:  # frame the workspace; make the models visible at its scale
                self.model_scale.value = scene.readable_model_scale(d)
                scene.set_model_scale(self._handles, self.model_scale.value)
                position, look_at = self._camera_pose()
                self.server.initial_camera.position = position
                self.server.initial_camera.look_at = look_at
                for client in self.server.get_clients().values():
                    self._frame_client(client)
            names = tuple(d.vehicles)
            step = self._time_step(d)
            self.time_slider.step = step
            self.time_slider.min = d.t_start_s
            self.time_slider.max = max(d.t_end_s, d.t_start_s + step)
            # defaults: the highest vehicle as downwash source, the most disturbed one plotted
            top = max(names, key=lambda n: float(np.mean(d.vehicles[n].position_m[:, 2])))
            worst = max(names, key=lambda n: float(np.max(loaded.series[n].usage)) if n in loaded.series else -1.0)
            self.source.options = ("(none)", *names)
            if self.source.value not in names:
                self.source.value = top
            self.plot_vehicle.options = names
            if self.plot_vehicle.value not in names:
                self.plot_vehicle.value = worst
            editable = tuple(n for n in names if self._editable(n))
            self.edit_vehicle.options = ("(none)", *editable)
            if self.edit_vehicle.value not in editable:
                self.edit_vehicle.value = "(none)"
            self.legend.image = plots.render_usage_legend(d.authority_fraction)
            for folder in (self._folder_time, self._folder_layers, self._folder_plots, self._folder_edit):
                folder.visible = True
            self._folder_edit.visible = d.scenario is not None
            self.status.content = self._status_text()
            self._rebuild_layers()
            self._rebuild_plot()
            self._rebuild_gizmo()
            self._apply_visibility()
            t = float(np.clip(self.t_s, d.t_start_s, d.t_end_s))
            self.set_time(t, force=True)

    @staticmethod
    def _time_step(d: ReviewData) -> float:
        dts = [float(np.min(np.diff(v.t_s))) for v in d.vehicles.values() if v.t_s.size > 1]
        span = d.t_end_s - d.t_start_s
        step = min(dts) if dts else 0.1
        return float(max(step, span / 2000.0, 1e-3))

    def set_time(self, t_s: float, *, force: bool = False) -> dict[str, np.ndarray]:
        """Move every vehicle to plan time ``t_s`` (s) and mark it on the plot."""
        with self._lock:
            if self.loaded is None:
                return {}
            self.t_s = float(t_s)
            positions = scene.set_time(self._handles, self.loaded.data, self.t_s)
            if abs(self.time_slider.value - self.t_s) > 0.5 * self.time_slider.step:
                self.time_slider.value = self.t_s
            now = time.monotonic()
            if self._plot is not None and (force or not self.play.value or now - self._last_plot_s > 1 / PLOT_RATE_HZ):
                self.plot_image.image = self._plot.with_marker(self.t_s)
                self._last_plot_s = now
            return positions

    def _apply_visibility(self) -> None:
        with self._lock:
            for h in self._handles.trajectories.values():
                h.visible = self.show_traj.value
            for h in self._handles.obstacles:
                h.visible = self.show_obst.value
            for h in self._layer_handles:
                h.visible = self.show_cut.value if h.name.endswith("/cutoff") else self.show_iso.value

    def _rebuild_layers(self) -> None:
        with self._lock:
            for h in self._layer_handles:
                h.remove()
            self._layer_handles = []
            if self._layer_root is not None:
                self._layer_root.remove()
                self._layer_root = None
            if self.loaded is None or self.source.value not in self.loaded.data.vehicles:
                return
            d = self.loaded.data
            src = d.vehicles[self.source.value]
            tgt_name = self.plot_vehicle.value if self.plot_vehicle.value in d.vehicles else src.name
            if tgt_name == src.name and len(d.vehicles) > 1:
                tgt_name = next(n for n in d.vehicles if n != src.name)
            depth = float(max(np.max(src.position_m[:, 2]) - d.workspace_min_m[2], 1.0))
            self._layer_root = self.server.scene.add_frame(f"/vehicles/{src.name}/downwash", show_axes=False)
            self._layer_handles, profiles = layers.add_layers(
                self.server.scene,
                f"/vehicles/{src.name}/downwash",
                src.vehicle,
                d.vehicles[tgt_name].vehicle,
                depth_m=depth,
                level=d.authority_fraction,
                invalid_rule=getattr(getattr(d.scenario, "limits", None), "invalid_zone_rule", None),
                show_iso=self.show_iso.value,
                show_cutoff=self.show_cut.value,
            )
            iso = ", ".join(p.label for p in profiles[:-1])
            r_cut = float(np.max(profiles[-1].r_m))
            self.layer_note.content = (
                f"Jet of **{src.name}**: iso-speed surfaces at {iso} (red, orange, blue). "
                f"Cutoff surface (purple) for target **{tgt_name}** at usage {d.authority_fraction:.2f}: "
                + (
                    f"widest r_cut = {r_cut:.2f} m."
                    if r_cut > 0
                    else "r_cut = 0 everywhere (this source cannot push this target to the limit)."
                )
            )

    def _rebuild_plot(self) -> None:
        with self._lock:
            if self.loaded is None or self.plot_vehicle.value not in self.loaded.series:
                self._plot = None
                return
            name = self.plot_vehicle.value
            self._plot = plots.render_series(
                self.loaded.series[name], name=name, limit=self.loaded.data.authority_fraction
            )
            self.plot_image.image = self._plot.with_marker(self.t_s)

    def _plot_vehicle_changed(self) -> None:
        """The plotted vehicle is also the cutoff surface's target: redraw both."""
        self._rebuild_plot()
        self._rebuild_layers()
        self._apply_visibility()

    # ----- playback and export ---------------------------------------------------------------
    def _play_loop(self) -> None:
        period = 1.0 / PLAY_RATE_HZ
        while self._running:
            time.sleep(period)
            try:
                if not self.play.value or self.loaded is None:
                    continue
                d = self.loaded.data
                t = self.t_s + period * self.speed.value
                if t > d.t_end_s:
                    t = d.t_start_s
                self.set_time(t)
            except Exception:  # noqa: BLE001 - never kill the player thread
                traceback.print_exc(file=sys.stderr)
                time.sleep(1.0)

    def export(self, out_dir: Path, *, frame_dt_s: float = 0.1) -> Path:
        """Write a self-contained recording of the current plan to ``out_dir`` (see proxplan.web.export)."""
        from proxplan.web.export import record_scene, write_export

        if self.loaded is None:
            from proxplan.fileio import UserError

            raise UserError("nothing to export: no plan is loaded")
        d = self.loaded.data
        with self._lock:
            t_keep = self.t_s
            playing = self.play.value
            self.play.value = False
            try:
                payload, frames = record_scene(
                    self.server,
                    lambda t: scene.set_time(self._handles, d, t),
                    t_start_s=d.t_start_s,
                    t_end_s=d.t_end_s,
                    frame_dt_s=frame_dt_s,
                    prelude=self._record_initial_camera,
                )
            finally:
                self.set_time(t_keep, force=True)
                self.play.value = playing
        return write_export(out_dir, payload, name=d.name, frames=frames, duration_s=d.t_end_s - d.t_start_s)

    def _record_initial_camera(self) -> None:
        """Re-send the initial camera so a recording opens framed on the workspace."""
        position, look_at = self._camera_pose()
        self.server.initial_camera.position = position
        self.server.initial_camera.look_at = look_at

    def default_export_dir(self) -> Path:
        """Beside the plan.json that is shown, else in the working directory."""
        d = self.loaded.data if self.loaded else None
        name = f"{d.name if d else 'plan'}_recording"
        if d is not None and d.source_path is not None and d.source_path.suffix == ".json":
            return d.source_path.parent / name
        return Path.cwd() / name

    def _export_clicked(self, client: Any) -> None:
        out = self.export(self.default_export_dir())
        _log(f"wrote recording to {out}")
        if client is not None:
            client.add_notification("proxplan", f"recording written to {out}", auto_close_seconds=10.0)
            client.send_file_download("recording.viser", (out / "recording.viser").read_bytes())

    def stop(self) -> None:
        self._running = False
        self._player.join(timeout=2.0)
