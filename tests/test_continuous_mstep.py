"""The M-step of a continuous flight: the applied force along the interval's mean thrust
direction (``pinquad.mstep.updates.applied_force``), the mass that then minimises the
force rows' objective (``profiled_mass``), and why: on a flight the project did not
simulate, the held force leaves a lateral residual that the continuous one does not."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flightgen import CRAZYFLIE, FlightSpec, generate
from flightgen.rotation import euler_from_quats
from flightgen.spec import CLEAN
from pinquad.core.conventions import rotation_from_euler
from pinquad.models.sources import interval_inputs
from pinquad.mstep.stats import QuadraticSums
from pinquad.mstep.updates import applied_force, body_regressor, closed_form_mass, profiled_mass

GRAVITY = 9.81


def _states(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    x0 = rng.normal(size=(n, 12))
    x0[:, 6:9] = rng.uniform(-0.8, 0.8, size=(n, 3))
    x1 = x0 + 0.05 * rng.normal(size=(n, 12))
    return x0, x1


def test_applied_force_derivative_matches_central_differences():
    """d tau / d(Theta_k, Theta_{k+1}) against central differences (h = 1e-6 rad), zero
    in the velocity columns."""
    rng = np.random.default_rng(3)
    x0, x1 = _states(rng, 5)
    thrust = rng.uniform(0.2, 0.5, size=5)
    _, jac = applied_force(x0, x1, thrust, continuous=True)
    h = 1e-6
    for m in range(3):
        for which, col in ((0, m), (1, 9 + m)):
            plus = [x0.copy(), x1.copy()]
            minus = [x0.copy(), x1.copy()]
            plus[which][:, 6 + m] += h
            minus[which][:, 6 + m] -= h
            num = (applied_force(*plus, thrust, True)[0]
                   - applied_force(*minus, thrust, True)[0]) / (2 * h)
            np.testing.assert_allclose(jac[:, :, col], num, rtol=0, atol=1e-8)
    assert np.all(jac[:, :, 3:9] == 0.0)


def test_applied_force_held_and_unturned():
    """Held: F e3 and no state derivative. Continuous without a turn over the interval:
    F e3 too; a turn by theta about body y tilts it by theta / 2."""
    rng = np.random.default_rng(4)
    x0, x1 = _states(rng, 4)
    thrust = np.full(4, 0.3)
    held, jac = applied_force(x0, x1, thrust, continuous=False)
    assert jac is None
    np.testing.assert_array_equal(held, np.outer(thrust, [0.0, 0.0, 1.0]))
    still, _ = applied_force(x0, x0, thrust, continuous=True)
    np.testing.assert_allclose(still, held, rtol=0, atol=1e-15)
    level = np.zeros((1, 12))
    pitched = level.copy()
    pitched[0, 7] = 0.02
    turned, _ = applied_force(level, pitched, np.array([0.3]), continuous=True)
    np.testing.assert_allclose(turned[0], 0.3 * np.array([np.sin(0.02), 0.0, 1.0 + np.cos(0.02)])
                               / 2, rtol=0, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.02, 0.05), st.lists(st.floats(0.2, 3.0), min_size=4, max_size=4),
       st.lists(st.sampled_from([-1.0, 1.0]), min_size=3, max_size=3), st.floats(1e-3, 1e-2))
def test_profiled_mass_is_the_minimum_descent_reaches(mass, lateral, signs, noise):
    """On force-row sums q_j = a_j m^2 - 2 b_j m + c_j with lateral applied forces, the
    profiled mass is a stationary point of J(m) = 1/2 sum_j log q_j - 3 log m (m J' =
    sum_j t_j - 3 below 1e-10 sum_j |t_j|), lower than its neighbours, and J falls
    monotonically from the closed form c_z / b_z to it (or it is the end of the factor-2
    range); with no lateral force it is the closed form. Lateral accelerations 0.2-3
    m/s^2 either way, lateral applied forces off by 0.1-1 %, per-transition noise as a
    flight's (accelerations 0.5 m/s^2, forces 0.3 m m/s^2 rms): q is smooth in m."""
    lateral = [sgn * v for sgn, v in zip(signs, lateral, strict=False)] + [lateral[3]]
    a = np.zeros((6, 4, 4))
    b = np.zeros((6, 4))
    c = np.zeros(6)
    acc = np.array([lateral[0], lateral[1], 9.81 + lateral[2]])
    force = mass * acc * (1.0 + noise * np.array([1.0, -1.0, lateral[3]]))
    a[0:3, 0, 0] = acc**2 + 0.5**2
    b[0:3, 0] = acc * force
    c[0:3] = force**2 + (0.3 * mass) ** 2
    stats = QuadraticSums(a, b, c, 1.0)

    def objective(m: float) -> float:
        q = a[0:3, 0, 0] * m * m - 2.0 * b[0:3, 0] * m + c[0:3]
        return 0.5 * float(np.sum(np.log(q))) - 3.0 * np.log(m)

    m0 = closed_form_mass(stats, 0.0)
    m = profiled_mass(stats, 0.0)
    assert 0.5 * m0 <= m <= 2.0 * m0
    path = np.array([objective(v) for v in np.linspace(m0, m, 200)])
    assert np.all(np.diff(path) <= 1e-10 * np.abs(path[1:]))
    at_end = min(abs(m / m0 - 0.5), abs(m / m0 - 2.0)) < 0.011
    if not at_end:
        h = 1e-6 * m
        assert objective(m) <= min(objective(m - h), objective(m + h)) + 1e-14
        q = a[0:3, 0, 0] * m * m - 2.0 * b[0:3, 0] * m + c[0:3]
        terms = (a[0:3, 0, 0] * m * m - b[0:3, 0] * m) / q
        assert abs(float(np.sum(terms)) - 3.0) < 1e-10 * float(np.sum(np.abs(terms)))
    b[0:2] = 0.0
    c[0:2] = 0.0
    held = QuadraticSums(a, b, c, 1.0)
    assert profiled_mass(held, 0.0) == closed_form_mass(held, 0.0)


