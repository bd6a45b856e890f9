"""Compiled E-step for :class:`~pinquad.models.ssm.QuadSSM`: EKF + RTS smoother in two numba calls.

The same equations as the generic ``estimators.rts.smooth(QuadSSM(obs, theta), obs.ys)``,
in algebraically equal forms that need fewer operations, so the same result up to
rounding (the tests hold it to 1e-9 relative; the differences seen are ~1e-10, as
with the Joseph-form kernels these replaced), more than twenty times faster than the
generic path, because EM runs hundreds of E-steps on logs of thousands of steps and the
online estimator one per update.

Forward pass (``estimators.ekf``), steps k = 0 .. N-1, prior (m^-_0, P^-_0) =
``QuadSSM.initial()`` = (x0, diag(p0)):

    update over the observed (non-NaN) rows o of y_k, H[o] selecting state rows s(o):
        nu = wrap(y_k[o] - m^-_k[s(o)])           (wrap only on Euler rows, to (-pi, pi])
        S  = P^-_k[s(o), s(o)] + diag(r[o]),  S = L L^T
        W  = L^{-1} H[o] P^-,  white = L^{-1} nu
        m_k = m^- + K nu = m^- + W^T white        (K = P^- H^T S^{-1}, never formed)
        P_k = P^- - K S K^T = P^- - W^T W         (the generic path's Joseph form
                                                   A P A^T + K R K^T, A = I - K H, is
                                                   equal for the optimal gain; W^T W is
                                                   symmetric by construction)
        log p(y) += -1/2 (|white|^2 + 2 sum log L_ii + |o| log 2 pi)
    predict (``QuadSSM.transition`` / ``QuadSSM.process_cov`` at the filtered mean):
        m^-_{k+1} = m_k + dt f(m_k, u_k),  F_k = I + dt df/dx (m_k, u_k)
        P^-_{k+1} = F_k P_k F_k^T + Q_k(m_k)      (symmetrised; F P and F (F P)^T skip
                                                   the entries outside F's block pattern)
        Q_k = diag(fixed_q)  or  blockdiag(q_pos I3, dt (R/m) diag(S_f) (R/m)^T,
                                           q_euler I3, dt I^{-1} diag(S_tau) I^{-1}),
              + diag(RESET_VAR) on the transitions marked in ``Observations.resets``

Backward pass (``estimators.rts``), k = N-2 .. 0:

    G_k = P_k F_k^T (P^-_{k+1})^{-1}            (Cholesky solve of P^-_{k+1} G^T = F_k P_k)
    m^s_k = m_k + G_k (m^s_{k+1} - m^-_{k+1})
    Cov(x_{k+1}, x_k | y) = C_k = P^s_{k+1} G_k^T
    P^s_k = P_k + G_k (P^s_{k+1} - P^-_{k+1}) G_k^T = P_k + G_k (C_k - F_k P_k)
                                        (P^-_{k+1} G_k^T = F_k P_k; lower triangle, mirrored)

EM's force-free warm-up model (``KinematicSSM``: f = [v, 0, E^{-1} omega, 0] with the
paper's fixed Q0) runs through the same passes with its own transition kernel, and
``loglik_quad`` runs the forward pass alone (no stored arrays) for the observed
information's 33 likelihood evaluations. The ten-parameter model
(``full_inertia.FullQuadSSM``: full inertia tensor and CoM offset) runs through the same
passes with its own dynamic rows (``_full_dynamics``), process covariance
(``_process_cov_full``) and F P product (its velocity rows reach the rate columns), behind
the same agreement check, and so does effect discovery's ``discovery.EffectSSM`` (QuadSSM
plus lateral drag and wind forces: ``_effect_dynamics``, whose velocity block is full).

No outlier gate (EM runs the generic path with ``gate_sigma=None`` too). Anything the
kernels do not cover (another model class, a gate, a QuadSSM whose behaviour has moved
away from these kernels) goes to the generic smoother instead.
"""

from __future__ import annotations

import math
import threading
import warnings

import numpy as np
from numba import njit
from numpy.typing import NDArray

from estimators.ekf import run_filter
from estimators.protocol import Posterior, StateSpaceModel
from estimators.rts import smooth as generic_smooth
from pinquad.core.kernels import rotation, rotation_derivatives, wrap
from pinquad.models import ssm as _ssm
from pinquad.models.effect import EffectSSM
from pinquad.models.full import FullQuadSSM
from pinquad.models.ssm import KinematicSSM, Observations, QuadSSM

Array = NDArray[np.float64]

_N = 12
_LOG_2PI = math.log(2.0 * math.pi)
_TWO_PI = 2.0 * math.pi


# Element loops instead of slice assignment: numba compiles a shape-mismatch error path
# for every `a[k] = b`, which cost seconds of the first-call compile time.
@njit(cache=True)
def _fill(a, v):
    for r in range(a.shape[0]):
        for c in range(a.shape[1]):
            a[r, c] = v


@njit(cache=True)
def _copy_vec(src, dst):
    for r in range(src.shape[0]):
        dst[r] = src[r]


@njit(cache=True)
def _copy_mat(src, dst):
    for r in range(src.shape[0]):
        for c in range(src.shape[1]):
            dst[r, c] = src[r, c]


