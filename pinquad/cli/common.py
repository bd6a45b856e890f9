"""What the command lines share: the online commands'
``--memory`` value and its description, and the measured-flight diagnostics' log
arguments."""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def memory_arg(text: str) -> float | None:
    """The online commands' --memory: a positive number of seconds, inf, or none."""
    if text.strip().lower() == "none":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected seconds (> 0), inf or none, got {text!r}") from None
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected seconds (> 0), inf or none, got {text!r}")
    return value


def memory_label(memory_s: float | None) -> str:
    """How the online M-step remembers samples that left the window, in words."""
    if memory_s is None:
        return "window only"
    if math.isinf(memory_s):
        return "every airborne sample (incremental EM)"
    return f"forgotten with time constant {memory_s:g} s"


def add_measured_log_arguments(parser: argparse.ArgumentParser) -> None:
    """The measured-flight diagnostics' shared arguments: LOG names, --data,
    --rotor-inertia (``response``, ``axis_inertia``)."""
    from pinquad.realdata.flights import POOL_FLIGHTS

    parser.add_argument("logs", nargs="*", default=list(POOL_FLIGHTS),
                        help="log names in the data directory, or paths (default: the seven "
                             "clean logs)")
    parser.add_argument("--data", type=Path, default=None,
                        help="Crazyflie data directory (default: $PINQUAD_CRAZYFLIE_DATA, else "
                             "../shared/data/crazyflie next to the repository)")
    parser.add_argument("--rotor-inertia", type=float, default=0.0,
                        help="J_r [kg m^2] added to the yaw torque as J_r sum spin_i omega_i'")


def measured_logs(args: argparse.Namespace):
    """Yield (name, ``realdata.RealObservations``) for the parsed ``args.logs`` (names in
    ``args.data``'s flight directory, or paths), with kf from its thrust stand, under a
    progress bar. Raises LogFormatError / ValueError / FileNotFoundError."""
    import sys

    from tqdm import tqdm

    from pinquad.realdata.flights import (
        RealDataOptions,
        flights_dir,
        load_real,
        stand_dir,
        thrust_coefficient,
    )

    flights = flights_dir(args.data)
    kf = thrust_coefficient(stand_dir(args.data))
    for name in tqdm(args.logs, unit="log", file=sys.stderr):
        path = Path(name) if Path(name).exists() else flights / name
        yield path.name, load_real(path, RealDataOptions(), kf)


def positive_factors(values: list[float]) -> str | None:
    """An error message if any --simulate factor is not a positive finite number."""
    if any(not (v > 0 and math.isfinite(v)) for v in values):
        return "--simulate factors must be positive numbers"
    return None
