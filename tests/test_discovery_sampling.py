"""Actuation between samples (issue 22 item 2): a log whose thrust and torques are the
command SAMPLED at each row of a faster controller must not read as drag."""

from __future__ import annotations

from dataclasses import replace

from flightgen import CRAZYFLIE, FlightSpec, generate, write_csv
from pinquad.discovery.calibrated import discovery_config, discovery_start
from pinquad.discovery.discover import discover
from pinquad.io.read import read_log
from pinquad.pipeline.identify import LogOptions, identify_log


def test_a_clean_100_hz_flightgen_flight_selects_nothing(tmp_path):
    """A clean (no effect, default noise) 20 s aggressive flight of the independent
    generator, logged at 100 Hz: nothing is selected, with the sampling nuisance in the
    selection's models and, since the E- and M-steps turn the thrust with the interval's
    mean rotation (``models.continuous``, ``mstep.updates.applied_force``), without it
    too. Read the way pinquad read every log before issue 22 (the row held over its
    interval, explicit Euler, no nuisance) the intra-interval change of the thrust
    direction is taken for drag."""
    spec = FlightSpec(duration=20.0, trajectory="sines", aggressive=True, log_rate=100,
                      seed=4, vehicle=CRAZYFLIE, floor=None)
    log = read_log(write_csv(generate(spec), tmp_path / "clean.csv"))
    options = LogOptions(msteps=("regressor",), estep="rts", max_iterations=100,
                         information=False)
    result = identify_log(log, options)
    start = discovery_start(result.runs[0])
    assert start.obs.continuous
    cfg = discovery_config(result.kind, result.log.meta.actuation)
    assert cfg.sampling_nuisance == (0,)
    assert discovery_config(result.kind, "held").sampling_nuisance == ()
    found = discover(start.obs, start.theta, start.posterior, cfg=cfg)
    assert found.selected == (), [(s.effect, s.gain) for s in found.scores]
    without = discover(start.obs, start.theta, start.posterior,
                       cfg=replace(cfg, sampling_nuisance=(), refit_em=False))
    assert without.selected == (), [(s.effect, s.gain) for s in without.scores]
    held = identify_log(replace(log, meta=replace(log.meta, actuation="held")), options)
    old = discovery_start(held.runs[0])
    assert not old.obs.continuous
    before = discover(old.obs, old.theta, old.posterior,
                      cfg=replace(discovery_config(held.kind, "held"), refit_em=False))
    assert "drag" in before.selected, [(s.effect, s.gain) for s in before.scores]


def test_discovery_command_rejects_a_condition_the_generator_does_not_have(capsys):
    """``--generator flightgen`` with pinquad's ``drag+wind`` condition: exit 2, a message
    naming the flightgen conditions, nothing flown."""
    from pinquad.cli.discovery import main

    assert main(["--generator", "flightgen", "--conditions", "drag+wind", "--seeds", "1"]) == 2
    err = capsys.readouterr().err
    assert "drag+wind" in err and "ground_effect" in err
