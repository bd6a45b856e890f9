"""EM: monotone likelihood on a linear-Gaussian model; M-steps against known answers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from estimators.linear import LinearGaussianModel, linear_change, linear_em_mstep
from estimators.protocol import Posterior
from estimators.rts import smooth
from pinquad.identification.em import run_em
from pinquad.models.sources import observations
from pinquad.models.ssm import NoiseModel, Theta, kinematic_floor
from pinquad.mstep.protocol import REGRESSOR, MStep
from pinquad.mstep.updates import body_regressor, regressor_mstep
from pinquad.sim.simulator import SimConfig, flight_log, simulate


@dataclass(frozen=True)
class _Data:
    ys: np.ndarray


def test_em_loglik_never_decreases_on_linear_gaussian_model():
    rng = np.random.default_rng(21)
    n = 3
    a = np.array([[0.9, 0.1, 0.0], [-0.1, 0.85, 0.05], [0.0, 0.0, 0.7]])
    c = rng.standard_normal((2, n))
    truth = LinearGaussianModel(a=a, c=c, q=0.1 * np.eye(n), r=np.diag([0.2, 0.3]),
                                m0=np.zeros(n), p0=np.eye(n))
    _, ys = truth.simulate(400, rng)
    ys[rng.random(ys.shape) < 0.15] = np.nan
    start = LinearGaussianModel(a=0.5 * np.eye(n), c=c, q=np.eye(n), r=np.eye(2),
                                m0=np.zeros(n), p0=np.eye(n))
    res = run_em(_Data(ys), start, smooth, MStep(linear_em_mstep), max_iterations=40, tol=0.0,
                 tol_loglik=0.0, model_factory=lambda data, model: model,
                 distance=linear_change, quadcopter=False)
    ll = res.loglik
    assert ll.size >= 30
    steps = np.diff(ll)
    assert np.all(steps >= -1e-8 * np.abs(ll[:-1])), steps.min()
    assert ll[-1] > ll[0] + 10.0  # it did climb


def test_em_stops_at_the_last_good_iterate_when_the_e_step_breaks_down():
    """A filter that loses positive definiteness mid-run ends EM at the last iterate
    whose E-step worked, not converged, with the reason recorded (no traceback)."""
    rng = np.random.default_rng(5)
    n = 2
    truth = LinearGaussianModel(a=0.9 * np.eye(n), c=np.eye(n), q=0.1 * np.eye(n),
                                r=0.2 * np.eye(n), m0=np.zeros(n), p0=np.eye(n))
    _, ys = truth.simulate(200, rng)
    start = LinearGaussianModel(a=0.5 * np.eye(n), c=np.eye(n), q=np.eye(n), r=np.eye(n),
                                m0=np.zeros(n), p0=np.eye(n))
    calls = []

    def breaking(model, data):
        calls.append(model)
        if len(calls) == 4:
            raise np.linalg.LinAlgError("Matrix is not positive definite")
        return smooth(model, data)

    res = run_em(_Data(ys), start, breaking, MStep(linear_em_mstep), max_iterations=10, tol=0.0,
                 tol_loglik=0.0, model_factory=lambda data, model: model,
                 distance=linear_change, quadcopter=False)
    assert not res.converged
    assert res.failure is not None and "not positive definite" in res.failure
    assert res.loglik.size == 3 and res.e_steps == 4
    assert res.theta is calls[2]  # the iterate of the last E-step that worked


def _clean_flight():
    flight = simulate(SimConfig(sensor="B"), np.random.default_rng(3))
    return flight, flight_log(flight)


@pytest.fixture(scope="module")
def clean():
    return _clean_flight()


def _truth_posterior(states: np.ndarray) -> Posterior:
    n = states.shape[0]
    return Posterior(states.copy(), np.zeros((n, 12, 12)), np.zeros((n - 1, 12, 12)), 0.0,
                     "truth", np.zeros((n, 12), dtype=bool))


def test_noise_free_transitions_recover_true_parameters(clean):
    """With the true states and noise-free actuation the M-step is exact."""
    flight, log = clean
    obs = observations(log, "B")
    # Replace the logged commands by what actually acted (noise included): then every
    # transition satisfies the model exactly.
    inputs = flight.applied.copy()
    from dataclasses import replace

    obs = replace(obs, inputs=inputs)
    theta = Theta(0.1, np.diag([1e-4, 2e-4, 1e-4]),
                  NoiseModel(np.full(6, 1e-6), kinematic_floor(obs.dt), np.full(12, 1e-4)))
    new = regressor_mstep(_truth_posterior(flight.states), obs, theta).theta
    veh = flight.config.vehicle
    assert abs(new.mass / veh.mass - 1) < 1e-6
    np.testing.assert_allclose(np.diag(new.inertia), np.diag(veh.inertia), rtol=1e-6)


def test_regressor_mstep_equals_independent_least_squares(clean):
    """Mass = sum F^2 / sum F a_z (profiled ML), and the inertia matches a direct
    minimisation of the same objective built from a hand-built regressor."""
    from scipy.optimize import minimize

    flight, log = clean
    obs = observations(log, "B")
    states = flight.states
    theta = Theta(0.1, np.diag([1e-4, 2e-4, 1e-4]),
                  NoiseModel(np.full(6, 1e-6), kinematic_floor(obs.dt), np.full(12, 1e-4)))
    ours = regressor_mstep(_truth_posterior(states), obs, theta).theta
    use = ~obs.exclude[:-1]
    x0, x1 = states[:-1][use], states[1:][use]
    u = obs.inputs[:-1][use]
    dt, g = obs.dt, 9.81
    # hand-built body regressor rows
    rot = np.array([_rot(e) for e in x0[:, 6:9]])
    acc_b = np.einsum("kji,kj->ki", rot, (x1[:, 3:6] - x0[:, 3:6]) / dt + [0, 0, g])
    mass = np.sum(u[:, 0] ** 2) / np.sum(u[:, 0] * acc_b[:, 2])
    assert abs(ours.mass / mass - 1) < 1e-12
    wd = (x1[:, 9:12] - x0[:, 9:12]) / dt
    w = x0[:, 9:12]

    def torque_resid(i_diag):
        ixx, iyy, izz = i_diag
        return np.column_stack([
            ixx * wd[:, 0] + (izz - iyy) * w[:, 1] * w[:, 2] - u[:, 1],
            iyy * wd[:, 1] + (ixx - izz) * w[:, 0] * w[:, 2] - u[:, 2],
            izz * wd[:, 2] + (iyy - ixx) * w[:, 0] * w[:, 1] - u[:, 3]])

    def objective(log_i):
        i_diag = np.exp(log_i)
        return 0.5 * np.sum(np.log(np.sum(torque_resid(i_diag) ** 2, axis=0))) - np.sum(log_i)

    ref = minimize(objective, np.log([2e-4, 3e-4, 2e-4]), method="Nelder-Mead",
                   options={"xatol": 1e-10, "fatol": 1e-14, "maxiter": 20000})
    np.testing.assert_allclose(np.diag(ours.inertia), np.exp(ref.x), rtol=1e-5)
    # and the vectorised regressor agrees with the hand-built one
    y = body_regressor(x0, x1, dt, g)
    np.testing.assert_allclose(y[:, 0:3, 0], acc_b, rtol=1e-12, atol=1e-12)


def _rot(e):
    from pinquad.core.conventions import rotation_from_euler

    return rotation_from_euler(e)


def test_per_parameter_over_relaxation_converges_higher_in_fewer_e_steps(clean):
    """One over-relaxation factor per parameter (``run_em(per_parameter=True)``, the
    refit's) reaches the same mass and inertia as the shared factor, at a log-likelihood
    no lower, in fewer E-steps (sensor B, seed 3: 65 against 96 when written), with the
    log-likelihood never falling along the accepted iterates."""
    from pinquad.estep.fast_smoother import smooth_quad
    from pinquad.identification.em import initial_theta

    _, log = clean
    obs = observations(log, "B")
    start = initial_theta(obs, 0.03, np.diag([1.5e-4, 1.5e-4, 2.5e-4]), 9.81)
    shared = run_em(obs, start, smooth_quad, REGRESSOR, max_iterations=300)
    per = run_em(obs, start, smooth_quad, REGRESSOR, max_iterations=300,
                 per_parameter=True)
    assert shared.converged and per.converged
    assert per.e_steps < 0.8 * shared.e_steps
    assert per.loglik[-1] >= shared.loglik[-1] - 1e-7 * abs(shared.loglik[-1])
    assert per.decreases == ()
    pi = lambda r: np.r_[r.theta.mass, np.diag(r.theta.inertia)]  # noqa: E731
    np.testing.assert_allclose(pi(per), pi(shared), rtol=1e-4)


def test_over_relaxation_is_what_the_m_step_declares(clean):
    """EM over-relaxes an M-step's steps exactly when the M-step declares it
    (``MStep.over_relaxation``), not by what its function is called: the regressor update
    undeclared runs plain EM, bit for bit what the declared one gives with ``accelerate``
    off, and the declared one's iterates differ from them (its relaxed steps)."""
    from pinquad.estep.fast_smoother import smooth_quad
    from pinquad.identification.em import initial_theta

    _, log = clean
    obs = observations(log.slice(0, 600), "B")
    start = initial_theta(obs, 0.03, np.diag([1.5e-4, 1.5e-4, 2.5e-4]), 9.81)
    undeclared = run_em(obs, start, smooth_quad, MStep(regressor_mstep), max_iterations=12)
    off = run_em(obs, start, smooth_quad, REGRESSOR, max_iterations=12, accelerate=False)
    relaxed = run_em(obs, start, smooth_quad, REGRESSOR, max_iterations=12)
    np.testing.assert_array_equal(undeclared.mass, off.mass)
    np.testing.assert_array_equal(undeclared.inertia_diag, off.inertia_diag)
    assert undeclared.e_steps == off.e_steps
    assert not np.array_equal(relaxed.mass, off.mass)


def test_per_parameter_over_relaxation_follows_a_variance_to_zero(monkeypatch):
    """pinquad's simulator puts no noise on the lateral force, so its maximum-likelihood
    variance is near zero and plain EM steps creep there by a fraction of a percent each.
    On 20 s of a sensor-B flight, per-parameter EM (the refit's) with the cap
    ``ETA_MAX_PER_PARAMETER`` (1024) converges (33 E-steps measured) to a log-likelihood
    no lower than the cap of 16 reaches in 150 E-steps without converging (measured
    +0.54 nats above it)."""
    from pinquad.core.params import PAPER_VEHICLE
    from pinquad.identification import em
    from pinquad.identification.identify import get_smoother
    from pinquad.models.sources import observations
    from pinquad.sim.simulator import SimConfig, flight_log, simulate

    flight = simulate(SimConfig(sensor="B"), np.random.default_rng(7))
    obs = observations(flight_log(flight).slice(0, 2000), "B")
    theta0 = em.initial_theta(obs, PAPER_VEHICLE.mass * 0.9, PAPER_VEHICLE.inertia * 1.2, 9.81)

    def fit():
        return em.run_em(obs, theta0, get_smoother("rts"), REGRESSOR, max_iterations=150,
                         tol=1e-5, tol_loglik=1e-7, per_parameter=True)

    fast = fit()
    monkeypatch.setattr(em, "ETA_MAX_PER_PARAMETER", 16.0)
    slow = fit()
    assert fast.converged and fast.e_steps <= 60, fast.e_steps
    assert fast.loglik[-1] >= slow.loglik[-1]
    # the lateral force rows' variance went further towards zero, the thrust row's stayed
    assert np.all(fast.theta.noise.wrench[0:2] < slow.theta.noise.wrench[0:2])
    assert fast.theta.noise.wrench[2] == pytest.approx(slow.theta.noise.wrench[2], rel=1e-3)


def test_a_recorded_logs_base_em_over_relaxes_per_parameter(tmp_path):
    """The base EM of a log with thrust and torque columns (``recorded.fit_run``,
    ``RECORDED_PER_PARAMETER``) on a clean 20 s, 250 Hz flight of the independent
    generator: converged in at most 60 E-steps (29 measured), where the shared factor
    runs its 100 without converging and ends lower (31.7 nats measured), at the same mass
    and inertia within 0.05 standard errors (0.02 measured)."""
    from flightgen import CRAZYFLIE, FlightSpec, generate, write_csv
    from pinquad.identification.identify import identify
    from pinquad.io.read import read_log
    from pinquad.pipeline.identify import LogOptions, identify_log, initial_guess

    spec = FlightSpec(duration=20.0, trajectory="sines", aggressive=True, log_rate=250,
                      seed=1, vehicle=CRAZYFLIE, floor=None)
    log = read_log(write_csv(generate(spec), tmp_path / "clean.csv"))
    run = identify_log(log, LogOptions(msteps=("regressor",), information=True)).runs[0]
    mass0, inertia0, _ = initial_guess(log)
    shared, _ = identify(run.observations, mass0, inertia0, log.meta.gravity, "rts",
                         "regressor", 100, False)
    assert run.converged and run.e_steps <= 60, run.e_steps
    assert run.e_steps <= 0.6 * shared.e_steps, (run.e_steps, shared.e_steps)
    assert run.loglik[-1] > shared.loglik[-1]
    estimate = lambda r: np.r_[r.mass, np.diag(r.inertia)]  # noqa: E731
    assert np.all(np.abs(estimate(run) - estimate(shared)) < 0.05 * run.stderr)
