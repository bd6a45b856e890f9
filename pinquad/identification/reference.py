"""The estimate against what the vehicle is known to be without flight data: a vehicle
file's ``[reference]`` values (a scale, a pendulum, a CAD model) with their uncertainty.

A reference is always judged. Its relative uncertainty u is the file's ``mass_rel_se`` /
``inertia_rel_se``, else a stated default (``DEFAULT_MASS_REL_SE``,
``DEFAULT_INERTIA_REL_SE``). An estimate x with total standard error s disagrees with the
reference r when

    |x - r| > 2 sqrt(s^2 + (u r)^2),

an independent measurement of the same body saying that the flight's model, or what it
assumed, does not hold on this log; the parameter is then not trusted ("model not
adequate"), however small its own error bar. Such a disagreement has two readings, and
the reason names both: the file describes another vehicle (its thrust map scales every
estimate), or the vehicle carries a load the file does not hold. Since both readings
touch every parameter (another thrust map scales the inertia as it scales the mass; a
load adds inertia as it adds mass), a mass that disagrees makes the inertia untrusted
too (:func:`vehicle_mismatch`).

A payload the log declares (sidecar ``payload_mass``, ``--payload-mass``) moves the mass
reference by its mass m_p: r_m = m_file + m_p, with the file's relative uncertainty on
the file's part only, sqrt((u m_file)^2) (the declared payload is taken as weighed). Its
inertia is taken as a point mass at the centre of mass, which adds none: the inertia
reference stays the file's. A payload hung away from the centre (on a cable, an arm) adds
m_p d^2 about the axes perpendicular to its offset d, which the verdict cannot know; the
inertia then disagrees with the file's reference and says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import SHIPPED, VehicleSpec, shipped_path
from pinquad.identification.budget import named_vehicle, vehicle_spec
from pinquad.io.logs import LogMeta

Array = NDArray[np.float64]

Z_REFERENCE = 2.0
"""Combined standard errors beyond which an estimate disagrees with the reference."""
REFERENCE_MARK = "from the vehicle's reference"
"""In every reason :func:`reference_check` gives (:func:`only_the_reference`)."""
DEFAULT_MASS_REL_SE = 0.02
"""Relative standard uncertainty [-] of a ``[reference] mass`` given without
``mass_rel_se``: a kitchen or postal scale reads to 1 g (a uniform rounding of 0.3 g
standard error) and is good to about 1 % of its reading; the vehicle weighed is rarely
exactly the one flown (another battery: a 250 mAh Crazyflie cell is 7-8 g +- 0.3 g;
markers, a deck, tape: tenths of a gram each). On a 35-70 g vehicle that is 1-2 %: 2 %
covers it, and is still 12x smaller than the 25 % a wrong vehicle file or an undeclared
payload of a quarter of the mass makes."""
DEFAULT_INERTIA_REL_SE = 0.30
"""Relative standard uncertainty [-] of a ``[reference] inertia`` given without
``inertia_rel_se``: a bifilar or trifilar pendulum measures a small vehicle's inertia to
2-5 %, but a file that does not say how well it knows its inertia more often holds a CAD
or point-mass estimate, which misses batteries, wiring, markers and decks by 20-50 % (the
Parrot-frame file's own estimate is uncertain by a factor of about 1.5), or another
build's published value (a Crazyflie 2.0 without decks against a 2.1 with them: about
10 %). 30 % keeps such an estimate from judging a flight's inertia unless they differ by
more than about 60 %, as another vehicle's file does (a 250-class frame's inertia is 100x
a Crazyflie's)."""


@dataclass(frozen=True)
class ReferenceValues:
    """values (4,) of [m, I_xx, I_yy, I_zz] [kg, kg m^2] and their standard errors (4,)
    (NaN: no reference for that parameter); source: the vehicle file, in words (its name,
    its path, whether each uncertainty is stated or the default, the declared payload);
    where: the file's name and path alone."""

    values: Array
    stderr: Array
    source: str
    where: str = ""


def reference_values(spec: VehicleSpec | None, payload_mass: float = 0.0
                     ) -> ReferenceValues | None:
    """The vehicle file's reference with its stated uncertainty, or the default one
    (module docstring), the mass moved by a declared ``payload_mass`` [kg]; None when
    there is no file or it gives no reference value."""
    if spec is None:
        return None
    ref = spec.reference
    values = np.full(4, np.nan)
    stderr = np.full(4, np.nan)
    words = []
    if ref.mass is not None:
        rel = DEFAULT_MASS_REL_SE if ref.mass_rel_se is None else ref.mass_rel_se
        values[0], stderr[0] = ref.mass + payload_mass, ref.mass * rel
        words.append(f"mass +-{100 * rel:.2g} %" + (" (not stated: the default)"
                                                    if ref.mass_rel_se is None else ""))
        if payload_mass:
            words.append(f"plus the declared payload {payload_mass * 1e3:.4g} g")
    if ref.inertia is not None:
        rel = DEFAULT_INERTIA_REL_SE if ref.inertia_rel_se is None else ref.inertia_rel_se
        values[1:] = np.asarray(ref.inertia, dtype=float)
        stderr[1:] = values[1:] * rel
        words.append(f"inertia +-{100 * rel:.2g} %" + (" (not stated: the default)"
                                                       if ref.inertia_rel_se is None else ""))
    if not np.isfinite(values).any():
        return None
    where = f"{spec.name}'s [reference] " + (
        "(shipped with pinquad)" if _is_shipped(spec) else f"in {spec.source}")
    return ReferenceValues(values, stderr, f"{where}, {', '.join(words)}", where)


