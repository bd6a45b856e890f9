"""The apparent-inertia frequency response (pinquad.response): exact on a rigid body,
and what it shows on the real Crazyflie logs (which must be present: fails, not skips)."""

from __future__ import annotations

import os
import subprocess
import sys
from functools import cache
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pinquad.realdata.response import apparent_inertia

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "crazyflie"


def _rigid_flight(inertia: np.ndarray, delay_steps: int = 0, n: int = 6000, dt: float = 0.01):
    """A flight whose torque bins are exactly I * (mean angular acceleration over the bin)
    and whose gyro samples the rate at the bin's start (the measured-log layout)."""
    rng = np.random.default_rng(3)
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, 15.0, fs=1.0 / dt, output="sos")
    rate = sosfiltfilt(sos, rng.standard_normal((n + 1, 3)), axis=0)
    torque = inertia * (rate[1:] - rate[:-1]) / dt
    torque = np.roll(torque, delay_steps, axis=0)
    inputs = np.column_stack([np.full(n, 0.34), torque])
    exclude = np.zeros(n, dtype=bool)
    exclude[:50] = exclude[-50:] = True  # take-off and landing are cut
    obs = SimpleNamespace(t=dt * np.arange(n), dt=dt, inputs=inputs, exclude=exclude)
    log = SimpleNamespace(gyro=rate[:n])
    return SimpleNamespace(obs=obs, log=log, rotor_acc=np.zeros(n), source="synthetic")


def test_rigid_body_gives_its_inertia_at_every_frequency():
    inertia = np.array([16e-6, 17e-6, 29e-6])
    r = apparent_inertia(_rigid_flight(inertia), "rigid", reference=inertia)
    band = (r.freq > 0.5) & (r.freq < 12.0)
    np.testing.assert_allclose(r.gain[band], np.broadcast_to(inertia, r.gain[band].shape),
                               rtol=1e-6)
    assert np.max(np.abs(r.phase[band])) < 1e-6
    assert np.min(r.coherence[band]) > 0.999999
    assert r.seconds == pytest.approx((6000 - 100) * 0.01, abs=0.02)
    # against the true inertia only the span's end samples (one-sided differences) are
    # left unexplained; a 20 % wrong inertia leaves 20 % of the torque
    assert np.all(r.unexplained < 0.02)
    off = apparent_inertia(_rigid_flight(inertia), "rigid", reference=1.2 * inertia)
    np.testing.assert_allclose(off.unexplained, 0.2, rtol=0.1)


def test_a_late_torque_shows_as_a_phase_lag_not_a_gain_change():
    inertia = np.array([16e-6, 17e-6, 29e-6])
    r = apparent_inertia(_rigid_flight(inertia, delay_steps=2), "late")
    for hz in (2.0, 5.0, 8.0):
        gain, phase, _ = r.at(hz)
        f = r.freq[int(np.argmin(np.abs(r.freq - hz)))]
        np.testing.assert_allclose(phase, -2 * np.pi * f * 0.02, atol=0.05)
        np.testing.assert_allclose(gain, inertia, rtol=0.05)


def test_closed_loop_disturbance_makes_the_gain_fall_while_em_keeps_the_inertia():
    """The simulated Crazyflie in closed loop: with the simulator's torque noise the
    apparent inertia is flat near the truth; with ten times that noise (torques the
    controller answers) it falls with frequency, the torque leading, as on the measured
    logs, while direct EM on the same flight still finds the inertia."""
    from pinquad.realdata.response import simulated_response

    nominal = simulated_response(1.0, seed=0, sensor="A")
    loud = simulated_response(10.0, seed=0, sensor="A")
    assert not nominal.crashed and not loud.crashed
    truth = nominal.truth
    # the nominal loop carries a little of the same mixing (unexplained share 0.14-0.26):
    # flat means within 15 % here, against the two- to fourfold excess of the loud flight
    for lo, hi in ((3.0, 5.0), (5.0, 8.0), (8.0, 12.0)):
        np.testing.assert_allclose(nominal.response.band_gain(lo, hi), truth, rtol=0.15)
    assert np.all(loud.response.band_gain(3.0, 5.0) > 1.5 * truth)
    assert np.all(nominal.response.unexplained < 0.3)
    assert np.all(loud.response.unexplained > 0.5)
    low, high = loud.response.band_gain(3.0, 5.0), loud.response.band_gain(12.0, 16.0)
    assert np.all(low > 1.8 * high)
    for hz in (5.0, 8.0):
        _, phase, coherence = loud.response.at(hz)
        assert np.all(phase > 0) and np.all(coherence > 0.6)
    assert np.max(np.abs(nominal.em_rel_error)) < 0.02
    assert np.max(np.abs(loud.em_rel_error)) < 0.05


