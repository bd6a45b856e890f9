"""pinquad.sim.control (minimum-jerk reference, flatness, LQR gains) and pinquad.sim.sensors
(rates, NaN rows, frozen noise levels), against closed forms and chi-square bands."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are
from scipy.stats import chi2

from pinquad.core.conventions import rotation_from_euler
from pinquad.core.params import FROZEN_SENSOR_NOISE, Scenario
from pinquad.sim.control import _min_jerk, build_reference, design_gains, flatness_attitude
from pinquad.sim.sensors import SENSORS, measure, measure_one

G = 9.81
SCENARIO = Scenario(start=np.array([0.0, 0.0, 0.0]),
                    waypoints=np.array([[1.0, 0.0, 1.0], [1.0, 3.0, 1.5]]),
                    dt=0.01, cruise_speed=1.0, hover_time=0.5, yaw=0.3)


def test_min_jerk_blend_closed_form_end_conditions():
    """The quintic 10 s^3 - 15 s^4 + 6 s^5 goes 0 -> 1 with zero velocity and acceleration
    at both ends, peak slope 15/8 at s = 1/2."""
    pos, vel, acc = _min_jerk(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(pos, [0.0, 0.5, 1.0], atol=1e-12)
    np.testing.assert_allclose(vel, [0.0, 1.875, 0.0], atol=1e-12)
    np.testing.assert_allclose(acc, [0.0, 0.0, 0.0], atol=1e-12)


def test_reference_reaches_each_waypoint_at_rest_and_is_self_consistent():
    ref = build_reference(SCENARIO)
    dt = SCENARIO.dt
    np.testing.assert_allclose(ref.t, np.arange(ref.t.size) * dt)
    np.testing.assert_allclose(ref.pos[0], SCENARIO.start)
    for wp, t_wp in zip(SCENARIO.waypoints, ref.waypoint_times, strict=True):
        k = int(round(t_wp / dt))
        np.testing.assert_allclose(ref.pos[k], wp, atol=1e-12)
        np.testing.assert_allclose(ref.vel[k], 0.0, atol=1e-12)
        np.testing.assert_allclose(ref.acc[k], 0.0, atol=1e-12)
        # The last moving sample is within one step of the waypoint, nearly at rest.
        assert np.linalg.norm(ref.pos[k - 1] - wp) < 1e-5
        assert np.linalg.norm(ref.vel[k - 1]) < 1e-2
    # Segment 2 (|d| = sqrt(9.25) m at 1 m/s) takes 1.875 |d| s: peak speed = cruise speed.
    d = np.linalg.norm(SCENARIO.waypoints[1] - SCENARIO.waypoints[0])
    seg = ref.t > ref.waypoint_times[0]
    assert np.max(np.linalg.norm(ref.vel[seg], axis=1)) == pytest.approx(1.0, rel=1e-3)
    assert ref.waypoint_times[1] - ref.waypoint_times[0] - SCENARIO.hover_time == \
        pytest.approx(1.875 * d, abs=dt)
    # Velocity and acceleration are the time derivatives of position (central differences).
    np.testing.assert_allclose(np.gradient(ref.pos, dt, axis=0)[1:-1], ref.vel[1:-1],
                               atol=2e-3)
    np.testing.assert_allclose(np.gradient(ref.vel, dt, axis=0)[1:-1], ref.acc[1:-1],
                               atol=2e-2)
    np.testing.assert_allclose(ref.yaw, SCENARIO.yaw)


@pytest.mark.parametrize("acc_cmd, yaw", [
    (np.array([0.0, 0.0, 0.0]), 0.0),
    (np.array([2.0, -1.0, 0.5]), 0.7),
    (np.array([-3.0, 2.5, -2.0]), -2.5),
])
def test_flatness_thrust_axis_and_yaw(acc_cmd, yaw):
    euler, norm = flatness_attitude(acc_cmd, yaw, G)
    t = acc_cmd + np.array([0.0, 0.0, G])
    rot = rotation_from_euler(euler)
    assert norm == pytest.approx(np.linalg.norm(t), rel=1e-12)
    np.testing.assert_allclose(rot[:, 2], t / np.linalg.norm(t), atol=1e-9)
    # Body x lies in the vertical plane of heading yaw (orthogonal to y_C), pointing ahead.
    y_c = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    assert abs(rot[:, 0] @ y_c) < 1e-9
    assert rot[:, 0] @ heading > 0.0
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-9)


def _double_integrator_k(q1: float, q2: float) -> np.ndarray:
    """Closed form of the LQR gain for e'' = u, cost e^T diag(q1, q2) e + u^2."""
    return np.array([math.sqrt(q1), math.sqrt(q2 + 2.0 * math.sqrt(q1))])


def test_lqr_gains_match_closed_form_and_riccati_and_stabilise():
    gains = design_gains()
    k_pos = _double_integrator_k(10.0, 1.0)
    k_att = _double_integrator_k(100.0, 6400.0)
    np.testing.assert_allclose(gains.kp, k_pos[0], rtol=1e-6)
    np.testing.assert_allclose(gains.kv, k_pos[1], rtol=1e-6)
    np.testing.assert_allclose(gains.ka, k_att[0], rtol=1e-6)
    np.testing.assert_allclose(gains.kw, k_att[1], rtol=1e-6)
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    b = np.array([[0.0], [1.0]])
    other = design_gains(pos_weights=(3.0, 0.5), att_weights=(7.0, 2.0))
    p = solve_continuous_are(a, b, np.diag([3.0, 0.5]), np.eye(1))
    np.testing.assert_allclose([other.kp[0], other.kv[0]], (b.T @ p).ravel(), rtol=1e-6)
    for kp, kv in ((gains.kp[0], gains.kv[0]), (gains.ka[0], gains.kw[0])):
        eig = np.linalg.eigvals(a - b @ np.array([[kp, kv]]))
        assert np.all(eig.real < 0.0)


N_ROWS = 3000
CHANNELS = {"position": (0, "position_every"), "velocity": (3, "velocity_every"),
            "euler": (6, "euler_every"), "gyro": (9, "gyro_every")}


@pytest.mark.parametrize("name", ["A", "B", "C"])
def test_sensor_suite_rates_nan_rows_and_noise_level(name):
    suite = SENSORS[name]
    rng = np.random.default_rng(11)
    states = 0.3 * rng.standard_normal((N_ROWS, 12))
    force = rng.standard_normal((N_ROWS, 3)) + np.array([0.0, 0.0, G])
    meas = measure(suite, states, force, np.random.default_rng(100 + ord(name)))
    truth = {q: states[:, c:c + 3] for q, (c, _) in CHANNELS.items()} | {"accel": force}
    every = {q: getattr(suite, attr) for q, (_, attr) in CHANNELS.items()}
    every["accel"] = suite.accel_every
    expected_every = {"A": dict(position=2, velocity=0, euler=0, gyro=1, accel=1),
                      "B": dict(position=2, velocity=2, euler=2, gyro=1, accel=0),
                      "C": dict(position=2, velocity=2, euler=0, gyro=1, accel=0)}[name]
    assert every == expected_every
    for q, n_every in every.items():
        got = getattr(meas, q)
        sampled = np.zeros(N_ROWS, bool)
        if n_every:
            sampled[::n_every] = True
        assert np.all(np.isfinite(got[sampled])), q
        assert np.all(np.isnan(got[~sampled])), q
        if not n_every:
            continue
        noise = (got - truth[q])[sampled].ravel()
        sigma = getattr(FROZEN_SENSOR_NOISE, q)
        dof = noise.size  # known zero mean: sum of squares / sigma^2 ~ chi2(n)
        stat = float(noise @ noise) / sigma**2
        assert chi2.ppf(0.0005, dof) < stat < chi2.ppf(0.9995, dof), (q, stat / dof)
        assert abs(noise.mean()) < 4.0 * sigma / math.sqrt(dof), q


def test_measure_one_samples_only_on_its_rate():
    suite = SENSORS["B"]
    state = np.arange(12, dtype=float) * 0.1
    rng = np.random.default_rng(2)
    odd = measure_one(suite, 3, state, np.zeros(3), rng)
    assert np.all(np.isnan(odd.position)) and np.all(np.isnan(odd.euler))
    assert np.all(np.isnan(odd.accel))
    assert np.all(np.abs(odd.gyro - state[9:12]) < 5 * FROZEN_SENSOR_NOISE.gyro)
    even = measure_one(suite, 4, state, np.zeros(3), rng)
    assert np.all(np.abs(even.position - state[0:3]) < 5 * FROZEN_SENSOR_NOISE.position)
    assert np.all(np.abs(even.euler - state[6:9]) < 5 * FROZEN_SENSOR_NOISE.euler)
