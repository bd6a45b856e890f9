"""``python -m pinquad.bench``: how fast the E-step, EM and the online update are.

Prints a table and writes ``bench.json`` (``--out``). Every figure is the median of
several runs (``--repeats``, 5 by default; ``--repeats-large``, 3, for N >= 100,000;
one run of the end-to-end offline command), and every comparison is made in one
process on the same inputs:

* E-step (EKF + RTS smoother with cross-covariances) for N = 1,000 / 10,000 / 100,000
  steps. Ours is the compiled ``pinquad.estep.fast_smoother.smooth_quad`` on the quadcopter
  model; long inputs are a simulated sensor-B flight's inputs and measurements repeated
  end to end (``pinquad.experiments.bench_estep``). The peers (filterpy, pykalman, dynamax, our
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
* The online update latency on an 800-sample window, p50 and p99, from
  ``pinquad.experiments.online.measure_update_latency`` (``not available`` if that is missing).
* ``--profile``: where our E-step's time goes (wrapper checks vs compiled loops).

``--check N`` runs only the correctness checks on an N-step case and exits 1 if a
present peer disagrees (absent peers are listed, not failed).
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import io
import json
import math
import os
import platform
import pstats
import resource
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pinquad.cli.help import HelpFormatter

RESULT_TAG = "BENCH-RESULT "
DEFAULT_N = (1_000, 10_000, 100_000)
LARGE_N = 100_000
PEERS = ("generic", "filterpy", "pykalman", "dynamax", "gtsam")
SECTIONS = ("estep", "memory", "em", "online", "offline")
EM_SECONDS = 60.0


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


def _status_mb(field: str) -> float | None:
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
    before = _status_mb("VmRSS") if exact else maxrss_mb()
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    after = _status_mb("VmHWM") if exact else maxrss_mb()
    growth = None if before is None or after is None else after - before
    return {"rss_growth_mb": growth, "python_peak_mb": peak / 2**20,
            "rss_before_mb": before, "rss_method": "VmHWM reset" if exact else "ru_maxrss"}


def median(xs: list[float]) -> float | None:
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


def write_json_atomic(path: Path, data: dict) -> None:
    """Write ``data`` whole or not at all (temporary file, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", dir=path.parent)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        json.dump(data, fh, indent=2, allow_nan=False)
        fh.write("\n")
    os.replace(tmp, path)


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


def _worker_estep(spec: dict) -> dict:
    """Time ours and one peer alternately on one case (module docstring)."""
    from pinquad.experiments.bench_estep import TOLERANCE, contestant, load_case, mean_error

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
    from pinquad.experiments.bench_estep import contestant, load_case

    case = load_case(Path(spec["case"]))
    if spec["method"] == "ours":
        # load the compiled kernels from numba's cache first (a short call)
        from pinquad.estep.fast_smoother import smooth_quad

        smooth_quad(case.model, case.ys[:50])
    run, _ = contestant(spec["method"]).prepare(case)
    out = call_peak_memory(run)
    out.update(method=spec["method"], N=case.n_steps)
    return out


def em_observations(seconds: float = EM_SECONDS, seed: int = 7):
    """Sensor-B observations of a simulated flight of the paper's scenario, hovering at
    the last waypoint long enough to last ``seconds``, cut to exactly that length."""
    from pinquad.models.sources import observations
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
    from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_VEHICLE
    from pinquad.estep.fast_smoother import smooth_quad
    from pinquad.identification.em import initial_theta, run_em
    from pinquad.mstep.updates import regressor_mstep

    obs = em_observations(float(spec.get("seconds", EM_SECONDS)))
    theta0 = initial_theta(obs, PAPER_INITIAL_MASS, PAPER_INITIAL_INERTIA,
                           PAPER_VEHICLE.gravity)

    def run():
        return run_em(obs, theta0, smooth_quad, regressor_mstep, max_iterations=100)

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
        from pinquad.experiments.online import measure_update_latency
    except Exception as exc:  # the online module is optional for the benchmark
        return {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    reset_peak_rss()
    before = _status_mb("VmRSS")
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
            "wall_s": wall, "peak_rss_mb": _status_mb("VmHWM"), "rss_before_mb": before}


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


def worker_main(kind: str, spec_json: str) -> int:
    """Entry point of a worker process: print the result as one tagged JSON line."""
    import warnings

    warnings.simplefilter("ignore")
    result = _workers()[kind](json.loads(spec_json))
    print(RESULT_TAG + json.dumps(_clean(result)), flush=True)
    return 0


# --------------------------------------------------------------------------- sections


def log(msg: str) -> None:
    """Progress on stderr (the table goes to stdout)."""
    print(msg, file=sys.stderr, flush=True)


def build_cases(ns: list[int], workdir: Path, seed: int) -> dict[int, Path]:
    """Build and save the case of every N (tiled from one simulated flight)."""
    from pinquad.experiments.bench_estep import base_observations, build_case

    base = base_observations(seed)
    paths = {}
    for n in ns:
        t0 = time.perf_counter()
        case = build_case(base, n)
        paths[n] = workdir / f"case_{n}.npz"
        case.save(paths[n])
        log(f"  case N={n:,}: built in {time.perf_counter() - t0:.1f} s")
    return paths


def run_estep(args: argparse.Namespace, ns: list[int], cases: dict[int, Path]) -> dict:
    """The E-step timings of ours and every requested peer at every N."""
    from pinquad.experiments.bench_estep import CONTESTANTS

    methods = ["ours", *[p for p in args.peers if p != "ours"]]
    res: dict[str, Any] = {"N": ns, "runs": {}, "status": {}, "notes": {}, "check_error": {},
                           "ours_same_process_s": {}, "speedup_vs_ours": {},
                           "first_call_s": {}, "describe": {}}
    for name in methods:
        peer = CONTESTANTS[name]
        res["describe"][name] = peer.note
        meds: list[float | None] = []
        runs, status, notes, errs, ours_in, first = [], [], [], [], [], []
        missing = peer.missing()
        compile_s: list[float | None] = []
        for i, n in enumerate(ns):
            reps = args.repeats_large if n >= LARGE_N else args.repeats
            out: dict[str, Any]
            prev = meds[i - 1] if i else None
            if missing:
                out = {"status": "absent", "note": "not installed: " + ", ".join(missing)}
            elif i and status[i - 1] in ("timeout", "skipped"):
                out = {"status": "skipped", "note": f"slower than {args.timeout:.0f} s at a "
                       f"smaller N"}
            elif i and status[i - 1] in ("mismatch", "error"):
                out = {"status": "skipped", "note": f"{status[i - 1]} at N={ns[i - 1]:,}"}
            elif prev is not None and prev * n / ns[i - 1] > args.timeout:
                out = {"status": "skipped", "note": f"projected {prev * n / ns[i - 1]:.0f} s "
                       f"(linear from N={ns[i - 1]:,}) > {args.timeout:.0f} s time-out"}
            else:
                log(f"  E-step {name} N={n:,} ({reps} runs)")
                spec = {"case": str(cases[n]), "method": name, "repeats": reps,
                        "timeout": args.timeout}
                out = run_worker("estep", spec, timeout=args.timeout * (reps + 2) + 300)
            times = out.get("ours_s" if name == "ours" else "peer_s") or []
            runs.append(times)
            meds.append(median(times))
            status.append(out.get("status", "error"))
            notes.append(out.get("note", ""))
            errs.append(out.get("check_error"))
            first.append(out.get("first_s", out.get("ours_first_s")))
            ours_in.append(median(out.get("ours_s") or []))
            compile_s.append(out.get("compile_s"))
            if out.get("status") not in ("ok", None):
                log(f"    {name} N={n:,}: {out.get('status')} {out.get('note', '')}")
        res[f"{name}_s"] = meds
        res["runs"][name] = runs
        res["status"][name] = status
        res["notes"][name] = notes
        res["first_call_s"][name] = first
        if name != "ours":
            res["check_error"][name] = errs
            res["ours_same_process_s"][name] = ours_in
            res["speedup_vs_ours"][name] = [
                None if p is None or o is None else p / o
                for p, o in zip(meds, ours_in, strict=True)]
        if name == "dynamax":
            res["dynamax_compile_s"] = compile_s
    res["exponent"] = {name: loglog_slope(ns, res[f"{name}_s"]) for name in methods}
    for name in PEERS:  # the JSON keeps every peer's key, null where not run
        res.setdefault(f"{name}_s", [None] * len(ns))
    return res


def run_memory(args: argparse.Namespace, ns: list[int], cases: dict[int, Path],
               estep: dict) -> dict:
    """Peak memory of every method that ran at every N (one worker per measurement)."""
    out: dict[str, Any] = {}
    for name in estep["status"]:
        rss, py = [], []
        for i, n in enumerate(ns):
            if estep["status"][name][i] != "ok":
                rss.append(None)
                py.append(None)
                continue
            log(f"  memory {name} N={n:,}")
            r = run_worker("memory", {"case": str(cases[n]), "method": name},
                           timeout=args.timeout * 2 + 300)
            rss.append(r.get("rss_growth_mb"))
            py.append(r.get("python_peak_mb"))
        out[name] = {"rss_growth_mb": rss, "python_peak_mb": py}
    return out


def profile_estep(case_path: Path, runs: int = 5) -> dict:
    """Where ``smooth_quad``'s time goes on one case: cProfile of the whole call, and
    stage timings (medians of ``runs``) of the wrapper's model checks and the two
    compiled passes (called directly), all in this process."""
    from pinquad.estep import fast_smoother as fs
    from pinquad.experiments.bench_estep import load_case

    case = load_case(case_path)
    model, ys = case.model, np.ascontiguousarray(case.ys)
    fs.smooth_quad(model, ys)
    prof = cProfile.Profile()
    for _ in range(runs):
        prof.enable()
        fs.smooth_quad(model, ys)
        prof.disable()
    buf = io.StringIO()
    stats = pstats.Stats(prof, stream=buf)
    stats.sort_stats("tottime").print_stats(12)
    top = []
    for (file, line, func), (_, ncalls, tottime, cumtime, _) in sorted(
            stats.stats.items(), key=lambda kv: -kv[1][2])[:12]:
        top.append({"function": f"{Path(file).name}:{line}({func})", "calls": ncalls,
                    "tottime_s": tottime / runs, "cumtime_s": cumtime / runs})
    out: dict[str, Any] = {"N": case.n_steps, "runs": runs, "cprofile_top": top,
                           "cprofile_text": buf.getvalue()}
    total, faults, kernel, user = [], [], [], []
    for _ in range(runs):
        gc.collect()
        r0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        fs.smooth_quad(model, ys)
        total.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        faults.append(r1.ru_minflt - r0.ru_minflt)
        kernel.append(r1.ru_stime - r0.ru_stime)
        user.append(r1.ru_utime - r0.ru_utime)
    out["total_s"] = median(total)
    # fresh output arrays (means, covariances, cross-covariances, filter intermediates)
    # are paid for in page faults: kernel time, not arithmetic
    out["page_faults_per_call"] = median(faults)
    out["kernel_s"] = median(kernel)
    out["user_s"] = median(user)
    try:
        # the same calls, on the same arrays, as smooth_quad makes (the forward pass's
        # workspace is reused between calls; the posterior's arrays are fresh each call)
        stages: dict[str, list[float]] = {"checks": [], "forward": [], "backward": [],
                                          "output arrays": []}
        x0, p0 = model.initial()
        x0 = np.ascontiguousarray(x0, dtype=float)
        p0 = np.ascontiguousarray(p0, dtype=float)
        inputs = np.ascontiguousarray(model.obs.inputs, dtype=float)
        for _ in range(runs):
            gc.collect()
            t0 = time.perf_counter()
            prep = fs._prepared(model, ys)
            if prep is None:
                raise ValueError("the compiled kernels do not cover this model")
            ys_c, consts = prep
            t1 = time.perf_counter()
            fwd = fs._filter_arrays(ys_c.shape[0])
            fs._forward_into(x0, p0, inputs, ys_c, *consts, True, *fwd)
            t2 = time.perf_counter()
            post = fs.posterior_arrays(ys_c.shape[0])
            t3 = time.perf_counter()
            fs._backward_into(*fwd, *post)
            t4 = time.perf_counter()
            stages["checks"].append(t1 - t0)
            stages["forward"].append(t2 - t1)
            stages["output arrays"].append(t3 - t2)
            stages["backward"].append(t4 - t3)
            del post
        out["stages_s"] = {k: median(v) for k, v in stages.items()}
        other = out["total_s"] - sum(out["stages_s"].values())
        out["stages_s"]["rest (median total - stages)"] = other
    except (AttributeError, TypeError, ValueError) as exc:
        out["stages_error"] = f"stage timings unavailable ({type(exc).__name__}: {exc})"
    return out


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


def run_offline_default(workdir: Path, timeout: float) -> dict:
    """The end-to-end offline command, once (:func:`_worker_offline`)."""
    spec = {"out": str(workdir / "offline-run"), "timeout": timeout}
    return run_worker("offline", spec, timeout=timeout + 60)


def _workers() -> dict[str, Callable[[dict], dict]]:
    """The worker functions by kind (``--worker KIND``)."""
    return {"estep": _worker_estep, "memory": _worker_memory, "em": _worker_em,
            "online": _worker_online, "offline": _worker_offline}


# --------------------------------------------------------------------------- output


def _fmt_s(t: float | None) -> str:
    if t is None:
        return "-"
    if t < 1e-3:
        return f"{t * 1e6:.0f} us"
    if t < 1.0:
        return f"{t * 1e3:.1f} ms"
    return f"{t:.2f} s"


def _fmt(x: float | None, spec: str = ".2f", suffix: str = "") -> str:
    return "-" if x is None else f"{x:{spec}}{suffix}"


def format_report(res: dict) -> str:
    """The printed tables."""
    from pinquad.experiments.bench_estep import CONTESTANTS

    lines = []
    s = res["settings"]
    m = res["machine"]
    lines.append(f"pinquad benchmark  ({m['cpu_count']} CPUs, {m.get('cpu_model', '')}, "
                 f"Python {m['python']}, numpy {m['versions'].get('numpy')}; load average "
                 f"at start {m['loadavg_at_start'][0]:.2f}, at end "
                 f"{m.get('loadavg_at_end', [math.nan])[0]:.2f})")
    lines.append(f"medians of {s['repeats']} runs ({s['repeats_large']} at N >= "
                 f"{LARGE_N:,}); peer time-out {s['timeout_s']:.0f} s")
    es = res.get("estep")
    if es:
        ns = es["N"]
        names = list(es["status"])
        lines.append("")
        lines.append("E-step: EKF + RTS smoother (with cross-covariances), wall time")
        head = f"{'method':<30}" + "".join(f"{'N=' + format(n, ','):>14}" for n in ns)
        head += f"{'slope':>8}  check vs ours"
        lines.append(head)
        for name in names:
            row = f"{CONTESTANTS[name].label:<30}"
            for i in range(len(ns)):
                st = es["status"][name][i]
                t = es[f"{name}_s"][i]
                row += f"{_fmt_s(t) if st == 'ok' else st:>14}"
            row += f"{_fmt(es['exponent'].get(name)):>8}"
            if name != "ours":
                errs = [e for e in es["check_error"][name] if e is not None]
                row += f"  {max(errs):.0e}" if errs else "  -"
            lines.append(row)
        if "dynamax_compile_s" in es:
            row = f"{'  dynamax compile (per N)':<30}"
            row += "".join(f"{_fmt_s(t):>14}" for t in es["dynamax_compile_s"])
            lines.append(row)
        lines.append("")
        lines.append("peer time / ours (both timed alternately in the same process)")
        for name in names:
            if name == "ours":
                continue
            row = f"{CONTESTANTS[name].label:<30}"
            row += "".join(f"{_fmt(x, '.1f', 'x'):>14}" for x in es["speedup_vs_ours"][name])
            lines.append(row)
        notes = [(name, i, es["notes"][name][i]) for name in names for i in range(len(ns))
                 if es["notes"][name][i]]
        for name, i, note in notes:
            lines.append(f"  note: {name} at N={ns[i]:,}: {note}")
    mem = res.get("memory")
    if mem:
        ns = res["estep"]["N"]
        lines.append("")
        lines.append("peak memory of one call: RSS growth MB / Python-tracked peak MB")
        for name, mm in mem.items():
            row = f"{CONTESTANTS[name].label:<30}"
            for r, p in zip(mm["rss_growth_mb"], mm["python_peak_mb"], strict=True):
                row += f"{'-' if r is None else f'{r:.0f} / {p:.0f}':>14}"
            lines.append(row)
    prof = res.get("profile")
    if prof:
        lines.append("")
        lines.append(f"profile of ours at N={prof['N']:,}: total {_fmt_s(prof['total_s'])}")
        lines.append(f"  CPU time split: user {_fmt_s(prof['user_s'])}, kernel "
                     f"{_fmt_s(prof['kernel_s'])} ({prof['page_faults_per_call']:.0f} minor "
                     f"page faults: first touch of fresh output memory)")
        for k, v in prof.get("stages_s", {}).items():
            lines.append(f"  {k:<40}{_fmt_s(v):>12}  ({100 * v / prof['total_s']:.1f} %)")
        if "stages_error" in prof:
            lines.append("  " + prof["stages_error"])
        lines.append("  cProfile, by own time per call:")
        for row in prof["cprofile_top"][:8]:
            lines.append(f"    {row['function'][:60]:<60}{_fmt_s(row['tottime_s']):>12}")
    lines.append("")
    em = res.get("offline_em_60s")
    if em is not None:
        lines.append(f"offline EM, {em.get('seconds', EM_SECONDS):.0f} s flight "
                     f"({em.get('steps', '?')} steps), regressor M-step: "
                     f"{_fmt_s(res.get('offline_em_60s_s'))} "
                     f"({em.get('e_steps', '?')} E-steps, converged {em.get('converged')}, "
                     f"mass {_fmt(em.get('mass'), '.4f')} kg vs {em.get('mass_true')})")
    off = res.get("offline_default")
    if off is not None:
        lines.append(f"python -m pinquad.offline (defaults, 1 run): "
                     f"{_fmt_s(res.get('offline_default_s'))} [{off.get('status')}]"
                     + (f" {off.get('note')}" if off.get("note") else ""))
    on = res.get("online")
    if on is not None:
        if on.get("available"):
            lines.append(f"online update, {on['window']}-sample window ({on['n']} updates): "
                         f"p50 {on['p50_ms']:.2f} ms, p99 {on['p99_ms']:.2f} ms")
        else:
            lines.append(f"online update latency: not available ({on.get('reason', '')})")
    return "\n".join(lines)


# --------------------------------------------------------------------------- main


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m pinquad.bench",
        description="Benchmark the E-step against filterpy, pykalman, dynamax and GTSAM, "
                    "offline EM, the offline command and the online update.",
        formatter_class=HelpFormatter)
    p.add_argument("--out", type=Path, default=Path("bench.json"), help="JSON result file")
    p.add_argument("--n", type=int, nargs="+", default=list(DEFAULT_N),
                   help="E-step lengths (steps)")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per figure")
    p.add_argument("--repeats-large", type=int, default=3,
                   help=f"timed runs per figure at N >= {LARGE_N:,}")
    p.add_argument("--timeout", type=float, default=120.0,
                   help="stop a peer whose single call takes longer [s]")
    p.add_argument("--peers", nargs="*", default=list(PEERS), choices=list(PEERS),
                   help="peers to compare with ours")
    p.add_argument("--only", nargs="+", choices=list(SECTIONS),
                   help="run only these sections (all when not given)")
    p.add_argument("--quick", action="store_true",
                   help="skip the end-to-end `python -m pinquad.offline` run (minutes)")
    p.add_argument("--no-memory", action="store_true", help="skip the memory measurements")
    p.add_argument("--profile", action="store_true",
                   help="also profile our E-step (at the N closest to 10,000)")
    p.add_argument("--seed", type=int, default=1, help="seed of the simulated base flight")
    p.add_argument("--check", type=int, metavar="N",
                   help="only run the correctness checks on an N-step case")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    p.add_argument("--spec", help=argparse.SUPPRESS)
    return p