@njit(cache=True)
def _transition(x, u, dt, mass, inertia, inertia_inv, gravity, x_next, jac):
    """x_next = x + dt f(x, u), jac = I + dt df/dx, f as in
    pinquad.vehicle.model.state_derivative_and_jacobian (written into x_next (12,), jac (12, 12))."""
    phi, theta, psi = x[6], x[7], x[8]
    wx, wy, wz = x[9], x[10], x[11]
    sf, cf = math.sin(phi), math.cos(phi)
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    tt = st / ct
    f_over_m = u[0] / mass
    _fill(jac, 0.0)
    f = x_next  # holds f until the last loop turns it into x + dt f
    f[0] = x[3]
    f[1] = x[4]
    f[2] = x[5]
    jac[0, 3] = 1.0
    jac[1, 4] = 1.0
    jac[2, 5] = 1.0

    f[3] = f_over_m * (cf * st * cp + sf * sp)
    f[4] = f_over_m * (cf * st * sp - sf * cp)
    f[5] = f_over_m * (cf * ct) - gravity
    jac[3, 6] = f_over_m * (-sf * st * cp + cf * sp)
    jac[3, 7] = f_over_m * (cf * ct * cp)
    jac[3, 8] = f_over_m * (-cf * st * sp + sf * cp)
    jac[4, 6] = f_over_m * (-sf * st * sp - cf * cp)
    jac[4, 7] = f_over_m * (cf * ct * sp)
    jac[4, 8] = f_over_m * (cf * st * cp + sf * sp)
    jac[5, 6] = f_over_m * (-sf * ct)
    jac[5, 7] = f_over_m * (-cf * st)

    a = sf * wy + cf * wz
    f[6] = wx + tt * a
    f[7] = cf * wy - sf * wz
    f[8] = a / ct
    jac[6, 6] = tt * (cf * wy - sf * wz)
    jac[6, 7] = a / (ct * ct)
    jac[6, 9] = 1.0
    jac[6, 10] = sf * tt
    jac[6, 11] = cf * tt
    jac[7, 6] = -sf * wy - cf * wz
    jac[7, 10] = cf
    jac[7, 11] = -sf
    jac[8, 6] = (cf * wy - sf * wz) / ct
    jac[8, 7] = a * st / (ct * ct)
    jac[8, 10] = sf / ct
    jac[8, 11] = cf / ct

    iw0 = inertia[0, 0] * wx + inertia[0, 1] * wy + inertia[0, 2] * wz
    iw1 = inertia[1, 0] * wx + inertia[1, 1] * wy + inertia[1, 2] * wz
    iw2 = inertia[2, 0] * wx + inertia[2, 1] * wy + inertia[2, 2] * wz
    r0 = u[1] - (wy * iw2 - wz * iw1)
    r1 = u[2] - (wz * iw0 - wx * iw2)
    r2 = u[3] - (wx * iw1 - wy * iw0)
    for r in range(3):
        f[9 + r] = inertia_inv[r, 0] * r0 + inertia_inv[r, 1] * r1 + inertia_inv[r, 2] * r2
    # d(omega x I omega)/d omega = [omega]x I - [I omega]x, row by row
    for c in range(3):
        d0 = -wz * inertia[1, c] + wy * inertia[2, c]
        d1 = wz * inertia[0, c] - wx * inertia[2, c]
        d2 = -wy * inertia[0, c] + wx * inertia[1, c]
        if c == 0:
            d1 -= iw2
            d2 += iw1
        elif c == 1:
            d0 += iw2
            d2 -= iw0
        else:
            d0 -= iw1
            d1 += iw0
        for r in range(3):
            jac[9 + r, 9 + c] = -(inertia_inv[r, 0] * d0 + inertia_inv[r, 1] * d1
                                  + inertia_inv[r, 2] * d2)
    for r in range(_N):
        x_next[r] = x[r] + dt * f[r]
        for c in range(_N):
            jac[r, c] = dt * jac[r, c]
        jac[r, r] += 1.0


@njit(cache=True)
def _transition_kinematic(x, dt, x_next, jac):
    """KinematicSSM.transition (the force-free warm-up model: p' = v, v' = 0,
    Theta' = E^{-1} omega, omega' = 0), written with the same expressions in the same
    order as pinquad.ssm so the two agree to the last bit."""
    phi, theta = x[6], x[7]
    wx, wy, wz = x[9], x[10], x[11]
    sf, cf = math.sin(phi), math.cos(phi)
    st, ct = math.sin(theta), math.cos(theta)
    tt = st / ct
    a = sf * wy + cf * wz
    for r in range(_N):
        x_next[r] = x[r]
    for r in range(3):
        x_next[r] += dt * x[3 + r]
    x_next[6] += dt * (wx + tt * a)
    x_next[7] += dt * (cf * wy - sf * wz)
    x_next[8] += dt * a / ct
    _fill(jac, 0.0)
    for r in range(_N):
        jac[r, r] = 1.0
    jac[0, 3] = dt
    jac[1, 4] = dt
    jac[2, 5] = dt
    jac[6, 6] += dt * tt * (cf * wy - sf * wz)
    jac[6, 7] = dt * a / (ct * ct)
    jac[6, 9] = dt
    jac[6, 10] = dt * sf * tt
    jac[6, 11] = dt * cf * tt
    jac[7, 6] = dt * (-sf * wy - cf * wz)
    jac[7, 10] = dt * cf
    jac[7, 11] = -dt * sf
    jac[8, 6] = dt * (cf * wy - sf * wz) / ct
    jac[8, 7] = dt * a * st / (ct * ct)
    jac[8, 10] = dt * sf / ct
    jac[8, 11] = dt * cf / ct


@njit(cache=True)
def _process_cov_start(use_fixed, fixed_q, q_kin, q):
    """q = diag(fixed_q) (returns True: Q is complete), or zero but for the position and
    Euler rows' kinematic variances (returns False: the dynamic blocks follow)."""
    _fill(q, 0.0)
    if use_fixed:
        for i in range(_N):
            q[i, i] = fixed_q[i]
        return True
    for i in range(3):
        q[i, i] = q_kin[i]
        q[6 + i, 6 + i] = q_kin[3 + i]
    return False


