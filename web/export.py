"""Self-contained recording of the review scene (viser's scene serializer), replayable anywhere.

The export directory holds ``recording.viser`` (the scene plus the vehicles moving along the plan,
one frame per ``frame_dt_s`` of plan time), ``index.html`` (viser's prebuilt client, copied from
the installed package) and ``README.txt``. Replay without the planner or Python packages:

    cd DIR && python3 -m http.server 8000
    # open http://localhost:8000/?playbackPath=recording.viser
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from proxplan.fileio import output_folder

README = """proxplan review recording: {name}

Replay (no planner needed; any static web server works):
    cd {dirname} && python3 -m http.server 8000
    open http://localhost:8000/?playbackPath=recording.viser

recording.viser  viser scene recording ({frames} frames, {duration:.1f} s of plan time)
index.html       viser {version} web client
"""


def viser_client_index() -> Path:
    """The installed viser client's single-file ``index.html``."""
    import viser

    return Path(viser.__file__).resolve().parent / "client" / "build" / "index.html"


def record_scene(
    server,
    set_time: Callable[[float], object],
    *,
    t_start_s: float,
    t_end_s: float,
    frame_dt_s: float = 0.1,
    speed: float = 1.0,
    prelude: Callable[[], None] | None = None,
) -> tuple[bytes, int]:
    """Serialize the current scene and one frame per ``frame_dt_s`` of plan time.

    ``set_time(t_s)`` must move the scene to plan time ``t_s`` (it is called for every frame).
    ``prelude()`` runs once at the start of the recording (e.g. to record the initial camera).
    Playback runs at ``speed`` times real time. Returns (bytes, number of frames).
    """
    times = np.arange(t_start_s, t_end_s + 0.5 * frame_dt_s, frame_dt_s)
    serializer = server.get_scene_serializer()
    try:
        if prelude is not None:
            prelude()
        for t in times:
            set_time(float(t))
            serializer.insert_sleep(frame_dt_s / speed)
    finally:
        payload = serializer.serialize()
    return payload, int(times.size)


def write_export(out_dir: str | Path, payload: bytes, *, name: str, frames: int, duration_s: float) -> Path:
    """Write recording.viser, index.html and README.txt to ``out_dir`` (all three, or none)."""
    import viser

    out_dir = Path(out_dir).resolve()
    with output_folder(out_dir, flag="--export") as stage:
        (stage / "recording.viser").write_bytes(payload)
        shutil.copyfile(viser_client_index(), stage / "index.html")
        (stage / "README.txt").write_text(
            README.format(name=name, dirname=out_dir, frames=frames, duration=duration_s, version=viser.__version__)
        )
    return out_dir