def run_checks(n_steps: int, seed: int, peers: list[str]) -> int:
    """``--check``: ours against every peer on one case; 1 if a present peer disagrees."""
    from pinquad.experiments.bench_estep import (
        TOLERANCE,
        base_observations,
        build_case,
        check_all,
    )

    case = build_case(base_observations(seed), n_steps)
    names = list(peers) + (["dynamax_shipped"] if "dynamax" in peers else [])
    results = check_all(case, names)
    print(f"smoothed means vs ours (pinquad.fast_smoother), N={n_steps:,}, "
          f"tolerance {TOLERANCE:.0e} of the state scale")
    bad = False
    for r in results:
        err = "-" if r.error is None else f"{r.error:.1e}"
        print(f"  {r.name:<16}{r.status:<10}{err:>10}  {r.message}")
        bad |= r.status in ("mismatch", "error") and r.name != "dynamax_shipped"
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.worker:
        return worker_main(args.worker, args.spec or "{}")
    if args.check is not None:
        return run_checks(args.check, args.seed, args.peers)
    if args.repeats < 1 or args.repeats_large < 1 or any(n < 2 for n in args.n):
        print("error: --repeats must be >= 1 and every --n >= 2", file=sys.stderr)
        return 2
    sections = set(args.only or SECTIONS)
    if args.no_memory:
        sections.discard("memory")
    if args.quick:
        sections.discard("offline")
    ns = sorted(set(args.n))
    res: dict[str, Any] = {
        "schema": "pinquad.bench/1",
        "command": "python -m pinquad.bench " + " ".join(argv if argv is not None
                                                          else sys.argv[1:]),
        "machine": machine_info(),
        "settings": {"repeats": args.repeats, "repeats_large": args.repeats_large,
                     "timeout_s": args.timeout, "seed": args.seed, "sections": sorted(sections),
                     "timing": "median wall time (perf_counter) of the runs; gc collected "
                               "before and disabled during each call; each (method, N) in a "
                               "fresh worker process, alternating ours and the peer",
                     "inputs": "a simulated sensor-B flight of the paper's scenario "
                               "(3,744 steps of 10 ms for seed 1) repeated end to end and cut "
                               "to N; peers get the model linearised along the EKF's filtered "
                               "means (pinquad/bench_estep.py)",
                     "memory": "per (method, N) a fresh worker loads the case, imports "
                               "(and compiles) the method, then runs it once: rss_growth_mb = "
                               "peak RSS during the call (VmHWM, reset before it) minus RSS "
                               "before it; python_peak_mb = tracemalloc peak of the call "
                               "(NumPy and numba arrays; not XLA or GTSAM C++ memory)"},
        "estep": None, "online_update_ms": {"p50": None, "p99": None},
        "offline_em_60s_s": None, "offline_default_s": None,
    }
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pinquad-bench-") as tmp:
        workdir = Path(tmp)
        need_cases = bool(sections & {"estep", "memory"}) or args.profile
        prof_n = min(ns, key=lambda n: abs(math.log(n / 10_000)))
        case_ns = sorted(set(ns) | ({prof_n} if args.profile else set()))
        cases = {}
        if need_cases:
            log("building E-step cases")
            cases = build_cases(case_ns, workdir, args.seed)
        if "estep" in sections:
            log("E-step timings")
            res["estep"] = run_estep(args, ns, cases)
            if "memory" in sections:
                log("memory")
                res["estep"]["memory"] = run_memory(args, ns, cases, res["estep"])
                res["memory"] = res["estep"]["memory"]
        if args.profile:
            log("profile")
            res["profile"] = profile_estep(cases[prof_n])
        if "em" in sections:
            log("offline EM on a 60 s flight")
            em = run_worker("em", {"repeats": max(1, min(args.repeats, 3))}, timeout=3600)
            res["offline_em_60s"] = em
            res["offline_em_60s_s"] = median(em.get("s") or [])
        if "online" in sections:
            log("online update latency")
            on = run_worker("online", {"n_updates": 200, "window": 800}, timeout=1800)
            res["online"] = on
            if on.get("available"):
                res["online_update_ms"] = {"p50": on["p50_ms"], "p99": on["p99_ms"]}
        if "offline" in sections:
            log("python -m pinquad.offline (defaults), one run")
            off = run_offline_default(workdir, timeout=3 * 3600)
            res["offline_default"] = off
            res["offline_default_s"] = off["s"]
    res["total_s"] = time.perf_counter() - t_start
    res["machine"]["loadavg_at_end"] = list(os.getloadavg())
    text = format_report(res)
    print(text)
    if res.get("profile") and args.profile:
        print("\ncProfile of ours (sorted by own time):")
        print(res["profile"]["cprofile_text"])
    res.get("profile", {}).pop("cprofile_text", None)
    write_json_atomic(args.out, _clean(res))
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
