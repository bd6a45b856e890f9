"""``python -m pinquad.response [LOG ...]``: the apparent inertia against frequency of
measured flights (``pinquad.realdata.response``), or of simulated closed-loop flights with
``--simulate FACTOR ...``; tables and the figure from ``pinquad.report.response``."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from pinquad.cli.common import check_band, output_problem
from pinquad.cli.measured import (
    add_measured_log_arguments,
    measured_logs,
    measured_vehicle_spec,
    positive_factors,
    reference_inertia,
)
from pinquad.io.logs import LogFormatError
from pinquad.realdata.response import ApparentInertia, apparent_inertia, simulated_response
from pinquad.report.response import (
    band_lines,
    format_response,
    format_simulated,
    plot_response,
    unexplained_line,
)

Array = NDArray[np.float64]


def _figure(results: Sequence[ApparentInertia], out: Path, reference: Array, **kwargs
            ) -> bool:
    """:func:`plot_response` to ``out``, printing its path, or the error on stderr
    (False) if it cannot be written."""
    try:
        print(f"figure: {plot_response(results, out, reference, **kwargs)}")
    except OSError as exc:
        print(f"error: {out}: cannot write the figure ({exc.strerror or exc})", file=sys.stderr)
        return False
    return True


def _run_simulated(factors: Sequence[float], seed: int, sensor: str, out: Path | None,
                   band: tuple[float, float] = (3.0, 8.0)
                   ) -> int:
    t0 = time.perf_counter()
    results = [simulated_response(f, seed, sensor, band=band)
               for f in tqdm(factors, unit="flight", file=sys.stderr)]
    print(f"simulated Crazyflie 2.1, closed loop, sensor {sensor}, generator seed {seed} for "
          f"every flight; torque process noise x {', '.join(f'{f:g}' for f in factors)}; "
          "|H| of the logged commanded torque against the logged gyro, band medians "
          "[1e-6 kg m^2]; EM: EKF + RTS E-step, regressor M-step on the same log; "
          "measured-flight pipeline: pinquad.realdata's identification of the same flight "
          f"with rotor speeds from the commanded wrench, inertia M-step band {band[0]:g}-"
          f"{band[1]:g} Hz\n")
    print(format_simulated(results))
    if out is not None and not _figure(
            [r.response for r in results], out, results[0].truth,
            reference_label="true inertia",
            title="simulated closed loop: apparent inertia against frequency, torque noise "
                  "x factor"):
        return 2
    print(f"{len(results)} flights in {time.perf_counter() - t0:.0f} s")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m pinquad.response",
        description="Apparent inertia |torque / angular acceleration| against frequency on "
                    "measured Crazyflie flights: where the rigid-body torque model holds.")
    add_measured_log_arguments(p)
    p.add_argument("--out", type=Path, default=None,
                   help="write the figure here (PNG; default: none)")
    p.add_argument("--simulate", type=float, nargs="+", metavar="FACTOR", default=None,
                   help="instead of measured logs, fly the simulated Crazyflie in closed loop "
                        "once per FACTOR, with the torque process noise multiplied by it, and "
                        "print its apparent inertia and what EM identifies (about 10-20 s "
                        "per flight)")
    p.add_argument("--seed", type=int, default=0,
                   help="generator seed of every simulated flight (with --simulate)")
    p.add_argument("--band", type=float, nargs=2, metavar=("LO", "HI"), default=[3.0, 8.0],
                   help="torque band [Hz] of the measured-flight pipeline's inertia M-step "
                        "on the simulated flights (with --simulate; its default 3-8 Hz)")
    p.add_argument("--sensor", choices=("A", "B", "C"), default="B",
                   help="sensor set of the simulated flights (with --simulate; B, the default, "
                        "logs the pose the measured-flight pipeline needs)")
    args = p.parse_args(argv)
    check_band(p, args.band)
    if (code := output_problem(args.out, directory=False)) is not None:
        return code
    if args.simulate is not None:
        error = positive_factors(args.simulate)
        if error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        return _run_simulated(args.simulate, args.seed, args.sensor, args.out,
                              tuple(args.band))
    t0 = time.perf_counter()
    try:
        reference = reference_inertia(measured_vehicle_spec(args.vehicle))
        results = [apparent_inertia(real, name, args.rotor_inertia, reference=reference)
                   for name, real in measured_logs(args.logs, args.data, args.vehicle)]
    except (LogFormatError, ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"apparent inertia |H_j(f)| = |S_a,tau / S_a,a| per axis, J_r = "
          f"{args.rotor_inertia:g} kg m^2 on the yaw torque; {len(results)} logs")
    print(format_response(results, published=reference))
    for line in band_lines(results, "logs"):
        print(line)
    print()
    for r in results:
        print(unexplained_line(r, "the vehicle file's reference inertia"))
    if args.out is not None and not _figure(results, args.out, reference):
        return 2
    print(f"{len(results)} logs in {time.perf_counter() - t0:.0f} s")
    return 0

