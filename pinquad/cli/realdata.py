"""``python -m pinquad.realdata [--data DIR] [--jobs N] [--rotor-inertia pooled|per-flight|
none|VALUE] [--vehicle NAME|FILE]`` identifies every flight of the IMRC Lab data set (or,
with a vehicle file, every flight log in ``--data``) and prints the table (pooled J_r: a
first pass fits J_r per flight on the pool logs, then every log is identified with J_r
fixed). The vehicle (default the shipped crazyflie21) gives the mixer, kf (the shipped
file: the thrust stand in the data directory), the fault thresholds, where EM starts and
the reference the table compares with."""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from pinquad.cli.common import add_backend_arguments, backend_from_args, check_band
from pinquad.cli.help import non_negative_int
from pinquad.core.execution import open_executor
from pinquad.core.vehicle_file import load_vehicle
from pinquad.discovery.null import NullSettings
from pinquad.io.datadir import missing_data_hint
from pinquad.io.logs import LogFormatError, vehicle_file_named
from pinquad.io.read import is_flight_log
from pinquad.pipeline.realdata import TableJob, run_jobs
from pinquad.realdata.consistency import between_flights
from pinquad.realdata.dataset import POOL_FLIGHTS, flights_dir, stand_dir
from pinquad.realdata.observation_options import RealDataOptions, options_for_vehicle
from pinquad.realdata.rotor_inertia import pooled_rotor_inertia
from pinquad.realdata.thrust import thrust_coefficient, vehicle_thrust_coefficient
from pinquad.report.realdata import format_table


