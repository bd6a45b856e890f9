"""The negative log-posterior of a trajectory under a
:class:`~estimators.protocol.StateSpaceModel`, and its whitened linearisation: the
objective shared by the GTSAM batch smoother (``estimators.factor_graph``) and the
iterated EKF + RTS smoother (``estimators.iterated``).

Each factor is a residual r with covariance Sigma = L L^T (L lower Cholesky factor):

    prior        r_0   = x_0 - m_0                            Sigma = P_0
    transition   r^f_k = x_{k+1} - f_k(x_k)                   Sigma = Q_k(x_k), k < N-1
    measurement  r^h_k = residual(y_k, h_k(x_k))[o_k]         Sigma = R_k[o_k, o_k]

where o_k are the observed rows of y_k not flagged as rejected, and

    J(x) = sum over factors of 1/2 ||L^{-1} r||^2 + 1/2 log det(2 pi Sigma)
         = -log p(x_0..N-1, y_obs | theta)      [nats].

No GTSAM here: this module is NumPy only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Array, StateSpaceModel

_LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class MeasurementWhitening:
    """Whitening of the measurement factors, fixed for one smoothing call (R_k does not
    depend on x). One group per distinct pattern of used rows: steps (K,), rows (o,),
    inv_chol (K, o, o) = L^{-1} with L L^T = R_k[rows, rows]; logdet_const: the sum of
    1/2 log det(2 pi R_k[o_k, o_k]) over all measurement factors."""

    groups: tuple[tuple[NDArray[np.intp], NDArray[np.intp], Array], ...]
    logdet_const: float


@dataclass(frozen=True)
class Linearisation:
    """Every whitened factor at one trajectory (see the module docstring).

    prior_a (n, n), prior_b (n,); trans_prev (N-1, n, n) = -L^{-1} F_k,
    trans_next (N-1, n, n) = L^{-1}, trans_b (N-1, n) = -L^{-1} r^f_k;
    meas: (k, A (o, n), b (o,)) per step with used rows; half_sq: 1/2 of the sum of all
    squared whitened residuals; cost: J = half_sq + the log-det constants.
    """

    prior_a: Array
    prior_b: Array
    trans_prev: Array
    trans_next: Array
    trans_b: Array
    meas: list[tuple[int, Array, Array]]
    half_sq: float
    cost: float


def chol_inv(covs: Array, what: str, steps: Sequence[int]) -> tuple[Array, Array]:
    """Batched L^{-1} and log det for a stack of covariances (K, d, d); names the first
    step whose covariance is not positive definite instead of a bare LinAlgError."""
    try:
        chol = np.linalg.cholesky(covs)
    except np.linalg.LinAlgError:
        for j, cov in enumerate(covs):
            if not np.all(np.isfinite(cov)) or np.any(np.linalg.eigvalsh(
                    0.5 * (cov + cov.T)) <= 0.0):
                raise ValueError(
                    f"{what} at step {steps[j]} is not positive definite; the factor graph "
                    f"whitens by its Cholesky factor (add a small jitter to a degenerate "
                    f"covariance)") from None
        raise
    inv = np.linalg.inv(chol)
    logdet = 2.0 * np.log(np.einsum("kii->ki", chol)).sum(axis=1)
    return inv, logdet


def used_rows(ys: Array, rejected: Array | None) -> Array:
    used = ~np.isnan(ys)
    if rejected is not None:
        used &= ~np.asarray(rejected, dtype=bool)
    return used


def whiten_measurements(model: StateSpaceModel, used: Array) -> MeasurementWhitening:
    has_rows = np.flatnonzero(used.any(axis=1))
    if has_rows.size == 0:
        return MeasurementWhitening((), 0.0)
    r_stack = np.stack([np.asarray(model.meas_cov(int(k)), dtype=float) for k in has_rows])
    patterns, which = np.unique(used[has_rows], axis=0, return_inverse=True)
    which = np.asarray(which).reshape(-1)
    groups = []
    logdet_const = 0.0
    for p, pattern in enumerate(patterns):
        members = np.flatnonzero(which == p)
        steps = has_rows[members]
        rows = np.flatnonzero(pattern)
        sub = r_stack[members][:, rows][:, :, rows]
        inv, logdet = chol_inv(sub, "measurement covariance R_k[o, o]", list(steps))
        logdet_const += 0.5 * float(logdet.sum()) + 0.5 * rows.size * steps.size * _LOG_2PI
        groups.append((steps, rows, inv))
    return MeasurementWhitening(tuple(groups), logdet_const)


def linearise(model: StateSpaceModel, ys: Array, traj: Array,
               meas_white: MeasurementWhitening) -> Linearisation:
    """Evaluate and whiten every factor at ``traj`` (N, n); the model is called once per
    step, so the line search's accepted trial doubles as the next linearisation."""
    n_steps, n = traj.shape
    m0, p0 = model.initial()
    p0_inv, p0_logdet = chol_inv(np.asarray(p0, dtype=float)[None], "prior covariance P_0",
                                  [0])
    prior_a = p0_inv[0]
    prior_b = -prior_a @ (traj[0] - np.asarray(m0, dtype=float))
    half_sq = 0.5 * float(prior_b @ prior_b)
    logdets = 0.5 * float(p0_logdet[0]) + 0.5 * n * _LOG_2PI

    n_trans = n_steps - 1
    f_val = np.empty((n_trans, n))
    f_jac = np.empty((n_trans, n, n))
    q_stack = np.empty((n_trans, n, n))
    for k in range(n_trans):
        x = traj[k]
        q_stack[k] = model.process_cov(x, k)
        f_val[k], f_jac[k] = model.transition(x, k)
    if n_trans:
        q_inv, q_logdet = chol_inv(q_stack, "process covariance Q_k", range(n_trans))
        trans_next = q_inv
        trans_prev = -(q_inv @ f_jac)
        trans_b = -np.einsum("kij,kj->ki", q_inv, traj[1:] - f_val)
        half_sq += 0.5 * float(np.sum(trans_b * trans_b))
        logdets += 0.5 * float(q_logdet.sum()) + 0.5 * n * n_trans * _LOG_2PI
    else:
        trans_next = trans_prev = np.empty((0, n, n))
        trans_b = np.empty((0, n))

    meas: list[tuple[int, Array, Array]] = []
    for steps, rows, inv in meas_white.groups:
        h_jac = np.empty((steps.size, rows.size, n))
        resid = np.empty((steps.size, rows.size))
        for j, k in enumerate(steps):
            y_pred, jac = model.measure(traj[k], int(k))
            # Unused rows get y_pred so that residual() never sees a NaN it might wrap.
            y_full = np.where(np.isnan(ys[k]), y_pred, ys[k])
            resid[j] = model.residual(y_full, y_pred)[rows]
            h_jac[j] = np.asarray(jac)[rows]
        # d residual / dx = -H, so A = L^{-1}(-H) and b = -L^{-1} r as for the other factors.
        a = -(inv @ h_jac)
        b = -np.einsum("kij,kj->ki", inv, resid)
        half_sq += 0.5 * float(np.sum(b * b))
        meas.extend((int(k), a[j], b[j]) for j, k in enumerate(steps))
    cost = half_sq + logdets + meas_white.logdet_const
    return Linearisation(prior_a, prior_b, trans_prev, trans_next, trans_b, meas, half_sq,
                          cost)


