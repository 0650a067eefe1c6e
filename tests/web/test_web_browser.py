"""`proxplan view` in a real browser: headless Debian Chromium driven over the DevTools protocol.

Starts the app on a free port with a hand-made plan, loads the page, waits for the scene, saves a
screenshot to test-artifacts/ and checks the 3-D canvas is not blank (grey-level spread well above
that of an empty scene: a bare viser server with nothing in it). Also reloads the page (disconnect +
reconnect) and checks the server survives and shuts down cleanly on Ctrl-C (SIGINT), also when the
test itself runs in the background of a non-interactive shell, whose children inherit SIGINT
ignored; a bad plan file is an error at start-up (exit 2, one line), never a page that shows it
forever.
"""

from __future__ import annotations

import base64
import io
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
WIDTH, HEIGHT = 1280, 800
CANVAS_BOX = (slice(160, 740), slice(0, 930))  # rows, cols of the 3-D view clear of GUI panel and toasts

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(
        not CHROMIUM.exists(), reason="needs Debian chromium at /usr/bin/chromium (.ci/run installs it)"
    ),
]


class Chromium:
    """Headless Chromium with one page, driven over the DevTools protocol (websocket)."""

    def __init__(self) -> None:
        from websockets.sync.client import connect

        self.profile = tempfile.mkdtemp(prefix="proxplan-chromium-")
        self.proc = subprocess.Popen(
            [
                str(CHROMIUM),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--no-first-run",
                f"--user-data-dir={self.profile}",
                f"--window-size={WIDTH},{HEIGHT}",
                "--remote-debugging-port=0",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = Path(self.profile) / "DevToolsActivePort"
        deadline = time.monotonic() + 30.0
        while not (port_file.exists() and port_file.read_text().strip()):
            if time.monotonic() > deadline or self.proc.poll() is not None:
                self.close()
                raise RuntimeError("chromium did not open its DevTools port")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10))
        page = next(t for t in targets if t["type"] == "page")
        self.ws = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=10)
        self._id = 0
        self.call("Emulation.setDeviceMetricsOverride", width=WIDTH, height=HEIGHT, deviceScaleFactor=1, mobile=False)

    def call(self, method: str, **params):
        self._id += 1
        self.ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=60))
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg["result"]

    def text(self) -> str:
        res = self.call(
            "Runtime.evaluate", expression="document.body ? document.body.innerText : ''", returnByValue=True
        )
        return res["result"].get("value") or ""

    def wait_for_text(self, needle: str, timeout_s: float = 60.0) -> str:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            text = self.text()
            if needle in text:
                return text
            time.sleep(0.25)
        raise AssertionError(f"page never showed {needle!r}; it shows: {self.text()[:500]!r}")

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def close(self) -> None:
        try:
            if getattr(self, "ws", None) is not None:
                self.ws.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            shutil.rmtree(self.profile, ignore_errors=True)


def _grey(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)


def _canvas_spread(png: bytes) -> float:
    """Standard deviation of the grey levels in the 3-D view region, 0-255."""
    return float(_grey(png)[CANVAS_BOX].std())


def _settled_screenshot(browser: Chromium, timeout_s: float = 40.0) -> bytes:
    """Screenshot once two consecutive ones (1 s apart) agree: the scene has arrived and rendered."""
    last = browser.screenshot()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(1.0)
        shot = browser.screenshot()
        if np.array_equal(_grey(shot)[CANVAS_BOX], _grey(last)[CANVAS_BOX]):
            return shot
        last = shot
    return last


def _rendered_screenshot(browser: Chromium, needed: float, timeout_s: float = 180.0) -> bytes:
    """The first settled screenshot whose 3-D view spreads more than ``needed`` (the scene has
    arrived and rendered), else the last one after ``timeout_s``: headless Chromium renders WebGL
    in software, and on a busy machine it can hold a half-faded-in frame for seconds, which two
    equal screenshots in a row do not rule out."""
    deadline = time.monotonic() + timeout_s
    shot = _settled_screenshot(browser)
    while _canvas_spread(shot) <= needed and time.monotonic() < deadline:
        time.sleep(1.0)
        shot = _settled_screenshot(browser)
    return shot


EMPTY_SERVER = (
    "import contextlib, json, sys, time, viser\n"
    "with contextlib.redirect_stdout(sys.stderr):\n    s = viser.ViserServer(host='127.0.0.1', port=0, verbose=False)\n"
    "print(json.dumps({'url': f'http://127.0.0.1:{s.get_port()}'}), flush=True)\ntime.sleep(600)\n"
)