@njit(cache=True)
def _process_cov(x, dt, mass, use_fixed, fixed_q, q_kin, s_f, q_tau, q):
    """Q (12, 12) of QuadSSM.process_cov at x, written into q."""
    if _process_cov_start(use_fixed, fixed_q, q_kin, q):
        return
    g = np.empty((3, 3))
    rotation(x, g)
    for r in range(3):
        for c in range(3):
            g[r, c] = g[r, c] / mass
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for j in range(3):
                acc += (g[r, j] * s_f[j]) * g[c, j]
            q[3 + r, 3 + c] = dt * acc
            q[9 + r, 9 + c] = q_tau[r, c]


@njit(cache=True)
def _full_dynamics(x, u, dt, gravity, m_inv, h, i_o, x_next, jac):
    """Replace the velocity and rate rows of ``_transition``'s x_next (12,) and jac
    (12, 12) by those of ``full_inertia.FullQuadSSM`` (ten inertial parameters: spatial
    inertia inverse m_inv (6, 6) about the body origin, first moment h = m c (3,),
    rotational inertia about the origin i_o (3, 3)):

        [a_O; omega'] = M^-1 ([0, 0, F, tau] - [w x (w x h); w x I_O w]),
        v' = R a_O - g e3,  omega' as above (explicit Euler, Jacobian I + dt df/dx)."""
    wx, wy, wz = x[9], x[10], x[11]
    w = np.array([wx, wy, wz])
    iw = i_o @ w
    wh = np.array([wy * h[2] - wz * h[1], wz * h[0] - wx * h[2], wx * h[1] - wy * h[0]])
    bias = np.empty(6)
    bias[0] = wy * wh[2] - wz * wh[1]
    bias[1] = wz * wh[0] - wx * wh[2]
    bias[2] = wx * wh[1] - wy * wh[0]
    bias[3] = wy * iw[2] - wz * iw[1]
    bias[4] = wz * iw[0] - wx * iw[2]
    bias[5] = wx * iw[1] - wy * iw[0]
    tau = np.array([0.0, 0.0, u[0], u[1], u[2], u[3]])
    acc = m_inv @ (tau - bias)
    wdh = wx * h[0] + wy * h[1] + wz * h[2]
    d_bias = np.empty((6, 3))
    for r in range(3):
        for c in range(3):
            d_bias[r, c] = w[r] * h[c] - 2.0 * h[r] * w[c]
        d_bias[r, r] += wdh
    sw = np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])
    siw = np.array([[0.0, -iw[2], iw[1]], [iw[2], 0.0, -iw[0]], [-iw[1], iw[0], 0.0]])
    d_bias[3:6, :] = sw @ i_o - siw
    d_acc = -(m_inv @ d_bias)
    rot = np.empty((3, 3))
    d_rot = np.empty((3, 3, 3))
    rotation_derivatives(x[6], x[7], x[8], rot, d_rot)
    for r in range(3):
        fv = rot[r, 0] * acc[0] + rot[r, 1] * acc[1] + rot[r, 2] * acc[2]
        if r == 2:
            fv -= gravity
        x_next[3 + r] = x[3 + r] + dt * fv
        x_next[9 + r] = x[9 + r] + dt * acc[3 + r]
        for c in range(_N):
            jac[3 + r, c] = 0.0
            jac[9 + r, c] = 0.0
        jac[3 + r, 3 + r] = 1.0
        jac[9 + r, 9 + r] = 1.0
        for k in range(3):
            jac[3 + r, 6 + k] = dt * (d_rot[r, 0, k] * acc[0] + d_rot[r, 1, k] * acc[1]
                                      + d_rot[r, 2, k] * acc[2])
            jac[3 + r, 9 + k] = dt * (rot[r, 0] * d_acc[0, k] + rot[r, 1] * d_acc[1, k]
                                      + rot[r, 2] * d_acc[2, k])
            jac[9 + r, 9 + k] += dt * d_acc[3 + r, k]


@njit(cache=True)
def _process_cov_full(x, dt, use_fixed, fixed_q, q_kin, m_inv, s_wrench, q):
    """Q (12, 12) of ``full_inertia.FullQuadSSM`` at x: the kinematic diagonal, and over
    the velocity and rate rows dt G diag(S) G^T, G = M^-1 with its force rows turned by R."""
    if _process_cov_start(use_fixed, fixed_q, q_kin, q):
        return
    rot = np.empty((3, 3))
    rotation(x, rot)
    g = m_inv.copy()
    for r in range(3):
        for c in range(6):
            g[r, c] = rot[r, 0] * m_inv[0, c] + rot[r, 1] * m_inv[1, c] + rot[r, 2] * m_inv[2, c]
    rows = np.array([3, 4, 5, 9, 10, 11])
    for a in range(6):
        for b in range(6):
            acc = 0.0
            for j in range(6):
                acc += (g[a, j] * s_wrench[j]) * g[b, j]
            q[rows[a], rows[b]] = dt * acc


@njit(cache=True)
def _f_times_full(f, p, out):
    """out = F p for the full model's Jacobian: ``_f_times``'s pattern with the velocity
    rows reaching the rate columns too (rows 3-5: columns r, 6-11)."""
    _f_times(f, p, out)
    for r in range(3, 6):
        f9, f10, f11 = f[r, 9], f[r, 10], f[r, 11]
        for c in range(_N):
            out[r, c] += f9 * p[9, c] + f10 * p[10, c] + f11 * p[11, c]


