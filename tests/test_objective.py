"""estimators.objective: the negative log-posterior J(x) = -log p(x, y) on a small linear-
Gaussian model (estimators.linear), against a hand-written gradient, finite differences,
and the exact dense posterior (its mean is the minimiser, and J there equals
1/2 log det(2 pi Sigma_post) - log p(y))."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.linear import LinearGaussianModel, dense_posterior
from estimators.objective import negative_log_posterior


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(4)
    n, m, steps = 3, 2, 12
    a = rng.standard_normal((n, n))
    a *= 0.9 / max(abs(np.linalg.eigvals(a)))
    lq = 0.3 * rng.standard_normal((n, n))
    lr = 0.3 * rng.standard_normal((m, m))
    model = LinearGaussianModel(a=a, c=rng.standard_normal((m, n)),
                                q=lq @ lq.T + 0.1 * np.eye(n), r=lr @ lr.T + 0.2 * np.eye(m),
                                m0=rng.standard_normal(n), p0=0.5 * np.eye(n))
    _, ys = model.simulate(steps, rng)
    ys[3, 0] = np.nan
    ys[7] = np.nan
    return model, ys, rng


def _hand_gradient(model: LinearGaussianModel, ys: np.ndarray, x: np.ndarray) -> np.ndarray:
    """dJ/dx written out factor by factor from the model's matrices."""
    g = np.zeros_like(x)
    g[0] += np.linalg.solve(model.p0, x[0] - model.m0)
    q_inv = np.linalg.inv(model.q)
    for k in range(x.shape[0] - 1):
        r = q_inv @ (x[k + 1] - model.a @ x[k])
        g[k + 1] += r
        g[k] -= model.a.T @ r
    for k in range(x.shape[0]):
        o = np.flatnonzero(~np.isnan(ys[k]))
        if o.size:
            c_o = model.c[o]
            g[k] -= c_o.T @ np.linalg.solve(model.r[np.ix_(o, o)], ys[k, o] - c_o @ x[k])
    return g


def _fd_gradient(model, ys, x, h=1e-5):
    g = np.zeros_like(x)
    for idx in np.ndindex(*x.shape):
        e = np.zeros_like(x)
        e[idx] = h
        g[idx] = (negative_log_posterior(model, ys, x + e)
                  - negative_log_posterior(model, ys, x - e)) / (2 * h)
    return g


def test_gradient_matches_hand_derivation_and_finite_differences(case):
    model, ys, rng = case
    x = rng.standard_normal((ys.shape[0], model.state_dim))
    fd = _fd_gradient(model, ys, x)
    hand = _hand_gradient(model, ys, x)
    assert np.max(np.abs(hand)) > 1.0  # away from the optimum: a real gradient
    np.testing.assert_allclose(fd, hand, rtol=1e-5, atol=1e-5)


def test_minimum_is_the_dense_posterior_mean_with_the_exact_value(case):
    model, ys, rng = case
    dense = dense_posterior(model, ys)
    mean = dense.mean
    np.testing.assert_allclose(_fd_gradient(model, ys, mean), 0.0, atol=1e-6)
    j_mean = negative_log_posterior(model, ys, mean)
    # -log p(x*, y) = -log p(x* | y) - log p(y), and p(x* | y) is the Gaussian peak.
    _, logdet = np.linalg.slogdet(2 * math.pi * dense.joint_cov)
    assert j_mean == pytest.approx(0.5 * logdet - dense.loglik, rel=1e-8, abs=1e-8)
    for _ in range(5):
        step = 0.05 * rng.standard_normal(mean.shape)
        assert negative_log_posterior(model, ys, mean + step) > j_mean
    # Quadratic in x: J(x* + d) - J(x*) = 1/2 d^T Sigma_post^{-1} d.
    d = 0.1 * rng.standard_normal(mean.shape)
    expect = 0.5 * d.ravel() @ np.linalg.solve(dense.joint_cov, d.ravel())
    assert negative_log_posterior(model, ys, mean + d) - j_mean == pytest.approx(expect,
                                                                                 rel=1e-6)


def test_rejected_rows_drop_out_of_the_objective(case):
    model, ys, _ = case
    x = np.zeros((ys.shape[0], model.state_dim))
    rejected = np.zeros(ys.shape, bool)
    rejected[2] = True
    dropped = ys.copy()
    dropped[2] = np.nan
    assert negative_log_posterior(model, ys, x, rejected=rejected) == pytest.approx(
        negative_log_posterior(model, dropped, x), rel=1e-12)
    assert negative_log_posterior(model, ys, x) != pytest.approx(
        negative_log_posterior(model, dropped, x), rel=1e-6)