@cache
def _closed_loop_response():
    """``realdata``'s band-passed M-step and direct EM on one simulated closed-loop flight
    (sensor B, the simulator's own torque noise; ~50 s, so computed once)."""
    from pinquad.realdata.response import simulated_response

    return simulated_response(1.0, seed=0, sensor="B")


def test_direct_em_on_a_closed_loop_flight_is_within_target():
    """Direct EM on the simulated closed-loop flight reads every inertia entry within 2 %
    of the truth (paper.md: every regressor estimate within 3 %)."""
    sim = _closed_loop_response()
    assert np.max(np.abs(sim.em_rel_error)) < 0.02, sim.em_rel_error


@pytest.mark.xfail(strict=True, reason="the README's caveat: the band-passed M-step reads a "
                   "closed-loop flight high, measured +14.3 / +12.2 / +14.2 % (I_xx / I_yy / "
                   "I_zz, seed 0, sensor B) where direct EM is within 0.8 %; when the pipeline "
                   "is fixed this passes: update the README")
def test_measured_flight_pipeline_reads_a_closed_loop_flight_within_target():
    """The measured-flight pipeline (``realdata``'s band-passed M-step) should read the
    simulated closed-loop flight's inertia like any estimate of ours: within 3 % of the
    truth on every axis (paper.md's inertia target)."""
    sim = _closed_loop_response()
    assert np.all(np.abs(sim.band_rel_error) < 0.03), sim.band_rel_error


def test_simulate_rejects_a_non_positive_factor():
    out = subprocess.run([sys.executable, "-m", "pinquad.response", "--simulate", "0"],
                         capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert out.returncode == 2
    assert "positive" in out.stderr and "Traceback" not in out.stderr


def test_real_logs_roll_and_pitch_gain_falls_with_frequency(tmp_path):
    """The README's reading of the figure: on the clean logs the roll and pitch apparent
    inertia is near the published value at 5-8 Hz and about a third lower at 8-12 Hz."""
    assert (DATA / "imrc_brushed").is_dir(), f"the Crazyflie data are missing: {DATA}"
    env = dict(os.environ, PINQUAD_CRAZYFLIE_DATA=str(DATA))
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    fig = tmp_path / "response.png"
    out = subprocess.run([sys.executable, "-m", "pinquad.response", "--out", str(fig)],
                         capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert fig.is_file() and fig.stat().st_size > 10_000
    medians = {}
    for line in out.stdout.splitlines():
        if "median over the logs" in line:
            axis = line.split()[1]
            medians[axis] = {part.split(" Hz ")[0].strip(): float(part.split(" Hz ")[1])
                             for part in line.split(": ", 1)[1].split(", ")}
    for axis, published in (("x", 16.57), ("y", 16.66)):
        assert medians[axis]["5-8"] == pytest.approx(published, rel=0.15)
        assert medians[axis]["8-12"] < 0.8 * medians[axis]["5-8"]
        assert medians[axis]["3-5"] > medians[axis]["5-8"]


def test_missing_log_exits_2_with_the_path(tmp_path):
    env = dict(os.environ, PINQUAD_CRAZYFLIE_DATA=str(DATA))
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-m", "pinquad.response", "nosuchlog"],
                         capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 2
    assert "nosuchlog" in out.stderr and "Traceback" not in out.stderr


def _rotor_speed_log_in_milliseconds(path: Path) -> Path:
    """A 3 s hover log with rotor speeds whose time column is in milliseconds (the
    pipeline's check names it; the readers themselves accept any increasing times)."""
    t = 10.0 * np.arange(300)  # [ms], a 100 Hz log
    cols = {"t": t, "pos_x": np.zeros(300), "pos_y": np.zeros(300),
            "pos_z": np.full(300, 0.5), "quat_w": np.ones(300), "quat_x": np.zeros(300),
            "quat_y": np.zeros(300), "quat_z": np.zeros(300), "gyro_x": np.zeros(300),
            "gyro_y": np.zeros(300), "gyro_z": np.zeros(300),
            **{f"rpm_{i}": np.full(300, 16000.0) for i in range(1, 5)}}
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",",
               header=",".join(cols), comments="")
    return path


@pytest.mark.parametrize("command", ["response", "axis_inertia"])
def test_measured_log_commands_check_the_log_before_any_work(command, tmp_path, capsys):
    """``response`` and ``axis_inertia`` read a log through the pipeline's read and check:
    a time column in milliseconds exits 2 naming the file and the column."""
    import importlib

    main = importlib.import_module(f"pinquad.cli.{command}").main
    path = _rotor_speed_log_in_milliseconds(tmp_path / "ms.csv")
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "column 't'" in err and "milliseconds" in err, err
