"""``python -m pinquad.axis_inertia [LOG ...]``: inertia of measured flights by direct
maximum likelihood per body axis (``pinquad.realdata.axis_inertia``); ``--simulate FACTOR
...`` checks the estimator on simulated closed-loop flights with a known inertia."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import numpy as np
from tqdm import tqdm

from pinquad.cli.measured import (
    add_measured_log_arguments,
    measured_logs,
    measured_vehicle_spec,
    positive_factors,
    reference_inertia,
)
from pinquad.io.logs import LogFormatError
from pinquad.realdata.axis_inertia import UNRELIABLE_SE, AxisFit, identify_axes, simulated_axes


def _cell(fit: AxisFit) -> str:
    flag = " (!)" if fit.unreliable else ""
    return f"{1e6 * fit.inertia:.1f} ± {1e6 * fit.se:.1f} (phi {fit.phi:.2f}){flag}"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m pinquad.axis_inertia",
        description="Inertia of measured Crazyflie flights by direct maximum likelihood per "
                    "body axis, with the unmodelled torques as a coloured disturbance.")
    add_measured_log_arguments(p)
    p.add_argument("--simulate", type=float, nargs="+", metavar="FACTOR", default=None,
                   help="instead of measured logs, identify simulated closed-loop flights "
                        "(sensor B) with the torque process noise multiplied by each FACTOR")
    p.add_argument("--seeds", type=int, nargs="+", default=[0],
                   help="generator seeds of the simulated flights (with --simulate)")
    p.add_argument("--parts", type=int, default=1,
                   help="identify each log's flight cut into this many equal consecutive "
                        "pieces, each alone (a consistency check)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    if args.parts < 1:
        print(f"error: --parts {args.parts}: expected a positive number", file=sys.stderr)
        return 2
    if args.simulate is not None:
        error = positive_factors(args.simulate)
        if error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        print("simulated Crazyflie 2.1, closed loop, sensor B, read as a measured log; "
              f"seeds {', '.join(map(str, args.seeds))}; inertia [1e-6 kg m^2] ± standard "
              "error, error vs truth\n")
        print("| torque noise | seed | roll | pitch | yaw |")
        print("|---|---|---|---|---|")
        jobs = [(f, s) for f in args.simulate for s in args.seeds]
        for factor, seed in tqdm(jobs, unit="flight", file=sys.stderr):
            fits, truth = simulated_axes(factor, seed)
            cells = [f"{_cell(fit)}, {100 * (fit.inertia / truth[j] - 1):+.1f} % "
                     f"({(fit.inertia - truth[j]) / fit.se:+.1f} SE)"
                     for j, fit in enumerate(fits)]
            print(f"| x{factor:g} | {seed} | " + " | ".join(cells) + " |")
        print(f"\ntruth {', '.join(f'{1e6 * v:.2f}' for v in truth)} e-6 kg m^2; "
              f"{len(jobs)} flights in {time.perf_counter() - t0:.0f} s")
        return 0
    rows = []
    try:
        spec = measured_vehicle_spec(args.vehicle)
        reference = reference_inertia(spec)
        for name, real in measured_logs(args.logs, args.data, args.vehicle):
            for part in range(args.parts):
                label = name if args.parts == 1 else f"{name} [{part + 1}/{args.parts}]"
                rows.append((label, identify_axes(real, reference, args.rotor_inertia,
                                                  part, args.parts)))
            kf = real.kf.kf
    except (LogFormatError, ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not rows:
        print("error: no logs given", file=sys.stderr)
        return 2
    print(f"direct maximum likelihood per axis, coloured torque disturbance; kf = {kf:.4e} "
          f"N/(rad/s)^2; J_r = {args.rotor_inertia:g} kg m^2 on yaw; inertia [1e-6 kg m^2] ± "
          "statistical standard error (kf's and the yaw ratio's uncertainty not included); "
          f"(!): standard error undefined or over {100 * UNRELIABLE_SE:.0f} % of the "
          "estimate (a fit that ran off)\n")
    print("| log | I_xx | I_yy | I_zz |")
    print("|---|---|---|---|")
    for name, fits in rows:
        print(f"| {name} | " + " | ".join(_cell(f) for f in fits) + " |")
    cells = []
    for j in range(3):
        kept = np.array([fits[j].inertia for _, fits in rows if not fits[j].unreliable])
        if kept.size == 0:
            cells.append("- (all flagged)")
            continue
        m = float(kept.mean())
        sd = float(kept.std(ddof=1)) if kept.size > 1 else 0.0
        cells.append(f"{1e6 * m:.1f} ± {1e6 * sd:.1f} ({100 * sd / m:.0f} %, {kept.size} of "
                     f"{len(rows)})")
    print("| mean ± sd ((!) left out) | " + " | ".join(cells) + " |")
    print(f"| reference: {spec.reference.inertia_note or 'the file body inertia'} | "
          + " | ".join(f"{1e6 * v:.2f}" for v in reference) + " |")
    print(f"\n{len(rows)} logs in {time.perf_counter() - t0:.0f} s")
    return 0
