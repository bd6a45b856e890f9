"""What a benchmark worker measures: ``python -m pinquad.bench --worker KIND --spec
JSON`` runs one of these in a fresh process (:func:`pinquad.experiments.bench.run_worker`)
and prints its result as one tagged JSON line (:func:`worker_main`). The kinds:
``estep`` (ours and one peer timed alternately), ``memory`` (one call's peak memory),
``em`` (offline EM on a 60 s flight), ``online`` (the online update's latency),
``offline`` (the offline command end to end) and ``discovery`` (``offline --log`` on a
60 s, 500 Hz log with one effect: ``bench_discovery``); see :mod:`pinquad.experiments.bench`.
"""

from __future__ import annotations

import json
import math
import resource
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_VEHICLE
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.experiments.bench import (
    EM_SECONDS,
    CallTimeout,
    call_peak_memory,
    reset_peak_rss,
    status_mb,
    timed_call,
    worker_result_line,
)
from pinquad.experiments.bench_cases import TOLERANCE, load_case, mean_error
from pinquad.experiments.bench_estep import contestant
from pinquad.identification.em import initial_theta, run_em
from pinquad.models.sources import Observations, observations
from pinquad.mstep.protocol import REGRESSOR


def _worker_estep(spec: dict) -> dict:
    """Time ours and one peer alternately on one case (module docstring)."""
    case = load_case(Path(spec["case"]))
    name, repeats, limit = spec["method"], int(spec["repeats"]), float(spec["timeout"])
    ours_run, _ = contestant("ours").prepare(case)
    out: dict[str, Any] = {"method": name, "N": case.n_steps}
    out["ours_first_s"], ref = timed_call(ours_run)
    if name == "ours":
        out["ours_s"] = [timed_call(ours_run)[0] for _ in range(repeats)]
        out["status"] = "ok"
        return out
    t0 = time.perf_counter()
    run, info = contestant(name).prepare(case)
    out["prepare_s"] = time.perf_counter() - t0
    out.update(info)
    try:
        out["first_s"], mean = timed_call(run, limit)
    except CallTimeout:
        out["status"] = "timeout"
        out["note"] = f"first call stopped after {limit:.0f} s"
        return out
    err = mean_error(mean, ref)
    out["check_error"] = err
    del mean
    if not (math.isfinite(err) and err <= TOLERANCE):
        out["status"] = "mismatch"
        out["note"] = f"smoothed means differ from ours by {err:.2e} of the state scale"
        return out
    ours_t, peer_t = [], []
    for _ in range(repeats):
        ours_t.append(timed_call(ours_run)[0])
        try:
            peer_t.append(timed_call(run, limit)[0])
        except CallTimeout:
            out["note"] = f"a timed call was stopped after {limit:.0f} s"
            break
    out.update(ours_s=ours_t, peer_s=peer_t, status="ok" if peer_t else "timeout")
    return out


def _worker_memory(spec: dict) -> dict:
    """One call of a method after load/import/compile: growth of peak RSS and the
    tracemalloc peak (module docstring)."""
    case = load_case(Path(spec["case"]))
    if spec["method"] == "ours":
        # load the compiled kernels from numba's cache first (a short call)
        smooth_quad(case.model, case.ys[:50])
    run, _ = contestant(spec["method"]).prepare(case)
    out = call_peak_memory(run)
    out.update(method=spec["method"], N=case.n_steps)
    return out


def em_observations(seconds: float = EM_SECONDS, seed: int = 7) -> Observations:
    """Sensor-B observations of a simulated flight of the paper's scenario, hovering at
    the last waypoint long enough to last ``seconds``, cut to exactly that length."""
    # deferred on purpose: only the em worker flies; importing the simulator would cost
    # every other worker process seconds and ~100 MB
    from pinquad.sim.simulator import SimConfig, flight_log, simulate

    cfg = SimConfig(sensor="B")
    base = simulate(cfg, np.random.default_rng(seed))
    extra = max(0.0, seconds - float(base.t[-1])) + 1.0
    flight = simulate(SimConfig(sensor="B", settle_time=cfg.settle_time + extra),
                      np.random.default_rng(seed))
    log = flight_log(flight)
    n = int(round(seconds / log.dt))
    return observations(log.slice(0, min(n, log.n)), "B")


