"""The online estimator (issue 5): the memory of samples that left the window adds up,
one closed-loop flight from the paper's start lifts off, passes its waypoints and
converges, and the command line (closed loop and ``--log`` replay) writes its report.

The statistics over 20 seeded cycles per source are the command's
(``python -m pinquad.online``), not a test's."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.params import PAPER_VEHICLE
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.experiments import online
from pinquad.io.logs import write_log
from pinquad.models.sources import observations
from pinquad.models.ssm import NoiseModel, QuadSSM, Theta
from pinquad.mstep.stats import QuadraticSums
from pinquad.mstep.updates import expected_quadratics, remember_leaving
from pinquad.sim.simulator import SimConfig, flight_log, simulate

ROOT = Path(__file__).resolve().parents[1]
TRUTH = np.array([PAPER_VEHICLE.mass, *PAPER_VEHICLE.inertia_diag])


def _posterior_of_a_flight():
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(5))).slice(100, 500)
    obs = observations(log, "B")
    noise = NoiseModel(wrench=np.array([1e-8, 1e-8, 4e-6, 4e-10, 4e-10, 4e-10]),
                       q_kin=np.full(6, 1e-12), meas=np.full(12, 1e-4))
    theta = Theta(PAPER_VEHICLE.mass, np.diag(PAPER_VEHICLE.inertia_diag), noise,
                  PAPER_VEHICLE.gravity)
    return obs, smooth_quad(QuadSSM(obs, theta), obs.ys)


def test_remembered_statistics_add_up_to_the_whole_window():
    """Folding in the first n transitions and then the next n' (no forgetting) gives the
    statistics of those n + n' transitions, and forgetting scales what was remembered by
    exp(-n dt / memory_s)."""
    obs, post = _posterior_of_a_flight()
    g = PAPER_VEHICLE.gravity
    first = remember_leaving(None, post, obs, 150, g, math.inf)
    assert first is not None and first.n == 150
    shifted = replace(obs, exclude=np.r_[np.ones(150, bool), np.zeros(obs.n - 150, bool)])
    both = first.plus(QuadraticSums.of(expected_quadratics(post, shifted, g)))
    whole = QuadraticSums.of(expected_quadratics(post, obs, g))
    assert both.n == whole.n == obs.n - 1
    for name in ("a", "b", "c"):
        np.testing.assert_allclose(getattr(both, name), getattr(whole, name), rtol=1e-10,
                                   atol=1e-14 * float(np.abs(getattr(whole, name)).max()))
    again = remember_leaving(first, post, obs, 100, g, memory_s=2.0)
    decay = math.exp(-100 * obs.dt / 2.0)
    assert again.n == pytest.approx(decay * 150 + 100)
    fresh = remember_leaving(None, post, obs, 100, g, math.inf)
    np.testing.assert_allclose(again.c, decay * first.c + fresh.c, rtol=1e-12)
    assert remember_leaving(first, post, obs, 0, g, math.inf) is first


@pytest.fixture(scope="module")
def cycles():
    """Sensor A, seed 1, cycle 0 from the paper's start, flown once per memory setting."""
    return {}


def _cycle(cycles, memory_s):
    if memory_s not in cycles:
        cycles[memory_s] = online.run_online_cycle(("A", 1, 0, memory_s))
    return cycles[memory_s]


@pytest.mark.parametrize("memory_s", [math.inf, None])
def test_one_closed_loop_flight_from_the_papers_start(cycles, memory_s):
    """Sensor A, the source whose window-only I_zz was the widest: from m0 = 1 g and the
    paper's I0 the vehicle lifts off, passes every waypoint within 0.15 m and does not
    crash, and the converged estimate (median of the last 10 % of updates) has the mass
    within 0.5 % of the truth (docs/online.md's targets). With the default memory the
    inertia is within 5 % too; window-only, see the next test."""
    cycle = _cycle(cycles, memory_s)
    assert cycle.lifted_off and not cycle.crashed
    assert cycle.miss.max() <= 0.15
    conv = online.converged_estimate(cycle.history)
    error = np.abs(conv - TRUTH) / TRUTH
    assert error[0] <= 0.005
    if memory_s is not None:
        assert np.all(error[1:] <= 0.05), error


