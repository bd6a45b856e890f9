"""The benchmark's sections and its result document (``python -m pinquad.bench``; the
measurements are described in :mod:`pinquad.experiments.bench`).

:func:`run_benchmark` builds the E-step cases, runs the chosen sections, each
measurement in a fresh worker process, and returns the JSON-ready result that
``bench.json`` holds; :func:`run_checks` is ``--check N``. Options come as one
:class:`BenchOptions`.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pinquad.experiments.bench import (
    DEFAULT_N,
    DISCOVERY_BEFORE,
    LARGE_N,
    PEERS,
    SECTIONS,
    log,
    loglog_slope,
    machine_info,
    median,
    run_worker,
)
from pinquad.experiments.bench_cases import base_observations, build_case
from pinquad.experiments.bench_estep import CONTESTANTS, CheckResult, check_all
from pinquad.experiments.bench_profile import profile_estep


@dataclass(frozen=True)
class BenchOptions:
    """What to run: ``n`` the E-step lengths [steps] (sorted, distinct, each >= 2);
    ``repeats`` timed runs per figure (``repeats_large`` from :data:`LARGE_N` steps on);
    ``timeout_s`` [s] the longest single peer call before it is stopped; ``peers`` the
    E-step peers compared with ours; ``sections`` the sections to run (of
    :data:`SECTIONS`); ``profile`` whether to profile our E-step; ``seed`` the seed of
    the simulated base flight."""

    n: tuple[int, ...] = DEFAULT_N
    repeats: int = 5
    repeats_large: int = 3
    timeout_s: float = 120.0
    peers: tuple[str, ...] = PEERS
    sections: frozenset[str] = frozenset(SECTIONS)
    profile: bool = False
    seed: int = 1


def build_cases(ns: list[int], workdir: Path, seed: int) -> dict[int, Path]:
    """Build and save the case of every N (tiled from one simulated flight)."""
    base = base_observations(seed)
    paths = {}
    for n in ns:
        t0 = time.perf_counter()
        case = build_case(base, n)
        paths[n] = workdir / f"case_{n}.npz"
        case.save(paths[n])
        log(f"  case N={n:,}: built in {time.perf_counter() - t0:.1f} s")
    return paths


def run_estep(options: BenchOptions, cases: dict[int, Path]) -> dict:
    """The E-step timings of ours and every requested peer at every N of ``options``
    (``cases``: the saved case of each N)."""
    ns = list(options.n)
    methods = ["ours", *[p for p in options.peers if p != "ours"]]
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
            reps = options.repeats_large if n >= LARGE_N else options.repeats
            out: dict[str, Any]
            prev = meds[i - 1] if i else None
            if missing:
                out = {"status": "absent", "note": "not installed: " + ", ".join(missing)}
            elif i and status[i - 1] in ("timeout", "skipped"):
                out = {"status": "skipped", "note": f"slower than {options.timeout_s:.0f} s at a "
                       f"smaller N"}
            elif i and status[i - 1] in ("mismatch", "error"):
                out = {"status": "skipped", "note": f"{status[i - 1]} at N={ns[i - 1]:,}"}
            elif prev is not None and prev * n / ns[i - 1] > options.timeout_s:
                out = {"status": "skipped", "note": f"projected {prev * n / ns[i - 1]:.0f} s "
                       f"(linear from N={ns[i - 1]:,}) > {options.timeout_s:.0f} s time-out"}
            else:
                log(f"  E-step {name} N={n:,} ({reps} runs)")
                spec = {"case": str(cases[n]), "method": name, "repeats": reps,
                        "timeout": options.timeout_s}
                out = run_worker("estep", spec, timeout=options.timeout_s * (reps + 2) + 300)
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


def run_memory(options: BenchOptions, cases: dict[int, Path], estep: dict) -> dict:
    """Peak memory of every method that ran (``estep``: the result of :func:`run_estep`)
    at every N (one worker per measurement)."""
    ns = list(options.n)
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
                           timeout=options.timeout_s * 2 + 300)
            rss.append(r.get("rss_growth_mb"))
            py.append(r.get("python_peak_mb"))
        out[name] = {"rss_growth_mb": rss, "python_peak_mb": py}
    return out


def run_offline_default(workdir: Path, timeout: float) -> dict:
    """The end-to-end offline command, once, with a time limit ``timeout`` [s] (the
    ``offline`` worker of :mod:`pinquad.experiments.bench_workers`)."""
    spec = {"out": str(workdir / "offline-run"), "timeout": timeout}
    return run_worker("offline", spec, timeout=timeout + 60)


def run_checks(n_steps: int, seed: int, peers: list[str]) -> list[CheckResult]:
    """``--check``: ours against every peer on one ``n_steps``-step case tiled from the
    flight of ``seed`` (and dynamax with its shipped defaults when dynamax is asked)."""
    case = build_case(base_observations(seed), n_steps)
    names = list(peers) + (["dynamax_shipped"] if "dynamax" in peers else [])
    return check_all(case, names)


def checks_failed(results: list[CheckResult]) -> bool:
    """Whether a present peer disagrees with ours or fails (absent peers, and dynamax
    with its shipped defaults, which is expected to differ, do not count)."""
    return any(r.status in ("mismatch", "error") and r.name != "dynamax_shipped"
               for r in results)


def run_benchmark(options: BenchOptions, command: str) -> dict:
    """Run the sections of ``options`` and return the result document of ``bench.json``
    (``command``: the command line it records). Progress goes to stderr."""
    sections = options.sections
    ns = list(options.n)
    res: dict[str, Any] = {
        "schema": "pinquad.bench/1",
        "command": command,
        "machine": machine_info(),
        "settings": {"repeats": options.repeats, "repeats_large": options.repeats_large,
                     "timeout_s": options.timeout_s, "seed": options.seed,
                     "sections": sorted(sections),
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
        "offline_em_60s_s": None, "offline_default_s": None, "log_discovery_60s_s": None,
    }
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pinquad-bench-") as tmp:
        workdir = Path(tmp)
        need_cases = bool(sections & {"estep", "memory"}) or options.profile
        prof_n = min(ns, key=lambda n: abs(math.log(n / 10_000)))
        case_ns = sorted(set(ns) | ({prof_n} if options.profile else set()))
        cases = {}
        if need_cases:
            log("building E-step cases")
            cases = build_cases(case_ns, workdir, options.seed)
        if "estep" in sections:
            log("E-step timings")
            res["estep"] = run_estep(options, cases)
            if "memory" in sections:
                log("memory")
                res["estep"]["memory"] = run_memory(options, cases, res["estep"])
                res["memory"] = res["estep"]["memory"]
        if options.profile:
            log("profile")
            res["profile"] = profile_estep(cases[prof_n])
        if "em" in sections:
            log("offline EM on a 60 s flight")
            em = run_worker("em", {"repeats": max(1, min(options.repeats, 3))}, timeout=3600)
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
        if "discovery" in sections:
            log("python -m pinquad.offline --log on a 60 s, 500 Hz log with drag, one run")
            disc = run_worker("discovery", {"workdir": str(workdir), "timeout": 3600.0},
                              timeout=3700)
            disc["before"] = DISCOVERY_BEFORE
            res["log_discovery_60s"] = disc
            res["log_discovery_60s_s"] = disc.get("s")
            res["log_discovery_60s_before_s"] = DISCOVERY_BEFORE["s"]
    res["total_s"] = time.perf_counter() - t_start
    res["machine"]["loadavg_at_end"] = list(os.getloadavg())
    return res