def _worker_em(spec: dict) -> dict:
    """Offline EM on a 60 s flight: regressor M-step from the paper's initial guess."""
    obs = em_observations(float(spec.get("seconds", EM_SECONDS)))
    theta0 = initial_theta(obs, PAPER_INITIAL_MASS, PAPER_INITIAL_INERTIA,
                           PAPER_VEHICLE.gravity)

    def run():
        return run_em(obs, theta0, smooth_quad, REGRESSOR, max_iterations=100)

    first, res = timed_call(run)
    times = [first] + [timed_call(run)[0] for _ in range(int(spec["repeats"]) - 1)]
    mem = call_peak_memory(run)
    return {"s": times, "first_s": first, "steps": obs.n, "seconds": float(obs.n * obs.dt),
            "iterations": res.iterations, "e_steps": res.e_steps, "converged": res.converged,
            "mass": res.theta.mass, "mass_true": PAPER_VEHICLE.mass,
            "inertia_diag": np.diag(res.theta.inertia).tolist(),
            "inertia_diag_true": np.diag(PAPER_VEHICLE.inertia).tolist(),
            "rss_growth_mb": mem["rss_growth_mb"], "python_peak_mb": mem["python_peak_mb"]}


def _worker_online(spec: dict) -> dict:
    """Online update latency, if ``pinquad.experiments.online.measure_update_latency`` exists."""
    try:
        # deferred on purpose: the online module is optional for the benchmark, and only
        # this worker needs it (it imports the simulator: seconds and ~100 MB)
        from pinquad.experiments.online import measure_update_latency
    except Exception as exc:  # the online module is optional for the benchmark
        return {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    reset_peak_rss()
    before = status_mb("VmRSS")
    t0 = time.perf_counter()
    lat = np.asarray(measure_update_latency(n_updates=int(spec["n_updates"]),
                                            window=int(spec["window"])), dtype=float)
    wall = time.perf_counter() - t0
    if lat.size == 0:
        return {"available": False, "reason": "measure_update_latency returned no samples"}
    return {"available": True, "n": int(lat.size), "window": int(spec["window"]),
            "p50_ms": float(np.percentile(lat, 50) * 1e3),
            "p99_ms": float(np.percentile(lat, 99) * 1e3),
            "max_ms": float(lat.max() * 1e3), "mean_ms": float(lat.mean() * 1e3),
            "wall_s": wall, "peak_rss_mb": status_mb("VmHWM"), "rss_before_mb": before}


def _worker_offline(spec: dict) -> dict:
    """``python -m pinquad.offline`` (defaults; output into a scratch directory) as a
    subprocess of this fresh worker: wall time, and the peak RSS of the largest process
    in the run (ru_maxrss over this worker's waited-for children)."""
    cmd = [sys.executable, "-m", "pinquad.offline", "--out", spec["out"]]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=spec["timeout"])
    except subprocess.TimeoutExpired:
        return {"s": None, "status": "timeout", "note": f"stopped after {spec['timeout']:.0f} s"}
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    out = {"s": wall, "status": "ok" if proc.returncode == 0 else "error",
           "returncode": proc.returncode, "command": "python -m pinquad.offline",
           "max_rss_mb": peak}
    if proc.returncode != 0:
        out["note"] = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    return out


def _worker_discovery(spec: dict) -> dict:
    """``python -m pinquad.offline --log`` on the 60 s, 500 Hz discovery log
    (``pinquad.experiments.bench_discovery``), once."""
    # deferred on purpose: only this worker flies a log (flightgen) and needs the
    # discovery pipeline's modules; the other workers would pay for them in time and memory
    from pinquad.experiments.bench_discovery import time_log_discovery

    return time_log_discovery(Path(spec["workdir"]), float(spec["timeout"]), spec.get("jobs"))


def _workers() -> dict[str, Callable[[dict], dict]]:
    """The worker functions by kind (``--worker KIND``)."""
    return {"estep": _worker_estep, "memory": _worker_memory, "em": _worker_em,
            "online": _worker_online, "offline": _worker_offline,
            "discovery": _worker_discovery}


def worker_main(kind: str, spec_json: str) -> int:
    """Entry point of a worker process: print the result as one tagged JSON line."""
    warnings.simplefilter("ignore")
    result = _workers()[kind](json.loads(spec_json))
    print(worker_result_line(result), flush=True)
    return 0
