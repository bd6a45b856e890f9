"""``python -m pinquad.actuators [--data DIR]``: the thrust-stand fits of the rotor thrust
coefficient kf (``pinquad.vehicle.actuators.fit_thrust_stand``), per file and pooled;
``python -m pinquad.actuators --csv FILE [...]``: kf from any vehicle's steady rotor speed
and thrust (``pinquad.vehicle.steady_thrust``). Both print the vehicle file's
[actuators] section."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.core.params import CRAZYFLIE21
from pinquad.io.datadir import default_data_dir, missing_data_hint
from pinquad.io.logs import LogFormatError
from pinquad.vehicle.actuators import GRAM_FORCE, ThrustStandFit, fit_thrust_stand
from pinquad.vehicle.steady_thrust import actuator_section, fit_steady_thrust


def _format_fit(fit: ThrustStandFit) -> str:
    lines = [
        f"{fit.source}:",
        f"  kf = {fit.kf:.4e} +- {fit.kf_se:.1e} N/(rad/s)^2   residual RMS "
        f"{fit.residual_rms * 1e3:.1f} mN ({fit.residual_rms / GRAM_FORCE:.2f} gf)",
        f"  rows used {fit.n_used} of {fit.n_rows}; hover rpm for {CRAZYFLIE21.mass * 1e3:.1f} g: "
        f"{fit.hover_rpm():.0f} rev/min",
    ]
    if fit.lag_rows >= 0:
        lines.append(f"  load-cell zero {fit.tare / GRAM_FORCE:+.2f} gf removed; load cell trails "
                     f"the rpm by {fit.lag_rows} rows")
    lines += [f"  excluded: {e}" for e in fit.excluded]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pinquad.actuators [--data DIR]``: print the thrust-stand fits."""
    parser = argparse.ArgumentParser(
        prog="python -m pinquad.actuators",
        description="Fit the rotor thrust coefficient kf (T = kf * omega^2) to Bitcraze "
                    "thrust-stand CSVs, per file and pooled.")
    parser.add_argument("--data", type=Path, default=None,
                        help="directory of thrust-stand CSVs, or the Crazyflie data directory "
                             "holding thrust_stand/ (default: $PINQUAD_CRAZYFLIE_DATA, else "
                             "../shared/data/crazyflie next to the repository, else the copy "
                             "`python -m pinquad.data fetch crazyflie` downloads)")
    parser.add_argument("--csv", type=Path, default=None,
                        help="a CSV of steady points: rotor speed and measured total thrust, "
                             "units in the header (weight[g], thrust[N], rpm, omega[rad/s])")
    parser.add_argument("--speed-column", action="append", default=None, metavar="COLUMN",
                        help="speed column(s) (default: the column named rpm/omega/speed); "
                             "one column stands for every rotor")
    parser.add_argument("--thrust-column", default=None, metavar="COLUMN")
    parser.add_argument("--speed-unit", choices=["rpm", "rad/s", "krpm"], default=None,
                        help="when the header does not say (default rpm)")
    parser.add_argument("--thrust-unit", choices=["N", "g", "kg", "mN"], default=None,
                        help="when the header does not say (default N; g is grams-force)")
    parser.add_argument("--motors", type=int, default=4,
                        help="rotors whose total thrust was measured (default 4)")
    parser.add_argument("--speeds-from", type=Path, default=None, metavar="LOG",
                        help="take the speeds from a CSV logged during the run, matched on "
                             "--join")
    parser.add_argument("--join", default=None, metavar="COL=LOGCOL",
                        help="column of --csv and of --speeds-from that name the same step "
                             "(e.g. rpm=pwm)")
    parser.add_argument("--speed-range", type=float, nargs=2, default=None,
                        metavar=("MIN", "MAX"), help="keep points in this speed range [rev/min]")
    args = parser.parse_args(argv)
    if args.csv is not None:
        return _steady(args)
    data = args.data if args.data is not None else default_data_dir()
    if (data / "thrust_stand").is_dir():
        data = data / "thrust_stand"
    csvs = sorted(data.glob("*.csv")) if data.is_dir() else []
    if not csvs:
        print(f"error: {data}: no thrust-stand CSV file found; expected a directory with "
              f"*.csv files having columns weight[g], rpm1..rpm4: {missing_data_hint()}",
              file=sys.stderr)
        return 2
    try:
        fits = [fit_thrust_stand(p) for p in csvs]
        pooled = fit_thrust_stand(csvs) if len(csvs) > 1 else None
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print("Thrust-stand fit: total thrust [N] = kf * sum_i omega_i^2, omega in rad/s "
          "(+- is one jackknife standard error)")
    for fit in fits:
        print(_format_fit(fit))
    if pooled is not None:
        print(_format_fit(replace(pooled, source="pooled (" + pooled.source + ")")))
        ks = np.array([f.kf for f in fits])
        ses = np.array([f.kf_se for f in fits])
        spread = float(ks.max() - ks.min())
        if spread > 3.0 * float(np.sqrt((ses**2).max() * 2)):
            print(f"note: the files disagree by {spread / pooled.kf * 100:.1f} % of kf, far more "
                  "than their standard errors: take that spread, not the pooled standard "
                  "error, as the real uncertainty of kf for another vehicle.")
    ks = np.array([f.kf for f in fits])
    se = float(ks.std(ddof=1) / np.sqrt(ks.size)) if ks.size > 1 else fits[0].kf_se
    print("\nvehicle file section (kf: equal-weight mean of the runs, kf_se: between-run "
          "standard error):\n")
    print(actuator_section(float(ks.mean()), se, f"fitted by python -m pinquad.actuators to "
                           f"{', '.join(f.source for f in fits)}"))
    return 0


