"""Verdicts (``pinquad.identification.verdict``): every class reached on hand-built
estimates, the range boundary, the torque share and innovation consistency on data
whose answer is known, and the command line's exit code 3 on a flight whose torque
channel cannot explain the angular acceleration (its report still written)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pinquad.cli.offline import main as offline_main
from pinquad.core.params import CRAZYFLIE21
from pinquad.experiments.discovery_mc import simulate_log
from pinquad.identification.verdict import (
    IMPLAUSIBLE,
    NOT_ADEQUATE,
    NOT_IDENTIFIABLE,
    NOT_JUDGED,
    TRUSTED,
    VerdictEvidence,
    judge,
    vehicle_range,
)
from pinquad.identification.verdict_evidence import innovation_consistency, torque_excitation, torque_share
from pinquad.io.logs import write_log
from pinquad.io.runs import LOG_REPORT_KEYS
from pinquad.models.ssm import NoiseModel, Observations, Theta

M, J = CRAZYFLIE21.mass, np.diag(CRAZYFLIE21.inertia).copy()
CF = vehicle_range("crazyflie21")
GOOD = VerdictEvidence(np.full(3, 0.9), "all frequencies", {"pos": 1.0, "euler": 1.0, "gyro": 1.0})
SMALL_SE = np.r_[0.01 * M, 0.02 * J]


def test_trusted_and_each_failure_class_on_hand_built_estimates():
    ok = judge(M, np.diag(J), SMALL_SE, GOOD, CF)
    assert ok.overall == TRUSTED and ok.reasons == ()
    assert [p.name for p in ok.parameters] == ["mass", "I_xx", "I_yy", "I_zz"]

    # the torques explain 3 % about x: I_xx not identifiable, the mass stays trusted
    low = replace(GOOD, torque_share=np.array([0.03, 0.9, 0.9]))
    v = judge(M, np.diag(J), SMALL_SE, low, CF)
    assert v.get("I_xx").verdict == NOT_IDENTIFIABLE and v.overall == NOT_IDENTIFIABLE
    assert v.get("mass").trusted and v.get("I_yy").trusted
    assert "3 %" in v.get("I_xx").reasons[0]

    # gyro innovations 2x the predicted size (NIS 4 > 3): inertia's model not adequate,
    # the mass (resting on pos) trusted
    bad_gyro = replace(GOOD, nis_ratio={"pos": 1.0, "euler": 1.0, "gyro": 4.0})
    v = judge(M, np.diag(J), SMALL_SE, bad_gyro, CF)
    assert {p.name: p.verdict for p in v.parameters} == {
        "mass": TRUSTED, "I_xx": NOT_ADEQUATE, "I_yy": NOT_ADEQUATE, "I_zz": NOT_ADEQUATE}
    assert "2.0x" in v.get("I_xx").reasons[0]

    # a value 350x the vehicle's with a tiny error bar: implausible
    far = np.diag([5745e-6, J[1], J[2]])
    v = judge(M, far, np.r_[SMALL_SE[:1], 0.5e-6, SMALL_SE[2:]], GOOD, CF)
    assert v.get("I_xx").verdict == IMPLAUSIBLE
    assert any("outside" in r for r in v.get("I_xx").reasons)
    assert any("triangle" in r for r in v.get("I_xx").reasons)  # 16.7 + 29.3 < 5745
    # the real-log failure, 5745e-6 +- 52e-6 kg m^2 with the torques explaining
    # 3 %: the most severe label wins and every reason is kept (torque share, an error
    # bar wider than a Crazyflie's whole range, triangle inequality, outside the range)
    v = judge(M, far, np.r_[SMALL_SE[:1], 52e-6, SMALL_SE[2:]], low, CF)
    reasons = v.get("I_xx").reasons
    assert v.get("I_xx").verdict == NOT_IDENTIFIABLE and len(reasons) == 4
    assert reasons[0].startswith("torques explain 3 %") and "cover" in reasons[1]
    assert "outside" in reasons[-1]

    # triangle inequality: I_zz > I_xx + I_yy is no rigid body (every moment judged so)
    v = judge(M, np.diag([10e-6, 10e-6, 25e-6]), SMALL_SE, GOOD, CF)
    assert all(v.get(n).verdict == IMPLAUSIBLE for n in ("I_xx", "I_yy", "I_zz"))
    assert "triangle" in v.get("I_zz").reasons[0]
    # negative mass
    assert judge(-M, np.diag(J), SMALL_SE, GOOD, CF).get("mass").verdict == IMPLAUSIBLE
    # mass 3x the vehicle's: outside the factor-2 range
    assert judge(3 * M, np.diag(J), SMALL_SE, GOOD, CF).get("mass").verdict == IMPLAUSIBLE


def test_standard_error_boundary_against_the_vehicle_range():
    """4 se may cover at most 25 % of the range: mass range M/2 .. 2M (width 1.5 M), so
    se = 0.09375 M is the boundary."""
    lo, hi = CF.mass
    boundary = 0.25 * (hi - lo) / 4
    assert boundary == pytest.approx(0.09375 * M)
    at = judge(M, np.diag(J), np.r_[boundary * (1 - 1e-9), SMALL_SE[1:]], GOOD, CF)
    past = judge(M, np.diag(J), np.r_[boundary * 1.04, SMALL_SE[1:]], GOOD, CF)
    assert at.get("mass").trusted
    assert past.get("mass").verdict == NOT_IDENTIFIABLE and "26.0 %" in past.get("mass").reasons[0]
    # no standard error: nothing to judge it by, never "trusted"; the other checks still stand
    assert judge(M, np.diag(J), np.full(4, np.nan), GOOD, CF).overall == NOT_JUDGED
    # an unknown vehicle without sidecar guesses has no range: positivity and triangle only
    assert vehicle_range("unknown") is None
    assert judge(3 * M, np.diag(J), SMALL_SE, GOOD, None).overall == TRUSTED


def _rotating_obs(rng: np.random.Generator, torque_noise: float) -> tuple[Observations, np.ndarray]:
    """Body rates driven by known torques (J = the Crazyflie's), logged torques with
    white noise of ``torque_noise`` times the torque's standard deviation added."""
    n, dt = 3000, 0.01
    t = np.arange(n) * dt
    tau = 1e-5 * np.column_stack([np.sin(2.1 * t), np.sin(3.3 * t + 1), np.sin(1.7 * t + 2)])
    tau += 3e-6 * rng.standard_normal((n, 3))
    omega = np.zeros((n, 3))
    for k in range(n - 1):
        w = omega[k]
        omega[k + 1] = w + dt * (tau[k] - np.cross(w, J * w)) / J
    logged = tau + torque_noise * tau.std(axis=0) * rng.standard_normal((n, 3))
    mean = np.zeros((n, 12))
    mean[:, 9:12] = omega
    inputs = np.column_stack([np.full(n, M * 9.81), logged])
    obs = Observations(t, dt, inputs, ("gyro",), omega.copy(), np.zeros(12), np.ones(12))
    return obs, mean


def test_torque_share_reads_how_much_the_torques_explain():
    rng = np.random.default_rng(3)
    obs, mean = _rotating_obs(rng, 0.0)
    np.testing.assert_allclose(torque_share(obs, mean, np.diag(J)), 1.0, atol=1e-6)
    noisy, mean = _rotating_obs(rng, 5.0)
    share = torque_share(noisy, mean, np.diag(J))
    # white noise of 5x the signal's sd: 1 / (1 + 25) = 3.8 % of the variance explained
    assert np.all(share < 0.08) and np.all(share > 0.01)
    # excluded transitions are left out: excluding all but a few leaves too few to judge
    few = replace(noisy, exclude=np.r_[np.ones(noisy.n - 5, dtype=bool), np.zeros(5, dtype=bool)])
    assert np.isnan(torque_share(few, mean, np.diag(J))).all()


def _excitation_obs(dt: float, tau: np.ndarray) -> Observations:
    n = tau.shape[0]
    inputs = np.column_stack([np.full(n, M * 9.81), tau])
    return Observations(np.arange(n) * dt, dt, inputs, ("gyro",), np.zeros((n, 3)),
                        np.zeros(12), np.ones(12))


def _theta(torque_intensity: np.ndarray, fixed_q: np.ndarray | None = None) -> Theta:
    wrench = np.r_[1e-6, 1e-6, 1e-6, torque_intensity]
    return Theta(M, np.diag(J), NoiseModel(wrench, np.full(6, 1e-8), np.full(3, 1e-4), fixed_q))


def test_torque_excitation_compares_sampled_torques_with_the_noise_in_the_same_band():
    rng = np.random.default_rng(11)
    intensity = np.array([1e-13, 4e-13, 9e-13])  # N^2 m^2 s
    # white torques at 100 Hz: the band is 0-50 Hz, the whole Nyquist band, no filter;
    # rms sigma against sqrt(2 S 50 Hz) = sqrt(100 S)
    sigma = np.array([2e-6, 3e-6, 6e-6])
    tau = sigma * rng.standard_normal((20000, 3))
    ratio, words = torque_excitation(_excitation_obs(0.01, tau), _theta(intensity),
                                     actuation="sampled")
    np.testing.assert_allclose(ratio, sigma / np.sqrt(100 * intensity), rtol=0.02)
    assert words == "0-50 Hz"
    # a 2 Hz sine logged at 500 Hz passes the 50 Hz low-pass whole: rms A / sqrt(2),
    # and the noise is still counted over 50 Hz, not the 250 Hz Nyquist band
    t = np.arange(25000) * 0.002
    amp = np.array([1e-5, 2e-5, 3e-5])
    sine = amp * np.sin(2 * np.pi * 2 * t)[:, None] + 1e-4
    ratio, _ = torque_excitation(_excitation_obs(0.002, sine), _theta(intensity),
                                 actuation="sampled")
    np.testing.assert_allclose(ratio, amp / np.sqrt(2) / np.sqrt(100 * intensity), rtol=0.01)
    # not measured: a fixed noise model, or an M-step that reads one band only
    fixed, words = torque_excitation(_excitation_obs(0.01, tau), _theta(intensity, np.ones(12)),
                                     actuation="sampled")
    assert np.isnan(fixed).all() and "fixed" in words
    banded, words = torque_excitation(_excitation_obs(0.01, tau), _theta(intensity), (3.0, 8.0),
                                      actuation="sampled")
    assert np.isnan(banded).all() and "3-8 Hz" in words
    # a held input (what acted over each row, no unrecorded answer to the noise): not measured
    held, words = torque_excitation(_excitation_obs(0.01, tau), _theta(intensity),
                                    actuation="held")
    assert np.isnan(held).all() and "held" in words


def test_torques_no_larger_than_the_noise_make_that_inertia_not_identifiable():
    quiet = replace(GOOD, torque_excitation=np.array([0.5, 4.0, 1.9]), excitation_band="0-50 Hz")
    verdict = judge(M, np.diag(J), SMALL_SE, quiet, CF)
    assert [p.verdict for p in verdict.parameters] == [TRUSTED, NOT_IDENTIFIABLE, TRUSTED,
                                                         NOT_IDENTIFIABLE]
    assert "0.50x the size of the process noise's (0-50 Hz" in verdict.get("I_xx").reasons[0]
    # at the threshold (3x) and NaN (not measured) judge nothing; under it, untrusted
    edge = replace(quiet, torque_excitation=np.array([3.0, np.nan, 3.0]))
    assert judge(M, np.diag(J), SMALL_SE, edge, CF).overall == TRUSTED
    below = replace(quiet, torque_excitation=np.array([2.49, np.nan, 2.9]))
    assert [p.verdict for p in judge(M, np.diag(J), SMALL_SE, below, CF).parameters] == [
        TRUSTED, NOT_IDENTIFIABLE, TRUSTED, NOT_IDENTIFIABLE]


@pytest.fixture(scope="module")
def noisy_torque_log():
    """The discovery Monte Carlo's clean Crazyflie flight (seed 1) with white noise of 5x
    each torque's standard deviation added to the logged torques: the 100 Hz torque
    channel no longer says how the body turns, the thrust is untouched."""
    log, flight = simulate_log((), 1)
    assert not flight.crashed
    rng = np.random.default_rng(5)
    noise = 5.0 * log.torque.std(axis=0) * rng.standard_normal(log.torque.shape)
    return replace(log, torque=log.torque + noise)


def test_untrusted_headline_exits_3_and_still_writes_the_report(noisy_torque_log, tmp_path, capsys):
    path = write_log(noisy_torque_log, tmp_path / "noisy.csv")
    out = tmp_path / "run"
    code = offline_main(["--log", str(path), "--mstep", "regressor", "--no-discover",
                         "--max-iterations", "30",
                         "--out", str(out)])
    assert code == 3
    printed = capsys.readouterr()
    assert "exit code 3" in printed.err
    # the short report: the log's contents, then one line per parameter with its verdict
    lines = printed.out.splitlines()
    assert "noisy.csv: thrust/torque commands, simulator truth;" in printed.out
    report_lines = [line for line in lines
                    if line.split()[:1] in (["mass"], ["I_xx"], ["I_yy"], ["I_zz"])]
    assert len(report_lines) == 4
    assert all(any(w in line for w in ("trusted", "not identifiable", "model not adequate",
                                       "implausible", "not judged")) for line in report_lines)
    report = json.loads((out / "report.json").read_text())
    # DESIGN 4.3's keys all there, plus base and verdict
    assert set(report) >= {"schema", "source", "estimates", "em", "discovery", "cycles",
                           "base", "verdict"}
    assert set(report["estimates"]) >= {"mass", "inertia", "com", "stderr", "verdict"}
    for path in LOG_REPORT_KEYS:  # every documented added key is written
        node = report
        for key in path.replace("[]", "").split("."):
            node = node[0] if isinstance(node, list) else node
            assert key in node, path
            node = node[key]
    assert report["source"]["log_type"] == "thrust/torque commands, simulator truth"
    assert report["source"]["log_kind"] == "simulated"
    verdict = report["verdict"]
    assert verdict["overall"] == NOT_IDENTIFIABLE and verdict["reasons"]
    params = verdict["parameters"]
    assert params["mass"]["verdict"] == TRUSTED
    for name in ("I_xx", "I_yy"):
        assert params[name]["verdict"] == NOT_IDENTIFIABLE
        assert params[name]["reasons"][0].startswith("torques explain")
    # the mass is still right; nothing discovered, so the headline is the base fit
    assert report["estimates"]["mass"] == pytest.approx(M, rel=0.01)
    assert report["estimates"]["mass"] == report["base"]["mass"]
    # printed: the untrusted inertia with its verdict and main reason beside it
    i_xx = next(line for line in report_lines if line.split()[0] == "I_xx")
    assert "not identifiable: torques explain" in i_xx
    # the table of runs (report.md, --explain) shows it with its verdict, not an error bar
    md = (out / "report.md").read_text()
    row = next(line for line in md.splitlines() if line.startswith("| B | regressor"))
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert "±" in cells[2] and "(not identifiable: torques explain" in cells[3]
    assert "±" not in cells[3]
    assert "verdict: not identifiable" in md


def test_innovation_consistency_flags_understated_noise(noisy_torque_log):
    """At the EM estimate every channel's innovations are as large as the model says
    (ratio near 1, EM fits the noise); with the position noise variance understated
    100x the position innovations are far larger than predicted."""
    from pinquad.discovery.calibrated import discovery_start
    from pinquad.pipeline.identify import LogOptions, identify_log

    run = identify_log(noisy_torque_log, LogOptions(msteps=("regressor",), information=False,
                                                    max_iterations=10)).runs[0]
    start = discovery_start(run)
    fitted = innovation_consistency(start.obs, start.theta)
    assert set(fitted) == set(start.obs.channels)
    assert all(0.5 < r < 2.0 for r in fitted.values()), fitted
    meas = start.theta.noise.meas.copy()
    i = start.obs.channels.index("pos")
    meas[3 * i:3 * i + 3] /= 100.0
    theta = Theta(start.theta.mass, start.theta.inertia,
                  NoiseModel(start.theta.noise.wrench, start.theta.noise.q_kin, meas,
                             start.theta.noise.fixed_q), start.theta.gravity)
    tight = innovation_consistency(start.obs, theta)
    assert tight["pos"] > 3.0
    v = judge(run.mass, run.inertia, run.stderr, VerdictEvidence(nis_ratio=tight), CF)
    assert v.get("mass").verdict == NOT_ADEQUATE