def _start_view(path: Path | None) -> tuple[subprocess.Popen, str]:
    """``proxplan view PATH`` on a free port (a bare viser server with an empty scene for None)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    argv = ["-c", EMPTY_SERVER] if path is None else ["-m", "proxplan.cli", "view", str(path), "--port", "0", "--json"]
    proc = subprocess.Popen(
        [sys.executable, *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    ready, _, _ = select.select([proc.stdout], [], [], 60.0)
    if not ready:
        proc.kill()
        raise AssertionError("proxplan view printed no URL within 60 s")
    line = proc.stdout.readline()
    if not line:
        proc.wait(10)
        raise AssertionError(f"proxplan view exited {proc.returncode}: {proc.stderr.read()}")
    return proc, json.loads(line)["url"]


def _stop(proc: subprocess.Popen) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
    return proc.returncode


def test_view_renders_plan_in_headless_chromium(tmp_path):
    from proxplan.web.demo import DEMO_SPEC, write_demo_plan

    plan = write_demo_plan(tmp_path / "demo")
    bad = tmp_path / "bad" / "plan.json"
    bad.parent.mkdir()
    bad.write_text('{"scenario": "x", "dt_s": 0.1, "vehicles": {')
    ARTIFACTS.mkdir(exist_ok=True)

    bad_run = subprocess.run([sys.executable, "-m", "proxplan.cli", "view", str(bad), "--port", "0"],
                             capture_output=True, text=True, timeout=60)  # fmt: skip
    assert bad_run.returncode == 2 and bad_run.stdout == ""
    assert bad_run.stderr.count("\n") == 1 and "not valid JSON" in bad_run.stderr and str(bad) in bad_run.stderr

    good_proc, good_url = _start_view(plan)
    empty_proc, empty_url = _start_view(None)
    browser = Chromium()
    try:
        browser.call("Page.navigate", url=empty_url)
        time.sleep(2.0)
        empty = _settled_screenshot(browser)
        (ARTIFACTS / "web_view_empty_scene.png").write_bytes(empty)
        needed = 2.0 * _canvas_spread(empty) + 3.0  # a scene well above a bare viser page

        browser.call("Page.navigate", url=good_url)
        text = browser.wait_for_text(DEMO_SPEC["name"])
        browser.wait_for_text("Jet of")  # the layers are built
        assert "Error" not in text
        shot = _rendered_screenshot(browser, needed)
        (ARTIFACTS / "web_view_plan.png").write_bytes(shot)
        assert _canvas_spread(shot) > needed, (_canvas_spread(shot), needed)

        # reconnect: the page is served again with the same scene, the server is still up
        browser.call("Page.navigate", url=empty_url)
        browser.call("Page.navigate", url=good_url)
        browser.wait_for_text(DEMO_SPEC["name"])
        again = _rendered_screenshot(browser, needed)
        assert _canvas_spread(again) > needed, (_canvas_spread(again), needed)
        assert good_proc.poll() is None
    finally:
        browser.close()
        code = _stop(good_proc)
        empty_proc.kill()
        empty_proc.wait(10)
    assert code == 0, good_proc.stderr.read() if good_proc.stderr else ""


@pytest.mark.slow
def test_exported_recording_replays_without_the_app(tmp_path):
    """`--export` output served by a plain static web server replays in Chromium (no proxplan)."""
    import functools
    import threading
    from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

    from proxplan.web.demo import write_demo_plan

    plan = write_demo_plan(tmp_path / "demo")
    out = tmp_path / "rec"
    proc = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "view", str(plan), "--export", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr

    class Quiet(SimpleHTTPRequestHandler):
        def log_message(self, *args) -> None:  # keep the test output clean
            pass

    handler = functools.partial(Quiet, directory=str(out))
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    browser = Chromium()
    try:
        browser.call("Page.navigate", url=f"http://127.0.0.1:{httpd.server_port}/?playbackPath=recording.viser")
        time.sleep(3.0)
        shot = _settled_screenshot(browser)
        ARTIFACTS.mkdir(exist_ok=True)
        (ARTIFACTS / "web_recording_replay.png").write_bytes(shot)
        assert _canvas_spread(shot) > 5.0  # an empty viser page measures about 0.5 here
    finally:
        browser.close()
        httpd.shutdown()
