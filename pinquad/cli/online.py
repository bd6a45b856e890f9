"""``python -m pinquad.online``: online EM in the closed loop (the paper's online scheme,
``pinquad.experiments.online``), or with ``--log PATH`` a recorded log replayed through
the online estimator as a stream (``pinquad.experiments.online_replay``), read, checked
and observed by the pipeline (``pinquad.pipeline.replay``)."""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pinquad.cli.common import add_backend_arguments, backend_from_args, memory_arg, memory_label
from pinquad.cli.help import HelpFormatter, positive_int
from pinquad.core import paper_results as paper
from pinquad.core.execution import BackendError, open_executor
from pinquad.core.params import PAPER_VEHICLE
from pinquad.experiments.online import newest_offline_report, offline_ranges, run_online_cycle
from pinquad.experiments.online_replay import replay_verdict, stream_fit
from pinquad.io.logs import LogFormatError
from pinquad.io.runs import REPORT_SCHEMA, OutputError, RunWriter, atomic_write_json, new_run_dir
from pinquad.pipeline.replay import replay_input
from pinquad.report.online import online_figures, online_report, online_tables, write_online_logs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pinquad.online",
                                description="Online EM in the closed loop (paper's online "
                                "experiment): sliding window, estimates fed to the controller.",
                                formatter_class=HelpFormatter)
    p.add_argument("--sensor", choices=["A", "B", "C"], action="append",
                   help="observation source(s) (default: A, B and C)")
    p.add_argument("--cycles", type=positive_int, default=20, help="seeded cycles per sensor")
    p.add_argument("--seed", type=int, default=0, help="base seed")
    add_backend_arguments(p, os.cpu_count() or 1, "closed-loop cycles")
    p.add_argument("--out", type=Path, help="output run directory (default runs/online-<time>)")
    p.add_argument("--log", type=Path, help="replay a recorded log through the online "
                   "estimator as a stream (no controller feedback)")
    p.add_argument("--offline-report", type=Path,
                   help="an offline report.json whose ranges the online ranges are compared with "
                   "(default: the newest runs/offline-*/report.json, if any)")
    p.add_argument("--memory", type=memory_arg, default=math.inf, metavar="SECONDS",
                   help="time constant [s] with which the M-step forgets samples that left "
                        "the window; inf keeps them all (incremental EM), none uses the "
                        "window alone (the paper's scheme)")
    p.add_argument("--view", action="store_true", help="open the browser view of the run")
    args = p.parse_args(argv)
    if args.log is not None:
        return replay(args)
    try:
        return run_experiment(args)
    except BackendError as exc:  # raised before any cycle runs or anything is written
        print(f"error: {exc}", file=sys.stderr)
        return 2


def run_experiment(args: argparse.Namespace) -> int:
    """The closed-loop online experiment (module docstring) on the backend the options
    name; writes its run directory. Raises BackendError when the backend cannot be had."""
    offline_path = args.offline_report or newest_offline_report()
    offline = None
    if offline_path is not None:
        try:
            offline = offline_ranges(offline_path)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    sensors = args.sensor or ["A", "B", "C"]
    jobs = [(s, i, args.seed, args.memory) for s in sensors for i in range(args.cycles)]
    out_dir = args.out or new_run_dir("online")
    try:
        writer = RunWriter(out_dir)
    except OutputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    backend = backend_from_args(args)
    print(f"online experiment: {len(jobs)} closed-loop cycles, {backend.describe()}",
          file=sys.stderr)
    t0 = time.perf_counter()
    with open_executor(backend, len(jobs)) as pool, writer:
        results = list(tqdm(pool.map(run_online_cycle, jobs), total=len(jobs),
                            desc="online cycles", file=sys.stderr))
        elapsed = time.perf_counter() - t0
        truth = np.array([PAPER_VEHICLE.mass, *PAPER_VEHICLE.inertia_diag])
        text, stats = online_tables(results, truth, paper, offline)
        text += ("\n\nOffline ranges from " + str(offline_path) if offline is not None else
                 "\n\nNo offline report to compare with (run python -m pinquad.offline first, "
                 "or pass --offline-report)")
        print(text)
        print(f"\n{len(results)} closed-loop flights, seeds "
              f"{min(r.seed for r in results)}..{max(r.seed for r in results)}; {elapsed:.1f} s; "
              f"M-step memory: {memory_label(args.memory)}")
        report = online_report(results, truth, stats, memory_label(args.memory), elapsed)
        atomic_write_json(writer.path("report.json"), report)
        writer.path("report.md").write_text("# pinquad online experiment\n\n" + text + "\n")
        online_figures(results, truth, writer.path("figures"))
        report["run_logs"] = write_online_logs(results, writer)
        atomic_write_json(writer.path("report.json"), report)
        final = writer.publish()
    print(f"run written to {final}")
    if args.view:
        from viz.__main__ import main as viz_main  # the viewer (viser) only when asked for

        return viz_main([str(final)])
    return 0


