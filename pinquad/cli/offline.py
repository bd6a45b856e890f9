"""``python -m pinquad.offline``: offline EM identification of mass and inertia.

Without ``--log`` it reproduces the paper's offline experiment: the paper's scenario
flown with sensors A, B and C, 20 seeded cycles each, EM from m0 = 0.001 kg and
I0 = diag(1e-4, 2e-4, 1e-4) kg m^2 with the regressor M-step and the paper's M-step on
the same logs; it prints the paper's Table II and III layouts with the paper's numbers
beside ours, bias, std and the Cramer-Rao bound, and writes a run directory.

With ``--log PATH`` it identifies the vehicle of a recorded log (CSV, Parquet or a
Crazyflie micro-SD binary log) through ``pinquad.pipeline`` (read, check, identify,
look for unmodelled effects, judge) and prints one line per parameter and per effect found
(``--explain``: the whole report); the run directory holds report.json, report.md, the log
as the E-step saw it (``logs/flight.parquet``), the smoothed state means
(``logs/flight-smoothed.npy``, (N, 12)) and figures, written whole or not at all. Its
headline (``estimates``) is the estimate under the final model (discovery's refit when
effects were selected; the base fit under ``base``), each with a verdict
(``pinquad.identification.verdict``); the command exits 3 when the headline is not
trusted, after writing the run directory.

Exit codes: 0 success; 2 bad input (nothing written); 3 headline not trusted (written).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from pinquad.cli.batch import BATCH_EXIT_CODES, is_batch, run_batch
from pinquad.cli.common import (
    add_backend_arguments,
    backend_from_args,
    check_band,
    failure_message,
)
from pinquad.cli.file_vehicle import run_file_vehicle
from pinquad.cli.help import HelpFormatter, non_negative_float, non_negative_int, positive_int
from pinquad.cli.known_mass import run_known_mass
from pinquad.core.execution import open_executor, worker_pool
from pinquad.core.params import PAPER_SCENARIO
from pinquad.core.vehicle_file import is_vehicle_file
from pinquad.discovery.null import NullSettings
from pinquad.experiments.offline_mc import CycleJob, run_cycles
from pinquad.io.runs import RunWriter, new_run_dir
from pinquad.pipeline import LOG_MAX_ITERATIONS, PipelineOptions, read, run
from pinquad.pipeline.identify import LogOptions
from pinquad.realdata.observation_options import FAULT_MODES
from pinquad.report.offline import offline_tables, summarize, write_offline_run
from pinquad.results.result import Result

UNTRUSTED = 3
"""Exit code of a run whose report is written but whose headline estimate is not
trusted (docs/verdict.md)."""

EXIT_CODES = ("exit codes: 0 success; 2 bad input or arguments (a message naming the file "
              "and what was expected, nothing written); 3 (with --log) the run finished and "
              "its report is written, but the headline estimate (the final model's mass and "
              "inertia) is not trusted: not identifiable from this log, model not adequate, "
              "or implausible; report.json's 'verdict' and the printed table say why")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m pinquad.offline",
        description="Offline EM identification of a quadcopter's mass and inertia. Without "
                    "--log: the paper's simulated offline experiment (Tables II and III).",
        epilog=f"{EXIT_CODES}; {BATCH_EXIT_CODES}", formatter_class=HelpFormatter)
    p.add_argument("--log", type=Path, nargs="+", metavar="PATH",
                   help="identify from a recorded log (CSV, Parquet or Crazyflie micro-SD "
                        "binary) instead of simulating; several paths or a quoted glob "
                        "pattern run a batch (pinquad.cli.batch): one run directory with a "
                        "per-log table.md and each log's run in logs/<name>/, --jobs logs "
                        "at a time")
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
    p.add_argument("--cycles", type=positive_int, default=20, help="Monte Carlo cycles per sensor")
    p.add_argument("--seed", type=int, default=0, help="base seed of the Monte Carlo cycles")
    p.add_argument("--vehicle", default=None, metavar="NAME|FILE",
                   help="simulated vehicle: paper (default), crazyflie21 (flies the paper's "
                        "scenario scaled by 0.3) or a vehicle file (.toml, docs/vehicles.md: "
                        "flown with sensor B, logged with rotor speeds and identified from "
                        "that log, --cycles seeds one after the other); with --log: the "
                        "log's vehicle, a shipped name or a vehicle file, overriding the "
                        "log's sidecar")
    p.add_argument("--payload-mass", type=non_negative_float, default=None, metavar="KG",
                   help="with --log: the mass [kg] of a load the vehicle carried that its "
                        "vehicle file does not hold (overrides the sidecar's "
                        "'payload_mass'); added to the file's [reference] mass that the "
                        "verdict compares the estimate with (its inertia is taken as a "
                        "point mass at the centre of mass: the inertia reference stays)")
    p.add_argument("--band", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                   help="torque band [Hz] of the inertia M-step on a rotor-speed log "
                        "(default 3-8 Hz, the measured Crazyflie flights'; a simulated "
                        "vehicle file's cycles: 0-45 Hz; LO = 0 filters low-pass only)")
    p.add_argument("--faults", choices=FAULT_MODES, default=None,
                   help="implausible rotor readings of a rotor-speed log: repair (rebuild "
                        "them from the micro-SD log's PWM commands through the diagonal "
                        "partner's map), repair-all (through the map of all trusted motors) "
                        "or exclude (skip their rows); default: the vehicle's (repair for "
                        "crazyflie21, exclude for a vehicle file without [faults] "
                        "repair_rel_se)")
    p.add_argument("--max-iterations", type=positive_int, default=None,
                   help="E-steps at most per EM run (default: 100 for the simulated cycles, "
                        f"{LOG_MAX_ITERATIONS} for a --log, whose measured flights' "
                        "band-limited M-step is not accelerated: a 40 s yaw sweep needs "
                        "about 130)")
    add_backend_arguments(p, os.cpu_count() or 1,
                          "Monte Carlo cycles, a batch's logs, or one log's EM runs beside "
                          "the reported one, its shadow-flight scoring and refit (the same "
                          "answer)")
    p.add_argument("--no-information", action="store_true",
                   help="skip standard errors and the Cramer-Rao bound (faster)")
    p.add_argument("--out", type=Path, help="output run directory (default: a fresh "
                   "runs/offline-<time>)")
    p.add_argument("--null-replicates", type=non_negative_int, default=NullSettings().replicates,
                   metavar="N",
                   help="--log: shadow flights of the base fit that each selected effect's "
                        "evidence must beat (the null calibration, "
                        "pinquad.discovery.null; at least 19 for p <= 0.05; 0: off)")
    p.add_argument("--null-seed", type=int, default=0,
                   help="--log: seed of the shadow flights")
    p.add_argument("--no-discover", action="store_true",
                   help="with --log: skip the search for unmodelled effects")
    p.add_argument("--explain", action="store_true",
                   help="with --log: print the whole report (every run's table, every "
                        "reason, the error budget, discovery's coefficients, held-out "
                        "residual RMS and null calibration, exclusions and notes) instead of "
                        "one line per parameter and per effect; report.md holds it either way")
    p.add_argument("--view", action="store_true", help="open the browser view of the run")
    p.add_argument("--mass", metavar="KG|file", default=None,
                   help="with --log: known-mass mode for a log whose actuation is motor "
                        "commands: a PX4 log (ULog or data-driven-dynamics CSV, docs/px4.md) "
                        "or a Crazyflie micro-SD log read as IMU-only (accelerometer, gyro, "
                        "motor commands; docs/imu_only.md): the mass in kg (or 'file': the "
                        "--vehicle file's [reference] mass) fixes the scale; identifies the "
                        "thrust curve, motor time constant and inertia by regression, and "
                        "(a PX4 log) the curve's scale and the inertia by EM beside it; "
                        "--vehicle names the rotor positions (.toml, a shipped name or "
                        ".yaml), --band the torque band (default 0.3-2 Hz)")
    p.add_argument("--range", type=str, nargs="+", action="append", default=None,
                   metavar="LO HI",
                   help="with --mass: the rows to fit, in seconds on the log's own clock, as "
                        "pairs LO HI (several pairs: several segments of one log); give "
                        "--range once per --log, in order ('auto': that log's flight "
                        "segments). Without it an IMU-only log is fitted on its flight "
                        "segments (motors on), a PX4 log on its armed segment")
    p.add_argument("--joint", action="store_true",
                   help="with --mass and several --log: one fit of the vehicle (curve, time "
                        "constant, inertia shared; each log's drag and damping its own), "
                        "printed beside each log's own fit")
    return p


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return 2


def _msteps(mstep: str) -> tuple[str, ...]:
    return ("regressor", "paper") if mstep == "both" else (mstep,)


def run_simulation(args: argparse.Namespace) -> int:
    """The paper's offline Monte Carlo experiment (module docstring)."""
    sensors = args.sensor or ["A", "B", "C"]
    msteps = _msteps(args.mstep)
    jobs = [CycleJob(sensor=s, cycle=i, seed=args.seed, vehicle=args.vehicle, estep=args.estep,
                     msteps=msteps, max_iterations=args.max_iterations or 100,
                     information=not args.no_information, keep_log=(i == 0))
            for s in sensors for i in range(args.cycles)]
    backend = backend_from_args(args)
    writer = RunWriter(args.out or new_run_dir("offline"))
    t0 = time.perf_counter()
    print(f"pinquad offline: {len(sensors)} sensor(s) x {args.cycles} cycles, seeds from base "
          f"{args.seed}, E-step {args.estep}, M-step(s) {', '.join(msteps)}, "
          f"{backend.describe()}")
    with open_executor(backend, len(jobs)) as executor, writer:
        results = run_cycles(jobs, executor)
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
        source = {"estep": args.estep, "vehicle": args.vehicle, "seed": args.seed,
                  "cycles": args.cycles, "msteps": list(msteps)}
        write_offline_run(writer, results, summary, tables, msteps, sensors, source,
                          (flown.waypoints, flown.start), elapsed)
        final = writer.publish()
    print(f"run written to {final}")
    return _view(final) if args.view else 0


