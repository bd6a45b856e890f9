"""write_csv: the flight's log as a CSV file in pinquad's log columns plus its JSON sidecar
``<path>.json`` (the generator's own writer). Empty cells where a sensor has no sample;
numbers written with 17 significant digits (round-trip exact)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flightgen.spec import Flight

Array = NDArray[np.float64]


def _cells(col: Array) -> NDArray[np.str_]:
    text = np.char.mod("%.17g", np.asarray(col, dtype=float))
    return np.where(np.isnan(col), "", text)


def write_csv(flight: Flight, path: str | Path, mass_guess: float | None = None,
              inertia_guess: Array | None = None) -> Path:
    """Write ``flight.columns`` to ``path`` (CSV) and the sidecar to ``path.json``;
    mass_guess [kg] / inertia_guess (3, 3) [kg m^2] override the sidecar's (None: left
    to the reader's default for the vehicle). Returns path."""
    path = Path(path)
    names = list(flight.columns)
    cells = np.column_stack([_cells(flight.columns[n]) for n in names])
    lines = [",".join(names)] + [",".join(row) for row in cells]
    path.write_text("\n".join(lines) + "\n")
    side = dict(flight.sidecar)
    if mass_guess is not None:
        side["mass_guess"] = float(mass_guess)
    if inertia_guess is not None:
        side["inertia_guess"] = np.asarray(inertia_guess, dtype=float).tolist()
    Path(str(path) + ".json").write_text(json.dumps(side, indent=2) + "\n")
    return path
