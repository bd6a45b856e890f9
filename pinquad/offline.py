"""``python -m pinquad.offline``: offline EM identification of mass and inertia.

Without ``--log`` it reproduces the paper's offline experiment: the paper's scenario
flown with sensors A, B and C, 20 seeded cycles each, EM from m0 = 0.001 kg and
I0 = diag(1e-4, 2e-4, 1e-4) kg m^2 with the regressor M-step and the paper's M-step on
the same logs; it prints the paper's Table II and III layouts with the paper's numbers
beside ours, bias, std and the Cramer-Rao bound, and writes a run directory.

With ``--log PATH`` it identifies the vehicle of a recorded log (CSV, Parquet or a
Crazyflie micro-SD binary log).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from pinquad.cli.help import HelpFormatter
from pinquad.io.logs import LogFormatError

DESCRIPTION = __doc__.split("\n\n")[0].split(": ", 1)[1]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m pinquad.offline",
        description="Offline EM identification of a quadcopter's mass and inertia. Without "
                    "--log: the paper's simulated offline experiment (Tables II and III).",
        formatter_class=HelpFormatter)
    p.add_argument("--log", type=Path, help="identify from a recorded log (CSV, Parquet or "
                   "Crazyflie micro-SD binary) instead of simulating")
    p.add_argument("--sensor", choices=["A", "B", "C"], action="append",
                   help="observation source(s); repeat for several (default: A, B and C for "
                        "simulation; B-like full use of what a log contains for --log)")
    p.add_argument("--estep", choices=["rts", "ieks", "gtsam"], default="rts",
                   help="E-step smoother: EKF + RTS (compiled); ieks, EKF + RTS iterated to "
                        "the MAP trajectory (generic Python: 10 minutes for one sensor-A EM run); or "
                        "gtsam, the GTSAM factor-graph batch smoother (the same MAP; 80 s for "
                        "one sensor-B EM run)")
    p.add_argument("--mstep", choices=["regressor", "paper", "both", "full"], default="both",
                   help="M-step(s) to run on the same logs; full (with --log, CSV or "
                        "Parquet logs with thrust and torques): all ten inertial parameters "
                        "(mass, centre of mass, full inertia tensor) with standard errors, "
                        "minutes per log")
    p.add_argument("--cycles", type=int, default=20, help="Monte Carlo cycles per sensor")
    p.add_argument("--seed", type=int, default=0, help="base seed of the Monte Carlo cycles")
    p.add_argument("--vehicle", choices=["paper", "crazyflie21"], default="paper",
                   help="simulated vehicle (crazyflie21 flies the paper's scenario scaled by 0.3)")
    p.add_argument("--max-iterations", type=int, default=100, help="E-steps at most per EM run")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                   help="worker processes for the cycles")
    p.add_argument("--no-information", action="store_true",
                   help="skip standard errors and the Cramer-Rao bound (faster)")
    p.add_argument("--out", type=Path, help="output run directory (default: a fresh "
                   "runs/offline-<time>)")
    p.add_argument("--no-discover", action="store_true",
                   help="with --log: skip the search for unmodelled effects")
    p.add_argument("--view", action="store_true", help="open the browser view of the run")
    return p


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return 2


def run_simulation(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from pinquad.core.params import PAPER_SCENARIO
    from pinquad.experiments.offline_mc import CycleJob, run_cycle
    from pinquad.io.logs import write_log
    from pinquad.io.runs import REPORT_SCHEMA, RunWriter, atomic_write_json, new_run_dir
    from pinquad.report.offline import (
        cycle_entries,
        offline_tables,
        plot_em_history,
        plot_trajectory,
        stats_json,
        summarize,
    )

    if args.cycles < 1:
        return _fail("--cycles must be at least 1")
    sensors = args.sensor or ["A", "B", "C"]
    msteps = ("regressor", "paper") if args.mstep == "both" else (args.mstep,)
    jobs = [CycleJob(sensor=s, cycle=i, seed=args.seed, vehicle=args.vehicle, estep=args.estep,
                     msteps=msteps, max_iterations=args.max_iterations,
                     information=not args.no_information, keep_log=(i == 0))
            for s in sensors for i in range(args.cycles)]
    out_dir = args.out or new_run_dir("offline")
    writer = RunWriter(out_dir)
    t0 = time.perf_counter()
    print(f"pinquad offline: {len(sensors)} sensor(s) x {args.cycles} cycles, seeds from base "
          f"{args.seed}, E-step {args.estep}, M-step(s) {', '.join(msteps)}, {args.jobs} worker(s)")
    try:
        results = []
        if args.jobs > 1:
            with ProcessPoolExecutor(max_workers=args.jobs) as pool:
                for res in tqdm(pool.map(run_cycle, jobs), total=len(jobs), desc="cycles",
                                unit="cycle", file=sys.stderr):
                    results.append(res)
        else:
            for job in tqdm(jobs, desc="cycles", unit="cycle", file=sys.stderr):
                results.append(run_cycle(job))
        elapsed = time.perf_counter() - t0
        summary = summarize(results)
        tables = offline_tables(summary)
        print()
        print(tables)
        seeds = sorted({c.seed for c in results})
        print(f"\n{len(results)} flights, seeds {seeds[0]}..{seeds[-1]} "
              f"(flight seed = base*100000 + sensor*1000 + cycle); {elapsed:.1f} s")
        fl = [c.flight for c in results]
        print(f"flights: worst closest approach to a waypoint {max(f['max_miss_m'] for f in fl):.3f} m, "
              f"crashes {sum(f['crashed'] for f in fl)}")
        flown = PAPER_SCENARIO if args.vehicle == "paper" else PAPER_SCENARIO.scaled(0.3)
        figs = writer.path("figures")
        figs.mkdir(exist_ok=True)
        for m in msteps:
            plot_em_history(results, m, figs / f"em_history_{m}.png")
        logs_dir = writer.path("logs")
        logs_dir.mkdir(exist_ok=True)
        run_logs = {}
        for c in results:
            if c.log is None:
                continue
            name = f"sensor{c.sensor}-cycle{c.cycle:02d}"
            write_log(c.log, logs_dir / f"{name}.parquet")
            if c.smoothed is not None:
                np.save(logs_dir / f"{name}-smoothed.npy", c.smoothed)
            plot_trajectory(c.log, flown.waypoints, figs / f"trajectory_{c.sensor}.png",
                            c.smoothed)
            run_logs[c.sensor] = {"log": f"logs/{name}.parquet",
                                  "smoothed": f"logs/{name}-smoothed.npy"}
        first = results[0]
        best = next((r for r in first.runs if r.mstep == msteps[0]), first.runs[0])
        report = {
            "schema": REPORT_SCHEMA,
            "source": {"kind": "simulation", "path": None, "sensor": "".join(sensors),
                       "estep": args.estep, "vehicle": args.vehicle,
                       "seed": args.seed, "cycles": args.cycles, "msteps": list(msteps)},
            "estimates": {"mass": best.mass, "inertia": np.asarray(best.inertia).tolist(),
                          "com": None, "stderr": {"mass": best.stderr[0],
                                                  "inertia_diag": best.stderr[1:4].tolist()}},
            "truth": {"mass": first.truth_mass, "inertia": first.truth_inertia.tolist(),
                      "com": [0.0, 0.0, 0.0]},
            "em": {"iterations": int(best.loglik.size), "loglik": best.loglik.tolist(),
                   "converged": bool(best.converged)},
            "discovery": {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                          "validation": "not run on simulated paper experiment"},
            "cycles": cycle_entries(results),
            "statistics": stats_json(summary),
            "scenario": {"start": flown.start.tolist(), "waypoints": flown.waypoints.tolist()},
            "run_logs": run_logs,
            "seconds": elapsed,
        }
        atomic_write_json(writer.path("report.json"), report)
        (writer.path("report.md")).write_text(
            "# pinquad offline experiment\n\n" + tables + "\n")
        final = writer.publish()
    except BaseException:
        writer.abort()
        raise
    print(f"run written to {final}")
    if args.view:
        return _view(final)
    return 0


def _view(run_dir: Path) -> int:
    from viz.__main__ import main as viz_main

    return viz_main([str(run_dir)])


def run_log(args: argparse.Namespace) -> int:
    from pinquad.experiments.logmode import identify_log

    return identify_log(args)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.log is not None:
            return run_log(args)
        if args.mstep == "full":
            return _fail("--mstep full identifies one recorded log (--log PATH); the "
                         "Monte Carlo experiment runs the regressor and paper M-steps")
        return run_simulation(args)
    except LogFormatError as exc:
        return _fail(str(exc))
    except (FileExistsError, FileNotFoundError, ValueError) as exc:
        return _fail(str(exc))
    except KeyboardInterrupt:
        return _fail("interrupted")


if __name__ == "__main__":
    raise SystemExit(main())
