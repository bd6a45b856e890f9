"""flightgen, the second flight generator (issue 22 item 4): its integrator, controller
and logs, and pinquad reading and identifying what it writes. flightgen imports no
pinquad (import-linter contract); these tests may."""

from __future__ import annotations

import numpy as np
import pytest

from flightgen import CLEAN, CRAZYFLIE, QUAD_250, Effects, FlightSpec, generate, write_csv
from flightgen.dynamics import make_body, rk4_step
from flightgen.rotation import quat_to_rot
from flightgen.vehicle import Vehicle
from pinquad.api import identify
from pinquad.io.read import read_log

TILTED = Vehicle(name="tilted", mass=0.035,
                 inertia=((16.6e-6, 1.2e-6, -0.8e-6), (1.2e-6, 16.7e-6, 0.5e-6),
                          (-0.8e-6, 0.5e-6, 29.3e-6)),
                 arm=0.046, thrust_max=0.6, torque_max=(0.01, 0.01, 0.003), ground_radius=0.046)


def _spin(dt: float, seconds: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Torque-free tumble of a full-tensor body in free fall: (x0, x_end, dt)."""
    body = make_body(TILTED, Effects(), floor=None)
    x = np.zeros(13)
    x[0:3] = (0.1, -0.2, 5.0)
    x[3:6] = (0.3, 0.1, 2.0)
    x[6:10] = (0.9, 0.1, -0.3, 0.2)
    x[6:10] /= np.linalg.norm(x[6:10])
    x[10:13] = (3.0, -1.0, 6.0)  # near the intermediate axis: a tumbling motion
    x0 = x.copy()
    for _ in range(int(round(seconds / dt))):
        x = rk4_step(x, dt, 0.0, np.zeros(3), body)
    return x0, x, dt


def _invariants(x: np.ndarray) -> tuple[float, np.ndarray]:
    j = TILTED.inertia_matrix
    w = x[10:13]
    return 0.5 * w @ j @ w, quat_to_rot(x[6:10]) @ j @ w


def test_torque_free_body_conserves_energy_and_momentum_to_rk4_accuracy():
    """0.5 w^T J w and the world angular momentum R J w stay constant (relative drift
    < 1e-9 over 2 s at 1 ms), the drift shrinks like dt^4 (at least 12x from 2 ms to 1
    ms), and free fall is exact (RK4 integrates the quadratic p(t) without error)."""
    drift = []
    for dt in (0.002, 0.001):
        x0, x1, _ = _spin(dt, 2.0)
        e0, h0 = _invariants(x0)
        e1, h1 = _invariants(x1)
        drift.append(max(abs(e1 - e0) / e0, np.linalg.norm(h1 - h0) / np.linalg.norm(h0)))
        t = 2.0
        fall = x0[0:3] + x0[3:6] * t - 0.5 * 9.81 * t * t * np.array([0, 0, 1.0])
        np.testing.assert_allclose(x1[0:3], fall, atol=1e-10)
    assert drift[1] < 1e-9
    assert drift[0] / drift[1] > 12.0


def test_hover_thrust_holds_the_vehicle_still():
    body = make_body(CRAZYFLIE, Effects(), floor=None)
    x = np.zeros(13)
    x[2], x[6] = 1.0, 1.0
    for _ in range(5000):
        x = rk4_step(x, 0.001, CRAZYFLIE.mass * 9.81, np.zeros(3), body)
    np.testing.assert_allclose(x[0:6], [0, 0, 1.0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(x[6:13], [1.0, 0, 0, 0, 0, 0, 0], atol=1e-12)


@pytest.mark.parametrize("kind", ["sines", "minsnap"])
def test_controller_tracks_a_gentle_trajectory_and_keeps_the_quaternion_unit(kind):
    flight = generate(FlightSpec(duration=10.0, trajectory=kind, dt=0.001, seed=2, noise=CLEAN))
    err = np.linalg.norm(flight.state[:, 0:3] - flight.reference, axis=1)
    assert err.max() < 0.03
    assert np.abs(np.linalg.norm(flight.state[:, 6:10], axis=1) - 1.0).max() < 1e-12
    assert np.ptp(flight.reference, axis=0)[:2].min() > 0.3  # it does move


def test_aggressive_flight_of_a_larger_quad_with_every_effect_stays_on_track():
    effects = Effects(drag=(0.1, 0.1, 0.2), ground_effect=1.0, com_offset=(0.003, -0.002),
                      wind=(0.05, 0.0), motor_lag=0.02, gyro_bias=(0.01, -0.02, 0.005))
    flight = generate(FlightSpec(duration=8.0, trajectory="minsnap", aggressive=True, dt=0.001,
                                 seed=4, vehicle=QUAD_250, effects=effects))
    err = np.linalg.norm(flight.state[:, 0:3] - flight.reference, axis=1)
    assert err[1000:].max() < 0.15
    acc = np.linalg.norm(flight.accel_world, axis=1)
    assert acc.max() > 4.0  # aggressive
    gyro = np.column_stack([flight.columns[f"gyro_{a}"] for a in "xyz"])
    true = np.column_stack([flight.columns[f"true_gyro_{a}"] for a in "xyz"])
    np.testing.assert_allclose((gyro - true).mean(axis=0), effects.gyro_bias, atol=2e-3)
    assert effects.coefficients()["tau_m"] == 0.02


def test_floor_take_off_strikes_and_landing_leave_no_contact_flag(tmp_path):
    flight = generate(FlightSpec(duration=16.0, dt=0.001, seed=5, start_on_floor=True, land=True,
                                 floor_strikes=2, log_rate=250))
    z = flight.state[:, 2]
    contact = flight.in_contact
    assert contact[:1000].all() and contact[-1000:].all()  # on the floor, then landed
    strikes = contact[5000:-5000]
    assert strikes.any()  # the dips strike the floor
    assert z.min() > -0.01  # the floor holds
    assert z.max() > 0.5
    log = read_log(write_csv(flight, tmp_path / "floor.csv"))
    assert log.contact is None
    assert "contact" not in flight.columns


@pytest.mark.parametrize("rate", [100, 250, 500])
def test_pinquad_reads_the_csv_with_mocap_at_100_hz_and_sampled_actuation(tmp_path, rate):
    flight = generate(FlightSpec(duration=2.0, dt=0.0005, seed=6, log_rate=rate))
    path = write_csv(flight, tmp_path / "f.csv", mass_guess=0.03)
    log = read_log(path)
    assert log.n == int(2.0 * rate) + 1
    assert log.dt == pytest.approx(1.0 / rate)
    every = rate // 100
    has_mocap = np.isfinite(log.position[:, 0])
    assert has_mocap[::every].all() and has_mocap.sum() == has_mocap[::every].size
    assert np.isfinite(log.euler[has_mocap]).all() and np.isnan(log.euler[~has_mocap]).all()
    assert np.isfinite(log.velocity[has_mocap]).all()
    assert np.isfinite(log.gyro).all() and np.isfinite(log.accel).all()
    step = int(round(1.0 / (rate * flight.spec.dt)))
    np.testing.assert_array_equal(log.thrust, flight.command[::step, 0])  # sampled, not averaged
    np.testing.assert_array_equal(log.torque, flight.command[::step, 1:4])
    assert log.truth is not None and log.truth.shape == (log.n, 12)
    np.testing.assert_allclose(log.truth[:, 0:3], flight.state[::step, 0:3])
    np.testing.assert_allclose(log.truth[:, 9:12], flight.state[::step, 10:13])
    np.testing.assert_allclose(log.euler[has_mocap], log.truth[has_mocap, 6:9], atol=0.03)
    np.testing.assert_allclose(np.median(log.accel[:, 2]), 9.81, atol=0.3)
    assert log.meta.vehicle == "crazyflie21" and log.meta.mass_guess == 0.03


INERTIA_FOUND = (15.54e-6, 15.74e-6, 31.28e-6)
"""identify() on the 10 s, 500 Hz, clean Crazyflie-class flight below (seed 3), its
sampled input read as the mean of each interval's two rows: I_xx -6 %, I_yy -6 %, I_zz
+7 % (each row held, as before issue 22's item 2: +3, +4, +18 %); the mass is right to
0.02 %. A finding for issue 22 (flights pinquad did not simulate; docs/trust.md), not a
tolerance to loosen: the verdict of ``offline --log`` calls this inertia not identifiable
(it moves by more than 5 % between the two readings of the input)."""


@pytest.fixture(scope="module")
def crazyflie_identification(tmp_path_factory):
    flight = generate(FlightSpec(duration=10.0, dt=0.001, seed=3, log_rate=500))
    path = write_csv(flight, tmp_path_factory.mktemp("fg") / "cf.csv")
    return identify(read_log(path), information=False).run


def test_identify_gets_the_mass_of_a_flightgen_crazyflie(crazyflie_identification):
    assert crazyflie_identification.mass == pytest.approx(CRAZYFLIE.mass, rel=0.02)


@pytest.mark.xfail(strict=True, reason="issue 22: I_xx 16.3, I_yy 16.4, I_zz 32.7 e-6 vs "
                   "16.6, 16.7, 29.3 e-6 kg m^2 on a 10 s 500 Hz flightgen log")
def test_identify_gets_the_inertia_of_a_flightgen_crazyflie(crazyflie_identification):
    found = np.diag(crazyflie_identification.inertia)
    np.testing.assert_allclose(found, np.diag(CRAZYFLIE.inertia_matrix), rtol=0.05)
