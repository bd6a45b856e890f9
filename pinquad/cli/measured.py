"""What the measured-flight diagnostics' command lines share (``python -m
pinquad.response``, ``python -m pinquad.axis_inertia``): the log arguments, the logs
they name through the pipeline's read and check (``pinquad.pipeline.measured``), and the
check of the ``--simulate`` factors."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from pinquad.core.vehicle_file import VehicleSpec, load_vehicle
from pinquad.io.datadir import missing_data_hint
from pinquad.io.logs import vehicle_file_named
from pinquad.pipeline.measured import measured_log
from pinquad.realdata.dataset import POOL_FLIGHTS, flights_dir, stand_dir
from pinquad.realdata.observations import RealObservations
from pinquad.realdata.thrust import thrust_coefficient

Array = NDArray[np.float64]


def add_measured_log_arguments(parser: argparse.ArgumentParser) -> None:
    """The measured-flight diagnostics' shared arguments: LOG names, --data,
    --rotor-inertia, --vehicle (``response``, ``axis_inertia``)."""
    parser.add_argument("logs", nargs="*", default=list(POOL_FLIGHTS),
                        help="log names in the data directory, or paths (default: the seven "
                             "clean logs)")
    parser.add_argument("--data", type=Path, default=None,
                        help="Crazyflie data directory (default: $PINQUAD_CRAZYFLIE_DATA, else "
                             "../shared/data/crazyflie next to the repository, else the copy "
                             "`python -m pinquad.data fetch crazyflie` downloads)")
    parser.add_argument("--rotor-inertia", type=float, default=0.0,
                        help="J_r [kg m^2] added to the yaw torque as J_r sum spin_i omega_i'")
    parser.add_argument("--vehicle", default="crazyflie21", metavar="NAME|FILE",
                        help="the logs' vehicle: crazyflie21 (default; kf from the data "
                             "directory's thrust stand) or a vehicle file (.toml, "
                             "docs/vehicles.md: its mixer, kf and reference)")


def measured_vehicle_spec(vehicle: str) -> VehicleSpec:
    """The vehicle file of ``--vehicle`` (a shipped name or a path relative to the working
    directory). Raises LogFormatError naming the option."""
    if vehicle == "crazyflie21":
        return load_vehicle(vehicle)
    return load_vehicle(vehicle_file_named(vehicle, Path.cwd(), "--vehicle"))


def reference_inertia(spec: VehicleSpec) -> Array:
    """(3,) [kg m^2] the diagnostics compare with: the file's [reference] inertia, else
    its body's."""
    ref = spec.reference.inertia
    return np.asarray(ref if ref is not None else np.diag(spec.inertia), dtype=float).copy()


def measured_logs(logs: Sequence[str], data: Path | None, vehicle: str = "crazyflie21"
                  ) -> Iterator[tuple[str, RealObservations]]:
    """Yield (name, observations) for ``logs`` (names in ``data``'s flight directory, or
    paths) under a progress bar, each read and checked as the log of ``vehicle``
    (``pipeline.measured.measured_log``): the shipped crazyflie21 with kf from the data's
    thrust stand, a vehicle file with its mixer, fault thresholds and kf. Raises
    LogFormatError / ValueError / FileNotFoundError."""
    shipped = vehicle == "crazyflie21"
    flights = flights_dir(data) if shipped or data is None else data
    if not flights.is_dir() and not all(Path(name).exists() for name in logs):
        raise FileNotFoundError(f"{flights}: no such directory; expected the Crazyflie flight "
                                f"logs: {missing_data_hint()}")
    kf = thrust_coefficient(stand_dir(data)) if shipped else None
    for name in tqdm(logs, unit="log", file=sys.stderr):
        path = Path(name) if Path(name).exists() else flights / name
        yield path.name, measured_log(path, vehicle, kf)


def positive_factors(values: list[float]) -> str | None:
    """An error message if any --simulate factor is not a positive finite number."""
    if any(not (v > 0 and math.isfinite(v)) for v in values):
        return "--simulate factors must be positive numbers"
    return None
