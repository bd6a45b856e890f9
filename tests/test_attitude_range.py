"""Attitudes near the Euler angles' singularity (pinquad.models.attitude_range): found
from the measured pitch, made resets and excluded transitions, and on the flightgen
flight that rolled over near 85 deg of pitch, the smoother follows the attitude again."""

from __future__ import annotations

import numpy as np

from flightgen import generate, write_csv
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.experiments.discovery_mc_flightgen import flight_spec
from pinquad.io.read import read_log
from pinquad.models.attitude_range import PITCH_LIMIT, near_euler_singularity
from pinquad.models.sources import floor_contact, observations
from pinquad.models.ssm import NoiseModel, QuadSSM, Theta


def test_rows_within_the_margin_of_a_measured_pitch_beyond_the_limit():
    t = np.arange(100) * 0.002  # 500 Hz rows, attitude measured on every 5th (100 Hz)
    euler = np.full((100, 3), np.nan)
    euler[::5] = 0.0
    euler[50, 1] = -1.2  # one sample beyond -60 deg, at t = 0.1 s
    found = near_euler_singularity(t, euler, margin=0.01)
    np.testing.assert_array_equal(np.flatnonzero(found.rows), np.arange(45, 56))
    assert found.transitions() == 12  # 44 -> 45 up to 55 -> 56
    assert np.isclose(found.max_pitch, 1.2)
    assert "beyond +-60 deg (at most 69 deg" in found.report_lines()[0]
    euler[50, 1] = 0.9 * PITCH_LIMIT
    calm = near_euler_singularity(t, euler)
    assert not calm.rows.any() and calm.report_lines() == ()


def test_a_flip_is_cut_out_of_the_smoothing(tmp_path):
    """Flightgen's 500 Hz floor-strike flight 7016 pitches to 84 deg and rolls over 13 s
    in. Smoothed with the noise EM fitted to it without this exclusion (below), the
    smoother loses the attitude there and its backward pass carries the error back to the
    take-off; with the excursion's transitions as resets it follows the measured
    attitude within the motion capture's noise (5 mrad) elsewhere."""
    spec = flight_spec("floor_strikes", 7016, 16, 500)
    log = read_log(write_csv(generate(spec), tmp_path / "flip.csv"))
    contact = floor_contact(log, 0.035)
    singular = near_euler_singularity(log.t, log.euler)
    assert np.degrees(singular.max_pitch) > 80 and 100 < singular.transitions() < 400
    noise = NoiseModel(
        wrench=np.array([1.63e-05, 1.14e-05, 1.35e-05, 1.48e-12, 2.14e-12, 7.33e-13]),
        q_kin=np.array([4e-12] * 3 + [4e-10] * 3),
        meas=np.array([1.05e-06, 9.94e-07, 1.00e-06, 5.02e-05, 6.46e-05, 5.98e-05,
                       1.47e-03, 4.10e-04, 1.27e-03, 9.08e-05, 9.26e-05, 1.00e-04]))
    theta = Theta(0.035, np.diag([16.62e-6, 16.68e-6, 29.28e-6]), noise, 9.81)
    rms = {}
    for name, cut in (("plain", None), ("cut", singular)):
        obs = observations(log, "B", contact, cut)
        if cut is not None:
            touching = singular.touching()
            assert touching.sum() == singular.transitions()
            assert np.all(obs.resets[touching]) and np.all(obs.exclude[touching])
        post = smooth_quad(QuadSSM(obs, theta), obs.ys)
        free = np.isfinite(obs.ys[:, 6]) & ~obs.exclude
        miss = np.angle(np.exp(1j * (obs.ys[free, 6:9] - post.mean[free, 6:9])))
        rms[name] = np.sqrt(np.mean(miss**2, axis=0))
    assert np.all(rms["plain"] > 0.1), rms  # radians off
    assert np.all(rms["cut"] < 0.01), rms
