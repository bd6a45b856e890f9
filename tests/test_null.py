"""Effect selection calibrated against the null (issue 22 item 3): shadow flights of the
base fit (pinquad.sim.shadow) and the calibration of selected effects against them
(pinquad.discovery.null), on flights of the independent generator flightgen."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from flightgen import Effects, FlightSpec, generate, write_csv
from pinquad.discovery.calibrated import discovery_start
from pinquad.discovery.null import NullSettings, calibrate, plausible_base_fit
from pinquad.discovery.residuals import compute_residuals
from pinquad.discovery.result import DiscoveryConfig
from pinquad.discovery.selection import score_candidate
from pinquad.identification.identify import identify
from pinquad.io.read import read_log
from pinquad.pipeline.identify import LogOptions, identify_log
from pinquad.sim.shadow import second_difference_var, shadow_flight

CFG = DiscoveryConfig()


def _start(tmp_path_factory, name: str, effects: Effects):
    flight = generate(FlightSpec(duration=16, log_rate=100, seed=4, floor=None, effects=effects))
    path = tmp_path_factory.mktemp(name) / f"{name}.csv"
    write_csv(flight, path)
    result = identify_log(read_log(path), LogOptions(msteps=("regressor",), information=False))
    return discovery_start(result.runs[0])


@pytest.fixture(scope="module")
def clean_start(tmp_path_factory):
    return _start(tmp_path_factory, "clean", Effects())


@pytest.fixture(scope="module")
def drag_start(tmp_path_factory):
    return _start(tmp_path_factory, "drag", Effects(drag=(0.006, 0.006, 0.007)))


def _drag_gain(start) -> float:
    res = compute_residuals(start.obs, start.posterior, start.theta.gravity, CFG.block_seconds)
    train = np.arange(res.n_blocks) % 2 == 0
    pi0 = np.r_[start.theta.mass, np.diag(start.theta.inertia)]
    return score_candidate(res, [], "drag", pi0, 0, CFG, train).gain


def test_a_shadow_flight_is_a_flight_of_the_base_fit_logged_like_the_log(clean_start):
    obs, theta = clean_start.obs, clean_start.theta
    shadow = shadow_flight(obs, theta, clean_start.posterior.mean, np.random.default_rng(3),
                           actuation="sampled")
    dist = np.linalg.norm(shadow.states[:, 0:3] - clean_start.posterior.mean[:, 0:3], axis=1)
    assert np.sqrt(np.mean(dist**2)) < 0.05
    assert np.array_equal(np.isnan(shadow.obs.ys), np.isnan(obs.ys))
    # at least as rough as the recorded input (the gap is filled with white noise; the
    # fit's process noise, which soaks up all it does not model, can make it rougher)
    ratio = second_difference_var(shadow.obs.inputs) / second_difference_var(obs.inputs)
    assert np.all(ratio > 0.8), ratio
    # EM on the shadow flight finds the mass it was flown with
    ident, _ = identify(shadow.obs, 0.025, np.diag([8e-6, 8e-6, 15e-6]), theta.gravity, "rts",
                        "regressor", 100, False)
    assert ident.mass == pytest.approx(theta.mass, rel=0.01)


def test_real_drag_beats_the_null_and_a_clean_flights_chance_gain_does_not(clean_start,
                                                                            drag_start):
    settings = NullSettings(replicates=19, seed=0)
    drag = calibrate(drag_start.obs, drag_start.theta, drag_start.posterior,
                     {"drag": _drag_gain(drag_start)}, CFG, settings, "sampled")
    assert drag.kept == ("drag",) and drag.p_value["drag"] == pytest.approx(0.05)
    assert drag.observed["drag"] > 0.5 > np.max(drag.null_gains["drag"])
    clean = calibrate(clean_start.obs, clean_start.theta, clean_start.posterior,
                      {"drag": _drag_gain(clean_start)}, CFG, settings, "sampled")
    assert clean.rejected == ("drag",) and clean.p_value["drag"] > 0.05
    assert clean.null_gains["drag"].shape == (19,)


def test_an_implausible_base_fit_is_flown_at_its_nearest_plausible_inertia(clean_start):
    """A base model that cannot explain its log (a CoM offset on flightgen's 500 Hz flights)
    drove the inertia to 1e-7 or 1e77 kg m^2; the shadow flights of such a fit broke down
    and every effect lost to their NaN gains (CoM offset unnamed on 2 of 10 flights)."""
    theta = clean_start.theta
    lo, hi = np.array([4e-6, 4e-6, 7e-6]), np.array([66e-6, 67e-6, 117e-6])
    assert plausible_base_fit(theta, (lo, hi)) is theta  # a plausible fit is flown as fitted
    wild = replace(theta, inertia=np.diag([3e-7, 1e-1, 20e-6]))
    flown = plausible_base_fit(wild, (lo, hi))
    assert np.allclose(np.diag(flown.inertia), [4e-6, 67e-6, 20e-6])
    # the torque noise never grows; where the inertia shrank, the angular-acceleration
    # noise S / I^2 stays the fit's
    s_tau, s_flown = theta.noise.wrench[3:6], flown.noise.wrench[3:6]
    assert np.allclose(s_flown, s_tau * np.array([1.0, (67e-6 / 1e-1) ** 2, 1.0]))
    assert np.array_equal(flown.noise.wrench[0:3], theta.noise.wrench[0:3])
    assert plausible_base_fit(wild, None) is wild
    settings = NullSettings(replicates=2, seed=0, alpha=0.3)
    cal = calibrate(clean_start.obs, wild, clean_start.posterior, {"drag": 0.5}, CFG, settings,
                    "sampled", inertia_bounds=(lo, hi))
    assert np.allclose(cal.flown_inertia, [4e-6, 67e-6, 20e-6])
    assert np.all(np.isfinite(cal.null_gains["drag"])) and cal.tracking_rms < 0.1
    assert "nearest point in that range, diag (4, 67, 20) e-6" in cal.to_report()[
        "shadow_inertia_note"]
    plain = calibrate(clean_start.obs, theta, clean_start.posterior, {"drag": 0.5}, CFG,
                      settings, "sampled", inertia_bounds=(lo, hi))
    assert plain.flown_inertia is None and plain.to_report()["shadow_inertia_note"] is None


def test_too_few_replicates_for_the_asked_level_are_refused():
    with pytest.raises(ValueError, match="at least 19"):
        NullSettings(replicates=5)
    assert NullSettings(replicates=0).replicates == 0
