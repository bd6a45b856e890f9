"""Rauch-Tung-Striebel smoother (Saerkkae, Bayesian Filtering and Smoothing, Thm 8.2 and
its extended form), returning lag-one cross-covariances for EM.

    G_k   = P_k F_k^T (P^-_{k+1})^{-1}
    m^s_k = m_k + G_k (m^s_{k+1} - m^-_{k+1})
    P^s_k = P_k + G_k (P^s_{k+1} - P^-_{k+1}) G_k^T
    Cov(x_{k+1}, x_k | y) = P^s_{k+1} G_k^T
"""

from __future__ import annotations

import numpy as np

from estimators.ekf import run_filter
from estimators.protocol import Array, FilterResult, Posterior, StateSpaceModel


def smooth_filtered(result: FilterResult) -> Posterior:
    """RTS backward pass over a finished forward filter."""
    n_steps, n = result.filtered_mean.shape
    mean = np.empty((n_steps, n))
    cov = np.empty((n_steps, n, n))
    cross = np.empty((max(n_steps - 1, 0), n, n))
    mean[-1] = result.filtered_mean[-1]
    cov[-1] = result.filtered_cov[-1]
    for k in range(n_steps - 2, -1, -1):
        pf = result.filtered_cov[k]
        pp = result.predicted_cov[k + 1]
        # G = P F^T Pp^{-1}  <=>  Pp G^T = F P (Pp symmetric)
        gain = np.linalg.solve(pp, result.transition_jac[k] @ pf).T
        mean[k] = result.filtered_mean[k] + gain @ (mean[k + 1] - result.predicted_mean[k + 1])
        c = pf + gain @ (cov[k + 1] - pp) @ gain.T
        cov[k] = 0.5 * (c + c.T)
        cross[k] = cov[k + 1] @ gain.T
    return Posterior(mean, cov, cross, result.loglik, "rts", result.rejected)


def smooth(model: StateSpaceModel, ys: Array, gate_sigma: float | None = None) -> Posterior:
    """EKF forward pass then RTS backward pass: p(x_k | all y) for every k."""
    return smooth_filtered(run_filter(model, ys, gate_sigma=gate_sigma))
