"""M-steps: mass and inertia (and the noise covariances) from a smoothed posterior.

Complete-data model of one transition k -> k+1 (explicit Euler, noise on the applied
wrench as in the paper's SDE): the body-frame wrench residual

    rho_k = Y_k pi - tau_k ~ N(0, S / dt),      tau_k = [0, 0, F_k, M_k]

where Y_k is the inertial regressor at (x_k, x_{k+1}) (``body_regressor``; equal to
Pinocchio's joint-torque regressor columns for a CoM at the thrust centre) and pi the
dynamic parameters. In state coordinates the density picks up the Jacobian
|d rho / d(v_{k+1}, omega_{k+1})| = m^3 det(I) / dt^6, so with S diagonal and profiled
out the M-step minimises over pi

    J(pi) = sum_j (N/2) log E[sum_k rho_kj^2] - N (3 log m + log det I)

with E[sum_k rho_kj^2] = pi^T A_j pi - 2 b_j^T pi + c_j built from the posterior means,
covariances and lag-one cross-covariances (first order in the state uncertainty, exact in
the finite-difference accelerations, whose variance dominates). The mass is the
one-dimensional minimiser of the force rows' part (``profiled_mass``; closed form when
only the body-z row carries a force); the inertia is found by damped Newton over
inertias kept physically consistent (positive, triangle inequalities).

On a continuous flight (``Observations.continuous``: the E-step turns the thrust with the
mean of R_k and R_{k+1}, ``pinquad.models.continuous``) the applied force is the thrust
along that mean direction, in the body frame at k:

    tau_k[0:3] = F_k u_k,   u_k = (e3 + R_k^T R_{k+1} e3) / 2        (``applied_force``)

so the force rows' residual is the one the E-step's transition leaves. It depends on the
attitudes, and the expectation gains the matching first-order terms (b_j += d_j Sigma
g_j^T, c_j += g_j Sigma g_j^T with g_j = d tau_kj / d(Theta_k, Theta_{k+1})).

``paper_mstep`` is the paper's closed form (mass from vertical velocity increments,
I_xx, I_yy, I_zz per axis, point estimates only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from estimators.protocol import Posterior
from pinquad.core.conventions import (
    rotation_and_derivatives,
    rotation_from_euler,
    wrap_angle,
)
from pinquad.core.params import VehicleRange
from pinquad.models.ssm import CHANNEL_SLICES, NoiseModel, Observations, Theta, kinematic_floor
from pinquad.mstep import compiled
from pinquad.mstep.stats import QuadraticSums, transition_mask

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RegressorStats:
    """Per-transition regressor quantities at the posterior mean.

    y (K, 6, 4): regressor of pi = [m, I_xx, I_yy, I_zz]; tau (K, 6): applied wrench;
    a (4, 4, 6)... see ``quadratic``: a (6, 4, 4), b (6, 4), c (6,) the per-row
    expected quadratic forms; n: number of transitions used.
    """

    y: Array
    tau: Array
    a: Array
    b: Array
    c: Array
    n: int


def body_regressor(x_now: Array, x_next: Array, dt: float, gravity: float) -> Array:
    """Y (K, 6, 4) with body wrench = Y @ [m, I_xx, I_yy, I_zz] for diagonal inertia and
    the CoM at the thrust centre.

    Force rows: m R^T ((v_{k+1} - v_k)/dt + g e3). Torque rows: I omega' + omega x I omega
    with omega' = (omega_{k+1} - omega_k)/dt, omega = omega_k.
    """
    rot = rotation_from_euler(x_now[:, 6:9])
    acc = (x_next[:, 3:6] - x_now[:, 3:6]) / dt
    acc[:, 2] += gravity
    w = x_now[:, 9:12]
    wd = (x_next[:, 9:12] - x_now[:, 9:12]) / dt
    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    y = np.zeros((x_now.shape[0], 6, 4))
    y[:, 0:3, 0] = np.einsum("kji,kj->ki", rot, acc)
    y[:, 3, 1], y[:, 4, 1], y[:, 5, 1] = wd[:, 0], wx * wz, -wx * wy
    y[:, 3, 2], y[:, 4, 2], y[:, 5, 2] = -wy * wz, wd[:, 1], wx * wy
    y[:, 3, 3], y[:, 4, 3], y[:, 5, 3] = wy * wz, -wx * wz, wd[:, 2]
    return y


def applied_force(x_now: Array, x_next: Array, thrust: Array, continuous: bool
                  ) -> tuple[Array, Array | None]:
    """The force rows of tau_k (K, 3) [N] in the body frame at k, and, on a continuous
    flight, their derivative (K, 3, 12) w.r.t. (Theta_k, v_k, v_{k+1}, Theta_{k+1})
    (None when they do not depend on the states).

    Held (explicit Euler): F_k e3. Continuous: F_k (e3 + R_k^T R_{k+1} e3) / 2, the
    thrust along the interval's mean direction (module docstring); x_now, x_next (K, 12)
    the states at k and k+1, thrust (K,) [N].
    """
    k = x_now.shape[0]
    force = np.zeros((k, 3))
    if not continuous:
        force[:, 2] = thrust
        return force, None
    rot0, d_rot0 = rotation_and_derivatives(x_now[:, 6:9])
    rot1, d_rot1 = rotation_and_derivatives(x_next[:, 6:9])
    half = 0.5 * np.asarray(thrust, dtype=float)
    axis1 = rot1[:, :, 2]                                   # R_{k+1} e3
    force[:, 2] = half
    force += half[:, None] * np.einsum("kji,kj->ki", rot0, axis1)
    d_force = np.zeros((k, 3, 12))
    # d(R_k^T R_{k+1} e3)/dTheta_k,m = (dR_k/dTheta_m)^T R_{k+1} e3; by Theta_{k+1},m:
    # R_k^T (dR_{k+1}/dTheta_m) e3
    d_force[:, :, 0:3] = half[:, None, None] * np.einsum("kjim,kj->kim", d_rot0, axis1)
    d_force[:, :, 9:12] = half[:, None, None] * np.einsum("kji,kjm->kim", rot0,
                                                          d_rot1[:, :, 2, :])
    return force, d_force


def _regressor_jacobian(x_now: Array, x_next: Array, dt: float, gravity: float
                        ) -> tuple[Array, Array]:
    """Non-zero blocks of the regressor's derivative w.r.t. the states.

    Returns d_force (K, 3, 12): derivative of the mass column's force rows w.r.t.
    (Theta_k, v_k, v_{k+1}, Theta_{k+1}) (zero in the last three); d_torque (K, 3, 3, 6):
    derivative of the inertia columns (p = Ixx, Iyy, Izz) torque rows w.r.t.
    (omega_k, omega_{k+1}). All other entries of dY/d(x_k, x_{k+1}) are zero.
    """
    k = x_now.shape[0]
    rot = rotation_from_euler(x_now[:, 6:9])
    d_rot = rotation_and_derivatives(x_now[:, 6:9])[1]
    acc = (x_next[:, 3:6] - x_now[:, 3:6]) / dt
    acc[:, 2] += gravity
    w = x_now[:, 9:12]
    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    rot_t = np.transpose(rot, (0, 2, 1))
    d_force = np.zeros((k, 3, 12))
    # d(R^T a)/dTheta_j = (dR/dTheta_j)^T a
    d_force[:, :, 0:3] = np.einsum("kbaj,kb->kaj", d_rot, acc)
    d_force[:, :, 3:6] = -rot_t / dt
    d_force[:, :, 6:9] = rot_t / dt
    inv = 1.0 / dt
    d = np.zeros((k, 3, 3, 6))
    # Ixx column [wd_x, wx wz, -wx wy]
    d[:, 0, 0, 0], d[:, 0, 0, 3] = -inv, inv
    d[:, 0, 1, 0], d[:, 0, 1, 2] = wz, wx
    d[:, 0, 2, 0], d[:, 0, 2, 1] = -wy, -wx
    # Iyy column [-wy wz, wd_y, wx wy]
    d[:, 1, 0, 1], d[:, 1, 0, 2] = -wz, -wy
    d[:, 1, 1, 1], d[:, 1, 1, 4] = -inv, inv
    d[:, 1, 2, 0], d[:, 1, 2, 1] = wy, wx
    # Izz column [wy wz, -wx wz, wd_z]
    d[:, 2, 0, 1], d[:, 2, 0, 2] = wz, wy
    d[:, 2, 1, 0], d[:, 2, 1, 2] = -wz, -wx
    d[:, 2, 2, 2], d[:, 2, 2, 5] = -inv, inv
    return d_force, d


def _expectation_parts(post: Posterior, idx: NDArray[np.int64], dt: float, gravity: float
                       ) -> tuple[Array, Array, Array, Array]:
    """The regressor's state derivatives and the smoothed joint covariances they meet, per
    used transition idx (K,): d_force (K, 3, 12), sig_f (K, 12, 12) of (Theta_k, v_k,
    v_{k+1}, Theta_{k+1}); d_torque (K, 3, 3, 6), sig_w (K, 6, 6) of (omega_k,
    omega_{k+1})."""
    x_now, x_next = post.mean[idx], post.mean[idx + 1]
    d_force, d_torque = _regressor_jacobian(x_now, x_next, dt, gravity)
    p_now, p_next, cross = post.cov[idx], post.cov[idx + 1], post.cross_cov[idx]
    # cross = Cov(x_{k+1}, x_k): rows of x_k in (Theta_k, v_k), of x_{k+1} in
    # (v_{k+1}, Theta_{k+1})
    now = np.r_[6:9, 3:6]
    nxt = np.r_[3:6, 6:9]
    sig_f = np.empty((idx.size, 12, 12))
    sig_f[:, 0:6, 0:6] = p_now[:, now[:, None], now]
    sig_f[:, 6:12, 6:12] = p_next[:, nxt[:, None], nxt]
    sig_f[:, 6:12, 0:6] = cross[:, nxt[:, None], now]
    sig_f[:, 0:6, 6:12] = np.transpose(sig_f[:, 6:12, 0:6], (0, 2, 1))
    sig_w = np.empty((idx.size, 6, 6))
    sig_w[:, 0:3, 0:3] = p_now[:, 9:12, 9:12]
    sig_w[:, 3:6, 0:3] = cross[:, 9:12, 9:12]
    sig_w[:, 0:3, 3:6] = np.transpose(cross[:, 9:12, 9:12], (0, 2, 1))
    sig_w[:, 3:6, 3:6] = p_next[:, 9:12, 9:12]
    return d_force, sig_f, d_torque, sig_w


def regressor_stats(post: Posterior, obs: Observations, gravity: float) -> RegressorStats:
    """Expected sufficient statistics of the wrench residuals over used transitions, with
    the applied force of ``applied_force`` (turned with the interval's mean rotation when
    ``obs.continuous``). Discovery's residuals take tau from here too, so on a continuous
    flight their force rows are the E-step's and the selection's sampling nuisance
    (``pinquad.discovery.residuals.sampling_columns``) fits only what that leaves; their
    covariance part (``covariance_terms``) is A's alone, without the b and c terms of
    the attitude-dependent force (first order in the attitude's smoothed uncertainty)."""
    cont = bool(obs.continuous)
    use = transition_mask(obs)
    idx = np.flatnonzero(use)
    x_now, x_next = post.mean[idx], post.mean[idx + 1]
    dt = obs.dt
    y = body_regressor(x_now, x_next, dt, gravity)
    tau = np.zeros((idx.size, 6))
    tau[:, 0:3], d_applied = applied_force(x_now, x_next, obs.inputs[idx, 0], cont)
    tau[:, 3:6] = obs.inputs[idx, 1:4]
    d_force, sig_f, d_torque, sig_w = _expectation_parts(post, idx, dt, gravity)
    a = np.einsum("kaq,kap->apq", y, y)
    a[0:3, 0, 0] += np.einsum("kai,kij,kaj->a", d_force, sig_f, d_force, optimize=True)
    a[3:6, 1:4, 1:4] += np.einsum("kpai,kij,kqaj->apq", d_torque, sig_w, d_torque,
                                  optimize=True)
    b = np.einsum("kap,ka->ap", y, tau)
    c = np.einsum("ka,ka->a", tau, tau)
    if d_applied is not None:
        b[0:3, 0] += np.einsum("kai,kij,kaj->a", d_force, sig_f, d_applied, optimize=True)
        c[0:3] += np.einsum("kai,kij,kaj->a", d_applied, sig_f, d_applied, optimize=True)
    return RegressorStats(y, tau, a, b, c, int(idx.size))


def covariance_terms(post: Posterior, obs: Observations, gravity: float) -> Array:
    """(K, 6, 4, 4) the posterior-covariance part of E[Y_k^T Y_k] per row of each used
    transition k (``transition_mask``): d_j Sigma_k d_j^T of ``regressor_stats``, not
    summed, so that sums over any set of transitions (discovery's blocks) need no second
    pass. ``regressor_stats(...).a`` = sum_k (Y_k^T Y_k + covariance_terms_k)."""
    idx = np.flatnonzero(transition_mask(obs))
    d_force, sig_f, d_torque, sig_w = _expectation_parts(post, idx, obs.dt, gravity)
    out = np.zeros((idx.size, 6, 4, 4))
    out[:, 0:3, 0, 0] = np.einsum("kai,kij,kaj->ka", d_force, sig_f, d_force, optimize=True)
    out[:, 3:6, 1:4, 1:4] = np.einsum("kpai,kij,kqaj->kapq", d_torque, sig_w, d_torque,
                                      optimize=True)
    return out


def expected_quadratics(post: Posterior, obs: Observations, gravity: float):
    """The a, b, c, n of ``regressor_stats`` (what the M-step needs of it): the compiled
    ``pinquad.mstep.compiled.regressor_quadratics`` (equal up to rounding; it skips the
    per-transition arrays)."""
    return compiled.regressor_quadratics(post, obs, gravity)


def _row_sums(stats, pi: Array) -> Array:
    """E[sum_k rho_kj^2] for each of the 6 rows."""
    return np.einsum("p,apq,q->a", pi, stats.a, pi) - 2.0 * stats.b @ pi + stats.c


@dataclass(frozen=True)
class MStepResult:
    """New parameters and what the M-step knows about them.

    theta: updated parameters; objective: J(pi) at the optimum (per transition);
    wrench_var (6,): profiled wrench residual variances S_j / dt per row.
    """

    theta: Theta
    objective: float
    wrench_var: Array


def _inertia_newton(mass: float, a_t: Array, b_t: Array, c_t: Array, previous: Array,
                    lo: Array | None = None, hi: Array | None = None) -> Array:
    """Minimise J(I) = 1/2 sum_j log q_j(I) - sum_i log I_i over diagonal inertias.

    q_j(I) = pi^T A_j pi - 2 b_j^T pi + c_j with pi = [m, I]; gradient
    g = 1/2 sum_j q_j'/q_j - 1/I and Hessian H = 1/2 sum_j (2 A_j/q_j - q_j' q_j'^T/q_j^2)
    + diag(1/I^2). Damped Newton from the better of the previous inertia and the
    unweighted least-squares solution, with backtracking that keeps the inertia
    physically consistent (positive, triangle inequalities) and inside the box lo <= I <=
    hi [kg m^2] (each trial point projected onto it, Armijo's test on the projected
    step; None: no box). For noise-free data the least-squares solution makes every q_j
    vanish and is returned as is.
    """
    lo = np.zeros(3) if lo is None else np.asarray(lo, dtype=float)
    hi = np.full(3, np.inf) if hi is None else np.asarray(hi, dtype=float)
    def parts(i_diag: Array) -> tuple[float, Array, Array]:
        pi = np.concatenate([[mass], i_diag])
        q = np.einsum("p,apq,q->a", pi, a_t, pi) - 2.0 * b_t @ pi + c_t
        if np.any(q <= 0):
            return np.inf, np.zeros(3), np.eye(3)
        dq = (2.0 * np.einsum("apq,q->ap", a_t, pi) - 2.0 * b_t)[:, 1:4]
        val = 0.5 * float(np.sum(np.log(q))) - float(np.sum(np.log(i_diag)))
        grad = 0.5 * np.sum(dq / q[:, None], axis=0) - 1.0 / i_diag
        hess = (0.5 * np.einsum("apq,a->pq", 2.0 * a_t[:, 1:4, 1:4], 1.0 / q)
                - 0.5 * np.einsum("ap,aq,a->pq", dq, dq, 1.0 / q**2) + np.diag(1.0 / i_diag**2))
        return val, grad, hess

    a_sum = a_t[:, 1:4, 1:4].sum(axis=0)
    rhs = (b_t[:, 1:4] - a_t[:, 1:4, 0] * mass).sum(axis=0)
    candidates = [np.clip(np.asarray(previous, dtype=float), lo, hi)]
    try:
        i_ls = np.linalg.solve(a_sum, rhs)
        if compiled.physical(np.asarray(i_ls, dtype=float)) and np.all((lo <= i_ls) & (i_ls <= hi)):
            pi_ls = np.concatenate([[mass], i_ls])
            q_ls = np.einsum("p,apq,q->a", pi_ls, a_t, pi_ls) - 2.0 * b_t @ pi_ls + c_t
            if np.all(q_ls <= 1e-12 * c_t):
                return i_ls
            candidates.append(i_ls)
    except np.linalg.LinAlgError:
        pass
    candidates = ([c for c in candidates if compiled.physical(np.asarray(c, dtype=float))]
                  or [np.clip(np.full(3, np.mean(previous)), lo, hi)])
    current = min(candidates, key=lambda c: parts(c)[0])
    val, grad, hess = parts(current)
    for _ in range(100):
        # projected Newton: entries on the box's edge pushed outwards are held there
        active = ((current >= hi) & (grad < 0)) | ((current <= lo) & (grad > 0))
        h_free, g_free = hess, grad
        if active.any():
            h_free, g_free = hess.copy(), np.where(active, 0.0, grad)
            h_free[active, :] = 0.0
            h_free[:, active] = 0.0
            h_free[active, active] = 1.0
        try:
            step = -np.linalg.solve(h_free, g_free)
            if grad @ step >= 0:  # not a descent direction: fall back to gradient
                step = np.where(active, 0.0, -grad * float(np.min(current)) ** 2)
        except np.linalg.LinAlgError:
            step = np.where(active, 0.0, -grad * float(np.min(current)) ** 2)
        if grad @ step == 0.0:  # every entry held on the edge: a constrained minimum
            break
        t = 1.0
        while t > 1e-12:
            trial = current + t * step
            moved = t * (grad @ step)
            if np.any((trial < lo) | (trial > hi)):
                trial = np.clip(trial, lo, hi)
                moved = grad @ (trial - current)
            if compiled.physical(np.asarray(trial, dtype=float)):
                v_new = parts(trial)[0]
                if v_new <= val + 1e-4 * moved:
                    break
            t *= 0.5
        else:
            break
        rel = float(np.max(np.abs(trial - current) / current))
        current = trial
        val, grad, hess = parts(current)
        if rel < 1e-12:
            break
    return current


def inertia_newton(mass: float, a_t: Array, b_t: Array, c_t: Array, previous: Array,
                   lo: Array | None = None, hi: Array | None = None) -> Array:
    """``_inertia_newton``, compiled (``pinquad.mstep.compiled.inertia_newton``: the same
    algorithm, so the same minimiser up to rounding, in ~1 % of the time)."""
    return compiled.inertia_newton(float(mass), np.ascontiguousarray(a_t, dtype=float),
                    np.ascontiguousarray(b_t, dtype=float), np.ascontiguousarray(c_t, dtype=float),
                    np.array(previous, dtype=float),
                    np.zeros(3) if lo is None else np.array(lo, dtype=float),
                    np.full(3, np.inf) if hi is None else np.array(hi, dtype=float))


def _inertia_from_d(d: Array) -> Array:
    return np.array([d[1] + d[2], d[0] + d[2], d[0] + d[1]])


def _d_from_inertia(i_diag: Array) -> Array:
    half = 0.5 * np.sum(i_diag)
    d = half - np.asarray(i_diag)
    return np.maximum(d, 1e-6 * half)




def remember_leaving(earlier: QuadraticSums | None, post: Posterior, obs: Observations,
                     n_left: int, gravity: float, memory_s: float) -> QuadraticSums | None:
    """The online estimator's memory after its window slid by ``n_left`` samples:

        S <- exp(-n_left dt / memory_s) S + (sums over transitions 0 .. n_left-1 of
                                              ``obs``, with ``post``'s moments)

    ``post``, ``obs``: the previous window's posterior and observations (the last ones
    in which the leaving samples were smoothed); memory_s [s]: time constant of the
    forgetting (inf: keep every transition, incremental EM in the sense of Neal and
    Hinton 1998). Transitions excluded in ``obs`` stay excluded."""
    n_left = min(n_left, obs.n - 1)
    if n_left <= 0:
        return earlier
    leaving = np.ones(obs.n, dtype=bool)
    leaving[:n_left] = False
    left = QuadraticSums.of(expected_quadratics(
        post, replace(obs, exclude=(obs.exclude if obs.exclude.size else False) | leaving),
        gravity))
    if earlier is None:
        return left
    return earlier.scaled(math.exp(-n_left * obs.dt / memory_s)).plus(left)


def closed_form_mass(stats, fallback: float) -> float:
    """The M-step's mass [kg] when only the body-z force row carries an applied force
    (b_x = c_x = b_y = c_y = 0, a held thrust): the x and y rows cancel against two of
    the three log m terms, the z row gives

        m = c_z / b_z = sum F^2 / sum E[a_z] F

    (``fallback`` when b_z <= 0, e.g. no used transition)."""
    return float(stats.c[2] / stats.b[2, 0]) if stats.b[2, 0] > 0 else fallback


def profiled_mass(stats, fallback: float) -> float:
    """The mass [kg] at the minimum of the force rows' part of J,

        J(m) = 1/2 sum_{j=x,y,z} log q_j(m) - 3 log m,   q_j = a_j m^2 - 2 b_j m + c_j,

    (a_j = A_j[0, 0]; the torque rows do not involve m) that descent reaches from the
    closed form m0 = ``closed_form_mass``, within a factor 2 of it: the first sign change
    of g(m) = m J'(m) = sum_j (a_j m^2 - b_j m) / q_j - 3 on 1 % steps downhill from m0,
    refined by Brent's method (the end of the range if there is none). m0 itself when
    the x and y rows carry no applied force (then it is the minimiser) or b_z <= 0
    (``fallback``). Why local: the body-z row alone fixes the mass; x and y only nudge
    it, and rows whose residual does not scale with m (no lateral acceleration) would
    pull a global search off along -3 log m."""
    m0 = closed_form_mass(stats, fallback)
    a, b, c = stats.a[0:3, 0, 0], stats.b[0:3, 0], stats.c[0:3]
    if stats.b[2, 0] <= 0 or not (np.any(b[0:2]) or np.any(c[0:2])):
        return m0

    def g(m: float) -> float:
        q = a * m * m - 2.0 * b * m + c
        return float(np.sum((a * m * m - b * m) / q)) - 3.0

    g0 = g(m0)
    if g0 == 0.0:
        return m0
    factor = 1.01 if g0 < 0.0 else 1.0 / 1.01
    near = m0
    while 0.5 * m0 <= near * factor <= 2.0 * m0:
        far = near * factor
        if (g(far) > 0.0) == (g0 < 0.0):
            return float(brentq(g, min(near, far), max(near, far), xtol=1e-15 * m0,
                                rtol=4 * np.finfo(float).eps))
        near = far
    return near


def regressor_mstep(post: Posterior, obs: Observations, theta: Theta,
                    earlier: QuadraticSums | None = None, *,
                    stats: QuadraticSums | None = None,
                    bounds: VehicleRange | None = None) -> MStepResult:
    """Joint ML update of mass, diagonal inertia and all noise variances (see module).

    ``earlier``: statistics of transitions no longer in ``obs`` (the online estimator's
    memory of samples that left its window), added to this posterior's for mass and
    inertia and the wrench noise; the measurement variances stay this posterior's own.
    ``stats``: ``expected_quadratics(post, obs, theta.gravity)`` when the caller has
    computed it already (discovery's effect M-step needs it too), else computed here.
    ``bounds``: the vehicle's plausible range; mass and inertia are maximised inside it
    (the mass's minimiser projected onto its interval, the inertia by projected Newton),
    so EM cannot leave it (None: positivity and the triangle inequalities only)."""
    if stats is None:
        stats = expected_quadratics(post, obs, theta.gravity)
    if earlier is not None:
        stats = QuadraticSums.of(stats).plus(earlier)
    n = stats.n
    mass = profiled_mass(stats, theta.mass)
    if bounds is not None:
        mass = bounds.clip_mass(mass)

    a_t, b_t, c_t = stats.a[3:6], stats.b[3:6], stats.c[3:6]
    inertia = inertia_newton(mass, a_t, b_t, c_t, np.diag(theta.inertia),
                             *(() if bounds is None else (bounds.inertia_lo, bounds.inertia_hi)))
    pi = np.concatenate([[mass], inertia])
    row_var = np.maximum(_row_sums(stats, pi) / n, 0.0)
    noise = update_noise(post, obs, theta, row_var)
    new = Theta(mass=mass, inertia=np.diag(inertia), noise=noise, gravity=theta.gravity)
    q = np.maximum(_row_sums(stats, pi), 1e-300)
    objective = float(0.5 * np.sum(np.log(q)) - 3.0 * np.log(mass) - np.sum(np.log(inertia)))
    return MStepResult(new, objective, row_var)


def update_noise(post: Posterior, obs: Observations, theta: Theta, wrench_row_var: Array
                 ) -> NoiseModel:
    """ML noise variances: S = dt E[rho rho^T] (diag), measurement variances
    r_i = mean over observed rows of (y - H m)^2 + (H P H^T)_ii, and kinematic
    variances of the position and Euler rows of the transition residual."""
    dt = obs.dt
    floor_f = 1e-6 * max(wrench_row_var[2], 1e-30)
    floor_t = 1e-6 * max(wrench_row_var[3:6].max(), 1e-30)
    wrench = dt * wrench_row_var
    wrench[0:3] = np.maximum(wrench[0:3], dt * floor_f)
    wrench[3:6] = np.maximum(wrench[3:6], dt * floor_t)
    meas = compiled.measurement_variances(post, obs, theta.noise.meas)
    q_kin = kinematic_floor(dt)
    return NoiseModel(wrench=wrench, q_kin=q_kin, meas=meas, fixed_q=None)




def measurement_variances(post: Posterior, obs: Observations, previous: Array) -> Array:
    """r_i = mean_k [(y_ki - m_k,s(i))^2 + P_k,s(i)s(i)] over steps where row i is observed
    (and not rejected as an outlier), floored at 1e-12."""
    h = obs.measurement_matrix()
    state_idx = np.argmax(h, axis=1)
    pred = post.mean[:, state_idx]
    var = post.cov[:, state_idx, state_idx]
    res = obs.ys - pred
    angle = obs.angle_rows()
    if angle.size:
        res[:, angle] = wrap_angle(res[:, angle])
    ok = ~np.isnan(obs.ys) & ~post.rejected
    out = np.array(previous, dtype=float)
    for i in range(obs.ys.shape[1]):
        if ok[:, i].any():
            out[i] = max(float(np.mean(res[ok[:, i], i] ** 2 + var[ok[:, i], i])), 1e-12)
    return out


def paper_mstep(post: Posterior, obs: Observations, theta: Theta) -> MStepResult:
    """The paper's closed-form updates from the smoothed means (noise kept fixed):

        m    = sum (r F)^2 dt / sum [r F g dt + (v_z,k - v_z,k-1) r F],  r = cos(phi) cos(theta)
        I_xx = sum (M_x + (I_yy - I_zz) w_y w_z)^2 dt
               / sum (w_x,k - w_x,k-1)(M_x + (I_yy - I_zz) w_y w_z)     (and cyclic)

    with the other two inertias at their current values.
    """
    use = np.flatnonzero(transition_mask(obs))
    mu0, mu1 = post.mean[use], post.mean[use + 1]
    dt = obs.dt
    g = theta.gravity
    u = obs.inputs[use]
    r = np.cos(mu0[:, 6]) * np.cos(mu0[:, 7])
    rf = r * u[:, 0]
    den = np.sum(rf * g * dt + (mu1[:, 5] - mu0[:, 5]) * rf)
    mass = float(np.sum(rf**2) * dt / den) if den > 0 else theta.mass
    i_old = np.diag(theta.inertia).copy()
    w = mu0[:, 9:12]
    dw = mu1[:, 9:12] - mu0[:, 9:12]
    new_i = i_old.copy()
    for ax, (b, c) in enumerate(((1, 2), (2, 0), (0, 1))):
        term = u[:, 1 + ax] + (i_old[b] - i_old[c]) * w[:, b] * w[:, c]
        den_i = float(np.sum(dw[:, ax] * term))
        if den_i > 0:
            new_i[ax] = float(np.sum(term**2) * dt / den_i)
    new = Theta(mass=mass, inertia=np.diag(new_i), noise=theta.noise, gravity=theta.gravity)
    return MStepResult(new, float("nan"), np.full(6, np.nan))


def state_index(channel: str) -> slice:
    """The state rows a measurement channel observes."""
    return CHANNEL_SLICES[channel]


def relative_change(a: Theta, b: Theta) -> float:
    """max relative change of mass and inertia diagonal between two parameter sets."""
    pa = np.concatenate([[a.mass], np.diag(a.inertia)])
    pb = np.concatenate([[b.mass], np.diag(b.inertia)])
    return float(np.max(np.abs(pa - pb) / np.maximum(np.abs(pb), 1e-300)))


def log10_safe(x: float) -> float:
    return math.log10(x) if x > 0 else float("-inf")
