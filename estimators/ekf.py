"""Extended Kalman filter over a :class:`~estimators.protocol.StateSpaceModel`.

Predict:  m^-_{k+1} = f_k(m_k),  P^-_{k+1} = F_k P_k F_k^T + Q_k,  F_k = df_k/dx (m_k)
Update (observed rows o of y_k only):
          nu = y_k[o] - h_k(m^-_k)[o],  S = H[o] P^- H[o]^T + R[o, o]
          K = P^- H[o]^T S^{-1},  m_k = m^- + K nu,  P_k = (I - K H[o]) P^- (I - K H[o])^T
              + K R[o, o] K^T   (Joseph form, keeps P symmetric positive definite)
Log-likelihood: sum_k log N(nu_k; 0, S_k).

Missing samples (NaN) simply have no rows. An optional gate drops a row whose
normalised innovation |nu_i| / sqrt(S_ii) exceeds ``gate_sigma`` (outliers), and the
row is reported in ``rejected``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Array, FilterResult, StateSpaceModel

_LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class UpdateResult:
    """One measurement update: posterior mean (n,), cov (n, n); quad = nu^T S^{-1} nu;
    logdet = log det S; used (rows used) and rejected (rows gated) index arrays."""

    mean: Array
    cov: Array
    quad: float
    logdet: float
    used: NDArray[np.int64]
    rejected: NDArray[np.int64]

    @property
    def loglik(self) -> float:
        """log N(nu; 0, S) of this update [nats] (0 when nothing was used)."""
        if self.used.size == 0:
            return 0.0
        return -0.5 * (self.quad + self.logdet + self.used.size * _LOG_2PI)


def update(model: StateSpaceModel, k: int, mean: Array, cov: Array, y: Array,
           gate_sigma: float | None = None) -> UpdateResult:
    """Condition (mean, cov) of x_k on the observed (non-NaN) rows of y_k."""
    obs = ~np.isnan(y)
    none = np.zeros(0, dtype=np.int64)
    if not obs.any():
        return UpdateResult(mean, cov, 0.0, 0.0, none, none)
    y_pred, h_full = model.measure(mean, k)
    r_full = model.meas_cov(k)
    nu_full = model.residual(np.where(obs, y, y_pred), y_pred)
    idx = np.flatnonzero(obs)
    h = h_full[idx]
    ph_t = cov @ h.T
    r_used = r_full[idx[:, None], idx]
    s = h @ ph_t + r_used
    nu = nu_full[idx]
    rejected = none
    if gate_sigma is not None:
        keep = np.abs(nu) <= gate_sigma * np.sqrt(np.diag(s))
        if not keep.all():
            rejected = idx[~keep]
            idx, h, nu = idx[keep], h[keep], nu[keep]
            ph_t = ph_t[:, keep]
            s = s[np.ix_(keep, keep)]
            r_used = r_used[np.ix_(keep, keep)]
    if idx.size == 0:
        return UpdateResult(mean, cov, 0.0, 0.0, idx, rejected)
    chol = np.linalg.cholesky(s)
    white = np.linalg.solve(chol, nu)
    gain_t = np.linalg.solve(chol.T, np.linalg.solve(chol, ph_t.T))
    new_mean = mean + gain_t.T @ nu
    a = np.eye(mean.shape[0]) - gain_t.T @ h
    new_cov = a @ cov @ a.T + gain_t.T @ r_used @ gain_t
    new_cov = 0.5 * (new_cov + new_cov.T)
    return UpdateResult(new_mean, new_cov, float(white @ white),
                        2.0 * float(np.log(np.diag(chol)).sum()), idx, rejected)


def predict(model: StateSpaceModel, k: int, mean: Array, cov: Array
            ) -> tuple[Array, Array, Array]:
    """Propagate (mean, cov) of x_k to x_{k+1}; returns mean, cov and df_k/dx."""
    q = model.process_cov(mean, k)
    new_mean, jac = model.transition(mean, k)
    new_cov = jac @ cov @ jac.T + q
    return new_mean, 0.5 * (new_cov + new_cov.T), jac


def run_filter(model: StateSpaceModel, ys: Array, gate_sigma: float | None = None
               ) -> FilterResult:
    """Run the EKF over measurements ys (N, m) (NaN = not observed)."""
    ys = np.asarray(ys, dtype=float)
    n_steps, meas_dim = ys.shape
    n = model.state_dim
    f_mean = np.empty((n_steps, n))
    f_cov = np.empty((n_steps, n, n))
    p_mean = np.empty((n_steps, n))
    p_cov = np.empty((n_steps, n, n))
    jacs = np.empty((max(n_steps - 1, 0), n, n))
    nis = np.full(n_steps, np.nan)
    dof = np.zeros(n_steps, dtype=np.int64)
    rejected = np.zeros((n_steps, meas_dim), dtype=bool)
    loglik = 0.0
    mean, cov = model.initial()
    mean = np.array(mean, dtype=float)
    cov = np.array(cov, dtype=float)
    for k in range(n_steps):
        p_mean[k] = mean
        p_cov[k] = cov
        upd = update(model, k, mean, cov, ys[k], gate_sigma)
        mean, cov = upd.mean, upd.cov
        rejected[k, upd.rejected] = True
        if upd.used.size:
            nis[k] = upd.quad
            dof[k] = upd.used.size
            loglik += upd.loglik
        f_mean[k] = mean
        f_cov[k] = cov
        if k + 1 < n_steps:
            mean, cov, jacs[k] = predict(model, k, mean, cov)
    return FilterResult(f_mean, f_cov, p_mean, p_cov, jacs, loglik, nis, dof, rejected)
