"""Compiled lateral drag and wind forces of :class:`~pinquad.models.effect.EffectSSM`
(QuadSSM plus body x/y forces, effect discovery's extended model; numba):

    f_b = -diag(D) R^T v + R^T wind,  f_b[2] = 0,
    v_{k+1} += dt R f_b / m,  F[3:6, 3:6] -= dt R diag(D) R^T / m
    (D (3,) [N s/m] with D[2] = 0, wind (3,) [N, world] with wind[2] = 0; the attitude
    dependence is left out of the Jacobian, as in EffectSSM).

Q is QuadSSM's (``quad_kernels.process_cov_quad``).
"""

from __future__ import annotations

from numba import njit

from pinquad.core.kernels import rotation
from pinquad.estep.quad_kernels import f_times_quad
from pinquad.models.kernel import STATE_DIM as _N


@njit(cache=True)
def effect_dynamics(x, dt, mass, drag, wind, x_next, jac, rot, f_b):
    """Add EffectSSM's lateral body forces (module docstring) to ``transition_quad``'s
    x_next (12,) and jac (12, 12): dt [s], mass [kg], drag D (3,), wind (3,); rot (3, 3)
    and f_b (3,): scratch (the caller's, so that a step allocates nothing)."""
    rotation(x, rot)
    for j in range(3):
        v_b = rot[0, j] * x[3] + rot[1, j] * x[4] + rot[2, j] * x[5]
        w_b = rot[0, j] * wind[0] + rot[1, j] * wind[1] + rot[2, j] * wind[2]
        f_b[j] = -drag[j] * v_b + w_b
    f_b[2] = 0.0
    for r in range(3):
        x_next[3 + r] += dt * (rot[r, 0] * f_b[0] + rot[r, 1] * f_b[1] + rot[r, 2] * f_b[2]) / mass
        for c in range(3):
            acc = 0.0
            for j in range(3):
                acc += rot[r, j] * drag[j] * rot[c, j]
            jac[3 + r, 3 + c] -= dt * acc / mass


@njit(cache=True)
def f_times_effect(f, p, out):
    """out = F p for EffectSSM's Jacobian: ``f_times_quad``'s pattern with the velocity
    rows reaching every velocity column (rows 3-5: columns 3-8)."""
    f_times_quad(f, p, out)
    for r in range(3, 6):
        for j in range(3, 6):
            if j != r:
                fj = f[r, j]
                for c in range(_N):
                    out[r, c] += fj * p[j, c]
