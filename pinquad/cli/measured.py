"""What the measured-flight diagnostics' command lines share (``python -m
pinquad.response``, ``python -m pinquad.axis_inertia``): the log arguments, loading the
logs they name, and the check of the ``--simulate`` factors."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

from tqdm import tqdm

from pinquad.io.datadir import missing_data_hint
from pinquad.realdata.dataset import POOL_FLIGHTS, flights_dir, stand_dir
from pinquad.realdata.observations import RealDataOptions, RealObservations, load_real
from pinquad.realdata.thrust import thrust_coefficient


def add_measured_log_arguments(parser: argparse.ArgumentParser) -> None:
    """The measured-flight diagnostics' shared arguments: LOG names, --data,
    --rotor-inertia (``response``, ``axis_inertia``)."""
    parser.add_argument("logs", nargs="*", default=list(POOL_FLIGHTS),
                        help="log names in the data directory, or paths (default: the seven "
                             "clean logs)")
    parser.add_argument("--data", type=Path, default=None,
                        help="Crazyflie data directory (default: $PINQUAD_CRAZYFLIE_DATA, else "
                             "../shared/data/crazyflie next to the repository, else the copy "
                             "`python -m pinquad.data fetch crazyflie` downloads)")
    parser.add_argument("--rotor-inertia", type=float, default=0.0,
                        help="J_r [kg m^2] added to the yaw torque as J_r sum spin_i omega_i'")


def measured_logs(logs: Sequence[str], data: Path | None
                  ) -> Iterator[tuple[str, RealObservations]]:
    """Yield (name, observations) for ``logs`` (names in ``data``'s flight directory, or
    paths), with kf from its thrust stand, under a progress bar. Raises LogFormatError /
    ValueError / FileNotFoundError."""
    flights = flights_dir(data)
    if not flights.is_dir() and not all(Path(name).exists() for name in logs):
        raise FileNotFoundError(f"{flights}: no such directory; expected the Crazyflie flight "
                                f"logs: {missing_data_hint()}")
    kf = thrust_coefficient(stand_dir(data))
    for name in tqdm(logs, unit="log", file=sys.stderr):
        path = Path(name) if Path(name).exists() else flights / name
        yield path.name, load_real(path, RealDataOptions(), kf)


def positive_factors(values: list[float]) -> str | None:
    """An error message if any --simulate factor is not a positive finite number."""
    if any(not (v > 0 and math.isfinite(v)) for v in values):
        return "--simulate factors must be positive numbers"
    return None
