"""The IMRC Lab Crazyflie data set: where its files are, what was flown, what the vehicle
is known to weigh, and where EM starts on it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import SHIPPED, is_vehicle_file, load_vehicle
from pinquad.io.datadir import default_data_dir

Array = NDArray[np.float64]

_REFERENCE = load_vehicle("crazyflie21").reference
assert _REFERENCE.mass is not None and _REFERENCE.inertia is not None
SCALE_MASS: float = _REFERENCE.mass
"""The vehicle on a scale, battery and decks included [kg] (dataset README; read from
``pinquad/data/crazyflie21.toml`` [reference])."""
PUBLISHED_INERTIA = np.asarray(_REFERENCE.inertia, dtype=float).copy()
"""Crazyflie 2.0 without decks, bifilar pendulum (Foerster) [kg m^2]."""


FLIGHTS: dict[str, str] = {
    "jana00": "figure-8 at 0.7 m, time scale 1.0 (fast)",
    "jana01": "yaw sweep at 0.7 m, time scale 5",
    "jana02": "figure-8 at 0.3 m, time scale 0.8",
    "jana03": "figure-8 at 0.3 m, time scale 0.8 (2nd controller)",
    "jana04": "yaw sweep at 0.5 m, time scale 5",
    "jana05": "yaw sweep at 0.5 m, time scale 4",
    "jana10": "circle at 0.5 m, time scale 5",
    "jana20": "random in 1 m box (M1 rpm faulty)",
    "jana23": "random in 1 m box (M1 rpm faulty)",
    "jana24": "random in 1 m box (M1 rpm faulty)",
    "jana25": "random in 1 m box (M1 rpm faulty)",
    "jana27": "random in 1 m box (M1 rpm faulty)",
    "jana28": "random in 1 m box (M1 rpm faulty)",
    "jana29": "random in 1 m box (M1 rpm faulty)",
}
"""The IMRC Lab flights and what was flown (dataset README)."""
YAW_FLIGHTS = ("jana01", "jana04", "jana05")
POOL_FLIGHTS = ("jana00", "jana01", "jana02", "jana03", "jana04", "jana05", "jana10")
"""The logs that share one rotor inertia by default: the seven with every rotor speed
measured (on jana20-29 M1's speed, hence its acceleration, is rebuilt from PWM through a
first-order lag: a model, not a measurement)."""


def flights_dir(data: Path | None = None) -> Path:
    """Directory of the micro-SD flight logs: ``data`` (the Crazyflie data directory or
    the flights directory itself), else ``imrc_brushed`` in ``default_data_dir()``."""
    base = data if data is not None else default_data_dir()
    return base / "imrc_brushed" if (base / "imrc_brushed").is_dir() else base


def stand_dir(data: Path | None = None) -> Path:
    """Directory of the thrust-stand CSVs (``thrust_stand`` next to the flights)."""
    base = data if data is not None else default_data_dir()
    for cand in (base / "thrust_stand", base.parent / "thrust_stand"):
        if cand.is_dir():
            return cand
    return base / "thrust_stand"


def default_guess(vehicle: str) -> tuple[float, Array, str]:
    """Initial (mass [kg], inertia (3, 3) [kg m^2], words) from the vehicle file's
    [guess] (``vehicle``: a shipped name or a ``.toml`` path; crazyflie21: 25 g and half
    the published inertia); a name pinquad does not know starts from the paper's m0 =
    0.001 kg, I0 = diag(1e-4, 2e-4, 1e-4). Raises VehicleFileError for a bad file."""
    spec = load_vehicle(vehicle if is_vehicle_file(vehicle) or vehicle in SHIPPED else "paper")
    words = spec.guess_note or f"{spec.name}'s [guess]"
    return spec.guess_mass, np.asarray(spec.guess_inertia, dtype=float), words
