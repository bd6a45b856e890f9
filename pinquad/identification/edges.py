"""Where a fit is held by a constraint or its error estimate has failed: no trusted number.

EM maximises the likelihood over the physically possible set of diagonal inertias
(``mstep.updates.inertia_newton``, ``mstep.band.profiled_inertia``,
``mstep.compiled.physical``): positive, inside the search box
(``identification.search_range``, judged by ``search_range.at_bound``) and obeying the
triangle inequalities

    I_k <= I_i + I_j   for every (i, j, k) a permutation of (x, y, z),

which any rigid body's principal moments obey (I_i + I_j - I_k = 2 sum over the mass of
the squared distance along axis k >= 0). A likelihood that pulls past a face of that set
(a yaw torque of the wrong sign, a torque scaled wrongly, or noise on a nearly flat
vehicle: a quadrotor's I_zz is typically 5-15 % below I_xx + I_yy) ends on it: the number
is the face, not a fit, and every parameter the face ties (all three moments: moving any of them
moves off the face) is "not identifiable" with that reason. A principal moment within
``TRIANGLE_RTOL`` of the sum of the other two is on the face (:func:`triangle_face`).

On a face the error estimates fail too: each block of the jackknife starts on the face
and stays there, so every block returns the same number and the jackknife's error is
exactly 0; the observed information is the curvature of a likelihood whose maximum lies
beyond the face. An error estimate that collapses, 0 or more than ``COLLAPSE_RATIO``
times smaller than the other one of the same fit (the jackknife against the observed
information), is a failure of the error, never a small error
(:func:`collapsed_errors`): the parameter is not trusted.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

NAMES = ("mass", "I_xx", "I_yy", "I_zz")
TRIANGLE_RTOL = 1e-3
"""A principal moment I_k with |I_i + I_j - I_k| <= TRIANGLE_RTOL I_k is on the triangle
face [-]. 0.1 % is far below an inertia's statistical error on a flight (I_xx: 1.7-2 %
on jana00, jana25 and eckart00), so an estimate that close cannot be told from one on
the face; the band M-step stops on the face to rounding (a relative gap of 1e-11 on
jana25, jana29 and the brushless eckart flights), the rigid-body M-step within its
backtracking's 1e-12. A fit inside the set stays well clear of it (jana00: 8.7 %,
jana23: 57 %)."""
COLLAPSE_RATIO = 0.01
"""An error estimate more than 100 x smaller than another estimate of the same
parameter's error has collapsed [-]. Where the fit is not held by the set, the block
jackknife and the observed information of the shared IMRC logs agree within a factor
of 4.1 either way (jackknife / information of [m, I_xx, I_yy, I_zz]: jana00 1.85, 0.78,
0.63, 2.44; jana23 2.04, 1.44, 1.16, 4.01); on the face the jackknife is 0 to rounding
(1e-20 kg m^2)."""


def triangle_face(inertia: Array) -> str | None:
    """The triangle face (module docstring) the inertia (3, 3) [kg m^2] lies on, in words
    with its numbers, or None. The principal moments are the symmetric part's
    eigenvalues, sorted; only the largest can reach the sum of the other two."""
    sym = 0.5 * (np.asarray(inertia, dtype=float) + np.asarray(inertia, dtype=float).T)
    p = np.linalg.eigvalsh(sym)
    if not p[0] > 0:
        return None  # not positive definite: implausible, judged as such
    gap = p[0] + p[1] - p[2]
    if abs(gap) > TRIANGLE_RTOL * p[2]:
        return None  # inside, or beyond: a broken triangle is implausible, judged so
    diagonal = np.allclose(sym, np.diag(np.diag(sym)), rtol=0, atol=1e-12 * p[2])
    if diagonal:
        k = int(np.argmax(np.diag(sym)))
        i, j = (NAMES[1 + n] for n in range(3) if n != k)
        face = f"{NAMES[1 + k]} = {i} + {j}"
    else:
        face = "largest principal moment = sum of the other two"
    return (f"ended on a face of the physically possible set, the triangle inequality "
            f"({face}: {p[0] * 1e6:.4g} + {p[1] * 1e6:.4g} - {p[2] * 1e6:.4g} = "
            f"{gap * 1e6:.2g} e-6 kg m^2, within {100 * TRIANGLE_RTOL:g} % of it): the face "
            "holds the three moments, not the log (a yaw torque of the wrong sign, the "
            "vehicle file's spin, or a wrongly scaled torque pushes an inertia there)")


def collapsed_errors(values: Array, judged: dict[str, Array | None],
                     against: dict[str, Array | None] | None = None
                     ) -> tuple[tuple[str, str], ...]:
    """(name, reason) for each of [m, I_xx, I_yy, I_zz] (``values`` (4,)) whose error
    estimate collapsed (module docstring). judged: what each (4,) standard error is (e.g.
    ``"observed information"``, ``"block jackknife"``) -> its values (None: not computed;
    NaN entries: not available); each is compared with the same parameter's other
    estimates, in ``judged`` and in ``against`` (compared with, not judged)."""
    def arrays(d: dict[str, Array | None] | None) -> dict[str, Array]:
        return {k: np.asarray(v, dtype=float) for k, v in (d or {}).items() if v is not None}

    mine, every = arrays(judged), {**arrays(against), **arrays(judged)}
    out = []
    for n, name in enumerate(NAMES):
        for what, se in ((k, float(v[n])) for k, v in mine.items()):
            if not np.isfinite(se) or not values[n]:
                continue
            worse = [(k, float(v[n])) for k, v in every.items()
                     if k != what and np.isfinite(v[n]) and se < COLLAPSE_RATIO * v[n]]
            if se > 0 and not worse:
                continue
            scale, unit = (1e3, "g") if n == 0 else (1e6, "e-6 kg m^2")
            against_text = "".join(f", {o / se:.3g} x less than the {k}'s {o * scale:.3g}"
                                   for k, o in worse[:1] if se > 0)
            out.append((name, f"the {what}'s standard error collapsed to {se * scale:.3g} "
                              f"{unit}{against_text}: a failure of the error estimate (a fit held "
                              "by a constraint or a degenerate information), not a small "
                              "error"))
            break
    return tuple(out)
