"""The estimate against what the vehicle is known to be without flight data: a vehicle
file's ``[reference]`` values with their stated uncertainty (a scale, a pendulum).

An estimate x with total standard error s disagrees with the reference r (relative
uncertainty u) when

    |x - r| > 2 sqrt(s^2 + (u r)^2),

an independent measurement of the same body saying that the flight's model, or what it
assumed, does not hold on this log; the parameter is then not trusted ("model not
adequate"), however small its own error bar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import VehicleSpec
from pinquad.identification.budget import vehicle_spec

Array = NDArray[np.float64]

Z_REFERENCE = 2.0
"""Combined standard errors beyond which an estimate disagrees with the reference."""
REFERENCE_MARK = "from the vehicle's reference"
"""In every reason :func:`reference_check` gives (:func:`only_the_reference`)."""


@dataclass(frozen=True)
class ReferenceValues:
    """values (4,) of [m, I_xx, I_yy, I_zz] [kg, kg m^2] and their standard errors (4,)
    (NaN: no reference for that parameter); source: the vehicle file, in words."""

    values: Array
    stderr: Array
    source: str


def reference_values(spec: VehicleSpec | None) -> ReferenceValues | None:
    """The vehicle file's reference with its stated uncertainty, or None (no file, or no
    uncertainty stated for any reference value)."""
    if spec is None:
        return None
    ref = spec.reference
    values = np.full(4, np.nan)
    stderr = np.full(4, np.nan)
    if ref.mass is not None and ref.mass_rel_se is not None:
        values[0], stderr[0] = ref.mass, ref.mass * ref.mass_rel_se
    if ref.inertia is not None and ref.inertia_rel_se is not None:
        values[1:] = np.asarray(ref.inertia, dtype=float)
        stderr[1:] = values[1:] * ref.inertia_rel_se
    if not np.isfinite(stderr).any():
        return None
    return ReferenceValues(values, stderr, f"{spec.name}'s [reference]")


def vehicle_reference(vehicle: str | None) -> ReferenceValues | None:
    """:func:`reference_values` of a shipped vehicle's name or a vehicle file, or None."""
    return reference_values(vehicle_spec(vehicle))


def reference_check(name: str, index: int, value: float, se: float,
                    reference: ReferenceValues | None, scale: float, unit: str) -> list[str]:
    """The reason parameter ``name`` (``index`` in [m, I_xx, I_yy, I_zz]) disagrees with
    the reference (module docstring), or none; scale and unit print it."""
    if reference is None or not np.isfinite(se):
        return []
    ref, ref_se = float(reference.values[index]), float(reference.stderr[index])
    if not (np.isfinite(ref) and np.isfinite(ref_se)):
        return []
    combined = float(np.hypot(se, ref_se))
    if abs(value - ref) <= Z_REFERENCE * combined:
        return []
    return [f"{value * scale:.4g} {unit} is {abs(value - ref) / combined:.1f} combined standard "
            f"errors {REFERENCE_MARK} {ref * scale:.4g} +- {ref_se * scale:.2g} "
            f"{unit} ({reference.source}): the flight's model, or what it assumed, does not "
            "hold on this log"]


def only_the_reference(reasons: tuple[str, ...]) -> bool:
    """Whether every reason of a parameter's verdict is the reference's: the flight
    carried the parameter, and only the vehicle's reference disagrees with the number."""
    return bool(reasons) and all(REFERENCE_MARK in r for r in reasons)
