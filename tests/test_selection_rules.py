"""Two rules of discovery's selection, on flights pinquad did not simulate.

Two folds (``DiscoveryConfig.two_fold``): flightgen's ground-effect flight 2008 of the
discovery Monte Carlo (100 Hz, 20 s, aggressive sums of sines, k_ge = 1, one pass 7 cm
above the ground plane) spends its lowest seconds in held-out blocks. Scored on the
even-block fold alone, ground effect had a held-out gain of 84 % but failed BIC on the
training blocks, and nothing was selected (docs/discovery.md). Both folds together
select it, and alone.

The shortest lag (``DiscoveryConfig.min_lag_intervals``): flightgen's floor-strike flight
7005 (100 Hz, take-off, two strikes, landing, no effect) passed the held-out, BIC and
likelihood tests with a "motor lag" of about 0.16 ms, under a fiftieth of its 10 ms
interval: the trace of how its sampled torques moved between rows, not a lag.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from flightgen import Effects, FlightSpec, generate, write_csv
from pinquad.discovery.calibrated import discover_calibrated, discovery_config, discovery_start
from pinquad.discovery.discover import select_effects
from pinquad.discovery.null import NullSettings
from pinquad.discovery.result import DiscoveryConfig
from pinquad.discovery.selection import shortest_lag
from pinquad.experiments.discovery_mc_flightgen import flight_spec
from pinquad.io.read import read_log
from pinquad.pipeline.identify import LogOptions, identify_log, input_reading


def _start(tmp_path_factory, condition: str, seed: int, index: int):
    spec = flight_spec(condition, seed, index, 100)
    path = write_csv(generate(spec), tmp_path_factory.mktemp("fg") / f"{condition}.csv")
    result = identify_log(read_log(path), LogOptions(msteps=("regressor",), information=False))
    cfg = discovery_config(result.kind, input_reading(result.kind, result.log))
    return discovery_start(result.runs[0]), cfg


@pytest.fixture(scope="module")
def ground_effect_start(tmp_path_factory):
    return _start(tmp_path_factory, "ground_effect", 2008, 8)


def test_an_effect_whose_signal_sits_in_held_out_blocks_is_selected(ground_effect_start):
    start, cfg = ground_effect_start
    assert cfg.two_fold
    both = select_effects(start.obs, start.theta, start.posterior, cfg)
    one = select_effects(start.obs, start.theta, start.posterior, replace(cfg, two_fold=False))
    assert both.selected == ("ground_effect",)
    assert one.selected == ()
    score_one = next(s for s in one.scores if s.effect == "ground_effect")
    score_both = next(s for s in both.scores if s.effect == "ground_effect" and s.round == 0)
    # what changed is the training evidence: BIC on the even blocks alone fails
    assert score_one.gain > cfg.min_heldout_gain and score_one.d_bic < 0
    assert score_both.d_bic > 0 and score_both.gain > cfg.min_heldout_gain
    # no other candidate rides along on the pooled evidence
    assert all(not s.passed for s in both.scores if s.effect != "ground_effect")


def test_a_lag_shorter_than_the_log_resolves_is_not_an_effect(tmp_path_factory):
    start, cfg = _start(tmp_path_factory, "floor_strikes", 7005, 5)
    assert cfg.min_lag_intervals == 0.25
    kept = select_effects(start.obs, start.theta, start.posterior, cfg)
    loose = select_effects(start.obs, start.theta, start.posterior,
                           replace(cfg, min_lag_intervals=0.0, min_lag_seconds=0.0))
    assert loose.selected == ("motor_lag",)
    lag = next(s for s in loose.scores if s.effect == "motor_lag" and s.passed).coefficients[0]
    assert 0.0 < lag < 0.25 * start.obs.dt
    assert kept.selected == ()


def test_the_shortest_lag_is_a_quarter_interval_or_two_milliseconds_whichever_is_longer():
    cfg = DiscoveryConfig()
    assert shortest_lag(cfg, 0.01) == pytest.approx(0.0025)  # 100 Hz: a quarter interval
    assert shortest_lag(cfg, 0.002) == pytest.approx(0.002)  # 500 Hz: 2 ms, not 0.5 ms
    assert shortest_lag(replace(cfg, min_lag_seconds=0.0), 0.002) == pytest.approx(0.0005)


def test_a_diverged_base_inertia_does_not_hide_an_effect_when_the_fits_start_plausibly(
        tmp_path):
    """flightgen's 500 Hz CoM-offset flights 3007 and 3009: in a one-BLAS-thread worker the
    base EM diverged to ~4e77 kg m^2, the candidates' profiled fits started there and
    overflowed, and nothing was selected. Here a short CoM-offset flight's base inertia
    is blown up by 1e70 by hand."""
    flight = generate(FlightSpec(duration=16, log_rate=100, seed=4, floor=None,
                                 effects=Effects(com_offset=(0.003, -0.002))))
    path = write_csv(flight, tmp_path / "com.csv")
    result = identify_log(read_log(path), LogOptions(msteps=("regressor",), information=False))
    start = discovery_start(result.runs[0])
    cfg = discovery_config(result.kind, input_reading(result.kind, result.log))
    wild = replace(start.theta, inertia=start.theta.inertia * 1e70)
    assert "com_offset" not in select_effects(start.obs, wild, start.posterior, cfg).selected
    plausible = select_effects(start.obs, wild, start.posterior, cfg,
                               np.diag(start.theta.inertia))
    assert plausible.selected[0] == "com_offset"
    com = next(s for s in plausible.scores if s.effect == "com_offset" and s.passed)
    assert com.coefficients == pytest.approx((0.003, -0.002), rel=0.02)
    # the whole discovery (no null here) starts its refit there too: without it the refit
    # kept the diverged inertia and printed a CoM offset of 1e-106 m
    lo, hi = np.diag(start.theta.inertia) / 4, np.diag(start.theta.inertia) * 4
    outcome = discover_calibrated(replace(start, theta=wild), cfg, NullSettings(replicates=0),
                                  "sampled", None, (lo, hi))
    found = outcome.result
    assert found is not None and found.selected[0] == "com_offset"
    assert found.coefficients["com_offset"] == pytest.approx((0.003, -0.002), rel=0.02)
    assert np.all(np.diag(found.inertia) < hi * 10)
