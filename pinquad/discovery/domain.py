"""Each library effect's physical domain: a fit outside it is not an effect of this vehicle.

* ``drag``: D_x, D_y, D_z >= 0 [N s/m] (air resists motion; a negative drag pushes);
* ``ground_effect``: k_ge >= 0 [-] (the floor adds thrust), and the flight must come
  within ``GROUND_REACH`` effect radii of the floor the log shows
  (``Observations.floor``), where the cushion acts at all: above that the law's gain is
  below (1/(4 * 4))^2 = 0.4 % per unit k_ge, and a fit there reads anything in the
  thrust as a huge k_ge;
* ``motor_lag``: tau_m >= 0 [s].

``com_offset``, ``wind`` and ``gyro_bias`` take either sign and are not bounded: a CoM
offset's only physical limit is the vehicle's own size, far beyond anything a flyable
vehicle shows (a CoM a rotor arm off its centre cannot hover), and a wind force or a
gyro offset have no sign.

The refit keeps each coefficient inside its domain: its profiled fits minimise over the
box c >= lower (``lower_bounds``; ``selection.profiled_fit``) and the likelihood's Newton
step is projected onto it (``uncertainty.information_fit``), as the M-step projects the
inertia onto its range. A coefficient the box holds is *on the edge* (``on_edge``): its
value is the bound, its free fit is reported beside it. A selected effect is not kept
(``outside_domain``) when

* its free fit lies beyond the domain by more than ``DOMAIN_SE`` standard errors (a
  drag within noise of zero is zero, not negative; beyond that the effect's form does
  not fit the residual), or
* every coefficient it has is on the edge: it then adds nothing to the model (a drag
  that projects to 0 on all three axes, a k_ge of 0), whatever its free fit's held-out
  gain was.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.effect_vocabulary import COEFFICIENT_NAMES
from pinquad.discovery.library import NON_NEGATIVE, lower_bounds
from pinquad.discovery.result import DiscoveryResult
from pinquad.models.ssm import Observations
from pinquad.mstep.stats import transition_mask

Array = NDArray[np.float64]

def project(coefficients: dict[str, Array]) -> dict[str, Array]:
    """The coefficients by effect, each clipped to its domain (``lower_bounds``)."""
    return {e: np.maximum(np.asarray(c, dtype=float), lower_bounds(e))
            for e, c in coefficients.items()}


def on_edge(coefficients: dict[str, Array]) -> dict[str, tuple[str, ...]]:
    """Effect -> the names of its coefficients on their domain's edge (at or below
    their lower bound); effects with none are left out."""
    out = {}
    for e, c in coefficients.items():
        at = np.asarray(c, dtype=float) <= lower_bounds(e)
        if at.any():
            out[e] = tuple(n for n, a in zip(COEFFICIENT_NAMES[e], at, strict=True) if a)
    return out
GROUND_REACH = 4.0
"""Ground effect needs data below this many effect radii above the floor [-]."""
FORCE_EFFECTS = ("drag", "ground_effect", "wind")
"""Effects on the force rows only: they rest on the mass, not on the inertia."""
DOMAIN_SE = 2.0
"""Standard errors beyond the domain's edge that make a coefficient outside it."""


def transition_heights(obs: Observations, mean: Array) -> Array:
    """(K,) [m] the smoothed height above the floor the log shows, z_k - z_f
    (``Observations.floor``), on the transitions k -> k+1 the M-step uses
    (``transition_mask``): what ``outside_domain``'s ground-effect reach is judged on.
    mean (N, 12): the smoothed states."""
    return mean[np.flatnonzero(transition_mask(obs)), 2] - obs.floor.height


def outside_domain(found: DiscoveryResult, heights: Array, ground_radius: float
                   ) -> dict[str, str]:
    """Selected effects of ``found`` not kept for their domain (module docstring), with
    the reason in words: a free fit beyond the domain by more than ``DOMAIN_SE``
    standard errors, every coefficient on the edge, or a ground effect the flight never
    came near the floor for. heights (K,) [m]: the vehicle's height above the floor the
    log shows (``Observations.floor``) on the transitions discovery used; ground_radius
    [m]: the effect radius."""
    out: dict[str, str] = {}
    for name in found.selected:
        coef = np.asarray(found.coefficients[name], dtype=float)
        free = np.asarray(found.coefficients_free.get(name, coef), dtype=float)
        se = np.asarray(found.stderr.get(name, np.full(coef.shape, np.nan)), dtype=float)
        names = COEFFICIENT_NAMES[name]
        reasons = []
        for i in NON_NEGATIVE.get(name, ()):
            margin = DOMAIN_SE * (se[i] if np.isfinite(se[i]) else 0.0)
            if free[i] < -margin:
                reasons.append(f"{names[i]} = {free[i]:.4g} is negative beyond {DOMAIN_SE:g} "
                               f"standard errors ({se[i]:.2g}): it cannot be")
        edge = on_edge({name: coef}).get(name, ())
        if not reasons and len(edge) == len(names):
            fits = ", ".join(f"{n} {v:.4g} ± {e:.2g}" for n, v, e in zip(names, free, se,
                                                                       strict=True))
            reasons.append(f"every coefficient is on its domain's edge ({', '.join(edge)} = 0; "
                           f"without the domain {fits}): the effect adds nothing")
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
            "closest_unphysical_fit": dict(zip(
                COEFFICIENT_NAMES[effect],
                np.asarray(found.coefficients_free.get(effect,
                                                       found.coefficients[effect])).tolist(),
                strict=True)),
            "stderr": np.asarray(found.stderr.get(effect, [])).tolist(),
            "unexplained_rows": rows}