def _steady(args: argparse.Namespace) -> int:
    join = None
    if args.join is not None:
        if "=" not in args.join:
            print(f"error: --join {args.join}: expected COL=LOGCOL (e.g. rpm=pwm)", file=sys.stderr)
            return 2
        left, right = args.join.split("=", 1)
        join = (left.strip(), right.strip())
    if args.motors < 1:
        print(f"error: --motors {args.motors}: expected at least 1", file=sys.stderr)
        return 2
    try:
        fit = fit_steady_thrust(
            args.csv, motors=args.motors, speed_columns=tuple(args.speed_column or ()),
            thrust_column=args.thrust_column, speed_unit=args.speed_unit,
            thrust_unit=args.thrust_unit, speeds_from=args.speeds_from, join=join,
            speed_range=tuple(args.speed_range) if args.speed_range else (0.0, float("inf")))
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"Steady-thrust fit: total thrust [N] = kf * sum_i omega_i^2 ({fit.motors} rotors, "
          "omega in rad/s; +- is the least-squares standard error from the residuals)")
    print(f"{fit.source}:")
    print(f"  kf = {fit.kf:.4e} +- {fit.kf_se:.1e} N/(rad/s)^2 ({100 * fit.kf_se / fit.kf:.2f} %)"
          f"   residual RMS {fit.residual_rms * 1e3:.2f} mN ({fit.residual_rms / GRAM_FORCE:.2f} gf)"
          f"   points {fit.n_points}")
    for note in fit.notes:
        print(f"  {note}")
    print("  speed [rev/min] | thrust [gf] | residual [gf]")
    for sp, th, r in zip(fit.speed_rpm.mean(axis=1), fit.thrust, fit.residuals(), strict=True):
        print(f"  {sp:8.0f} | {th / GRAM_FORCE:7.2f} | {r / GRAM_FORCE:+6.2f}")
    print("\nvehicle file section:\n")
    print(actuator_section(fit.kf, fit.kf_se, f"fitted by python -m pinquad.actuators to "
                           f"{fit.source} ({fit.n_points} points)"))
    return 0
