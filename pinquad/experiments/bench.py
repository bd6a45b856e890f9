"""``python -m pinquad.bench``: how fast the E-step, EM and the online update are.

Prints a table and writes ``bench.json`` (``--out``). Every figure is the median of
several runs (``--repeats``, 5 by default; ``--repeats-large``, 3, for N >= 100,000;
one run of the end-to-end offline command), and every comparison is made in one
process on the same inputs:

* E-step (EKF + RTS smoother with cross-covariances) for N = 1,000 / 10,000 / 100,000
  steps. Ours is the compiled ``pinquad.estep.fast_smoother.smooth_quad`` on the quadcopter
  model; long inputs are a simulated sensor-B flight's inputs and measurements repeated
  end to end (``pinquad.experiments.bench_cases``). The peers (filterpy, pykalman, dynamax, our
  GTSAM batch smoother, and our generic Python RTS) smooth the same model linearised
  along the EKF's filtered means, a linear time-varying model whose smoother equals the
  EKF-RTS one; each peer's smoothed means are checked against ours (1e-8 of the state
  scale) before it is timed. Each (peer, N) runs in its own worker process that times
  ours and the peer alternately; a peer call longer than ``--timeout`` seconds (120) is
  stopped, and a peer whose time at the previous N, scaled linearly, would exceed it is
  skipped, both with a note.
* Memory: a fresh worker per (method, N) runs the method once after loading the case and
  importing (and compiling) the library; it reports the peak resident set during the
  call above the resident set before it (the kernel's VmHWM, reset just before the call,
  so it sees every allocator: NumPy, numba, XLA, GTSAM) and the peak of the call's
  Python-traced allocations (``tracemalloc``: NumPy's and numba's arrays, not XLA's or
  GTSAM's C++ heap); see :func:`call_peak_memory`.
* One offline EM (regressor M-step, paper's initial guess, at most 100 E-steps) on a
  60 s simulated flight, and ``python -m pinquad.offline`` with its defaults end to end
  as a subprocess (skipped with ``--quick``).
* ``python -m pinquad.offline --log`` on a 60 s, 500 Hz simulated log with drag
  (``pinquad.experiments.bench_discovery``): base EM, discovery with its null
  calibration, verdicts, end to end, once (``log_discovery_60s_s``; the figure of the
  code before the speed-up beside it).
* The online update latency on an 800-sample window, p50 and p99, from
  ``pinquad.experiments.online.measure_update_latency`` (``not available`` if that is missing).
* ``--profile``: where our E-step's time goes (wrapper checks vs compiled loops).

``--check N`` runs only the correctness checks on an N-step case and exits 1 if a
present peer disagrees (absent peers are listed, not failed).

The benchmark's rooms: this module holds the measurement primitives (timed calls, peak
memory, machine description) and the worker protocol (:func:`run_worker`: one fresh
``python -m pinquad.bench --worker KIND --spec JSON`` process per measurement, its
result one tagged JSON line); ``bench_cases`` and ``bench_estep`` the E-step cases and
contestants; ``bench_workers`` what a worker measures; ``bench_profile`` the ``--profile``
section; ``bench_run`` the sections and the result document; ``pinquad.report.bench``
the printed tables; ``pinquad.cli.bench`` the command line.
"""

from __future__ import annotations

import gc
import json
import math
import os
import platform
import resource
import signal
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Callable
from importlib import metadata
from typing import Any

import numpy as np

RESULT_TAG = "BENCH-RESULT "
"""Prefix of the stdout line that carries a worker's JSON result."""
DEFAULT_N = (1_000, 10_000, 100_000)
"""E-step lengths [steps] timed by default."""
LARGE_N = 100_000
"""From this length [steps] on, ``repeats_large`` runs per figure."""
PEERS = ("generic", "filterpy", "pykalman", "dynamax", "gtsam")
"""The E-step peers compared with ours."""
SECTIONS = ("estep", "memory", "em", "online", "offline", "discovery")
"""The benchmark's sections, in the order they run."""
EM_SECONDS = 60.0
"""Length [s] of the simulated flight of the offline EM timing."""
DISCOVERY_BEFORE = {
    "s": 225.4,
    "cpu_s": 258.6,
    "commit": "a05de1b",
    "date": "2026-11-25",
    "load_average": [1.3, 1.0],
    "note": "python -m pinquad.offline --log on this log, the code before the "
            "speed-up (a worktree of main at the commit), numba caches warm, no profiler, "
            "nothing else running (load average at start and end; cpu_s: user + sys); "
            "on the shared machine earlier the same run took 440.4 s at load 4.7-10.2",
}
"""``log_discovery_60s_s`` of the code before the speed-up: ``python -m pinquad.offline
--log`` on the discovery log of ``bench_discovery``, measured once (minutes)."""


