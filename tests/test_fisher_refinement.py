"""The observed information when central differences break down (fisher.observed_information)
and the verdict of an estimate whose standard error was asked for and is missing."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinquad.identification import fisher
from pinquad.identification.fisher import (
    STDERR_UNAVAILABLE,
    observed_information,
    standard_errors,
)
from pinquad.identification.verdict import NOT_IDENTIFIABLE, NOT_JUDGED, TRUSTED, VerdictEvidence, judge
from pinquad.models.ssm import Theta

THETA = Theta(0.035, np.diag([16.6e-6, 16.7e-6, 29.3e-6]), None, 9.81)
SE_REL = np.array([1e-4, 2e-4, 3e-4, 4e-4])  # relative standard errors of the fake likelihood
OBS = SimpleNamespace(ys=np.zeros((1, 1)))  # the fake likelihoods below read only theta


@pytest.fixture(autouse=True)
def bare_model(monkeypatch):
    """The model handed to the likelihood is just its parameters."""
    monkeypatch.setattr(fisher, "QuadSSM", lambda obs, theta: SimpleNamespace(theta=theta))


def _phi(model) -> np.ndarray:
    th = model.theta
    return np.log(np.r_[th.mass, np.diag(th.inertia)]) - np.log(
        np.r_[THETA.mass, np.diag(THETA.inertia)])


def _peaked(model, ys) -> float:
    """A quadratic log-likelihood in log-parameters with a cliff: beyond 0.1 % the filter
    'breaks down' (raises), as the 250 Hz floor-strike flight's did at 0.2 %."""
    phi = _phi(model)
    if np.any(np.abs(phi) > 1e-3):
        raise np.linalg.LinAlgError("Matrix is not positive definite")
    return float(-0.5 * np.sum((phi / SE_REL) ** 2))


def test_a_step_that_breaks_the_filter_is_refined_until_the_curvature_is_measured():
    info = observed_information(OBS, THETA, _peaked)
    se = standard_errors(info) / np.r_[THETA.mass, np.diag(THETA.inertia)]
    np.testing.assert_allclose(se, SE_REL, rtol=1e-6)


def test_no_refinement_without_a_curvature_gives_nan_not_an_exception():
    def rough(model, ys) -> float:  # jumps of thousands of nats: no step finds a maximum
        return float(np.sin(1e7 * np.sum(_phi(model))) * 1e3)

    se = standard_errors(observed_information(OBS, THETA, rough))
    assert np.all(np.isnan(se))


def test_a_missing_standard_error_that_was_asked_for_is_not_trusted():
    inertia = np.diag([16.6e-6, 16.7e-6, 29.3e-6])
    se = np.array([np.nan, 1e-7, np.nan, 1e-7])
    quiet = judge(0.035, inertia, se, VerdictEvidence(), None)
    asked = judge(0.035, inertia, se, VerdictEvidence(), None, missing_stderr=STDERR_UNAVAILABLE)
    # not computed, not asked for: nothing to judge the number by, never trusted
    assert quiet.get("mass").verdict == NOT_JUDGED
    assert asked.get("mass").verdict == NOT_IDENTIFIABLE
    assert asked.get("mass").reasons == (STDERR_UNAVAILABLE,)
    assert asked.get("I_xx").verdict == TRUSTED and asked.get("I_yy").verdict == NOT_IDENTIFIABLE


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 4), st.floats(-1.0, 0.0))
def test_determined_covariance_drops_only_the_direction_the_data_leave(seed, flat, curvature):
    """A positive definite information in scaled units, made flat or wrongly curved
    (eigenvalue <= 0) along parameter ``flat`` alone: that parameter is undetermined,
    every other one keeps the covariance of its own block (the inverse with ``flat``
    removed); positive definite, nothing is undetermined and the covariance is the
    inverse."""
    rng = np.random.default_rng(seed)
    scale = 10.0 ** rng.uniform(-8, 0, size=5)
    root = rng.normal(size=(4, 4))
    block = root @ root.T + 0.5 * np.eye(4)
    keep = [i for i in range(5) if i != flat]
    scaled = np.zeros((5, 5))
    scaled[np.ix_(keep, keep)] = block
    scaled[flat, flat] = curvature
    info = scaled / np.outer(scale, scale)
    cov, undetermined = fisher.determined_covariance(info, scale)
    assert undetermined.tolist() == [i == flat for i in range(5)]
    expected = np.linalg.inv(block) * np.outer(scale[keep], scale[keep])
    np.testing.assert_allclose(cov[np.ix_(keep, keep)], expected, rtol=1e-8,
                               atol=1e-10 * np.abs(expected).max())
    scaled[flat, flat] = 2.0
    info = scaled / np.outer(scale, scale)
    cov, undetermined = fisher.determined_covariance(info, scale)
    assert not undetermined.any()
    np.testing.assert_allclose(cov, np.linalg.inv(scaled) * np.outer(scale, scale), rtol=1e-8,
                               atol=1e-10 * np.abs(cov).max())
