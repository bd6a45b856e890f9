"""The M-step's sufficient statistics that the Python and the compiled M-step share:
which transitions it uses, and the sums of its expected quadratic forms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.models.ssm import Observations

Array = NDArray[np.float64]


def transition_mask(obs: Observations) -> NDArray[np.bool_]:
    """(N-1,) transitions the M-step uses (not excluded)."""
    use = np.ones(obs.n - 1, dtype=bool)
    if obs.exclude.size:
        use &= ~obs.exclude[: obs.n - 1]
    return use


@dataclass(frozen=True)
class QuadraticSums:
    """Sums over transitions of the M-step's expected quadratic forms (the a, b, c of
    ``regressor_stats``: a (6, 4, 4), b (6, 4), c (6,)) and the number of transitions n
    they cover (a float once down-weighted): the complete-data sufficient statistics of
    mass and inertia, which add over disjoint sets of transitions. The compiled
    ``pinquad.mstep.compiled.regressor_quadratics`` returns this type."""

    a: Array
    b: Array
    c: Array
    n: float

    @classmethod
    def of(cls, stats) -> QuadraticSums:
        return cls(np.asarray(stats.a), np.asarray(stats.b), np.asarray(stats.c),
                   float(stats.n))

    def plus(self, other) -> QuadraticSums:
        return QuadraticSums(self.a + other.a, self.b + other.b, self.c + other.c,
                             self.n + float(other.n))

    def scaled(self, weight: float) -> QuadraticSums:
        return QuadraticSums(weight * self.a, weight * self.b, weight * self.c,
                             weight * self.n)
