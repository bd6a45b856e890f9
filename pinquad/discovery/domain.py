"""Each library effect's physical domain: a fit outside it is not an effect of this vehicle.

* ``drag``: D_x, D_y, D_z >= 0 [N s/m] (air resists motion; a negative drag pushes);
* ``ground_effect``: k_ge >= 0 [-] (the floor adds thrust), and the flight must come
  within ``GROUND_REACH`` effect radii of the floor (z = 0), where the cushion acts at
  all: above that the law's gain is below (1/(4 * 4))^2 = 0.4 % per unit k_ge, and a fit
  there reads anything in the thrust as a huge k_ge;
* ``motor_lag``: tau_m >= 0 [s].

``com_offset``, ``wind`` and ``gyro_bias`` take either sign. A coefficient is outside its
domain when it lies beyond it by more than ``DOMAIN_SE`` standard errors (a drag within
noise of zero is zero, not negative).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.effect_vocabulary import COEFFICIENT_NAMES
from pinquad.discovery.result import DiscoveryResult

Array = NDArray[np.float64]

NON_NEGATIVE = {"drag": (0, 1, 2), "ground_effect": (0,), "motor_lag": (0,)}
"""Effect -> the indices of its coefficients that cannot be negative."""
GROUND_REACH = 4.0
"""Ground effect needs data below this many effect radii above the floor [-]."""
FORCE_EFFECTS = ("drag", "ground_effect", "wind")
"""Effects on the force rows only: they rest on the mass, not on the inertia."""
DOMAIN_SE = 2.0
"""Standard errors beyond the domain's edge that make a coefficient outside it."""


def outside_domain(found: DiscoveryResult, heights: Array, ground_radius: float
                   ) -> dict[str, str]:
    """Selected effects of ``found`` whose fit is outside its physical domain (module
    docstring), with the reason in words. heights (K,) [m]: the vehicle's height above
    the floor on the transitions discovery used; ground_radius [m]: the effect radius."""
    out: dict[str, str] = {}
    for name in found.selected:
        coef = np.asarray(found.coefficients[name], dtype=float)
        se = np.asarray(found.stderr.get(name, np.full(coef.shape, np.nan)), dtype=float)
        names = COEFFICIENT_NAMES[name]
        reasons = []
        for i in NON_NEGATIVE.get(name, ()):
            margin = DOMAIN_SE * (se[i] if np.isfinite(se[i]) else 0.0)
            if coef[i] < -margin:
                reasons.append(f"{names[i]} = {coef[i]:.4g} is negative beyond {DOMAIN_SE:g} "
                               f"standard errors ({se[i]:.2g}): it cannot be")
        if name == "ground_effect":
            lowest = float(np.nanmin(heights)) if np.isfinite(heights).any() else np.inf
            reach = GROUND_REACH * ground_radius
            if lowest > reach:
                reasons.append(f"the flight never comes within {reach * 100:.3g} cm of the "
                               f"floor ({GROUND_REACH:g} effect radii; lowest "
                               f"{lowest * 100:.3g} cm): no ground effect can act there")
        if reasons:
            out[name] = "; ".join(reasons)
    return out


def unexplained_residual(found: DiscoveryResult, effect: str, reason: str) -> dict:
    """report.json's entry for an effect whose best fit is outside its domain: the
    closest unphysical fit (coefficients, standard errors, why it cannot be) and the
    residual it would have explained, per axis: held-out rms before and after, and the
    share of the residual's variance, 1 - (after / before)^2."""
    rows = {}
    for axis, before in found.rms_before.items():
        after = found.rms_after.get(axis, float("nan"))
        if np.isfinite(before) and before > 0 and np.isfinite(after) and after < before:
            rows[axis] = {"rms_before": before, "rms_after": after,
                          "share": 1.0 - (after / before) ** 2}
    return {"effect": effect, "reason": reason,
            "closest_unphysical_fit": dict(zip(COEFFICIENT_NAMES[effect],
                                               np.asarray(found.coefficients[effect]).tolist(),
                                               strict=True)),
            "stderr": np.asarray(found.stderr.get(effect, [])).tolist(),
            "unexplained_rows": rows}
