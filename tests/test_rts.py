"""EKF and RTS against the dense joint Gaussian posterior of a linear model."""

from __future__ import annotations

import numpy as np

from estimators.ekf import run_filter
from estimators.linear import dense_posterior
from estimators.rts import smooth


def test_rts_equals_dense_posterior(linear_case):
    model, ys = linear_case
    post = smooth(model, ys)
    dense = dense_posterior(model, ys)
    n = model.state_dim
    np.testing.assert_allclose(post.mean, dense.mean, rtol=1e-9, atol=1e-9)
    for k in range(ys.shape[0]):
        np.testing.assert_allclose(post.cov[k], dense.block(k, k), rtol=1e-8, atol=1e-10)
    for k in range(ys.shape[0] - 1):
        np.testing.assert_allclose(post.cross_cov[k], dense.block(k + 1, k), rtol=1e-8,
                                   atol=1e-10)
    assert abs(post.loglik - dense.loglik) < 1e-8 * abs(dense.loglik)
    assert post.mean.shape == (ys.shape[0], n)


def test_filter_last_step_equals_dense_marginal(linear_case):
    model, ys = linear_case
    res = run_filter(model, ys)
    dense = dense_posterior(model, ys)
    np.testing.assert_allclose(res.filtered_mean[-1], dense.mean[-1], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(res.filtered_cov[-1], dense.block(ys.shape[0] - 1, ys.shape[0] - 1),
                               rtol=1e-8, atol=1e-10)


def test_gate_rejects_a_gross_outlier(linear_case):
    model, ys = linear_case
    ys = ys.copy()
    ys[30] = model.c @ np.zeros(model.state_dim) + 1e3
    res = run_filter(model, ys, gate_sigma=6.0)
    assert res.rejected[30].all()
    assert res.rejected.sum() == model.meas_dim