def replay(args: argparse.Namespace) -> int:
    """``--log PATH``: the recorded log replayed through the online estimator (module
    docstring of ``pinquad.experiments.online_replay``); prints the estimates over time
    and, with ``--out``, writes a run directory."""
    try:
        writer = RunWriter(args.out) if args.out else None  # --out checked before any work
        ready = replay_input(args.log, (args.sensor or [None])[0])
    except (LogFormatError, ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    obs, rotor_acc = ready.obs, ready.rotor_acc
    fit = stream_fit(obs, ready.mass0, ready.inertia0, ready.log.meta.gravity,
                     memory_s=args.memory, rotor_acc=rotor_acc, bounds=ready.bounds)
    hist, lat = fit.history, fit.latencies
    if hist.size == 0:
        print(f"error: {args.log}: too short to replay (fewer than 50 samples)", file=sys.stderr)
        return 2
    memory = memory_label(args.memory)
    mstep = "regressor"
    if rotor_acc is not None:
        mstep = "measured-flight (mstep.BandMStep)"
        if args.memory is not None:
            memory = f"mass: {memory}; inertia: each window's band-passed fit alone"
    print(f"replayed {obs.n} samples of {args.log} in {hist.shape[0]} updates "
          f"(window 800, every 4, {mstep} M-step, memory: {memory}); "
          f"update p50 {1e3 * np.median(lat):.1f} ms, p99 {1e3 * np.percentile(lat, 99):.1f} ms")
    print("| t [s] | mass [kg] | I_xx | I_yy | I_zz |\n|---|---|---|---|---|")
    for i in np.unique(np.linspace(0, hist.shape[0] - 1, 12).astype(int)):
        r = hist[i]
        print(f"| {r[1]:.2f} | {r[2]:.5g} | {r[3]:.4g} | {r[4]:.4g} | {r[5]:.4g} |")
    verdict, budget = replay_verdict(fit, ready.log.meta, ready.vrange, ready.bounds,
                                     ready.measured_thrust)
    total = budget.total
    print(f"\nfinal estimate (last window of {fit.window.n} samples): mass "  # type: ignore[union-attr]
          f"{hist[-1, 2] * 1e3:.3f} ± {total[0] * 1e3:.3g} g, inertia diagonal "
          + ", ".join(f"{hist[-1, 3 + i] * 1e6:.4g} ± {total[1 + i] * 1e6:.3g}" for i in range(3))
          + f" e-6 kg m^2\nverdict: {verdict.overall}")
    for reason in verdict.reasons:
        print(f"  {reason}")
    if writer is not None:
        with writer:
            atomic_write_json(writer.path("report.json"), {
                "schema": REPORT_SCHEMA,
                "source": {"kind": "log", "path": str(args.log), "mode": "online-replay",
                           "estep": "rts", "mstep": mstep, "memory": memory},
                "estimates": {"mass": float(hist[-1, 2]), "inertia": np.diag(hist[-1, 3:6]).tolist(),
                              "com": None,
                              "stderr": {"mass": float(total[0]),
                                         "inertia_diag": total[1:].tolist()},
                              "stderr_parts": budget.to_report(),
                              "verdict": verdict.to_report()},
                "verdict": verdict.to_report(),
                "em": {"iterations": int(hist.shape[0]), "loglik": [], "converged": False},
                "discovery": {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                              "validation": "not run in replay"},
                "cycles": [{"sensor": "log", "mstep": mstep, "seed": None,
                            "estimates": {"mass": float(hist[-1, 2]),
                                          "inertia": np.diag(hist[-1, 3:6]).tolist()},
                            "history": {"t": hist[:, 1].tolist(), "mass": hist[:, 2].tolist(),
                                        "inertia_diag": hist[:, 3:6].tolist()}}],
            })
            writer.publish()
    if not verdict.trusted:
        print(f"exit code 3: the final estimate is {verdict.overall} (its verdict says why)",
              file=sys.stderr)
        return 3
    return 0
