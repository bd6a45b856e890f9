"""Pinocchio model, closed-form dynamics, regressors and Jacobians."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinquad.core.conventions import (
    euler_from_quat_wxyz,
    euler_from_rotation,
    quat_wxyz_from_euler,
    rotation_from_euler,
)
from pinquad.core.params import CRAZYFLIE21, PAPER_VEHICLE, Vehicle
from pinquad.models.navigation import NavTuning, SensorANavModel
from pinquad.mstep.updates import body_regressor
from pinquad.vehicle.model import (
    RigidBodyParams,
    dynamic_parameters,
    forward_dynamics,
    inertial_regressor,
    inverse_dynamics_wrench,
    load_model,
    pinocchio_motion,
    state_derivative_and_jacobian,
)


def random_state(rng: np.random.Generator) -> np.ndarray:
    x = rng.standard_normal(12)
    x[6:8] = rng.uniform(-1.0, 1.0, 2)
    x[8] = rng.uniform(-3.0, 3.0)
    return x


@pytest.mark.parametrize("vehicle", [PAPER_VEHICLE, CRAZYFLIE21])
def test_regressor_times_parameters_equals_rnea(vehicle):
    rng = np.random.default_rng(0)
    veh = Vehicle(vehicle.name, vehicle.mass, vehicle.inertia + 1e-6 * np.array(
        [[0, 1, 2], [1, 0, 3], [2, 3, 0]]), vehicle.arm, com=np.array([0.003, -0.002, 0.004]))
    model = load_model(veh)
    data = model.createData()
    pi = dynamic_parameters(veh)
    for _ in range(20):
        x, xd = random_state(rng), rng.standard_normal(12)
        y = inertial_regressor(model, data, x, xd)
        np.testing.assert_allclose(y @ pi, inverse_dynamics_wrench(model, data, x, xd),
                                   rtol=0, atol=1e-12 * max(1.0, np.abs(y @ pi).max()))


def test_closed_form_dynamics_equals_pinocchio_aba():
    rng = np.random.default_rng(1)
    veh = PAPER_VEHICLE
    model = load_model(veh)
    data = model.createData()
    body = RigidBodyParams.of(veh)
    for _ in range(20):
        x = random_state(rng)
        u = np.array([rng.uniform(0.5, 3.0), *rng.normal(0, 1e-3, 3)])
        f_pin = forward_dynamics(model, data, x, u)
        f_cf, _ = state_derivative_and_jacobian(x, u, body)
        np.testing.assert_allclose(f_cf, f_pin, rtol=1e-10, atol=1e-10)


def test_body_regressor_equals_pinocchio_columns():
    """The M-step's vectorised regressor is Pinocchio's for pi = [m, Ixx, Iyy, Izz]."""
    rng = np.random.default_rng(2)
    veh = PAPER_VEHICLE
    model = load_model(veh)
    data = model.createData()
    dt = 0.01
    x0 = np.array([random_state(rng) for _ in range(10)])
    x1 = x0 + dt * rng.standard_normal((10, 12))
    ours = body_regressor(x0, x1, dt, veh.gravity)
    for k in range(10):
        xd = (x1[k] - x0[k]) / dt
        y_pin = inertial_regressor(model, data, x0[k], xd)
        np.testing.assert_allclose(ours[k], y_pin[:, [0, 4, 6, 9]], rtol=1e-9, atol=1e-9)


def test_jacobian_equals_finite_differences():
    rng = np.random.default_rng(3)
    body = RigidBodyParams.of(PAPER_VEHICLE)
    for _ in range(10):
        x = random_state(rng)
        u = np.array([2.0, 1e-3, -2e-3, 5e-4])
        _, jac = state_derivative_and_jacobian(x, u, body)
        num = np.empty((12, 12))
        for i in range(12):
            e = np.zeros(12)
            e[i] = 1e-6
            num[:, i] = (state_derivative_and_jacobian(x + e, u, body)[0]
                         - state_derivative_and_jacobian(x - e, u, body)[0]) / 2e-6
        np.testing.assert_allclose(jac, num, rtol=1e-6, atol=1e-6)


def test_navigation_filter_jacobian_equals_finite_differences():
    rng = np.random.default_rng(4)
    accel = rng.normal([0, 0, 9.81], 1.0, (5, 3))
    model = SensorANavModel(accel, 0.01, NavTuning.tuned(0.01), x0=np.zeros(12))
    for k in range(5):
        x = random_state(rng)
        _, jac = model.transition(x, k)
        num = np.empty((12, 12))
        for i in range(12):
            e = np.zeros(12)
            e[i] = 1e-6
            num[:, i] = (model.transition(x + e, k)[0] - model.transition(x - e, k)[0]) / 2e-6
        np.testing.assert_allclose(jac, num, rtol=1e-6, atol=1e-8)


def test_hover_gives_zero_acceleration():
    veh = PAPER_VEHICLE
    model = load_model(veh)
    x = np.zeros(12)
    x[0:3] = [1.0, 2.0, 3.0]
    x[8] = 0.7
    f = forward_dynamics(model, model.createData(), x, np.array([veh.mass * veh.gravity, 0, 0, 0]))
    np.testing.assert_allclose(f, np.zeros(12), atol=1e-12)


def test_torque_free_spin_conserves_angular_momentum():
    """RK4 on Pinocchio's ABA: world angular momentum R I omega stays constant."""
    veh = PAPER_VEHICLE
    model = load_model(veh)
    data = model.createData()
    g_off = pin.Motion(np.zeros(3), np.zeros(3))
    model.gravity = g_off
    x = np.zeros(12)
    x[9:12] = [3.0, -2.0, 5.0]
    u = np.zeros(4)
    dt = 1e-4

    def momentum(state):
        return rotation_from_euler(state[6:9]) @ (veh.inertia @ state[9:12])

    h0 = momentum(x)
    for _ in range(2000):
        k1 = forward_dynamics(model, data, x, u)
        k2 = forward_dynamics(model, data, x + 0.5 * dt * k1, u)
        k3 = forward_dynamics(model, data, x + 0.5 * dt * k2, u)
        k4 = forward_dynamics(model, data, x + dt * k3, u)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(momentum(x), h0, rtol=1e-8, atol=1e-12)
    # kinetic energy too
    e0 = 0.5 * np.array([3.0, -2.0, 5.0]) @ veh.inertia @ np.array([3.0, -2.0, 5.0])
    assert abs(0.5 * x[9:12] @ veh.inertia @ x[9:12] - e0) < 1e-9 * e0


