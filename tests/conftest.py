"""Shared test fixtures."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.linear import LinearGaussianModel


def random_stable_model(rng: np.random.Generator, n: int = 4, m: int = 3) -> LinearGaussianModel:
    """A random linear-Gaussian model with spectral radius 0.95."""
    a = rng.standard_normal((n, n))
    a *= 0.95 / max(abs(np.linalg.eigvals(a)))
    c = rng.standard_normal((m, n))
    lq = rng.standard_normal((n, n)) * 0.3
    lr = rng.standard_normal((m, m)) * 0.3
    return LinearGaussianModel(
        a=a, c=c, q=lq @ lq.T + 0.05 * np.eye(n), r=lr @ lr.T + 0.1 * np.eye(m),
        m0=rng.standard_normal(n), p0=np.eye(n),
    )


@pytest.fixture
def linear_case():
    """A random stable model, 60 steps of data with about 20 % of the entries missing."""
    rng = np.random.default_rng(7)
    model = random_stable_model(rng)
    _, ys = model.simulate(60, rng)
    ys[rng.random(ys.shape) < 0.2] = np.nan
    ys[5] = np.nan
    return model, ys
