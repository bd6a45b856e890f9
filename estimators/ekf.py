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

import numpy as np

from estimators.protocol import Array, FilterResult, StateSpaceModel

_LOG_2PI = math.log(2.0 * math.pi)


def run_filter(model: StateSpaceModel, ys: Array, gate_sigma: float | None = None
               ) -> FilterResult:
    """Run the EKF over measurements ys (N, m) (NaN = not observed)."""
    ys = np.asarray(ys, dtype=float)
    n_steps, meas_dim = ys.shape
    n = model.state_dim
    eye = np.eye(n)
    f_mean = np.empty((n_steps, n))
    f_cov = np.empty((n_steps, n, n))
    p_mean = np.empty((n_steps, n))
    p_cov = np.empty((n_steps, n, n))
    jacs = np.empty((max(n_steps - 1, 0), n, n))
    nis = np.full(n_steps, np.nan)
    dof = np.zeros(n_steps, dtype=np.int64)
    rejected = np.zeros((n_steps, meas_dim), dtype=bool)
    observed_all = ~np.isnan(ys)
    loglik = 0.0

    mean, cov = model.initial()
    mean = np.array(mean, dtype=float)
    cov = np.array(cov, dtype=float)
    for k in range(n_steps):
        p_mean[k] = mean
        p_cov[k] = cov
        obs = observed_all[k]
        if obs.any():
            y_pred, h_full = model.measure(mean, k)
            r_full = model.meas_cov(k)
            nu_full = model.residual(np.where(obs, ys[k], y_pred), y_pred)
            idx = np.flatnonzero(obs)
            h = h_full[idx]
            ph_t = cov @ h.T
            s = h @ ph_t + r_full[np.ix_(idx, idx)]
            nu = nu_full[idx]
            if gate_sigma is not None:
                z = np.abs(nu) / np.sqrt(np.diag(s))
                keep = z <= gate_sigma
                if not keep.all():
                    rejected[k, idx[~keep]] = True
                    idx, h, nu = idx[keep], h[keep], nu[keep]
                    ph_t = ph_t[:, keep]
                    s = s[np.ix_(keep, keep)]
            if idx.size:
                chol = np.linalg.cholesky(s)
                white = np.linalg.solve(chol, nu)
                gain_t = np.linalg.solve(chol.T, np.linalg.solve(chol, ph_t.T))
                mean = mean + gain_t.T @ nu
                a = eye - gain_t.T @ h
                cov = a @ cov @ a.T + gain_t.T @ r_full[np.ix_(idx, idx)] @ gain_t
                cov = 0.5 * (cov + cov.T)
                quad = float(white @ white)
                nis[k] = quad
                dof[k] = idx.size
                loglik -= 0.5 * (quad + 2.0 * float(np.log(np.diag(chol)).sum())
                                 + idx.size * _LOG_2PI)
        f_mean[k] = mean
        f_cov[k] = cov
        if k + 1 < n_steps:
            q = model.process_cov(mean, k)
            mean, jac = model.transition(mean, k)
            jacs[k] = jac
            cov = jac @ cov @ jac.T + q
            cov = 0.5 * (cov + cov.T)
    return FilterResult(f_mean, f_cov, p_mean, p_cov, jacs, loglik, nis, dof, rejected)
