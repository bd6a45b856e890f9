"""Compiled dynamic rows, process covariance and F P product of
:class:`~pinquad.models.full.FullQuadSSM`, the ten-parameter model (numba).

Spatial inertia about the body origin O, M_O = [[m 1, -[h]x], [[h]x, I_O]], h = m c:

    [a_O; omega'] = M_O^-1 ([0, 0, F, M] - [w x (w x h); w x I_O w]),
    v' = R a_O - g e3  (explicit Euler, Jacobian I + dt df/dx),
    Q over the velocity and rate rows: dt G diag(S) G^T, G = M_O^-1 with its force rows
    turned by R (S (6,) [N^2 s, (N m)^2 s] the wrench noise intensities).

The kinematic rows are QuadSSM's (``quad_kernels.transition_quad``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pinquad.core.kernels import rotation, rotation_derivatives
from pinquad.estep.quad_kernels import f_times_quad, process_cov_start
from pinquad.models.kernel import STATE_DIM as _N


@njit(cache=True)
def full_dynamics(x, u, dt, gravity, m_inv, h, i_o, x_next, jac, accel, d_accel):
    """Replace the velocity and rate rows of ``transition_quad``'s x_next (12,) and jac
    (12, 12) by those of FullQuadSSM (module docstring): u (4,) = [F, M], dt [s],
    gravity [m/s^2], m_inv = M_O^-1 (6, 6), h = m c (3,), i_o = I_O (3, 3); writes a_O
    (3,) [m/s^2] into accel and d a_O / d omega (3, 3) into d_accel."""
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
    for r in range(3):
        accel[r] = acc[r]
        for c in range(3):
            d_accel[r, c] = d_acc[r, c]
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
def process_cov_full(x, dt, use_fixed, fixed_q, q_kin, m_inv, s_wrench, q):
    """Q (12, 12) of FullQuadSSM's flight process covariance at x: fixed, or the
    kinematic diagonal q_kin (6,) and over the velocity and rate rows dt G diag(S) G^T
    (S = s_wrench (6,), G from m_inv (6, 6); module docstring)."""
    if process_cov_start(use_fixed, fixed_q, q_kin, q):
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
def f_times_full(f, p, out):
    """out = F p for the full model's Jacobian: ``f_times_quad``'s pattern with the
    velocity rows reaching the rate columns too (rows 3-5: columns r, 6-11)."""
    f_times_quad(f, p, out)
    for r in range(3, 6):
        f9, f10, f11 = f[r, 9], f[r, 10], f[r, 11]
        for c in range(_N):
            out[r, c] += f9 * p[9, c] + f10 * p[10, c] + f11 * p[11, c]
