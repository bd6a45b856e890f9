"""``python -m pinquad.actuators [--data DIR]``: the thrust-stand fits of the rotor thrust
coefficient kf (``pinquad.vehicle.actuators.fit_thrust_stand``), per file and pooled."""

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
    args = parser.parse_args(argv)
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
    return 0