def test_pinocchio_motion_matches_free_flyer_velocity():
    rng = np.random.default_rng(5)
    x = random_state(rng)
    q, v, _ = pinocchio_motion(x, np.zeros(12))
    rot = rotation_from_euler(x[6:9])
    np.testing.assert_allclose(pin.Quaternion(q[3:7]).matrix(), rot, atol=1e-12)
    np.testing.assert_allclose(rot @ v[0:3], x[3:6], atol=1e-12)


def test_conventions_round_trip():
    rng = np.random.default_rng(6)
    eul = np.column_stack([rng.uniform(-3, 3, 50), rng.uniform(-1.5, 1.5, 50), rng.uniform(-3, 3, 50)])
    np.testing.assert_allclose(euler_from_rotation(rotation_from_euler(eul)), eul, atol=1e-10)
    np.testing.assert_allclose(euler_from_quat_wxyz(quat_wxyz_from_euler(eul)), eul, atol=1e-10)


def test_cross3_is_numpy_cross_bit_for_bit():
    from pinquad.vehicle.model import cross3

    rng = np.random.default_rng(0)
    for _ in range(2000):
        a = rng.normal(size=3) * 10.0 ** rng.uniform(-6, 6, 3)
        b = rng.normal(size=3) * 10.0 ** rng.uniform(-6, 6, 3)
        np.testing.assert_array_equal(cross3(a, b), np.cross(a, b))
