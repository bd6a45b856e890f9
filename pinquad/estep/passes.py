"""The compiled EKF forward pass and RTS backward pass (numba) over any model a
:class:`~pinquad.models.kernel.KernelDescription` describes; 12 states, m measurement
rows, N steps.

Forward pass (``estimators.ekf``), steps k = 0 .. N-1, prior (m^-_0, P^-_0) = (x0, P0):

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
    predict (the model's transition and Q at the filtered mean, by ``desc.kind``:
    ``quad_kernels`` for QUAD and KINEMATIC, with ``full_kernels``' dynamic rows and Q
    for FULL, with ``effect_kernels``' forces for EFFECT; on a continuous flight the
    kinematic rows by their mean rates, ``quad_kernels.continuous_rows`` and
    ``kinematic_noise``):
        m^-_{k+1} = m_k + dt f(m_k, u_k),  F_k = I + dt df/dx (m_k, u_k)
        P^-_{k+1} = F_k P_k F_k^T + Q_k(m_k)      (symmetrised; F P and F (F P)^T skip
                                                   the entries outside F's block pattern)
        Q_k += diag(reset_var) on the transitions marked in ``desc.resets``
    except on a restart (``desc.restarts``, ``models.ssm.restart_mask``: a log gap), where
    the state is re-initialised about the filtered mean instead of propagated:
        m^-_{k+1} = m_k,  F_k = 0,  P^-_{k+1} = diag(restart_var)
    (so the backward pass's gain over it is zero: the smoother restarts there)

Backward pass (``estimators.rts``), k = N-2 .. 0:

    G_k = P_k F_k^T (P^-_{k+1})^{-1}            (Cholesky solve of P^-_{k+1} G^T = F_k P_k)
    m^s_k = m_k + G_k (m^s_{k+1} - m^-_{k+1})
    Cov(x_{k+1}, x_k | y) = C_k = P^s_{k+1} G_k^T
    P^s_k = P_k + G_k (P^s_{k+1} - P^-_{k+1}) G_k^T = P_k + G_k (C_k - F_k P_k)
                                        (P^-_{k+1} G_k^T = F_k P_k; lower triangle, mirrored)

The passes take the per-step arrays as NamedTuples (:class:`FilterArrays`,
:class:`PosteriorArrays`) and write into them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from pinquad.core.kernels import wrap
from pinquad.estep.effect_kernels import effect_dynamics, f_times_effect
from pinquad.estep.full_kernels import f_times_full, full_dynamics, process_cov_full
from pinquad.estep.linalg import chol_solve, cholesky, copy_mat, copy_vec, fill, symmetrise
from pinquad.estep.quad_kernels import (
    continuous_rows,
    f_times_dense_rows,
    f_times_quad,
    kinematic_noise,
    process_cov_quad,
    transition_kinematic,
    transition_quad,
)
from pinquad.models.kernel import EFFECT, FULL, KINEMATIC
from pinquad.models.kernel import STATE_DIM as _N

Array = NDArray[np.float64]

_LOG_2PI = math.log(2.0 * math.pi)


class FilterArrays(NamedTuple):
    """The forward pass's per-step arrays, what the backward pass reads: filtered means
    f_mean (N, 12) and covariances f_cov (N, 12, 12), predicted means p_mean (N, 12) and
    covariances p_cov (N, 12, 12) (p_*[k] is the prior of step k), and the products
    fps[k] = F_k P_k (N - 1, 12, 12)."""

    f_mean: Array
    f_cov: Array
    p_mean: Array
    p_cov: Array
    fps: Array


class PosteriorArrays(NamedTuple):
    """The smoothed moments: mean (N, 12), cov (N, 12, 12) and lag-one
    cross-covariances cross[k] = Cov(x_{k+1}, x_k | y) (N - 1, 12, 12)."""

    mean: Array
    cov: Array
    cross: Array


def filter_arrays(n_steps: int) -> FilterArrays:
    """Fresh (uninitialised) :class:`FilterArrays` for N = n_steps."""
    return FilterArrays(np.empty((n_steps, _N)), np.empty((n_steps, _N, _N)),
                        np.empty((n_steps, _N)), np.empty((n_steps, _N, _N)),
                        np.empty((max(n_steps - 1, 0), _N, _N)))


def posterior_arrays(n_steps: int) -> PosteriorArrays:
    """Fresh (uninitialised) :class:`PosteriorArrays` for N = n_steps."""
    return PosteriorArrays(np.empty((n_steps, _N)), np.empty((n_steps, _N, _N)),
                           np.empty((max(n_steps - 1, 0), _N, _N)))


@njit(cache=True)
def _f_times(kind, continuous, f, p, out):
    """out = F p (12, 12) with the block pattern of the Jacobian F of a model of this
    kind (entries outside the pattern are exact zeros and are skipped; a continuous
    flight's position and velocity rows are summed over every column)."""
    if kind == FULL:
        f_times_full(f, p, out)
    elif kind == EFFECT:
        f_times_effect(f, p, out)
    else:
        f_times_quad(f, p, out)
    if continuous:
        f_times_dense_rows(f, p, out, 0, 6)


@njit(cache=True)
def _restart(mean, restart_var, x_next, jac, q):
    """A restart's transition (module docstring): x_next = mean (12,), jac = 0 and
    q = diag(restart_var) (12, 12)."""
    fill(jac, 0.0)
    fill(q, 0.0)
    for i in range(_N):
        x_next[i] = mean[i]
        q[i, i] = restart_var[i]


@njit(cache=True)
def forward_into(desc, x0, p0, ys, store, work):
    """EKF forward pass (module docstring) of the model ``desc`` from the prior x0 (12,),
    P0 (12, 12) over ys (N, m) (NaN: not observed). With store, writes the per-step
    arrays into work (:class:`FilterArrays`); without (the log-likelihood alone, saving
    the memory traffic), work is not touched (``filter_arrays(1)`` will do). Returns
    (log p(y) [nats], first step whose innovation covariance was not positive definite
    or -1)."""
    f_mean, f_cov, p_mean, p_cov, fps = work
    # Unpacked once: taking an array out of a NamedTuple costs a reference-count pair,
    # which inside the loop (a dozen arrays a step) made the pass a third slower.
    kind, dt, mass, gravity, use_fixed = desc.kind, desc.dt, desc.mass, desc.gravity, desc.use_fixed
    inputs, inertia, inertia_inv = desc.inputs, desc.inertia, desc.inertia_inv
    meas_var, state_of_row, is_angle = desc.meas_var, desc.state_of_row, desc.is_angle
    fixed_q, q_kin, s_f, q_tau = desc.fixed_q, desc.q_kin, desc.s_f, desc.q_tau
    resets, reset_var = desc.resets, desc.reset_var
    restarts, restart_var = desc.restarts, desc.restart_var
    m_inv, first_moment, i_o, s_wrench = desc.m_inv, desc.first_moment, desc.i_o, desc.s_wrench
    drag, wind, continuous = desc.drag, desc.wind, desc.continuous
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
    rot = np.empty((3, 3))
    f_body = np.empty(3)
    # a continuous flight's scratch (quad_kernels.continuous_rows, kinematic_noise)
    accel = np.zeros(3)
    d_accel = np.zeros((3, 3))
    s33 = np.empty((6, 3, 3))
    d_rot = np.empty((2, 3, 3, 3))
    rows_3x12 = np.empty((3, _N))
    loglik = 0.0
    for k in range(n_steps):
        if store:
            copy_vec(mean, p_mean[k])
            copy_mat(cov, p_cov[k])
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
            if not cholesky(s_mat, p, low):
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
                d_inv = 1.0 / d
                w = w * d_inv
                for c in range(_N):
                    w_mat[a, c] *= d_inv
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
            copy_vec(mean, f_mean[k])
            copy_mat(cov, f_cov[k])
        if k + 1 < n_steps:
            flowing = False
            if restarts[k]:
                _restart(mean, restart_var, x_next, jac, q)
            else:
                if kind == FULL:
                    process_cov_full(mean, dt, use_fixed, fixed_q, q_kin, m_inv, s_wrench, q)
                else:
                    process_cov_quad(mean, dt, mass, use_fixed, fixed_q, q_kin, s_f, q_tau, q, rot)
                flowing = continuous and kind != KINEMATIC  # the warm-up's rates are constant
                if flowing and not use_fixed:
                    kinematic_noise(mean, dt, q, s33[0], rows_3x12, s33[1])
                if resets[k]:
                    for i in range(_N):
                        q[i, i] += reset_var[i]
                if kind == KINEMATIC:
                    transition_kinematic(mean, dt, x_next, jac)
                else:
                    u = inputs[k]
                    transition_quad(mean, u, dt, mass, inertia, inertia_inv, gravity, x_next, jac)
                    if kind == FULL:
                        full_dynamics(mean, u, dt, gravity, m_inv, first_moment, i_o, x_next, jac,
                                      accel, d_accel)
                    else:
                        accel[2] = u[0] / mass
                        if kind == EFFECT:
                            effect_dynamics(mean, dt, mass, drag, wind, x_next, jac, rot, f_body)
                    if flowing:
                        continuous_rows(mean, dt, accel, d_accel, x_next, jac, s33, d_rot, rows_3x12)
            _f_times(kind, flowing, jac, cov, fp)
            if store:
                copy_mat(fp, fps[k])
            # F P F^T = F (F P)^T (P symmetric)
            for r in range(_N):
                for c in range(_N):
                    fp_t[r, c] = fp[c, r]
            _f_times(kind, flowing, jac, fp_t, new_cov)
            for r in range(_N):
                for c in range(_N):
                    new_cov[r, c] += q[r, c]
            symmetrise(new_cov, cov)
            copy_vec(x_next, mean)
    return loglik, -1


@njit(cache=True)
def backward_into(work, post):
    """RTS backward pass with lag-one cross-covariances (module docstring), from the
    forward pass's arrays work (:class:`FilterArrays`, F_k P_k included), into post
    (:class:`PosteriorArrays`). Returns the first step whose predicted covariance was
    not positive definite (-1 if none).

    With G^T = Pp^{-1} (F P) and C = Ps G^T = Cov(x_{k+1}, x_k | y):
    G (Ps - Pp) G^T = G (C - Pp G^T) = G (C - F P), one product instead of two."""
    f_mean, f_cov, p_mean, p_cov, fps = work
    mean, cov, cross = post
    n_steps = f_mean.shape[0]
    copy_vec(f_mean[n_steps - 1], mean[n_steps - 1])
    copy_mat(f_cov[n_steps - 1], cov[n_steps - 1])
    low = np.empty((_N, _N))
    gain_t = np.empty((_N, _N))
    diff = np.empty((_N, _N))
    acc = np.empty(_N)
    for k in range(n_steps - 2, -1, -1):
        pf = f_cov[k]
        pp = p_cov[k + 1]
        ps = cov[k + 1]
        fp = fps[k]
        if not cholesky(pp, _N, low):
            return k + 1
        copy_mat(fp, gain_t)
        chol_solve(low, _N, gain_t)
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
        # (a scalar sum per entry: accumulating into ck row by row kept every partial
        # sum in memory, since ck may alias ps, and took half the pass)
        ck = cross[k]
        for r in range(_N):
            for c in range(_N):
                s = 0.0
                for j in range(_N):
                    s += ps[r, j] * gain_t[j, c]
                ck[r, c] = s
                diff[r, c] = s - fp[r, c]
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
