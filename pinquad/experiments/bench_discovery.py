"""The benchmark's discovery case (``python -m pinquad.bench --only discovery``): one
minute of flight, analysed by the user's command.

The log: a 60 s flight of ``flightgen`` (its Crazyflie-class vehicle, logged at 500 Hz,
30,001 rows, actuation sampled at each row) with drag injected at the realistic default
D = (0.0062, 0.0062, 0.0070) N s/m, flight 0 of the discovery Monte Carlo's drag
condition (``discovery_mc_flightgen.flight_spec``, seed 1000) stretched to 60 s. It is
written to CSV in a scratch directory (:func:`write_discovery_log`) and
``python -m pinquad.offline --log LOG`` runs on it with its defaults (base EM with the
regressor and the paper's M-step, standard errors, discovery with its null calibration
of 19 shadow flights, the verdicts, figures) in a subprocess: its wall time is
``log_discovery_60s_s`` (target <= 60 s on 2 cores), with the selected effects
and their coefficients read back from report.json.

``pinquad.experiments.bench.DISCOVERY_BEFORE`` keeps the figure of the code before the
speed-up, measured once on the same log by the same command (it took minutes, too long
to repeat in every benchmark).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from flightgen import generate, write_csv
from pinquad.experiments.discovery_mc_flightgen import flight_spec

LOG_SECONDS = 60.0
"""Length [s] of the benchmark's discovery log."""
LOG_RATE = 500
"""Its log rate [Hz]."""
EFFECT = "drag"
"""The effect injected (at ``pinquad.sim.effects``' default)."""
SEED = 1000
"""flightgen's seed: the discovery Monte Carlo's first drag seed (base seed 0)."""


def write_discovery_log(workdir: Path, seconds: float = LOG_SECONDS, seed: int = SEED,
                        effect: str = EFFECT, log_rate: int = LOG_RATE) -> Path:
    """Fly the benchmark's log (module docstring) and write it as CSV (with its JSON
    sidecar) into ``workdir``; returns the CSV's path. Deterministic in ``seed``."""
    spec = flight_spec(effect, seed, 0, log_rate, duration=seconds)
    return write_csv(generate(spec), Path(workdir) / f"{effect}-{seconds:g}s-{log_rate}hz.csv")


def selected_effects(report: dict) -> dict[str, dict[str, list[float]]]:
    """effect -> {"coefficients": [...], "stderr": [...]} of report.json's discovery
    section (``stderr`` empty when the report has none)."""
    out = {}
    for entry in report.get("discovery", {}).get("selected", []):
        coeffs = entry.get("coefficients", {})
        stderr = entry.get("stderr", {})
        out[entry["effect"]] = {"coefficients": [float(v) for v in coeffs.values()],
                                "stderr": [float(v) for v in stderr.values()]
                                if isinstance(stderr, dict) else list(stderr)}
    return out


def time_log_discovery(workdir: Path, timeout: float, jobs: int | None = None) -> dict:
    """Write the log into ``workdir``, then run ``python -m pinquad.offline --log`` on it
    (its defaults; ``--jobs`` when given) as a subprocess, once: wall time [s], exit code,
    load average before and after, the selected effects and coefficients."""
    t0 = time.perf_counter()
    log = write_discovery_log(workdir)
    build_s = time.perf_counter() - t0
    out_dir = Path(workdir) / "discovery-run"
    cmd = [sys.executable, "-m", "pinquad.offline", "--log", str(log), "--out", str(out_dir)]
    if jobs is not None:
        cmd += ["--jobs", str(jobs)]
    load_before = list(os.getloadavg())
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"s": None, "status": "timeout", "note": f"stopped after {timeout:.0f} s"}
    wall = time.perf_counter() - t0
    result = {"s": wall, "status": "ok" if proc.returncode in (0, 3) else "error",
              "returncode": proc.returncode, "log_build_s": build_s,
              "command": "python -m pinquad.offline --log LOG" + (f" --jobs {jobs}" if jobs else ""),
              "log": {"seconds": LOG_SECONDS, "rate_hz": LOG_RATE, "effect": EFFECT,
                      "seed": SEED, "generator": "flightgen"},
              "loadavg_before": load_before, "loadavg_after": list(os.getloadavg())}
    report_path = out_dir / "report.json"
    if report_path.exists():
        report = json.loads(report_path.read_text())
        result["selected"] = selected_effects(report)
    if result["status"] != "ok":
        result["note"] = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    return result
