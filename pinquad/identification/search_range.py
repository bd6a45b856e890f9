"""Where EM may look for a recorded log's mass and inertia: the physically possible set.

A log whose torques explain little of the angular acceleration leaves the likelihood
nearly flat towards large inertia: unbounded, EM follows it to 1e80 kg m^2. EM therefore
searches inside a range (``run_em``'s ``bounds``):

* the range the verdict judges against (``verdict.vehicle_range``): a named vehicle's
  (a shipped one or a vehicle file), else the one around the sidecar's guesses;
* otherwise a range that holds any multirotor of the log's own hover mass,

      m_hover = median(F) / g over the airborne rows,
      m in [m_hover / 3, 3 m_hover],
      I_ii in [m_lo r_min^2, m_hi r_max^2],  r_min = 5 mm, r_max = 1 m,

  (r: the radius of gyration; a Crazyflie's is 2-3 cm, a 1.5 kg PX4 quad's 14-19 cm).

An estimate that ends on the range's edge is not a fit: the verdict says the log does
not determine it (``at_bound``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.params import VehicleRange
from pinquad.identification.verdict import vehicle_range
from pinquad.io.logs import FlightLog

Array = NDArray[np.float64]

MASS_SPAN = 3.0
"""The generic range's mass factor around the hover mass [-]."""
GYRATION_RADIUS = (0.005, 1.0)
"""The generic range's radius of gyration [m]: any multirotor's lies between."""
EDGE_RTOL = 1e-6
"""An estimate within this relative distance of the range's edge is on it."""


def hover_mass(log: FlightLog) -> float | None:
    """median(F) / g [kg] over the rows not flagged as floor contact, or None when the
    log has no thrust column or no positive thrust."""
    if log.thrust is None:
        return None
    thrust = np.asarray(log.thrust, dtype=float)
    if log.contact is not None:
        thrust = thrust[~np.asarray(log.contact, dtype=bool)]
    thrust = thrust[np.isfinite(thrust) & (thrust > 0)]
    if thrust.size == 0:
        return None
    return float(np.median(thrust)) / log.meta.gravity


def generic_range(mass: float) -> VehicleRange:
    """The range of any multirotor of hover mass ``mass`` [kg] (module docstring)."""
    lo, hi = mass / MASS_SPAN, mass * MASS_SPAN
    r_lo, r_hi = GYRATION_RADIUS
    return VehicleRange((lo, hi), np.full(3, lo * r_lo**2), np.full(3, hi * r_hi**2),
                        f"no vehicle named: any multirotor of the log's hover mass "
                        f"{mass * 1e3:.4g} g (mass / {MASS_SPAN:g} to x {MASS_SPAN:g}, "
                        f"radius of gyration {r_lo * 1e3:g} mm to {r_hi:g} m)")


def search_range(log: FlightLog) -> VehicleRange | None:
    """The range EM searches for ``log``'s mass and inertia (module docstring); None for a
    log with no named vehicle and no thrust column (its EM is not bounded here)."""
    meta = log.meta
    named = vehicle_range(meta.vehicle if meta.vehicle_named else "", meta.mass_guess,
                          meta.inertia_guess)
    if named is not None:
        return named
    mass = hover_mass(log)
    return None if mass is None else generic_range(mass)


def at_bound(values: Array, bounds: VehicleRange) -> list[str]:
    """The names of [m, I_xx, I_yy, I_zz] (``values`` (4,)) that sit on the range's edge."""
    lo = np.concatenate([[bounds.mass[0]], bounds.inertia_lo])
    hi = np.concatenate([[bounds.mass[1]], bounds.inertia_hi])
    v = np.asarray(values, dtype=float)
    edge = (np.abs(v - lo) <= EDGE_RTOL * lo) | (np.abs(v - hi) <= EDGE_RTOL * hi)
    return [n for n, e in zip(("mass", "I_xx", "I_yy", "I_zz"), edge, strict=True) if e]


def outside_range(values: Array, search: VehicleRange | None,
                  vrange: VehicleRange | None,
                  names: tuple[str, ...] = ("mass", "I_xx", "I_yy", "I_zz")) -> str | None:
    """Why a fit of [m, I_xx, I_yy, I_zz] (``values`` (4,)) is not physical: a parameter on
    the edge of the range EM searched, or outside the vehicle's plausible range; None
    when it is neither (only the parameters in ``names`` are looked at)."""
    edge = [] if search is None else [n for n in at_bound(values, search) if n in names]
    if edge:
        return (f"{', '.join(edge)} ended on the edge of the range EM searched "
                f"({search.source})")  # type: ignore[union-attr]
    if vrange is not None:
        lo = np.r_[vrange.mass[0], vrange.inertia_lo]
        hi = np.r_[vrange.mass[1], vrange.inertia_hi]
        out = [n for n, v, a, b in zip(("mass", "I_xx", "I_yy", "I_zz"), values, lo, hi,
                                       strict=True) if not a <= v <= b and n in names]
        if out:
            return f"{', '.join(out)} outside the vehicle's plausible range ({vrange.source})"
    return None
