"""pinquad.identification.window (the online window's prior and EM update) and
pinquad.experiments.flight (one seeded flight; the NEES band)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from estimators.protocol import Posterior
from pinquad.core.params import PAPER_VEHICLE
from pinquad.experiments.flight import fly, nees_band
from pinquad.identification.em import initial_theta
from pinquad.identification.identify import get_smoother
from pinquad.identification.window import window_em, window_prior
from pinquad.models.sources import observations
from pinquad.mstep.updates import regressor_mstep
from pinquad.sim.simulator import SimConfig, flight_log, simulate


def _posterior(n_steps: int, n: int = 12) -> Posterior:
    mean = np.arange(n_steps * n, dtype=float).reshape(n_steps, n)
    cov = np.stack([np.diag(np.full(n, 0.5 + k)) for k in range(n_steps)])
    cov[2, 4, 4] = 0.0  # a degenerate variance is floored
    return Posterior(mean=mean, cov=cov, cross_cov=np.zeros((n_steps - 1, n, n)),
                     loglik=0.0, method="rts", rejected=np.zeros((n_steps, 3), bool))


def test_window_prior_takes_the_previous_posterior_row_at_the_new_start():
    post = _posterior(6)
    x0, p0 = np.full(12, -1.0), np.full(12, 9.0)
    # Previous window started at step 10; the new one starts at 12 -> row 2.
    mean, var = window_prior((10, post, None), 12, x0, p0)
    np.testing.assert_array_equal(mean, np.arange(24, 36, dtype=float))
    expect = np.full(12, 2.5)
    expect[4] = 1e-10
    np.testing.assert_array_equal(var, expect)
    mean[0] = 1e9  # a copy: the posterior's arrays may be reused
    assert post.mean[2, 0] == 24.0
    # No overlap (start beyond the previous window, or before it) or no previous: (x0, p0).
    for previous, start in (((10, post, None), 16), ((10, post, None), 9), (None, 12)):
        mean, var = window_prior(previous, start, x0, p0)
        np.testing.assert_array_equal(mean, x0)
        np.testing.assert_array_equal(var, p0)


def test_window_em_moves_a_wrong_mass_toward_the_truth():
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(5))).slice(300, 700)
    win = observations(log, "B")
    truth = PAPER_VEHICLE.mass
    wrong = 1.5 * truth
    theta0 = initial_theta(win, wrong, np.diag(PAPER_VEHICLE.inertia_diag),
                           PAPER_VEHICLE.gravity)
    theta, post = window_em(win, theta0, True, 3, get_smoother("rts"), regressor_mstep, None)
    assert post.mean.shape == (win.n, 12)
    assert abs(theta.mass - truth) < 0.1 * abs(wrong - truth), theta.mass


def _wilson_hilferty(k: int, p: float) -> float:
    """Chi-square(k) quantile by the Wilson-Hilferty cube approximation (not scipy's)."""
    z = norm.ppf(p)
    return k * (1.0 - 2.0 / (9 * k) + z * math.sqrt(2.0 / (9 * k))) ** 3


def test_nees_band_against_tables_and_wilson_hilferty():
    # One step, 12 states: the printed chi-square table's 2.5 % and 97.5 % points.
    lo, hi = nees_band(1)
    assert lo == pytest.approx(4.404, abs=1e-3)
    assert hi == pytest.approx(23.337, abs=1e-3)
    for n in (50, 400):
        lo, hi = nees_band(n)
        assert lo == pytest.approx(_wilson_hilferty(12 * n, 0.025) / n, rel=1e-4)
        assert hi == pytest.approx(_wilson_hilferty(12 * n, 0.975) / n, rel=1e-4)
        assert lo < 12.0 < hi


def test_fly_one_seed_reaches_every_waypoint():
    stats = fly(("crazyflie21", 0, "tuned"))
    assert stats.lifted_off and not stats.crashed
    assert stats.miss.shape == (5,)
    assert np.all(stats.miss < 0.1), stats.miss
    assert stats.pos_err.shape == stats.euler_err.shape == (stats.n_steps,)
    # The onboard filter's position error is centimetre-level against 5 mm motion capture.
    assert np.median(stats.pos_err) < 0.02
    assert np.isfinite(stats.nees_mean) and stats.nees_mean > 0.0
