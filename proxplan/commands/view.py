"""`proxplan view`: the viser review app for a scenario (planned first) or a plan.json."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "view",
        help="review a scenario or plan in the browser (viser)",
        description=(
            "Start a viser server showing a plan in 3-D: workspace, obstacles, vehicle models moving "
            "along their trajectories (coloured by authority usage), the downwash jet and cutoff "
            "surface of a selected source, per-vehicle force/torque/usage plots, goal editing with "
            "background re-planning, and an export of a self-contained recording. A scenario YAML is "
            "planned first (progress on stderr and in the page)."
        ),
    )
    p.add_argument(
        "input", metavar="SCENARIO.yaml|DIR/plan.json", help="scenario to plan, or a plan.json (or its directory)"
    )
    p.add_argument("--port", type=int, default=8080, help="TCP port (default 8080; 0 picks a free one)")
    p.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1; 0.0.0.0 for all)")
    p.add_argument(
        "--export",
        metavar="DIR",
        default=None,
        help="write a self-contained recording (recording.viser + index.html) to DIR and exit",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object (url or export directory) on stdout")
    p.set_defaults(func=run)


def _terminal_progress():
    from tqdm import tqdm

    bar: dict[str, Any] = {"bar": None}

    def update(stage: str, fraction: float) -> None:
        if bar["bar"] is None:
            bar["bar"] = tqdm(total=100, desc="planning", unit="%", leave=False)
        b = bar["bar"]
        b.set_description(str(stage)[:30])
        b.n = round(100 * min(max(fraction, 0.0), 1.0))
        b.refresh()
        if fraction >= 1.0:
            b.close()
            bar["bar"] = None

    return update


def _check_listen_address(host: str, port: int) -> None:
    """UserError unless ``host`` can be listened on (viser would retry forever on a bad host). A
    port already in use is fine: viser takes the next free one and the printed URL says which."""
    import errno
    import socket

    from proxplan.fileio import UserError

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as err:
        raise UserError(
            f"--host {host}: cannot resolve this address ({err.strerror}); expected e.g. 127.0.0.1 or 0.0.0.0"
        ) from err
    family, socktype, proto, _, addr = infos[0]
    with socket.socket(family, socktype, proto) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(addr)
        except OSError as err:
            if err.errno != errno.EADDRINUSE:
                raise UserError(f"--host {host} --port {port}: cannot listen here ({err.strerror})") from err


def _check_input(path) -> None:
    """Read and validate the scenario or plan now; UserError naming file and key when it is bad."""
    from proxplan.planfile import load_scenario, read_plan
    from proxplan.verify import scenario_of_plan

    if path.suffix in (".yaml", ".yml"):
        load_scenario(path)
    else:
        plan = read_plan(path)
        if plan.format_version >= 2 and plan.scenario_spec is not None:  # older plans may lack theirs
            scenario_of_plan(plan, label=str(path))


def run(args: argparse.Namespace) -> int:
    import contextlib
    import json
    import logging
    import sys
    import time
    from pathlib import Path

    from proxplan.fileio import UserError

    path = Path(args.input)
    if not path.exists():
        raise UserError(f"{path}: no such file; expected SCENARIO.yaml, DIR/plan.json or DIR")
    if path.is_dir() and not (path / "plan.json").exists():
        raise UserError(f"{path}: directory holds no plan.json")
    if not 0 <= args.port <= 65535:
        raise UserError(f"--port: expected 0..65535, got {args.port}")
    _check_input(path)  # a bad file is a start-up error (exit 2), not a page that shows it forever
    if args.export:
        from proxplan.fileio import output_folder

        with output_folder(Path(args.export), flag="--export"):
            pass  # only checks that the folder can be written before anything is planned

    if not args.export:
        _check_listen_address(args.host, args.port)

    import viser

    from proxplan.web import ReviewApp

    logging.getLogger("websockets").setLevel(logging.CRITICAL)
    with contextlib.redirect_stdout(sys.stderr):  # viser's banner must not mix with --json output
        server = viser.ViserServer(
            host="127.0.0.1" if args.export else args.host, port=0 if args.export else args.port, verbose=False
        )
    app = ReviewApp(server, path, terminal_progress=_terminal_progress())
    try:
        if args.export:
            app.load()
            app.wait_idle()
            if app.loaded is None:
                return 1  # the load error is already on stderr
            out = app.export(Path(args.export))
            print(json.dumps({"export_dir": str(out)}) if args.json else f"wrote {out}")
            return 0
        import signal

        def _terminate(_signum, _frame):  # SIGTERM (e.g. a service manager): shut down like Ctrl-C
            raise KeyboardInterrupt

        signal.signal(signal.SIGTERM, _terminate)
        # Ctrl-C (SIGINT) stops the server however it was started: a process started in the
        # background of a non-interactive shell (``proxplan view ... &`` in a script, a test suite run
        # that way) inherits SIGINT *ignored*, and Python then leaves it ignored, so the server would
        # not stop on SIGINT at all.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        host = "localhost" if args.host in ("0.0.0.0", "127.0.0.1", "::") else args.host
        url = f"http://{host}:{server.get_port()}"
        print(json.dumps({"url": url}) if args.json else f"proxplan view: open {url}", flush=True)
        app.load()
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("proxplan view: stopped", file=sys.stderr)
        return 0
    finally:
        app.stop()
        with contextlib.redirect_stdout(sys.stderr):
            server.stop()