@njit(cache=True)
def _effect_dynamics(x, dt, mass, drag, wind, x_next, jac):
    """Add ``discovery.EffectSSM``'s lateral body forces to ``_transition``'s x_next (12,)
    and jac (12, 12): f_b = -drag * R^T v + R^T wind with f_b[2] = 0 (drag (3,) [N s/m]
    with drag[2] = 0, wind (3,) [N, world] with wind[2] = 0),
    v_{k+1} += dt R f_b / m, and jac[3:6, 3:6] -= dt R diag(drag) R^T / m (as EffectSSM,
    without the attitude dependence)."""
    rot = np.empty((3, 3))
    rotation(x, rot)
    f_b = np.empty(3)
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
def _f_times_effect(f, p, out):
    """out = F p for ``EffectSSM``'s Jacobian: ``_f_times``'s pattern with the velocity
    rows reaching every velocity column (rows 3-5: columns 3-8)."""
    _f_times(f, p, out)
    for r in range(3, 6):
        for j in range(3, 6):
            if j != r:
                fj = f[r, j]
                for c in range(_N):
                    out[r, c] += fj * p[j, c]


@njit(cache=True)
def _f_times_model(f, p, out, full, effect):
    """out = F p with the block pattern of the model's Jacobian: the ten-parameter
    model's (``_f_times_full``), EffectSSM's (``_f_times_effect``) or QuadSSM's."""
    if full:
        _f_times_full(f, p, out)
    elif effect:
        _f_times_effect(f, p, out)
    else:
        _f_times(f, p, out)


@njit(cache=True)
def _cholesky(a, p, low):
    """Lower Cholesky factor of a[:p, :p] into low; False if not positive definite."""
    for j in range(p):
        d = a[j, j]
        for m in range(j):
            d -= low[j, m] * low[j, m]
        if not d > 0.0:
            return False
        d = math.sqrt(d)
        low[j, j] = d
        for i in range(j + 1, p):
            s = a[i, j]
            for m in range(j):
                s -= low[i, m] * low[j, m]
            low[i, j] = s / d
    return True


@njit(cache=True)
def _chol_solve(low, p, b):
    """b[:p, :] <- (L L^T)^{-1} b[:p, :] in place (L = low[:p, :p]).

    Row-oriented substitution: every update is a whole row of b (12 contiguous numbers),
    which the compiler vectorises; per entry the arithmetic is that of column-wise
    forward/back substitution.
    """
    ncol = b.shape[1]
    for i in range(p):
        for m in range(i):
            lim = low[i, m]
            for c in range(ncol):
                b[i, c] -= lim * b[m, c]
        d = low[i, i]
        for c in range(ncol):
            b[i, c] /= d
    for i in range(p - 1, -1, -1):
        for m in range(i + 1, p):
            lmi = low[m, i]
            for c in range(ncol):
                b[i, c] -= lmi * b[m, c]
        d = low[i, i]
        for c in range(ncol):
            b[i, c] /= d


@njit(cache=True)
def _symmetrise(c, out):
    """out = (c + c^T) / 2, as the generic path does after every covariance update."""
    for r in range(_N):
        for s in range(_N):
            out[r, s] = 0.5 * (c[r, s] + c[s, r])


@njit(cache=True)
def _f_times(f, p, out):
    """out = F p for a transition Jacobian F (12 x 12) with the block pattern of
    ``_transition`` / ``_transition_kinematic`` (rows 0-2: columns r, r+3; rows 3-5: r,
    6-8; rows 6-8: 6-11; rows 9-11: 9-11; every other entry is an exact zero, so leaving
    it out of the sums changes nothing)."""
    for r in range(3):
        f0 = f[r, r]
        f1 = f[r, r + 3]
        for c in range(_N):
            out[r, c] = f0 * p[r, c] + f1 * p[r + 3, c]
    for r in range(3, 6):
        f0 = f[r, r]
        f6, f7, f8 = f[r, 6], f[r, 7], f[r, 8]
        for c in range(_N):
            out[r, c] = f0 * p[r, c] + f6 * p[6, c] + f7 * p[7, c] + f8 * p[8, c]
    for r in range(6, 9):
        f6, f7, f8 = f[r, 6], f[r, 7], f[r, 8]
        f9, f10, f11 = f[r, 9], f[r, 10], f[r, 11]
        for c in range(_N):
            out[r, c] = (f6 * p[6, c] + f7 * p[7, c] + f8 * p[8, c] + f9 * p[9, c]
                         + f10 * p[10, c] + f11 * p[11, c])
    for r in range(9, 12):
        f9, f10, f11 = f[r, 9], f[r, 10], f[r, 11]
        for c in range(_N):
            out[r, c] = f9 * p[9, c] + f10 * p[10, c] + f11 * p[11, c]


@njit(cache=True)
def _forward(x0, p0, inputs, ys, dt, mass, inertia, inertia_inv, gravity, meas_var,
             state_of_row, is_angle, use_fixed, fixed_q, q_kin, s_f, q_tau, kinematic, resets,
             reset_var, full, m_inv, first_moment, i_o, s_wrench, effect, drag, wind, store):
    """EKF forward pass (see module docstring) into fresh arrays. Returns filtered and
    predicted means and covariances, the products F_k P_k the backward pass needs, the
    log-likelihood and the first step whose innovation covariance was not positive
    definite (-1 if none).

    kinematic: the force-free warm-up transition (KinematicSSM) instead of the dynamic
    one; resets (N,) bool: transitions whose Q gets diag(reset_var) added; store: keep
    the per-step arrays (False when only the log-likelihood is wanted: the arrays then
    have length 1 and hold nothing of use, saving the memory traffic)."""
    n_steps = ys.shape[0]
    n_store = n_steps if store else 1
    f_mean = np.empty((n_store, _N))
    f_cov = np.empty((n_store, _N, _N))
    p_mean = np.empty((n_store, _N))
    p_cov = np.empty((n_store, _N, _N))
    fps = np.empty((max(n_store - 1, 0) if store else 1, _N, _N))
    loglik, bad = _forward_into(x0, p0, inputs, ys, dt, mass, inertia, inertia_inv, gravity,
                                meas_var, state_of_row, is_angle, use_fixed, fixed_q, q_kin,
                                s_f, q_tau, kinematic, resets, reset_var, full, m_inv,
                                first_moment, i_o, s_wrench, effect, drag, wind, store, f_mean,
                                f_cov, p_mean, p_cov, fps)
    return f_mean, f_cov, p_mean, p_cov, fps, loglik, bad