def _is_shipped(spec: VehicleSpec) -> bool:
    """Whether the file is one pinquad ships (named by its name, not a path on this
    machine)."""
    return spec.name in SHIPPED and Path(str(spec.source)).resolve() == \
        shipped_path(spec.name).resolve()


def vehicle_reference(vehicle: str | None) -> ReferenceValues | None:
    """:func:`reference_values` of a shipped vehicle's name or a vehicle file, or None."""
    return reference_values(vehicle_spec(vehicle))


def log_reference(meta: LogMeta) -> ReferenceValues | None:
    """:func:`reference_values` of the vehicle a log names, moved by the payload it
    declares (``LogMeta.payload_mass``), or None."""
    return reference_values(named_vehicle(meta), meta.payload_mass)


READINGS = ("either the vehicle file describes another vehicle, or the vehicle carries a "
            "load the file does not hold (declare it: sidecar \"payload_mass\" or "
            "--payload-mass, in kg)")
"""The two readings of a mass that disagrees with the vehicle's reference."""
INERTIA_READINGS = ("the flight's model, or what it assumed, does not hold on this log about "
                    "that axis (where the mass agrees with the file, neither another "
                    "vehicle's thrust map nor a load explains it), or the file's inertia is "
                    "not this vehicle's")
"""The readings of an inertia that disagrees with the vehicle's reference (the mass's
readings are named by :func:`vehicle_mismatch` when the mass disagrees too)."""


def reference_gap(index: int, value: float, se: float, reference: ReferenceValues | None
                  ) -> tuple[float, float, float] | None:
    """(r, its standard error, |x - r| / combined standard error) when the estimate
    ``value`` [SI] with total standard error ``se`` of parameter ``index`` in [m, I_xx,
    I_yy, I_zz] disagrees with the reference (module docstring); None when it agrees or
    cannot be compared."""
    if reference is None or not np.isfinite(se):
        return None
    ref, ref_se = float(reference.values[index]), float(reference.stderr[index])
    if not (np.isfinite(ref) and np.isfinite(ref_se)):
        return None
    combined = float(np.hypot(se, ref_se))
    if abs(value - ref) <= Z_REFERENCE * combined:
        return None
    return ref, ref_se, abs(value - ref) / combined


def reference_check(name: str, index: int, value: float, se: float,
                    reference: ReferenceValues | None, scale: float, unit: str) -> list[str]:
    """The reason parameter ``name`` (``index`` in [m, I_xx, I_yy, I_zz]) disagrees with
    the reference (module docstring), with both readings of it, or none; scale and unit
    print it."""
    gap = reference_gap(index, value, se, reference)
    if gap is None or reference is None:
        return []
    ref, ref_se, z = gap
    return [f"{value * scale:.4g} {unit} is {z:.1f} combined standard errors "
            f"{REFERENCE_MARK} {ref * scale:.4g} +- {ref_se * scale:.2g} {unit} "
            f"({reference.source}): {READINGS if index == 0 else INERTIA_READINGS}"]


def vehicle_mismatch(mass: float, se: float, reference: ReferenceValues | None) -> list[str]:
    """What a mass [kg] (total standard error ``se``) that disagrees with the reference
    says of an inertia from the same flight: under either reading the inertia is not the
    file's vehicle's (module docstring); none when the mass agrees."""
    gap = reference_gap(0, mass, se, reference)
    if gap is None or reference is None:
        return []
    return [f"the mass is {gap[2]:.1f} combined standard errors {REFERENCE_MARK} "
            f"{gap[0] * 1e3:.4g} g ({reference.where or reference.source}): the inertia is not "
            "that vehicle's either (another vehicle's thrust map scales the inertia as it "
            "scales the mass; a load adds inertia as it adds mass)"]


def only_the_reference(reasons: tuple[str, ...]) -> bool:
    """Whether every reason of a parameter's verdict is the reference's: the flight
    carried the parameter, and only the vehicle's reference disagrees with the number."""
    return bool(reasons) and all(REFERENCE_MARK in r for r in reasons)
