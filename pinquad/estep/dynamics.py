"""The prediction step's model pieces for any kernel-covered model (numba): the
transition and its Jacobian, the process covariance, and the F P product with the
Jacobian's block pattern, dispatched on ``desc.kind``
(:class:`~pinquad.models.kernel.KernelDescription`):

    x_{k+1} = x_k + dt f(x_k, u_k),  F_k = I + dt df/dx (x_k, u_k)
    Q_k = Q(x_k) + diag(reset_var) on the transitions marked in ``desc.resets``

QUAD and KINEMATIC: ``quad_kernels``; FULL: QuadSSM's kinematic rows with
``full_kernels``' dynamic rows and Q; EFFECT: QuadSSM plus ``effect_kernels``' forces.
"""

from __future__ import annotations

from numba import njit

from pinquad.estep.effect_kernels import effect_dynamics, f_times_effect
from pinquad.estep.full_kernels import f_times_full, full_dynamics, process_cov_full
from pinquad.estep.quad_kernels import (
    f_times_quad,
    process_cov_quad,
    transition_kinematic,
    transition_quad,
)
from pinquad.models.kernel import EFFECT, FULL, KINEMATIC
from pinquad.models.kernel import STATE_DIM as _N


@njit(cache=True)
def transition(desc, x, k, x_next, jac):
    """x_next (12,) = x + dt f(x, u_k) and jac (12, 12) = I + dt df/dx of the model
    ``desc`` describes, at state x (12,) and step k (input u_k = desc.inputs[k])."""
    if desc.kind == KINEMATIC:
        transition_kinematic(x, desc.dt, x_next, jac)
    else:
        u = desc.inputs[k]
        transition_quad(desc, x, u, x_next, jac)
        if desc.kind == FULL:
            full_dynamics(desc, x, u, x_next, jac)
        elif desc.kind == EFFECT:
            effect_dynamics(desc, x, x_next, jac)


@njit(cache=True)
def process_cov(desc, x, k, q):
    """Q_k (12, 12) of the model ``desc`` describes at state x (12,), transition k -> k+1,
    into q: the flight covariance, plus diag(reset_var) if desc.resets[k]."""
    if desc.kind == FULL:
        process_cov_full(desc, x, q)
    else:
        process_cov_quad(desc, x, q)
    if desc.resets[k]:
        reset_var = desc.reset_var
        for i in range(_N):
            q[i, i] += reset_var[i]


@njit(cache=True)
def f_times(desc, f, p, out):
    """out = F p (12, 12) with the block pattern of the Jacobian F of the model ``desc``
    describes (entries outside it are exact zeros and are skipped)."""
    if desc.kind == FULL:
        f_times_full(f, p, out)
    elif desc.kind == EFFECT:
        f_times_effect(f, p, out)
    else:
        f_times_quad(f, p, out)
