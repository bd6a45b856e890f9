"""The nuisance block of the one model (``Theta.nuisance``): the model adds its moment to
the logged torques, and a fit's block moves into the observations for discovery."""

from __future__ import annotations

import numpy as np

from pinquad.discovery.calibrated import start_from
from pinquad.models.nuisance import NuisanceMoment, torque_features
from pinquad.models.ssm import NoiseModel, Observations, QuadSSM, Theta, corrected


def _flight(n: int = 6) -> Observations:
    rng = np.random.default_rng(4)
    inputs = np.column_stack([np.full(n, 0.34), 1e-4 * rng.standard_normal((n, 3))])
    return Observations(t=0.01 * np.arange(n), dt=0.01, inputs=inputs, channels=("pos",),
                        ys=np.full((n, 3), np.nan), x0=np.zeros(12), p0=np.ones(12),
                        samples=inputs + 1e-5, continuous=True)


def _theta(nuisance: NuisanceMoment | None) -> Theta:
    noise = NoiseModel(wrench=np.full(6, 1e-6), q_kin=np.full(6, 1e-8), meas=np.full(3, 1e-4))
    return Theta(0.035, np.diag([1.6e-5, 1.7e-5, 2.9e-5]), noise, nuisance=nuisance)


def _block(n: int) -> NuisanceMoment:
    offset = 1e-4 * np.arange(3 * n, dtype=float).reshape(n, 3)
    return NuisanceMoment(torque_offset=offset, moment_coef=np.ones((3, 7)), rotor_inertia=2e-8)


def test_the_model_adds_the_nuisance_moment_to_the_logged_torques():
    obs = _flight()
    block = _block(obs.n)
    model = QuadSSM(obs, _theta(block))
    np.testing.assert_array_equal(model.obs.inputs[:, 1:4], obs.inputs[:, 1:4] + block.torque_offset)
    np.testing.assert_array_equal(model.obs.inputs[:, 0], obs.inputs[:, 0])
    np.testing.assert_array_equal(model.obs.samples[:, 1:4],
                                  obs.samples[:, 1:4] + block.torque_offset)
    # the same transition as the block moved into the observations of a plain Theta
    plain = QuadSSM(corrected(obs, _theta(block)), _theta(block).without_nuisance())
    x = np.r_[np.zeros(6), 0.1, -0.05, 0.3, 0.5, -0.2, 0.1]
    for k in range(obs.n - 1):
        nxt, jac = model.transition(x, k)
        nxt_p, jac_p = plain.transition(x, k)
        np.testing.assert_array_equal(nxt, nxt_p)
        np.testing.assert_array_equal(jac, jac_p)
    # and a different one from the logged torques alone (the block is not ignored)
    assert not np.array_equal(model.transition(x, 2)[0], QuadSSM(obs, _theta(None)).transition(x, 2)[0])


def test_without_a_block_the_observations_are_the_log():
    obs = _flight()
    theta = _theta(None)
    assert corrected(obs, theta) is obs
    assert theta.without_nuisance() is theta
    assert QuadSSM(obs, theta).obs is obs


def test_discovery_starts_from_the_block_moved_into_the_torques():
    obs = _flight()
    theta = _theta(_block(obs.n))
    post = object()
    start = start_from(obs, theta, post)  # type: ignore[arg-type]
    assert start.theta.nuisance is None
    assert start.theta.mass == theta.mass
    np.testing.assert_array_equal(start.obs.inputs[:, 1:4],
                                  obs.inputs[:, 1:4] + theta.nuisance.torque_offset)


def test_torque_features_are_thrust_body_velocity_and_rates():
    mean = np.zeros((2, 12))
    mean[:, 3:6] = [1.0, 0.0, 0.0]  # world-frame velocity along x
    mean[:, 8] = np.pi / 2  # yaw 90 deg: world x is body -y
    mean[:, 9:12] = [0.1, 0.2, 0.3]
    z = torque_features(mean, np.array([0.3, 0.4]))
    np.testing.assert_allclose(z[:, 0], [0.3, 0.4])
    np.testing.assert_allclose(z[:, 1:4], [[0.0, -1.0, 0.0]] * 2, atol=1e-12)
    np.testing.assert_allclose(z[:, 4:7], [[0.1, 0.2, 0.3]] * 2)
