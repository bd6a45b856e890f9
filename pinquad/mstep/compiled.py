"""Compiled expected sufficient statistics of the regressor M-step.

``regressor_quadratics(post, obs, gravity)`` returns the same per-row quadratic forms
as ``pinquad.mstep.updates.regressor_stats`` (a (6, 4, 4), b (6, 4), c (6,), n), summed over
the used transitions k -> k+1 in one compiled loop instead of NumPy arrays of shape
(K, ...) and einsums, because EM calls the M-step once per E-step (and the online
estimator once per update). Per transition (see ``pinquad.mstep.updates``):

    Y_k (6, 4): force rows   m R_k^T ((v_{k+1} - v_k)/dt + g e3)
                torque rows  I omega' + omega x I omega, omega' = (omega_{k+1} - omega_k)/dt
    tau_k = [0, 0, F_k, M_k]  (a continuous flight: F_k (e3 + R_k^T R_{k+1} e3) / 2 in the
                               force rows, ``updates.applied_force``)
    a_j += Y_kj^T Y_kj + E-terms,   b_j += Y_kj tau_kj,   c_j += tau_kj^2

with the first-order expectation terms d_j Sigma d_j^T of the regressor's state
derivative d_j (force rows: w.r.t. (Theta_k, v_k, v_{k+1}), dR/dTheta by central
differences with h = 1e-6 exactly as the reference; torque rows: w.r.t.
(omega_k, omega_{k+1})) and the smoothed joint covariance Sigma of those states (from the
covariances and the lag-one cross-covariance Cov(x_{k+1}, x_k)). The same sums in
another order: equal to the reference up to rounding (a test holds it to 1e-11
relative).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.kernels import rotation_derivatives, wrap
from pinquad.models.ssm import Observations
from pinquad.mstep.stats import QuadraticSums, transition_mask

Array = NDArray[np.float64]



@njit(cache=True)
def _quadratics(mean, cov, cross, inputs, idx, dt, gravity, continuous):
    """Sums a (6, 4, 4), b (6, 4), c (6,) over transitions idx[j] -> idx[j] + 1
    (continuous: the applied force along the interval's mean thrust direction)."""
    a = np.zeros((6, 4, 4))
    b = np.zeros((6, 4))
    c = np.zeros(6)
    rot = np.empty((3, 3))
    d_rot = np.empty((3, 3, 3))
    rot1 = np.empty((3, 3))
    d_rot1 = np.empty((3, 3, 3))
    acc = np.empty(3)
    y = np.empty((6, 4))
    tau = np.empty(6)
    d_force = np.zeros((3, 12))
    d_tau = np.zeros((3, 12))
    sig_f = np.empty((12, 12))
    sig_w = np.empty((6, 6))
    d_t = np.zeros((3, 3, 6))
    inv = 1.0 / dt
    # state rows of (Theta_k, v_k) in x_k and of (v_{k+1}, Theta_{k+1}) in x_{k+1};
    # (omega_k, omega_{k+1}): 9..11 of each
    rows_f = np.array([6, 7, 8, 3, 4, 5])
    rows_n = np.array([3, 4, 5, 6, 7, 8])
    n_f = 12 if continuous else 9
    for j in range(idx.shape[0]):
        k = idx[j]
        x0 = mean[k]
        x1 = mean[k + 1]
        # R and dR/dTheta_m from one evaluation of the angles' sines and cosines
        rotation_derivatives(x0[6], x0[7], x0[8], rot, d_rot)
        for i in range(3):
            acc[i] = (x1[3 + i] - x0[3 + i]) / dt
        acc[2] += gravity
        wx, wy, wz = x0[9], x0[10], x0[11]
        wd0 = (x1[9] - x0[9]) / dt
        wd1 = (x1[10] - x0[10]) / dt
        wd2 = (x1[11] - x0[11]) / dt
        for r in range(6):
            for p in range(4):
                y[r, p] = 0.0
        for i in range(3):
            y[i, 0] = rot[0, i] * acc[0] + rot[1, i] * acc[1] + rot[2, i] * acc[2]
        y[3, 1], y[4, 1], y[5, 1] = wd0, wx * wz, -wx * wy
        y[3, 2], y[4, 2], y[5, 2] = -wy * wz, wd1, wx * wy
        y[3, 3], y[4, 3], y[5, 3] = wy * wz, -wx * wz, wd2
        thrust = inputs[k, 0]
        tau[0] = 0.0
        tau[1] = 0.0
        tau[2] = thrust
        if continuous:
            # F (e3 + R_k^T R_{k+1} e3) / 2 and its derivative by Theta_k (columns 0..2)
            # and Theta_{k+1} (9..11), as updates.applied_force
            rotation_derivatives(x1[6], x1[7], x1[8], rot1, d_rot1)
            half = 0.5 * thrust
            for i in range(3):
                tau[i] = half * (rot[0, i] * rot1[0, 2] + rot[1, i] * rot1[1, 2]
                                 + rot[2, i] * rot1[2, 2])
                for m in range(3):
                    d_tau[i, m] = half * (d_rot[0, i, m] * rot1[0, 2] + d_rot[1, i, m] * rot1[1, 2]
                                          + d_rot[2, i, m] * rot1[2, 2])
                    d_tau[i, 9 + m] = half * (rot[0, i] * d_rot1[0, 2, m]
                                              + rot[1, i] * d_rot1[1, 2, m]
                                              + rot[2, i] * d_rot1[2, 2, m])
            tau[2] += half
        tau[3] = inputs[k, 1]
        tau[4] = inputs[k, 2]
        tau[5] = inputs[k, 3]
        for r in range(6):
            for p in range(4):
                yp = y[r, p]
                b[r, p] += yp * tau[r]
                for q in range(4):
                    a[r, p, q] += y[r, q] * yp
            c[r] += tau[r] * tau[r]
        # d(R^T acc)/dTheta_m = (dR/dTheta_m)^T acc; d/dv_k = -R^T/dt; d/dv_{k+1} = R^T/dt
        for i in range(3):
            for m in range(3):
                d_force[i, m] = (d_rot[0, i, m] * acc[0] + d_rot[1, i, m] * acc[1]
                                 + d_rot[2, i, m] * acc[2])
            for s in range(3):
                d_force[i, 3 + s] = -rot[s, i] / dt
                d_force[i, 6 + s] = rot[s, i] / dt
        # joint covariance of (Theta_k, v_k, v_{k+1}[, Theta_{k+1}]);
        # cross[k] = Cov(x_{k+1}, x_k)
        pk = cov[k]
        pn = cov[k + 1]
        ck = cross[k]
        for r in range(6):
            for s in range(6):
                sig_f[r, s] = pk[rows_f[r], rows_f[s]]
        for r in range(n_f - 6):
            for s in range(6):
                sig_f[6 + r, s] = ck[rows_n[r], rows_f[s]]
                sig_f[s, 6 + r] = ck[rows_n[r], rows_f[s]]
            for s in range(n_f - 6):
                sig_f[6 + r, 6 + s] = pn[rows_n[r], rows_n[s]]
        for i in range(3):
            acc_q = 0.0
            acc_b = 0.0
            acc_c = 0.0
            for r in range(n_f):
                dr = d_force[i, r]
                gr = d_tau[i, r]
                if dr != 0.0:
                    t = 0.0
                    for s in range(n_f):
                        t += sig_f[r, s] * d_force[i, s]
                    acc_q += dr * t
                if continuous and (dr != 0.0 or gr != 0.0):
                    u = 0.0
                    for s in range(n_f):
                        u += sig_f[r, s] * d_tau[i, s]
                    acc_b += dr * u
                    acc_c += gr * u
            a[i, 0, 0] += acc_q
            if continuous:
                b[i, 0] += acc_b
                c[i] += acc_c
        # joint covariance of (omega_k, omega_{k+1})
        for r in range(3):
            for s in range(3):
                sig_w[r, s] = pk[9 + r, 9 + s]
                sig_w[3 + r, s] = ck[9 + r, 9 + s]
                sig_w[r, 3 + s] = ck[9 + s, 9 + r]
                sig_w[3 + r, 3 + s] = pn[9 + r, 9 + s]
        # d_t[p, row, state]: derivative of inertia column p's torque rows (see
        # identify._regressor_jacobian); entries not set here stay zero
        d_t[0, 0, 0], d_t[0, 0, 3] = -inv, inv
        d_t[0, 1, 0], d_t[0, 1, 2] = wz, wx
        d_t[0, 2, 0], d_t[0, 2, 1] = -wy, -wx
        d_t[1, 0, 1], d_t[1, 0, 2] = -wz, -wy
        d_t[1, 1, 1], d_t[1, 1, 4] = -inv, inv
        d_t[1, 2, 0], d_t[1, 2, 1] = wy, wx
        d_t[2, 0, 1], d_t[2, 0, 2] = wz, wy
        d_t[2, 1, 0], d_t[2, 1, 2] = -wz, -wx
        d_t[2, 2, 2], d_t[2, 2, 5] = -inv, inv
        for r in range(3):
            for p in range(3):
                for q in range(3):
                    acc_q = 0.0
                    for i in range(6):
                        dpi = d_t[p, r, i]
                        if dpi != 0.0:
                            t = 0.0
                            for s in range(6):
                                t += sig_w[i, s] * d_t[q, r, s]
                            acc_q += dpi * t
                    a[3 + r, 1 + p, 1 + q] += acc_q
    return a, b, c


def regressor_quadratics(post: Posterior, obs: Observations, gravity: float
                         ) -> QuadraticSums:
    """The regressor M-step's expected quadratic forms over the used transitions
    (``identify.transition_mask``), compiled (module docstring), with the applied force
    of a continuous flight when ``obs.continuous``."""
    idx = np.flatnonzero(transition_mask(obs)).astype(np.int64)
    a, b, c = _quadratics(np.ascontiguousarray(post.mean, dtype=float),
                          np.ascontiguousarray(post.cov, dtype=float),
                          np.ascontiguousarray(post.cross_cov, dtype=float),
                          np.ascontiguousarray(obs.inputs, dtype=float), idx, float(obs.dt),
                          float(gravity), bool(obs.continuous))
    return QuadraticSums(a, b, c, float(idx.size))


@njit(cache=True)
def physical(i_diag):
    """Whether a diagonal inertia (3,) [kg m^2] is physical: positive and satisfying the
    triangle inequalities 2 I_i < I_xx + I_yy + I_zz (the Python M-step uses it too)."""
    total = i_diag[0] + i_diag[1] + i_diag[2]
    for i in range(3):
        if not (i_diag[i] > 0.0 and 2.0 * i_diag[i] < total):
            return False
    return True


@njit(cache=True)
def _inside(i_diag, lo, hi):
    """Whether lo <= i_diag <= hi elementwise (the M-step's box)."""
    for i in range(3):
        if not (lo[i] <= i_diag[i] <= hi[i]):
            return False
    return True


@njit(cache=True)
def _solve3(a, b, x):
    """x = a^{-1} b for a (3, 3) by Gaussian elimination with partial pivoting (what
    LAPACK's gesv does); False, like numpy's LinAlgError, when a pivot is exactly zero."""
    m = np.empty((3, 4))
    for r in range(3):
        for c in range(3):
            m[r, c] = a[r, c]
        m[r, 3] = b[r]
    for col in range(3):
        piv = col
        for r in range(col + 1, 3):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if m[piv, col] == 0.0:
            return False
        if piv != col:
            for c in range(4):
                m[col, c], m[piv, c] = m[piv, c], m[col, c]
        for r in range(col + 1, 3):
            f = m[r, col] / m[col, col]
            for c in range(col, 4):
                m[r, c] -= f * m[col, c]
    for r in range(2, -1, -1):
        s = m[r, 3]
        for c in range(r + 1, 3):
            s -= m[r, c] * x[c]
        x[r] = s / m[r, r]
    return True


@njit(cache=True)
def _q_rows(mass, a_t, b_t, c_t, i_diag, q):
    """q_j = pi^T A_j pi - 2 b_j^T pi + c_j, pi = [m, I] (3 torque rows j)."""
    pi = np.empty(4)
    pi[0] = mass
    for i in range(3):
        pi[1 + i] = i_diag[i]
    for j in range(3):
        s = 0.0
        for p in range(4):
            t = 0.0
            for r in range(4):
                t += a_t[j, p, r] * pi[r]
            s += pi[p] * t - 2.0 * b_t[j, p] * pi[p]
        q[j] = s + c_t[j]


@njit(cache=True)
def _parts(mass, a_t, b_t, c_t, i_diag, grad, hess, want_derivatives):
    """J(I) and (when asked, into grad and hess) its gradient and Hessian, as
    identify._inertia_newton's ``parts``; J = inf (gradient 0, Hessian identity) where
    some q_j <= 0."""
    q = np.empty(3)
    _q_rows(mass, a_t, b_t, c_t, i_diag, q)
    if q[0] <= 0.0 or q[1] <= 0.0 or q[2] <= 0.0:
        if not want_derivatives:
            return np.inf
        for p in range(3):
            grad[p] = 0.0
            for r in range(3):
                hess[p, r] = 1.0 if p == r else 0.0
        return np.inf
    val = 0.5 * (math.log(q[0]) + math.log(q[1]) + math.log(q[2]))
    val -= math.log(i_diag[0]) + math.log(i_diag[1]) + math.log(i_diag[2])
    if not want_derivatives:
        return val
    pi = np.empty(4)
    pi[0] = mass
    for i in range(3):
        pi[1 + i] = i_diag[i]
    dq = np.empty((3, 3))
    for j in range(3):
        for p in range(3):
            t = 0.0
            for r in range(4):
                t += a_t[j, 1 + p, r] * pi[r]
            dq[j, p] = 2.0 * t - 2.0 * b_t[j, 1 + p]
    for p in range(3):
        g = 0.0
        for j in range(3):
            g += dq[j, p] / q[j]
        grad[p] = 0.5 * g - 1.0 / i_diag[p]
        for r in range(3):
            h = 0.0
            for j in range(3):
                h += a_t[j, 1 + p, 1 + r] / q[j] - 0.5 * dq[j, p] * dq[j, r] / (q[j] * q[j])
            hess[p, r] = h
        hess[p, p] += 1.0 / (i_diag[p] * i_diag[p])
    return val


@njit(cache=True)
def inertia_newton(mass, a_t, b_t, c_t, previous, lo, hi):
    """identify._inertia_newton compiled: the same candidates (previous inertia, the
    unweighted least-squares solution), damped Newton steps, backtracking and stopping
    rule, so the same minimiser up to rounding. a_t (3, 4, 4), b_t (3, 4), c_t (3,) of
    the torque rows; previous (3,) diagonal inertia; lo, hi (3,) [kg m^2]: the box the
    inertia stays in (every trial point is projected onto it; 0 and inf: no box).
    Returns the diagonal inertia (3,)."""
    grad = np.empty(3)
    hess = np.empty((3, 3))
    a_sum = np.zeros((3, 3))
    rhs = np.zeros(3)
    for j in range(3):
        for p in range(3):
            rhs[p] += b_t[j, 1 + p] - a_t[j, 1 + p, 0] * mass
            for r in range(3):
                a_sum[p, r] += a_t[j, 1 + p, 1 + r]
    prev = np.minimum(np.maximum(previous.astype(np.float64), lo), hi)
    current = np.empty(3)
    have = False
    best = np.inf
    if physical(prev):
        current[:] = prev
        best = _parts(mass, a_t, b_t, c_t, prev, grad, hess, False)
        have = True
    i_ls = np.empty(3)
    if _solve3(a_sum, rhs, i_ls) and physical(i_ls) and _inside(i_ls, lo, hi):
        q_ls = np.empty(3)
        _q_rows(mass, a_t, b_t, c_t, i_ls, q_ls)
        if q_ls[0] <= 1e-12 * c_t[0] and q_ls[1] <= 1e-12 * c_t[1] and q_ls[2] <= 1e-12 * c_t[2]:
            return i_ls
        v_ls = _parts(mass, a_t, b_t, c_t, i_ls, grad, hess, False)
        if not have or v_ls < best:  # min() keeps the first of equal values
            current[:] = i_ls
            have = True
    if not have:
        mean_prev = (previous[0] + previous[1] + previous[2]) / 3.0
        for i in range(3):
            current[i] = min(max(mean_prev, lo[i]), hi[i])
    val = _parts(mass, a_t, b_t, c_t, current, grad, hess, True)
    step = np.empty(3)
    trial = np.empty(3)
    active = np.zeros(3, dtype=np.bool_)
    for _ in range(100):
        # projected Newton (Bertsekas 1982): an entry on the box's edge whose gradient
        # pushes it outwards is held there, Newton runs on the others
        n_active = 0
        for i in range(3):
            active[i] = ((current[i] >= hi[i] and grad[i] < 0.0)
                         or (current[i] <= lo[i] and grad[i] > 0.0))
            n_active += active[i]
        if n_active == 0:
            ok = _solve3(hess, grad, step)
        else:
            h_free = hess.copy()
            g_free = grad.copy()
            for i in range(3):
                if active[i]:
                    g_free[i] = 0.0
                    for r in range(3):
                        h_free[i, r] = 0.0
                        h_free[r, i] = 0.0
                    h_free[i, i] = 1.0
            ok = _solve3(h_free, g_free, step)
        slope = 0.0
        if ok:
            for i in range(3):
                step[i] = -step[i]
                slope += grad[i] * step[i]
        if not ok or slope >= 0.0:  # not a descent direction: fall back to gradient
            cmin = min(current[0], current[1], current[2])
            slope = 0.0
            for i in range(3):
                step[i] = 0.0 if active[i] else -grad[i] * cmin * cmin
                slope += grad[i] * step[i]
        if slope == 0.0:  # every entry held on the edge: a constrained minimum
            break
        t = 1.0
        accepted = False
        while t > 1e-12:
            # Armijo on the projected step; unprojected it is t * slope exactly
            moved = t * slope
            clipped = False
            for i in range(3):
                trial[i] = current[i] + t * step[i]
                if trial[i] < lo[i] or trial[i] > hi[i]:
                    trial[i] = min(max(trial[i], lo[i]), hi[i])
                    clipped = True
            if clipped:
                moved = 0.0
                for i in range(3):
                    moved += grad[i] * (trial[i] - current[i])
            if physical(trial):
                v_new = _parts(mass, a_t, b_t, c_t, trial, grad, hess, False)
                if v_new <= val + 1e-4 * moved:
                    accepted = True
                    break
            t *= 0.5
        if not accepted:
            break
        rel = 0.0
        for i in range(3):
            rel = max(rel, abs(trial[i] - current[i]) / current[i])
        current[:] = trial
        val = _parts(mass, a_t, b_t, c_t, current, grad, hess, True)
        if rel < 1e-12:
            break
    return current


@njit(cache=True)
def _measurement_variances(mean, cov, ys, rejected, state_of_row, is_angle, previous):
    out = previous.copy()
    n_steps, m = ys.shape
    for i in range(m):
        s = state_of_row[i]
        total = 0.0
        count = 0
        for k in range(n_steps):
            y = ys[k, i]
            if not math.isnan(y) and not rejected[k, i]:
                res = y - mean[k, s]
                if is_angle[i]:
                    res = wrap(res)
                total += res * res + cov[k, s, s]
                count += 1
        if count > 0:
            out[i] = max(total / count, 1e-12)
    return out


def measurement_variances(post: Posterior, obs: Observations, previous: Array) -> Array:
    """identify.measurement_variances compiled (the same sums, in another order):
    r_i = mean over observed, not rejected steps of (y_ki - m_k,s(i))^2 + P_k,s(i)s(i)
    (Euler residuals wrapped), floored at 1e-12; ``previous`` where never observed."""
    h = obs.measurement_matrix()
    state_of_row = np.argmax(h, axis=1).astype(np.int64)
    is_angle = np.zeros(h.shape[0], dtype=np.bool_)
    is_angle[obs.angle_rows()] = True
    return _measurement_variances(np.ascontiguousarray(post.mean, dtype=float),
                                  np.ascontiguousarray(post.cov, dtype=float),
                                  np.ascontiguousarray(obs.ys, dtype=float),
                                  np.ascontiguousarray(post.rejected, dtype=np.bool_),
                                  state_of_row, is_angle, np.array(previous, dtype=float))