def _view(run_dir: Path) -> int:
    from viz.__main__ import main as viz_main  # the viewer (viser) only when asked for

    return viz_main([str(run_dir)])


def pipeline_options(args: argparse.Namespace) -> PipelineOptions:
    """The pipeline's options (``pinquad.pipeline``) from the parsed --log options."""
    identification = LogOptions(
        sensors=tuple(args.sensor or ()), msteps=_msteps(args.mstep), estep=args.estep,
        max_iterations=args.max_iterations or LOG_MAX_ITERATIONS,
        information=not args.no_information, faults=args.faults,
        **({} if args.band is None else {"band": tuple(args.band)}))
    return PipelineOptions(identification, NullSettings(args.null_replicates, args.null_seed),
                           discover=not args.no_discover, vehicle=args.vehicle,
                           payload_mass=args.payload_mass)


def run_log(args: argparse.Namespace) -> int:
    """Identify the vehicle of ``args.log`` through the pipeline (``pinquad.pipeline``)
    and write a run directory (module docstring).

    Raises LogFormatError / ValueError (with the file named) on bad input; returns 0, or
    ``UNTRUSTED`` (3) when the headline estimate's verdict is not ``trusted`` (the run
    directory is written either way).
    """
    options = pipeline_options(args)  # the null's range checked before work
    t0 = time.perf_counter()
    print(f"pinquad offline --log {args.log}: E-step {args.estep}, "
          f"M-step(s) {', '.join(options.identification.msteps)}")
    writer = RunWriter(args.out or new_run_dir("log"))  # --out checked before any work
    log = read(args.log, args.vehicle, args.payload_mass)
    if args.vehicle is not None:
        print(f"vehicle: {log.meta.vehicle}")
    with worker_pool(args.jobs) as pool:
        result = Result.of(run(log, options, pool, str(args.log), t0))
    print(result.explain() if args.explain else result.summary())
    with writer:
        result.write(writer)
        final = writer.publish()
    print(f"run written to {final}" + ("" if args.explain else
                                       " (report.md, report.json; --explain prints it all)"))
    code = 0 if result.trusted else UNTRUSTED
    if code:
        print(f"exit code {UNTRUSTED}: the headline estimate is "
              f"{result.headline.final.verdict.overall} (report written; its verdict says "
              "why)", file=sys.stderr)
    viewed = _view(final) if args.view else 0
    return viewed or code


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    check_band(parser, args.band)
    try:
        if args.mass is not None:
            if args.log is None:
                return _fail("--mass identifies a recorded log: --log FILE --mass KG")
            if len(args.log) > 1 and not args.joint:
                return _fail("--mass with several logs: add --joint (one vehicle: the "
                             "curve, time constant and inertia shared) or run each log on "
                             "its own")
            return run_known_mass(args)
        if args.range is not None or args.joint:
            return _fail("--range and --joint go with --mass (known-mass mode)")
        if args.log is not None and is_batch(args.log):
            return run_batch(args, pipeline_options(args), backend_from_args(args),
                             argv=sys.argv[1:] if argv is None else argv)
        if args.log is not None:
            args.log = args.log[0]
            return run_log(args)
        if args.mstep == "full":
            return _fail("--mstep full identifies one recorded log (--log PATH); the "
                         "Monte Carlo experiment runs the regressor and paper M-steps")
        if args.vehicle is None:
            args.vehicle = "paper"
        if is_vehicle_file(args.vehicle):
            return run_file_vehicle(args)
        if args.vehicle not in ("paper", "crazyflie21"):
            return _fail(f"--vehicle {args.vehicle}: the Monte Carlo experiment flies paper, "
                         "crazyflie21 or a vehicle file (.toml)")
        return run_simulation(args)
    except (FileExistsError, FileNotFoundError, ValueError, FloatingPointError) as exc:
        # LogFormatError and numpy's LinAlgError are ValueErrors: each names the log
        return _fail(failure_message(exc, args.log if isinstance(args.log, Path) else None))
    except KeyboardInterrupt:
        return _fail("interrupted")