def test_a_flightgen_flight_leaves_no_lateral_force_under_the_continuous_model():
    """A noise-free aggressive 100 Hz flight of the independent generator (2 kHz
    controller, commands sampled at the log rows), its TRUE states: the held model's
    body x/y force residual m R_k^T (a_k + g e3) - F e3 is the thrust direction's turn
    over the interval (about F dt omega / 2); along the interval's mean direction it
    drops to the trapezoid rule's second-order remainder (ratio measured 0.04-0.05)."""
    spec = FlightSpec(duration=8.0, trajectory="sines", aggressive=True, log_rate=100,
                      dt=0.0005, seed=2, vehicle=CRAZYFLIE, noise=CLEAN, floor=None)
    flight = generate(spec)
    every = int(round(1.0 / (spec.log_rate * spec.dt)))
    truth = flight.state[::every]
    x = np.column_stack([truth[:, 0:6], euler_from_quats(truth[:, 6:10]), truth[:, 10:13]])
    inputs = interval_inputs(flight.command[::every], "sampled")
    x0, x1 = x[:-1], x[1:]
    dt = every * spec.dt
    measured = CRAZYFLIE.mass * body_regressor(x0, x1, dt, GRAVITY)[:, 0:3, 0]
    rms = {}
    for continuous in (False, True):
        force, _ = applied_force(x0, x1, inputs[:-1, 0], continuous)
        rms[continuous] = float(np.sqrt(np.mean((measured - force)[:, 0:2] ** 2)))
    tilt = np.linalg.norm(rotation_from_euler(x1[:, 6:9])[:, :, 2]
                          - rotation_from_euler(x0[:, 6:9])[:, :, 2], axis=1)
    assert rms[False] > 0.3 * float(np.sqrt(np.mean((0.5 * tilt * inputs[:-1, 0]) ** 2)))
    assert rms[True] < 0.1 * rms[False], rms