@njit(cache=True)
def _forward_into(x0, p0, inputs, ys, dt, mass, inertia, inertia_inv, gravity, meas_var,
                  state_of_row, is_angle, use_fixed, fixed_q, q_kin, s_f, q_tau, kinematic,
                  resets, reset_var, full, m_inv, first_moment, i_o, s_wrench, effect, drag,
                  wind, store, f_mean, f_cov, p_mean, p_cov, fps):
    """``_forward`` into given arrays (f_mean, p_mean (N, 12), f_cov, p_cov (N, 12, 12),
    fps (N - 1, 12, 12); unused when not store). Returns (log-likelihood, first bad
    step or -1)."""
    n_steps, m = ys.shape
    mean = x0.copy()
    cov = p0.copy()
    idx = np.empty(m, dtype=np.int64)
    sidx = np.empty(m, dtype=np.int64)
    nu = np.empty(m)
    white = np.empty(m)
    s_mat = np.empty((m, m))
    low = np.empty((m, m))
    w_mat = np.empty((m, _N))
    fp = np.empty((_N, _N))
    fp_t = np.empty((_N, _N))
    new_cov = np.empty((_N, _N))
    jac = np.empty((_N, _N))
    q = np.empty((_N, _N))
    x_next = np.empty(_N)
    loglik = 0.0
    for k in range(n_steps):
        if store:
            _copy_vec(mean, p_mean[k])
            _copy_mat(cov, p_cov[k])
        y = ys[k]
        p = 0
        for i in range(m):
            if not math.isnan(y[i]):
                idx[p] = i
                sidx[p] = state_of_row[i]
                p += 1
        if p > 0:
            # H selects state rows, so H P H^T and H P are plain gathers.
            for a in range(p):
                i = idx[a]
                res = y[i] - mean[sidx[a]]
                nu[a] = wrap(res) if is_angle[i] else res
                for b in range(p):
                    s_mat[a, b] = cov[sidx[a], sidx[b]]
                s_mat[a, a] += meas_var[i]
            if not _cholesky(s_mat, p, low):
                return loglik, k
            # white = L^{-1} nu, W = L^{-1} H P (S = L L^T); then K nu = W^T white and
            # K S K^T = W^T W, so P - K S K^T needs no gain and is symmetric by construction.
            quad = 0.0
            logdet = 0.0
            for a in range(p):
                w = nu[a]
                srow = sidx[a]
                for c in range(_N):
                    w_mat[a, c] = cov[srow, c]
                for b in range(a):
                    lab = low[a, b]
                    w -= lab * white[b]
                    for c in range(_N):
                        w_mat[a, c] -= lab * w_mat[b, c]
                d = low[a, a]
                w = w / d
                for c in range(_N):
                    w_mat[a, c] /= d
                white[a] = w
                quad += w * w
                logdet += math.log(d)
            for c in range(_N):
                acc = 0.0
                for a in range(p):
                    acc += w_mat[a, c] * white[a]
                mean[c] += acc
            for r in range(_N):
                for c in range(r + 1):
                    acc = 0.0
                    for a in range(p):
                        acc += w_mat[a, r] * w_mat[a, c]
                    v = cov[r, c] - acc
                    cov[r, c] = v
                    cov[c, r] = v
            loglik += -0.5 * (quad + 2.0 * logdet + p * _LOG_2PI)
        if store:
            _copy_vec(mean, f_mean[k])
            _copy_mat(cov, f_cov[k])
        if k + 1 < n_steps:
            if full:
                _process_cov_full(mean, dt, use_fixed, fixed_q, q_kin, m_inv, s_wrench, q)
            else:
                _process_cov(mean, dt, mass, use_fixed, fixed_q, q_kin, s_f, q_tau, q)
            if resets[k]:
                for i in range(_N):
                    q[i, i] += reset_var[i]
            if kinematic:
                _transition_kinematic(mean, dt, x_next, jac)
            else:
                _transition(mean, inputs[k], dt, mass, inertia, inertia_inv, gravity, x_next,
                            jac)
                if full:
                    _full_dynamics(mean, inputs[k], dt, gravity, m_inv, first_moment, i_o,
                                   x_next, jac)
                elif effect:
                    _effect_dynamics(mean, dt, mass, drag, wind, x_next, jac)
            _f_times_model(jac, cov, fp, full, effect)
            if store:
                _copy_mat(fp, fps[k])
            # F P F^T = F (F P)^T (P symmetric)
            for r in range(_N):
                for c in range(_N):
                    fp_t[r, c] = fp[c, r]
            _f_times_model(jac, fp_t, new_cov, full, effect)
            for r in range(_N):
                for c in range(_N):
                    new_cov[r, c] += q[r, c]
            _symmetrise(new_cov, cov)
            _copy_vec(x_next, mean)
    return loglik, -1


@njit(cache=True)
def _backward(f_mean, f_cov, p_mean, p_cov, fps):
    """``_backward_into`` fresh arrays: returns smoothed means, covariances,
    cross-covariances and the first step whose predicted covariance was not positive
    definite (-1 if none)."""
    n_steps = f_mean.shape[0]
    mean = np.empty((n_steps, _N))
    cov = np.empty((n_steps, _N, _N))
    cross = np.empty((max(n_steps - 1, 0), _N, _N))
    bad = _backward_into(f_mean, f_cov, p_mean, p_cov, fps, mean, cov, cross)
    return mean, cov, cross, bad