@pytest.mark.xfail(strict=True, reason="window-only (the paper's scheme) misses the 5 % "
                   "inertia target: this flight's converged I_zz is 11 % off (docs/online.md: "
                   "49/60 within 5 %, every failure I_zz, up to 16.6 %)")
def test_window_only_inertia_within_the_target(cycles):
    """The same 5 % inertia target for the window-only estimator."""
    conv = online.converged_estimate(_cycle(cycles, None).history)
    error = np.abs(conv - TRUTH) / TRUTH
    assert np.all(error[1:] <= 0.05), error


def test_update_latency_is_measured_for_the_benchmark():
    """The update latency is the benchmark's figure (``python -m pinquad.bench``, online
    section: p50 / p99), not a test's: here only that it measures one positive wall time
    per update."""
    lat = online.measure_update_latency(n_updates=3, window=200)
    assert lat.shape == (3,) and np.all(np.isfinite(lat)) and np.all(lat > 0)


def test_online_command_and_replay(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.online", "--sensor", "C", "--cycles", "1", "--jobs",
         "1", "--memory", "30", "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "M-step memory: forgotten with time constant 30 s" in proc.stdout
    report = json.loads((out / "report.json").read_text())
    assert report["source"]["mode"] == "online"
    assert report["source"]["memory"] == "forgotten with time constant 30 s"
    (cyc,) = report["cycles"]
    assert cyc["sensor"] == "C" and len(cyc["history"]["mass"]) > 100
    assert abs(cyc["estimates"]["mass"] - TRUTH[0]) <= 0.005 * TRUTH[0]

    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(8)))
    path = write_log(log, tmp_path / "flight.csv")
    replay = subprocess.run(
        [sys.executable, "-m", "pinquad.online", "--log", str(path), "--out",
         str(tmp_path / "replay")],
        capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    assert "regressor M-step, memory: every airborne sample (incremental EM)" in replay.stdout
    rep = json.loads((tmp_path / "replay" / "report.json").read_text())
    assert rep["source"]["mode"] == "online-replay"
    assert abs(rep["estimates"]["mass"] - TRUTH[0]) <= 0.005 * TRUTH[0]


@pytest.mark.parametrize("value", ["0", "-3", "soon"])
def test_bad_memory_is_a_clear_error(value):
    proc = subprocess.run([sys.executable, "-m", "pinquad.online", "--memory", value],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 2
    assert "expected seconds (> 0), inf or none" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_replay_of_a_measured_flight_converges_to_the_offline_answer():
    """jana02 (7.7 s figure-8, ``../shared/data``; fails if the data are missing) streamed
    through the online estimator with the measured-flight M-step: the last update's mass
    is within 1.5 % of the scale and its roll / pitch inertia within 10 % of the offline
    identification of the same log (``python -m pinquad.realdata``: 18.7, 16.9 e-6)."""
    from pinquad.experiments.online_replay import stream_em
    from pinquad.io.read import read_log
    from pinquad.realdata.dataset import SCALE_MASS, default_guess
    from pinquad.realdata.identify import identify_real
    from pinquad.realdata.observations import build_observations
    from pinquad.realdata.raw import raw_flight

    flight = ROOT.parent / "shared" / "data" / "crazyflie" / "imrc_brushed" / "jana02"
    assert flight.is_file(), f"the Crazyflie data are missing: expected {flight}"
    real = build_observations(raw_flight(read_log(flight)))
    mass0, inertia0, _ = default_guess("crazyflie21")
    hist, lat = stream_em(real.obs, mass0, inertia0, real.log.meta.gravity,
                          rotor_acc=real.rotor_acc)
    # the update latency is measured by ``python -m pinquad.bench``, not asserted here
    assert hist.shape[0] > 150 and lat.shape == (hist.shape[0],)
    assert abs(hist[-1, 2] / SCALE_MASS - 1.0) < 0.015
    offline = identify_real(real, mass0, inertia0, information=False)
    np.testing.assert_allclose(hist[-1, 3:5], np.diag(offline.inertia)[:2], rtol=0.10)