def _rotor_choice(text: str) -> str | float:
    if text in ("pooled", "per-flight", "none"):
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected pooled, per-flight, none or a value in kg m^2") from None


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pinquad.realdata [--data DIR] [--jobs N]``: identify every flight."""
    parser = argparse.ArgumentParser(
        prog="python -m pinquad.realdata",
        description="Identify mass and inertia of the real Crazyflie from every micro-SD "
                    "flight log and print the table against the vehicle file's [reference] "
                    "(the scale's mass, the published inertia).")
    parser.add_argument("--vehicle", default="crazyflie21", metavar="NAME|FILE",
                        help="the flights' vehicle: crazyflie21 (default: the jana* logs of "
                             "the data set, kf from its thrust stand) or a vehicle file (.toml, "
                             "docs/vehicles.md; every flight log in --data, kf from the file)")
    parser.add_argument("--data", type=Path, default=None,
                        help="Crazyflie data directory (with imrc_brushed/ and thrust_stand/) "
                             "or a directory of flight logs (default: $PINQUAD_CRAZYFLIE_DATA, "
                             "else ../shared/data/crazyflie next to the repository, else the "
                             "copy `python -m pinquad.data fetch crazyflie` downloads)")
    add_backend_arguments(parser, min(2, os.cpu_count() or 1), "logs")
    parser.add_argument("--max-iterations", type=int, default=150, help="E-steps per log")
    parser.add_argument("--no-information", action="store_true",
                        help="skip the observed information (jackknife errors only)")
    parser.add_argument("--channels", default="pos,euler,gyro",
                        help="measurement channels, comma-separated (pos, vel, euler, gyro)")
    parser.add_argument("--faults", choices=["repair", "repair-all", "exclude"],
                        default="repair", help="handling of implausible rotor speeds")
    parser.add_argument("--band", type=float, nargs=2, default=(3.0, 8.0),
                        metavar=("LO", "HI"), help="torque-row band of the inertia M-step [Hz]")
    parser.add_argument("--only", nargs="*", help="log names to run (default: all)")
    parser.add_argument("--no-discover", action="store_true",
                        help="skip effect discovery (the table's effects column)")
    parser.add_argument("--null-replicates", type=non_negative_int,
                        default=NullSettings().replicates, metavar="N",
                        help="shadow flights of each log's base fit that a found effect's "
                             "evidence must beat (pinquad.discovery.null; >= 19 for p <= "
                             "0.05; 0: no calibration)")
    parser.add_argument("--rotor-inertia", type=_rotor_choice, default=None,
                        help="rotor inertia J_r of the yaw torque J_r sum spin_i omega_i': "
                             "pooled (default, unless the vehicle file gives [actuators] "
                             "rotor_inertia, which is then used: one J_r fitted jointly on the "
                             "--pool logs, each pool log identified with the J_r of the "
                             "others, leave-one-out), per-flight (fitted on each log), none, "
                             "or a value [kg m^2]")
    parser.add_argument("--pool", nargs="*", default=None,
                        help="logs the pooled J_r is fitted on (default: crazyflie21's seven "
                             "with every rotor speed measured; a vehicle file's: every log); "
                             "run whatever --only says")
    args = parser.parse_args(argv)
    check_band(parser, args.band)
    shipped = args.vehicle == "crazyflie21"
    try:
        vehicle = args.vehicle if shipped else vehicle_file_named(args.vehicle, Path.cwd(),
                                                                  "--vehicle")
        spec = load_vehicle(vehicle)
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    flights = flights_dir(args.data) if shipped or args.data is None else args.data
    # absolute paths: a Dask worker need not share this process's working directory
    logs = sorted(p.absolute() for p in flights.iterdir() if p.is_file() and (
        p.name.startswith("jana") if shipped else is_flight_log(p))) if flights.is_dir() else []
    all_logs = list(logs)
    if args.only:
        logs = [p for p in logs if p.name in set(args.only)]
    if not logs:
        what = "jana*" if shipped else "micro-SD, CSV or Parquet"
        print(f"error: {flights}: no flight log ({what}) found; expected the IMRC Lab micro-SD "
              f"logs: {missing_data_hint()}", file=sys.stderr)
        return 2
    try:
        # the mixer and fault thresholds of the vehicle file (shipped:
        # pinquad/data/crazyflie21.toml); kf of the shipped one from the data's thrust stand
        options = options_for_vehicle(spec, RealDataOptions(
            channels=tuple(c.strip() for c in args.channels.split(",")), faults=args.faults))
        stand = stand_dir(args.data).absolute()
        kf = thrust_coefficient(stand) if shipped else vehicle_thrust_coefficient(spec)
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    # J_r: the command line's, else the one the vehicle file fixes, else pooled
    file_jr = spec.actuators.rotor_inertia if spec.actuators is not None else None
    mode = args.rotor_inertia if args.rotor_inertia is not None else \
        file_jr if file_jr is not None else "pooled"
    print(f"pinquad real data: {len(logs)} logs from {flights}, channels {options.channels}, "
          f"faults {options.faults}, torque band {args.band[0]:g}-{args.band[1]:g} Hz, "
          f"rotor inertia {mode}, {backend_from_args(args).describe()}; {kf.note}",
          file=sys.stderr)
    rotor, pass1 = None, ""
    try:
        null = NullSettings(args.null_replicates)
    except ValueError as exc:
        print(f"error: --null-replicates: {exc}", file=sys.stderr)
        return 2
    discover = None if args.no_discover else null
    pool: list[Path] = []
    if mode == "pooled":
        pool_names = set(args.pool if args.pool is not None else
                         POOL_FLIGHTS if shipped else [p.name for p in all_logs])
        pool = [p for p in all_logs if p.name in pool_names]
        if len(pool) < 2:
            print(f"error: --pool {' '.join(sorted(pool_names))}: fewer than two of these logs "
                  f"in {flights}; expected at least two to pool J_r over", file=sys.stderr)
            return 2
    try:
        # the backend is had (or refused: BackendError, exit 2) before any log is run
        with open_executor(backend_from_args(args), max(len(logs), len(pool))) as executor:
            if mode == "pooled":
                print(f"pass 1: J_r fitted per flight on the {len(pool)} pool logs "
                      f"({', '.join(p.name for p in pool)}) to pool it", file=sys.stderr)
                first = run_jobs([TableJob(p, replace(options, rotor_inertia=None),
                                           args.max_iterations, False,
                                           tuple(args.band), stand, keep_band_stats=True, kf=kf,
                                           vehicle=vehicle)
                                  for p in pool], executor)
                bad = [(p.name, r) for p, r in zip(pool, first, strict=True)
                       if isinstance(r, str)]
                if bad:
                    print("error: pool log not identified: "
                          + "; ".join(f"{n}: {w}" for n, w in bad), file=sys.stderr)
                    return 2
                rotor = pooled_rotor_inertia({r.name: r.fit.band_stats for r in first})
                pass1 = (f"; pass 1 (J_r per flight on the pool logs, then pooled) "
                         f"{time.perf_counter() - t0:.0f} s")
                print(rotor.describe(), file=sys.stderr)
                jobs = []
                for p in logs:
                    jr, how = rotor.for_log(p.name)
                    src = how if how == "leave-one-out" else "pooled on " + ", ".join(rotor.logs)
                    jobs.append(TableJob(p, replace(options, rotor_inertia=jr),
                                         args.max_iterations, not args.no_information,
                                         tuple(args.band), stand, fit_rotor_inertia=False,
                                         rotor_source=src, discover=discover, kf=kf,
                                         vehicle=vehicle))
            else:
                # None: J_r not fixed (fitted with per-flight, none with none)
                fixed = None if isinstance(mode, str) else mode
                src = {"per-flight": "fitted on this log", "none": ""}.get(mode, "given") \
                    if isinstance(mode, str) else ("given" if args.rotor_inertia is not None
                                                   else f"fixed by {spec.source}")
                jobs = [TableJob(p, replace(options, rotor_inertia=fixed), args.max_iterations,
                                 not args.no_information, tuple(args.band), stand,
                                 fit_rotor_inertia=mode == "per-flight", rotor_source=src,
                                 discover=discover, kf=kf, vehicle=vehicle)
                        for p in logs]
            results = run_jobs(jobs, executor)
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    failed = [(j.path.name, r) for j, r in zip(jobs, results, strict=True) if isinstance(r, str)]
    results = [r for r in results if not isinstance(r, str)]
    # flights of one vehicle against each other: errors scaled where they scatter more
    # than their statistical errors allow, verdicts judged again
    results, scatters = between_flights(results)
    print(format_table(results, rotor, spec, scatters))
    for name, why in failed:
        print(f"\n{name}: not identified: {why}")
    print(f"\n{len(results)} logs in {time.perf_counter() - t0:.0f} s "
          f"({sum(r.run.seconds for r in results):.0f} s of EM + standard errors in the workers"
          f"{pass1})")
    return 0
