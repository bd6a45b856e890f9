"""``python -m viz RUN_DIR [--port N] [--host H]``: serve the browser view of a finished run.

Serves on 127.0.0.1:8080 unless told otherwise; ``--host`` exposes it to other machines
only when the user asks. A directory that is not a run is a one-line error, exit 2.
"""

from __future__ import annotations

import argparse
import signal
import socket
import sys
import threading
import time
from pathlib import Path

from pinquad.cli.help import HelpFormatter


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m viz``."""
    p = argparse.ArgumentParser(
        prog="python -m viz",
        description="Browser view (viser) of a finished pinquad run directory: the vehicle "
                    "flying its logged trajectory (truth and estimate), the waypoints, the "
                    "mass and inertia estimates per EM iteration or online update beside "
                    "the truth, and any effect-discovery figures. Stop with Ctrl-C.",
        formatter_class=HelpFormatter)
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path,
                   help="run directory written by python -m pinquad.offline or pinquad.online "
                        "(holds report.json)")
    p.add_argument("--port", type=int, default=8080,
                   help="TCP port (the next free one is used if it is busy; 0 = any free port)")
    p.add_argument("--host", default="127.0.0.1",
                   help="interface to listen on; 0.0.0.0 exposes the view to the network")
    p.add_argument("--scale", type=float, default=None,
                   help="display magnification of the vehicle (default: 5 for the paper's "
                        "vehicle, 15 for the Crazyflie 2.1)")
    return p


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


RESOLVE_TIMEOUT_S = 5.0
"""How long a host name may take to resolve before the viewer gives up [s]."""


def bind_problem(host: str, timeout_s: float = RESOLVE_TIMEOUT_S) -> str | None:
    """Why this machine cannot listen on ``host`` (a name that does not resolve within
    ``timeout_s``, or an address that is not one of its interfaces), or None. Checked
    before the web server starts: given such a host, it waits forever."""
    found: list[object] = []

    def resolve() -> None:
        try:
            found.append(socket.getaddrinfo(host, None, type=socket.SOCK_STREAM))
        except OSError as exc:
            found.append(exc)

    worker = threading.Thread(target=resolve, daemon=True)
    worker.start()
    worker.join(timeout_s)
    if not found:
        return f"the name {host!r} did not resolve within {timeout_s:g} s"
    if isinstance(found[0], OSError):
        return f"the name {host!r} does not resolve ({found[0]})"
    family, _, _, _, address = found[0][0]  # type: ignore[index]
    try:
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            probe.bind((address[0], 0))
    except OSError as exc:
        return f"{host} is not an address of this machine ({exc.strerror or exc})"
    return None


def main(argv: list[str] | None = None) -> int:
    """Run the viewer until interrupted. Returns the process exit code."""
    args = build_parser().parse_args(argv)
    if not 0 <= args.port <= 65535:
        print(f"error: --port {args.port} is not a TCP port (0-65535)", file=sys.stderr)
        return 2
    if args.scale is not None and not args.scale > 0:
        print(f"error: --scale {args.scale} must be positive", file=sys.stderr)
        return 2

    problem = bind_problem(args.host)
    if problem is not None:
        print(f"error: --host {args.host}: cannot serve there: {problem}; use 127.0.0.1 "
              "(this machine) or 0.0.0.0 (every interface)", file=sys.stderr)
        return 2

    from viz.run import RunError

    try:
        from viz.app import serve

        viewer = serve(args.run_dir, host=args.host, port=args.port, scale=args.scale)
    except RunError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: cannot serve on {args.host}:{args.port} ({exc})", file=sys.stderr)
        return 2
    # A service manager or `timeout` stops us with SIGTERM: leave as cleanly as Ctrl-C.
    signal.signal(signal.SIGTERM, _interrupt)
    for warning in viewer.run.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"pinquad viewer of {args.run_dir}: open {viewer.url}  (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(3600.0)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