def negative_log_posterior(model: StateSpaceModel, ys: Array, trajectory: Array, *,
                           rejected: Array | None = None) -> float:
    """J(x) = -log p(x_0..N-1, y_obs | theta) [nats] at ``trajectory`` (N, n).

    Exactly: the sum over the prior, the N-1 transition factors and the measurement
    factors of 1/2 ||L^{-1} r||^2 + 1/2 log det(2 pi Sigma), with r and Sigma as in the
    module docstring (Q_k evaluated at trajectory[k], measurement residuals through
    ``model.residual`` on the observed rows not flagged in ``rejected`` (N, m)). It equals
    the negative log posterior -log p(x | y, theta) plus log p(y | theta), a constant in
    the trajectory, so it ranks trajectories exactly as the posterior does.
    """
    ys = np.asarray(ys, dtype=float)
    traj = np.asarray(trajectory, dtype=float)
    check_shapes(model, ys, traj)
    white = whiten_measurements(model, used_rows(ys, rejected))
    return linearise(model, ys, traj, white).cost


def check_shapes(model: StateSpaceModel, ys: Array, traj: Array | None) -> None:
    if ys.ndim != 2 or ys.shape[1] != model.meas_dim or ys.shape[0] == 0:
        raise ValueError(f"ys must have shape (N >= 1, {model.meas_dim}), got {ys.shape}")
    if traj is not None:
        if traj.shape != (ys.shape[0], model.state_dim):
            raise ValueError(f"trajectory must have shape {(ys.shape[0], model.state_dim)}, "
                             f"got {traj.shape}")
        if not np.all(np.isfinite(traj)):
            raise ValueError("trajectory contains non-finite values")

