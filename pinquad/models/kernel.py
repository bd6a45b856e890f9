"""How a state-space model describes itself to the compiled E-step (``pinquad.estep``).

The kernels never import a model class and never read a model's private fields: they
take one :class:`KernelDescription`, a NamedTuple of the model's kind and its constant
arrays, built here from the models' public attributes and properties, with the same
expressions the models use (so that, e.g., Q's torque block is bit-identical).

Only the exact classes below have a description (a subclass may override the dynamics,
so it gets None and goes to the generic smoother):

    QUAD       QuadSSM       x' = x + dt f(x, u; m, I), Q fixed or structured
    KINEMATIC  KinematicSSM  the force-free warm-up transition, fixed Q
    FULL       FullQuadSSM   ten inertial parameters (M_O^-1, h = m c, I_O)
    EFFECT     EffectSSM     QuadSSM plus lateral drag and wind forces
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from pinquad.models.effect import EffectSSM
from pinquad.models.full import FullQuadSSM
from pinquad.models.ssm import (
    RESET_VAR,
    RESTART_VAR,
    KinematicSSM,
    Observations,
    QuadSSM,
    restart_mask,
)

Array = NDArray[np.float64]

STATE_DIM = 12

# The model kinds (compile-time constants inside the kernels).
QUAD = 0
KINEMATIC = 1
FULL = 2
EFFECT = 3

_KINDS = {QuadSSM: QUAD, KinematicSSM: KINEMATIC, FullQuadSSM: FULL, EffectSSM: EFFECT}


class KernelDescription(NamedTuple):
    """A model as the compiled kernels take it (one argument instead of two dozen).

    Every field has the same type whatever the kind (unused ones are zeros), so the
    kernels compile once. N steps, m measurement rows; SI units.

    kind: QUAD, KINEMATIC, FULL or EFFECT;
    dt [s]; mass [kg]; inertia, inertia_inv (3, 3) [kg m^2, 1/(kg m^2)] about the CoM;
    gravity [m/s^2]; inputs (N, 4): u_k = [F (N), M (3, N m)];
    meas_var (m,): R = diag(meas_var); state_of_row (m,) int64: H[i, state_of_row[i]] = 1
    (H selects state rows); is_angle (m,) bool: rows whose residual wraps to (-pi, pi];
    use_fixed: Q = diag(fixed_q) (12,) instead of the structured Q built from
    q_kin (6,) [m^2, rad^2], s_f = S_f (3,) [N^2 s] and q_tau = dt I^-1 diag(S_tau) I^-1
    (3, 3) (FULL: s_wrench = S (6,) and m_inv instead of s_f and q_tau);
    resets (N,) bool: transitions whose Q gets diag(reset_var) (12,) added;
    restarts (N,) bool: transitions that restart the filter (``ssm.restart_mask``:
    x_{k+1} = x_k, F = 0, Q = diag(restart_var) (12,)), whatever ``resets`` says;
    m_inv (6, 6), first_moment (3,) [kg m], i_o (3, 3) [kg m^2]: FULL's M_O^-1, h, I_O;
    drag (3,) [N s/m], wind (3,) [N, world]: EFFECT's lateral forces (z entries 0);
    continuous: the kinematic rows advance by their mean rates over each interval and a
    structured Q carries their share of the noise (``Observations.continuous``,
    ``models.continuous``).
    """

    kind: int
    dt: float
    mass: float
    inertia: Array
    inertia_inv: Array
    gravity: float
    inputs: Array
    meas_var: Array
    state_of_row: NDArray[np.int64]
    is_angle: NDArray[np.bool_]
    use_fixed: bool
    fixed_q: Array
    q_kin: Array
    s_f: Array
    q_tau: Array
    resets: NDArray[np.bool_]
    reset_var: Array
    restarts: NDArray[np.bool_]
    restart_var: Array
    m_inv: Array
    first_moment: Array
    i_o: Array
    s_wrench: Array
    drag: Array
    wind: Array
    continuous: bool


def kernel_kind(model: object) -> int | None:
    """The kind of ``model`` if its class is exactly one the kernels cover, else None."""
    return _KINDS.get(type(model))


def kernel_description(model: object) -> KernelDescription | None:
    """``model``'s :class:`KernelDescription`; None if its class is not exactly one the
    kernels cover (``kernel_kind``) or its measurement matrix is not a row selector
    (the kernels rely on H P H^T and H P being gathers)."""
    kind = kernel_kind(model)
    if kind is None:
        return None
    assert isinstance(model, QuadSSM)
    obs, theta, body = model.obs, model.theta, model.body
    meas_dim = model.meas_dim
    h = obs.measurement_matrix()
    if (h.shape != (meas_dim, STATE_DIM) or np.count_nonzero(h) != meas_dim
            or np.any(h.sum(axis=1) != 1.0)):
        return None
    state_of_row = np.argmax(h, axis=1).astype(np.int64)
    is_angle = np.zeros(meas_dim, dtype=np.bool_)
    is_angle[obs.angle_rows()] = True
    nz = theta.noise
    use_fixed = nz.fixed_q is not None
    fixed_q = np.asarray(nz.fixed_q if use_fixed else np.zeros(STATE_DIM), dtype=float)
    # The same expression as QuadSSM.__init__, so that Q's torque block is bit-identical.
    q_tau = obs.dt * body.inertia_inv @ np.diag(nz.wrench[3:6]) @ body.inertia_inv
    m_inv, first_moment, i_o = np.zeros((6, 6)), np.zeros(3), np.zeros((3, 3))
    if isinstance(model, FullQuadSSM):
        m_inv = model.spatial_inertia_inv
        first_moment = model.first_moment
        i_o = model.inertia_origin
    drag, wind = np.zeros(3), np.zeros(3)
    if isinstance(model, EffectSSM):
        # EffectSSM's lateral forces only: its body z drag travels in the thrust input
        drag[:2] = model.drag[:2]
        wind[:2] = model.wind[:2]
    return KernelDescription(
        kind=kind, dt=float(obs.dt), mass=float(body.mass),
        inertia=np.ascontiguousarray(body.inertia, dtype=float),
        inertia_inv=np.ascontiguousarray(body.inertia_inv, dtype=float),
        gravity=float(body.gravity),
        inputs=np.ascontiguousarray(obs.inputs, dtype=float),
        meas_var=np.ascontiguousarray(nz.meas, dtype=float), state_of_row=state_of_row,
        is_angle=is_angle, use_fixed=use_fixed, fixed_q=fixed_q,
        q_kin=np.ascontiguousarray(nz.q_kin, dtype=float),
        s_f=np.ascontiguousarray(nz.wrench[0:3], dtype=float),
        q_tau=np.ascontiguousarray(q_tau), resets=reset_mask(obs),
        reset_var=RESET_VAR.copy(), restarts=restart_mask(obs),
        restart_var=RESTART_VAR.copy(),
        m_inv=np.ascontiguousarray(m_inv, dtype=float),
        first_moment=np.ascontiguousarray(first_moment, dtype=float),
        i_o=np.ascontiguousarray(i_o, dtype=float),
        s_wrench=np.ascontiguousarray(nz.wrench, dtype=float), drag=drag, wind=wind,
        continuous=bool(obs.continuous))


def reset_mask(obs: Observations) -> NDArray[np.bool_]:
    """(N,) ``obs.resets`` as the kernels index it (all False when empty)."""
    mask = np.zeros(obs.n, dtype=np.bool_)
    given = np.asarray(obs.resets, dtype=bool)[:obs.n]
    mask[:given.size] = given
    return mask