@njit(cache=True)
def _backward_into(f_mean, f_cov, p_mean, p_cov, fps, mean, cov, cross):
    """RTS backward pass with lag-one cross-covariances (see module docstring), from the
    forward pass's products F_k P_k, into mean (N, 12), cov (N, 12, 12) and cross
    (N - 1, 12, 12). Returns the first step whose predicted covariance was not positive
    definite (-1 if none).

    With G^T = Pp^{-1} (F P) and C = Ps G^T = Cov(x_{k+1}, x_k | y):
    G (Ps - Pp) G^T = G (C - Pp G^T) = G (C - F P), one product instead of two."""
    n_steps = f_mean.shape[0]
    _copy_vec(f_mean[n_steps - 1], mean[n_steps - 1])
    _copy_mat(f_cov[n_steps - 1], cov[n_steps - 1])
    low = np.empty((_N, _N))
    gain_t = np.empty((_N, _N))
    diff = np.empty((_N, _N))
    acc = np.empty(_N)
    for k in range(n_steps - 2, -1, -1):
        pf = f_cov[k]
        pp = p_cov[k + 1]
        ps = cov[k + 1]
        fp = fps[k]
        if not _cholesky(pp, _N, low):
            return k + 1
        _copy_mat(fp, gain_t)
        _chol_solve(low, _N, gain_t)
        # m^s_k = m_k + G (m^s_{k+1} - m^-_{k+1}); G[r, j] = gain_t[j, r]
        for c in range(_N):
            acc[c] = 0.0
        for j in range(_N):
            dj = mean[k + 1, j] - p_mean[k + 1, j]
            for c in range(_N):
                acc[c] += gain_t[j, c] * dj
        for c in range(_N):
            mean[k, c] = f_mean[k, c] + acc[c]
        # C = Ps G^T, into cross[k]; diff = C - F P
        ck = cross[k]
        for r in range(_N):
            for c in range(_N):
                ck[r, c] = 0.0
            for j in range(_N):
                s = ps[r, j]
                for c in range(_N):
                    ck[r, c] += s * gain_t[j, c]
            for c in range(_N):
                diff[r, c] = ck[r, c] - fp[r, c]
        # P^s_k = P + G diff (symmetric: lower triangle, mirrored)
        out = cov[k]
        for r in range(_N):
            for c in range(r + 1):
                s = 0.0
                for j in range(_N):
                    s += gain_t[j, r] * diff[j, c]
                v = pf[r, c] + s
                out[r, c] = v
                out[c, r] = v
    return -1


_PROBE = np.array([0.3, -0.2, 0.5, 0.4, -0.5, 0.6, 0.2, -0.3, 0.4, 0.5, -0.6, 0.7])


def _kernel_inputs(model: QuadSSM, meas_dim: int) -> tuple | None:
    """The model's constants as the kernels take them, computed as QuadSSM computes them
    (the last one: whether it is the force-free KinematicSSM); None if its measurement
    matrix is not a row selector (the kernels rely on it)."""
    obs, theta, body = model.obs, model.theta, model.body
    h = obs.measurement_matrix()
    if (h.shape != (meas_dim, _N) or np.count_nonzero(h) != meas_dim
            or np.any(h.sum(axis=1) != 1.0)):
        return None
    state_of_row = np.argmax(h, axis=1).astype(np.int64)
    is_angle = np.zeros(meas_dim, dtype=np.bool_)
    is_angle[obs.angle_rows()] = True
    nz = theta.noise
    use_fixed = nz.fixed_q is not None
    fixed_q = np.asarray(nz.fixed_q if use_fixed else np.zeros(_N), dtype=float)
    # The same expression as QuadSSM.__init__, so that Q's torque block is bit-identical.
    q_tau = obs.dt * body.inertia_inv @ np.diag(nz.wrench[3:6]) @ body.inertia_inv
    full = _is_full(model)
    m_inv = np.ascontiguousarray(model._m_inv if full else np.zeros((6, 6)), dtype=float)
    first_moment = np.ascontiguousarray(model._first_moment if full else np.zeros(3),
                                        dtype=float)
    i_o = np.ascontiguousarray(model._i_o if full else np.zeros((3, 3)), dtype=float)
    effect = _is_effect(model)
    drag, wind = np.zeros(3), np.zeros(3)
    if effect:
        # EffectSSM's lateral forces only: its body z drag travels in the thrust input
        drag[:2] = np.asarray(model._drag, dtype=float)[:2]
        wind[:2] = np.asarray(model._wind, dtype=float)[:2]
    return (float(obs.dt), float(body.mass), np.ascontiguousarray(body.inertia, dtype=float),
            np.ascontiguousarray(body.inertia_inv, dtype=float), float(body.gravity),
            np.ascontiguousarray(nz.meas, dtype=float), state_of_row, is_angle, use_fixed,
            fixed_q, np.ascontiguousarray(nz.q_kin, dtype=float),
            np.ascontiguousarray(nz.wrench[0:3], dtype=float), np.ascontiguousarray(q_tau),
            type(model) is KinematicSSM, _reset_mask(obs), _ssm.RESET_VAR.copy(), full, m_inv,
            first_moment, i_o, np.ascontiguousarray(nz.wrench, dtype=float), effect, drag, wind)


def _is_full(model: StateSpaceModel) -> bool:
    """Whether ``model`` is exactly ``models.full.FullQuadSSM``."""
    return type(model) is FullQuadSSM


def _is_effect(model: StateSpaceModel) -> bool:
    """Whether ``model`` is exactly ``models.effect.EffectSSM`` (QuadSSM plus drag / wind
    forces)."""
    return type(model) is EffectSSM


