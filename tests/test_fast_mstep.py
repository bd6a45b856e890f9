"""The compiled M-step statistics against ``identify.regressor_stats``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pinquad.em import initial_theta, run_em
from pinquad.experiment import get_smoother
from pinquad.fast_mstep import regressor_quadratics
from pinquad.identify import regressor_mstep, regressor_stats
from pinquad.params import PAPER_VEHICLE
from pinquad.sim import SimConfig, flight_log, simulate
from pinquad.sources import observations

TOL = 1e-11


@pytest.fixture(scope="module")
def flight():
    return simulate(SimConfig(), np.random.default_rng(7))


@pytest.mark.parametrize("source", ["A", "B", "C"])
def test_quadratics_match_regressor_stats(flight, source):
    """Posterior of a few EM steps (non-trivial covariances and cross-covariances), some
    transitions excluded; every entry of a, b, c to 1e-11 of its row's scale."""
    obs = observations(flight_log(flight).slice(0, 900), source)
    exclude = obs.exclude.copy()
    exclude[100:140] = True
    obs = replace(obs, exclude=exclude)
    theta0 = initial_theta(obs, PAPER_VEHICLE.mass * 0.9, PAPER_VEHICLE.inertia * 1.2, 9.81)
    post = run_em(obs, theta0, get_smoother("rts"), regressor_mstep, max_iterations=4).posterior
    ref = regressor_stats(post, obs, 9.81)
    fast = regressor_quadratics(post, obs, 9.81)
    assert fast.n == ref.n
    for j in range(6):
        scale = np.max(np.abs(ref.a[j]))
        np.testing.assert_allclose(fast.a[j], ref.a[j], rtol=0, atol=TOL * scale)
        np.testing.assert_allclose(fast.b[j], ref.b[j], rtol=0,
                                   atol=TOL * max(np.max(np.abs(ref.b[j])), 1e-300))
    np.testing.assert_allclose(fast.c, ref.c, rtol=TOL, atol=0)