# --------------------------------------------------------------------------- helpers


class CallTimeout(Exception):
    """A timed call ran past its time limit."""


def _alarm(signum: int, frame: Any) -> None:
    raise CallTimeout


def timed_call(fn: Callable[[], Any], limit: float | None = None) -> tuple[float, Any]:
    """Wall time [s] of ``fn()`` and its result; garbage collected before and disabled
    during the call (as ``timeit`` does). With ``limit`` the call is interrupted by
    SIGALRM after that many seconds (:class:`CallTimeout`): Python-level loops stop at
    once, a long call into compiled code when it returns."""
    gc.collect()
    gc.disable()
    if limit is not None:
        old = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        t0 = time.perf_counter()
        out = fn()
        return time.perf_counter() - t0, out
    finally:
        if limit is not None:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, old)
        gc.enable()


def maxrss_mb() -> float:
    """Peak resident set of this process so far [MB] (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def status_mb(field: str) -> float | None:
    """A memory line of /proc/self/status [MB], None where there is none."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def reset_peak_rss() -> bool:
    """Reset this process's peak RSS (VmHWM) to its current RSS (Linux >= 4.0)."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def call_peak_memory(fn: Callable[[], Any]) -> dict:
    """Memory of one call of ``fn``: ``rss_growth_mb``, the peak resident set during the
    call above the resident set just before it (the kernel's peak counter VmHWM, reset
    before the call; every allocator counts: NumPy, numba, XLA, GTSAM), and
    ``python_peak_mb``, the tracemalloc peak of the call (allocations reported to
    Python's tracer: NumPy's and numba's arrays and Python objects, not XLA's or
    GTSAM's C++ heap). Without /proc, the growth of ru_maxrss (a lower bound)."""
    gc.collect()
    exact = reset_peak_rss()
    before = status_mb("VmRSS") if exact else maxrss_mb()
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    after = status_mb("VmHWM") if exact else maxrss_mb()
    growth = None if before is None or after is None else after - before
    return {"rss_growth_mb": growth, "python_peak_mb": peak / 2**20,
            "rss_before_mb": before, "rss_method": "VmHWM reset" if exact else "ru_maxrss"}


def median(xs: list[float]) -> float | None:
    """Median of ``xs`` (a time [s] or a size [MB]); None for no values."""
    return float(np.median(xs)) if xs else None


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def machine_info() -> dict:
    """CPU count, platform and library versions of this run."""
    info: dict[str, Any] = {
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(),
        "loadavg_at_start": list(os.getloadavg()),
    }
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info["versions"] = {d: _version(d) for d in (
        "numpy", "scipy", "numba", "gtsam", "pin", "filterpy", "pykalman", "dynamax", "jax",
        "jaxlib")}
    return info


def loglog_slope(ns: list[int], ts: list[float | None]) -> float | None:
    """Least-squares slope of log t against log N over the points with a time."""
    pts = [(n, t) for n, t in zip(ns, ts, strict=True) if t is not None and t > 0]
    if len(pts) < 2:
        return None
    x = np.log([p[0] for p in pts])
    y = np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def _clean(x: Any) -> Any:
    """JSON-safe copy: NaN/inf -> None, NumPy scalars -> Python."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


# --------------------------------------------------------------------------- workers


def log(msg: str) -> None:
    """Progress on stderr (the table goes to stdout)."""
    print(msg, file=sys.stderr, flush=True)


def run_worker(kind: str, spec: dict, timeout: float | None) -> dict:
    """Run one worker in a fresh process; its result, or a status saying why none."""
    cmd = [sys.executable, "-m", "pinquad.bench", "--worker", kind, "--spec", json.dumps(spec)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"status": "timeout", "note": f"worker killed after {timeout:.0f} s"}
    for line in reversed(proc.stdout.splitlines()):
        if line.startswith(RESULT_TAG):
            return json.loads(line[len(RESULT_TAG):])
    tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    return {"status": "error", "note": f"worker exited {proc.returncode}: {tail}"}


def worker_result_line(result: dict) -> str:
    """A worker's result as the one tagged JSON line :func:`run_worker` looks for."""
    return RESULT_TAG + json.dumps(_clean(result))