def _reset_mask(obs: Observations) -> NDArray[np.bool_]:
    """(N,) ``obs.resets`` as the kernels index it (all False when empty)."""
    mask = np.zeros(obs.n, dtype=np.bool_)
    given = np.asarray(obs.resets, dtype=bool)[:obs.n]
    mask[:given.size] = given
    return mask


def _close(ours: Array, ref: Array) -> bool:
    """Equal to rounding, on the scale of the whole array (Q's off-diagonal entries are
    cancellation noise of order 1e-16 of its diagonal, in either evaluation order)."""
    return bool(np.all(np.abs(ours - ref) <= 1e-12 * max(float(np.max(np.abs(ref))), 1e-300)))


def _agrees_with_model(model: QuadSSM, consts: tuple) -> bool:
    """Whether the kernels still compute what ``model`` computes (pinquad/ssm.py may grow
    new terms): transition, Jacobian, Q, H, R and the wrapped residual at a probe state,
    at the first and the last transition."""
    (dt, mass, inertia, inertia_inv, gravity, meas_var, state_of_row, is_angle, use_fixed,
     fixed_q, q_kin, s_f, q_tau, kinematic, resets, reset_var, full, m_inv, first_moment, i_o,
     s_wrench, effect, drag, wind) = consts
    n_steps = model.obs.n
    x = np.asarray(model.obs.x0, dtype=float) + _PROBE
    x_next, jac, q = np.empty(_N), np.empty((_N, _N)), np.empty((_N, _N))
    probes = {0, max(n_steps - 2, 0)}
    if resets[:max(n_steps - 1, 0)].any():
        probes.add(int(np.flatnonzero(resets[:n_steps - 1])[0]))
    for k in probes:
        ref_x, ref_jac = model.transition(x, k)
        u = np.ascontiguousarray(model.obs.inputs[k], dtype=float)
        if kinematic:
            _transition_kinematic(x, dt, x_next, jac)
        else:
            _transition(x, u, dt, mass, inertia, inertia_inv, gravity, x_next, jac)
            if full:
                _full_dynamics(x, u, dt, gravity, m_inv, first_moment, i_o, x_next, jac)
            elif effect:
                _effect_dynamics(x, dt, mass, drag, wind, x_next, jac)
        if full:
            _process_cov_full(x, dt, use_fixed, fixed_q, q_kin, m_inv, s_wrench, q)
        else:
            _process_cov(x, dt, mass, use_fixed, fixed_q, q_kin, s_f, q_tau, q)
        if resets[k]:
            q = q + np.diag(reset_var)
        ref_q = model.process_cov(x, k)
        y_pred, h = model.measure(x, k)
        if not (_close(x_next, ref_x) and _close(jac, ref_jac) and _close(q, ref_q)
                and np.array_equal(y_pred, x[state_of_row])
                and np.array_equal(h[np.arange(h.shape[0]), state_of_row],
                                   np.ones(h.shape[0]))
                and np.count_nonzero(h) == h.shape[0]
                and np.array_equal(model.meas_cov(k), np.diag(meas_var))):
            return False
    y = y_pred + np.linspace(-7.0, 7.0, y_pred.shape[0])
    res = y - y_pred
    ours = np.array([wrap(r) if a else r for r, a in zip(res, is_angle, strict=True)])
    return bool(np.array_equal(model.residual(y, y_pred), ours))


# The methods (and the module functions they call) that define what a QuadSSM computes;
# the agreement check is a guard against this code drifting from the kernels, so its
# verdict holds for as long as none of these objects is replaced.
_MODEL_METHODS = ("initial", "transition", "process_cov", "measure", "meas_cov", "residual")
_checked: dict[tuple, bool] = {}


def _code_key(model: QuadSSM, consts: tuple) -> tuple | None:
    """Identity of the code behind ``model`` and of the kernel variant it needs (channels,
    fixed or structured Q, kinematic or dynamic); None when an instance overrides a
    method (then every call is checked)."""
    if any(name in vars(model) for name in _MODEL_METHODS):
        return None
    cls = type(model)
    return (cls, cls.__init__, *(getattr(cls, name) for name in _MODEL_METHODS),
            _ssm.state_derivative_and_jacobian, _ssm.wrap_angle, model.obs.channels,
            consts[8], consts[13], bool(consts[14].any()), bool(consts[22].any()),
            bool(consts[23].any()))


def _agrees_cached(model: QuadSSM, consts: tuple) -> bool:
    """``_agrees_with_model``, run once per code identity (``_code_key``) and process:
    it costs ~2 ms of Python per call, a fifth of an online update."""
    key = _code_key(model, consts)
    if key is None:
        return _agrees_with_model(model, consts)
    if key not in _checked:
        _checked[key] = _agrees_with_model(model, consts)
    return _checked[key]


def _prepared(model: StateSpaceModel, ys: Array) -> tuple[Array, tuple] | None:
    """(ys, kernel constants) if the kernels reproduce ``model``, else None (after a
    warning if the model is a QuadSSM the kernels no longer match)."""
    if type(model) not in (QuadSSM, KinematicSSM) and not _is_full(model) \
            and not _is_effect(model):
        return None
    ys = np.ascontiguousarray(ys, dtype=float)
    obs = model.obs
    if ys.ndim != 2 or ys.shape[1] != model.meas_dim or not 0 < ys.shape[0] <= obs.n:
        raise ValueError(f"ys has shape {ys.shape}; expected (N, {model.meas_dim}) with "
                         f"0 < N <= {obs.n} for channels {obs.channels}")
    consts = _kernel_inputs(model, ys.shape[1])
    if consts is not None and consts[13] and not consts[8]:
        return None  # KinematicSSM without a fixed Q: the generic path raises its error
    if consts is None or not _agrees_cached(model, consts):
        warnings.warn("QuadSSM no longer matches pinquad.fast_smoother's kernels; using the "
                      "generic smoother (update the fast path)", RuntimeWarning, stacklevel=3)
        return None
    return ys, consts


