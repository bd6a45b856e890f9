"""The pieces of the effect coefficients' standard errors (pinquad.discovery.uncertainty):
central differences of a log-likelihood and the reported choice between the jackknife
and the information. The whole path runs in test_discovery's gyro-offset refit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinquad.discovery.uncertainty import information_stderr, reported_stderr
from pinquad.identification.em import initial_theta
from pinquad.identification.fisher import central_differences
from pinquad.models.ssm import Observations


@settings(max_examples=25, deadline=None)
@given(st.integers(min_value=1, max_value=5), st.integers(min_value=0, max_value=2**32 - 1))
def test_central_differences_are_exact_on_a_quadratic(n, seed):
    """f(x) = b^T x - (x - a)^T A (x - a) / 2 has gradient b - A (x - a) and Hessian -A;
    central differences of a quadratic are exact up to rounding, at any steps."""
    rng = np.random.default_rng(seed)
    root = rng.normal(size=(n, n))
    a_mat = root @ root.T + n * np.eye(n)
    a, b, x0 = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
    steps = 10.0 ** rng.uniform(-3, 0, size=n)

    def f(x):
        return float(b @ x - 0.5 * (x - a) @ a_mat @ (x - a))

    value, grad, hess = central_differences(f, x0, steps)
    assert value == f(x0)
    np.testing.assert_allclose(grad, b - a_mat @ (x0 - a), rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(hess, -a_mat, rtol=1e-6, atol=1e-6 * np.abs(a_mat).max())


def test_an_evaluation_that_breaks_down_is_nan_in_the_derivatives_it_enters():
    def f(x):
        if x[0] > 0.5:
            raise np.linalg.LinAlgError("not positive definite")
        return float(-x @ x)

    _, grad, hess = central_differences(f, np.zeros(2), np.array([1.0, 1.0]))
    assert np.isnan(grad[0]) and np.isnan(hess[0, 0]) and np.isnan(hess[0, 1])
    assert grad[1] == 0.0 and hess[1, 1] == -2.0


def test_the_reported_error_is_the_larger_and_the_jackknife_without_information():
    jack = {"drag": np.array([1e-5, 2e-5, 3e-4]), "wind": np.array([1e-4, 1e-4])}
    info = {"drag": np.array([4e-5, 1e-5, np.nan])}
    out = reported_stderr(jack, info)
    np.testing.assert_array_equal(out["drag"], [4e-5, 2e-5, 3e-4])
    np.testing.assert_array_equal(out["wind"], jack["wind"])


def _tiny_gyro_observations(n: int = 6) -> Observations:
    """n rows of a hover measured by position and gyro (a shape, not a flight)."""
    ys = np.zeros((n, 6))
    return Observations(t=np.arange(n) * 0.01, dt=0.01, inputs=np.tile([0.34, 0, 0, 0], (n, 1)),
                        channels=("pos", "gyro"), ys=ys, x0=np.zeros(12), p0=np.ones(12))


def _quadratic_in_the_offset(curvature: np.ndarray):
    """A log-likelihood -sum(c_i b_i^2) / 2 of the gyro offset b read back from the
    de-biased gyro rows, which corrected_observations shifts by -b."""
    def loglik(model, ys) -> float:
        b = -ys[0, 3:6]
        return float(-0.5 * np.sum(curvature * b**2))
    return loglik


def test_the_information_is_the_curvature_and_a_breakdown_gives_none():
    obs = _tiny_gyro_observations()
    theta = initial_theta(obs, 0.035, np.diag([16.6e-6, 16.7e-6, 29.3e-6]), 9.81)
    offset = {"gyro_bias": np.array([0.03, -0.02, 0.0])}
    jack = {"gyro_bias": np.array([1e-5, 1e-5, 1e-5])}  # the search starts 30-100x low
    curvature = np.array([1e6, 4e6, 2.5e5])  # se 1e-3, 5e-4, 2e-3 rad/s
    se = information_stderr(obs, theta, np.zeros((6, 12)), offset, ["gyro_bias"], jack,
                            loglik=_quadratic_in_the_offset(curvature))
    np.testing.assert_allclose(se["gyro_bias"], 1.0 / np.sqrt(curvature), rtol=1e-6)

    def broken(model, ys) -> float:
        raise np.linalg.LinAlgError("innovation covariance not positive definite")

    se = information_stderr(obs, theta, np.zeros((6, 12)), offset, ["gyro_bias"], jack,
                            loglik=broken)
    assert np.all(np.isnan(se["gyro_bias"]))


def _quadratic_about(peak: np.ndarray, curvature: np.ndarray):
    """A log-likelihood -sum(c_i (b_i - peak_i)^2) / 2 of the gyro offset b (as above)."""
    def loglik(model, ys) -> float:
        b = -ys[0, 3:6]
        return float(-0.5 * np.sum(curvature * (b - peak) ** 2))
    return loglik


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3))
def test_the_newton_step_reaches_the_maximum_of_a_quadratic_likelihood(shift):
    """Coefficients a few standard errors off the maximum of a quadratic L (the refit's
    stall): ``information_fit`` moves them to it (to 1e-6 of a standard error) and says
    how much L gained; at the maximum itself it takes no step."""
    from pinquad.discovery.uncertainty import information_fit

    obs = _tiny_gyro_observations()
    theta = initial_theta(obs, 0.035, np.diag([16.6e-6, 16.7e-6, 29.3e-6]), 9.81)
    curvature = np.array([1e6, 4e6, 2.5e5])
    se = 1.0 / np.sqrt(curvature)
    peak = np.array([0.03, -0.02, 0.015])
    start = peak + np.asarray(shift) * se
    jack = {"gyro_bias": se / 3.0}
    fit = information_fit(obs, theta, np.zeros((6, 12)), {"gyro_bias": start}, ["gyro_bias"],
                          jack, loglik=_quadratic_about(peak, curvature))
    np.testing.assert_allclose(fit.stderr["gyro_bias"], se, rtol=1e-6)
    np.testing.assert_allclose(fit.maximiser["gyro_bias"], peak, rtol=0, atol=1e-6 * se.min())
    expected_gain = 0.5 * float(np.sum(np.asarray(shift) ** 2))
    if expected_gain > 1e-9:
        assert fit.gain == pytest.approx(expected_gain, rel=1e-5, abs=1e-9)
    at_peak = information_fit(obs, theta, np.zeros((6, 12)), {"gyro_bias": peak},
                              ["gyro_bias"], jack, loglik=_quadratic_about(peak, curvature))
    np.testing.assert_allclose(at_peak.maximiser["gyro_bias"], peak, rtol=0,
                               atol=1e-6 * se.min())