def _run_forward(model: QuadSSM, ys: Array, consts: tuple, store: bool) -> tuple:
    x0, p0 = model.initial()
    return _forward(np.ascontiguousarray(x0, dtype=float), np.ascontiguousarray(p0, dtype=float),
                    np.ascontiguousarray(model.obs.inputs, dtype=float), ys, *consts, store)


# The forward pass's per-step arrays (filtered and predicted moments, F P), reused from
# call to call (per thread): fresh arrays of this size cost about as much in page faults
# (~1 ms per 800 steps) as the arithmetic that fills them. They never leave this module,
# and are kept only up to _KEEP_STEPS steps (~35 MB) so that a long log's arrays are
# not held after its E-step.
_workspace = threading.local()
_KEEP_STEPS = 10_000


def _filter_arrays(n_steps: int) -> tuple[Array, Array, Array, Array, Array]:
    arrays = getattr(_workspace, "arrays", None)
    if arrays is None or arrays[0].shape[0] != n_steps:
        arrays = (np.empty((n_steps, _N)), np.empty((n_steps, _N, _N)), np.empty((n_steps, _N)),
                  np.empty((n_steps, _N, _N)), np.empty((max(n_steps - 1, 0), _N, _N)))
        _workspace.arrays = arrays if n_steps <= _KEEP_STEPS else None
    return arrays


def posterior_arrays(n_steps: int) -> tuple[Array, Array, Array]:
    """Arrays for ``smooth_quad(..., out=...)``: mean (N, 12), cov (N, 12, 12),
    cross-covariances (N - 1, 12, 12)."""
    return (np.empty((n_steps, _N)), np.empty((n_steps, _N, _N)),
            np.empty((max(n_steps - 1, 0), _N, _N)))


def _check_out(out: tuple[Array, Array, Array], n_steps: int) -> None:
    shapes = ((n_steps, _N), (n_steps, _N, _N), (max(n_steps - 1, 0), _N, _N))
    if len(out) != 3 or any(
            not (isinstance(a, np.ndarray) and a.shape == s and a.dtype == np.float64
                 and a.flags.c_contiguous and a.flags.writeable)
            for a, s in zip(out, shapes, strict=True)):
        raise ValueError(f"out must be three writeable C-contiguous float64 arrays of shapes "
                         f"{shapes} (see posterior_arrays)")


def loglik_quad(model: StateSpaceModel, ys: Array) -> float:
    """log p(y | theta) [nats] of the EKF on a QuadSSM (or KinematicSSM): the compiled
    forward pass alone, equal to ``estimators.ekf.run_filter(model, ys).loglik`` up to
    rounding (the same kernel as ``smooth_quad``'s forward pass), for the observed
    information's finite differences. Models the kernels do not cover, and filters whose
    innovation covariance stops being positive definite, go to the generic filter."""
    prep = _prepared(model, ys)
    if prep is not None:
        ys, consts = prep
        *_, loglik, bad = _run_forward(model, ys, consts, store=False)
        if bad < 0:
            return float(loglik)
    return float(run_filter(model, ys).loglik)


def smooth_quad(model: StateSpaceModel, ys: Array, gate_sigma: float | None = None, *,
                out: tuple[Array, Array, Array] | None = None) -> Posterior:
    """EKF + RTS smoother of a :class:`~pinquad.models.ssm.QuadSSM`, compiled (module docstring).

    A drop-in for ``estimators.rts.smooth`` (e.g. as ``run_em``'s smoother): ys (N, m)
    with NaN where not observed; returns the Posterior with method "rts", the filter's
    log-likelihood and no rejected rows. Anything the kernels do not reproduce (a model
    that is not exactly a QuadSSM, its force-free warm-up KinematicSSM, the ten-parameter
    FullQuadSSM or discovery's EffectSSM, other subclasses included, since they may
    override the dynamics; an outlier gate; a model whose behaviour no longer matches the
    kernels) is smoothed by the generic ``estimators.rts.smooth``, so the answer is always
    the generic path's; the last case also warns, as the fast path needs updating. A
    covariance that stops being positive definite also hands over to the generic path,
    which then raises or copes as it always does.

    out: arrays (``posterior_arrays(N)``) the compiled path writes the smoothed means,
    covariances and cross-covariances into, and the returned Posterior then holds,
    instead of fresh ones (a caller smoothing window after window reuses them and saves
    the page faults of fresh memory); the generic fallback ignores them.
    """
    if gate_sigma is not None:
        return generic_smooth(model, ys, gate_sigma=gate_sigma)
    prep = _prepared(model, ys)
    if prep is None:
        return generic_smooth(model, ys)
    ys, consts = prep
    n_steps = ys.shape[0]
    if out is None:
        out = posterior_arrays(n_steps)
    else:
        _check_out(out, n_steps)
    mean, cov, cross = out
    fwd = _filter_arrays(n_steps)
    x0, p0 = model.initial()
    loglik, bad = _forward_into(np.ascontiguousarray(x0, dtype=float),
                                np.ascontiguousarray(p0, dtype=float),
                                np.ascontiguousarray(model.obs.inputs, dtype=float), ys, *consts,
                                True, *fwd)
    if bad < 0:
        bad = _backward_into(*fwd, mean, cov, cross)
    if bad >= 0:
        # A covariance lost positive definiteness: the generic path then raises its own
        # error (innovation S) or carries on with an LU solve (predicted P^-); either way
        # its behaviour, not a new one, is the contract.
        return generic_smooth(model, ys)
    return Posterior(mean, cov, cross, float(loglik), "rts",
                     np.zeros(ys.shape, dtype=bool))
