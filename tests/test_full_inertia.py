"""All ten inertial parameters (issue 3's option): the regressor and the E-step model
against Pinocchio, the log-Cholesky map, and the M-step on noise-free transitions."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from conftest import offline_on_csv

from estimators.protocol import Posterior
from pinquad.core.params import PAPER_VEHICLE
from pinquad.identification import full_inertia as fi
from pinquad.models import full as full_model
from pinquad.models.ssm import NoiseModel, Observations, QuadSSM, Theta, kinematic_floor
from pinquad.sim.simulator import SimConfig, flight_log, simulate
from pinquad.vehicle.model import forward_dynamics, inertial_regressor, inverse_dynamics_wrench, load_model

COM = np.array([0.004, -0.003, 0.002])
INERTIA = np.array([[2.5e-4, 1.2e-5, -8e-6], [1.2e-5, 3.1e-4, 5e-6], [-8e-6, 5e-6, 2.0e-4]])
VEHICLE = replace(PAPER_VEHICLE, com=COM, inertia=INERTIA)


def _random_states(rng: np.random.Generator, n: int) -> np.ndarray:
    x = rng.normal(size=(n, 12))
    x[:, 6:8] *= 0.4
    return x


def test_spatial_regressor_is_pinocchios():
    """Y(x_k, x_{k+1}) equals Pinocchio's joint-torque regressor at x_k with the
    finite-difference accelerations, and Y pi equals RNEA's wrench."""
    rng = np.random.default_rng(0)
    model = load_model(VEHICLE)
    data = model.createData()
    pi = full_model.dynamic_parameters(VEHICLE.mass, COM, INERTIA)
    dt = 0.01
    x_now = _random_states(rng, 5)
    x_next = x_now + dt * rng.normal(size=(5, 12))
    ours = fi.spatial_regressor(x_now, x_next, dt, VEHICLE.gravity)
    for k in range(5):
        xdot = (x_next[k] - x_now[k]) / dt
        ref = inertial_regressor(model, data, x_now[k], xdot)
        np.testing.assert_allclose(ours[k], ref, rtol=1e-10, atol=1e-10 * np.abs(ref).max())
        wrench = inverse_dynamics_wrench(model, data, x_now[k], xdot)
        np.testing.assert_allclose(ours[k] @ pi, wrench, rtol=1e-10,
                                   atol=1e-12 * np.abs(wrench).max())


def test_log_cholesky_round_trip():
    pi = full_model.dynamic_parameters(VEHICLE.mass, COM, INERTIA)
    theta = fi.log_cholesky(pi)
    back, jac = fi.from_log_cholesky(theta)
    np.testing.assert_allclose(back, pi, rtol=1e-12, atol=1e-18)
    h = 1e-7
    for i in range(10):
        e = np.zeros(10)
        e[i] = h
        fd = (fi.from_log_cholesky(theta + e)[0] - fi.from_log_cholesky(theta - e)[0]) / (2 * h)
        np.testing.assert_allclose(jac[:, i], fd, rtol=1e-5, atol=1e-9 * np.abs(pi).max())
    with pytest.raises(ValueError, match="physically consistent"):
        fi.log_cholesky(full_model.dynamic_parameters(0.18, np.zeros(3), np.diag([1e-4, 1e-4, 3e-4])))


def _observations(n: int, dt: float = 0.01) -> Observations:
    rng = np.random.default_rng(1)
    return Observations(t=np.arange(n) * dt, dt=dt, inputs=rng.normal(size=(n, 4)) * 0.1
                        + np.array([1.8, 0, 0, 0]), channels=("pos", "gyro"),
                        ys=np.full((n, 6), np.nan), x0=np.zeros(12), p0=np.ones(12))


def _theta(obs: Observations, com: np.ndarray, inertia: np.ndarray) -> Theta:
    noise = NoiseModel(np.array([1e-6, 1e-6, 2e-6, 1e-9, 1e-9, 1e-9]),
                       kinematic_floor(obs.dt), np.full(6, 1e-4))
    return Theta(VEHICLE.mass, inertia, noise, VEHICLE.gravity, com)


def test_full_model_transition_is_pinocchios_aba():
    """The E-step model's derivative equals Pinocchio's ABA on the same ten parameters;
    its Jacobian equals finite differences; with c = 0 it is the diagonal model."""
    rng = np.random.default_rng(2)
    obs = _observations(4)
    model = full_model.FullQuadSSM(obs, _theta(obs, COM, INERTIA))
    pin_model = load_model(VEHICLE)
    data = pin_model.createData()
    for x in _random_states(rng, 4):
        nxt, jac = model.transition(x, 1)
        ref = forward_dynamics(pin_model, data, x, obs.inputs[1])
        np.testing.assert_allclose((nxt - x) / obs.dt, ref, rtol=1e-9, atol=1e-10)
        h = 1e-6
        for i in range(12):
            e = np.zeros(12)
            e[i] = h
            fd = (model.transition(x + e, 1)[0] - model.transition(x - e, 1)[0]) / (2 * h)
            np.testing.assert_allclose(jac[:, i], fd, rtol=1e-6, atol=1e-8)
    diag = _theta(obs, np.zeros(3), np.diag(np.diag(INERTIA)))
    full, plain = full_model.FullQuadSSM(obs, diag), QuadSSM(obs, diag)
    x = _random_states(rng, 1)[0]
    for a, b in zip(full.transition(x, 2), plain.transition(x, 2), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(full.process_cov(x, 2), plain.process_cov(x, 2), rtol=1e-10,
                               atol=1e-20)


def test_com_offset_effect_has_the_full_models_sign():
    """Discovery's ``com_offset`` coefficient c is the CoM's position from the thrust
    centre, as ``Vehicle.com`` and the ten-parameter model's CoM: from rest, under thrust
    alone, the diagonal model with the effect's torque F [-c_y, c_x, 0] added to its
    inputs starts turning as the full model with its CoM at c does (a rigid body's
    angular acceleration from rest is I_C^-1 times the torque about its CoM, whatever
    the reference point, so the rates after one step agree to rounding)."""
    from pinquad.discovery.refit import corrected_observations
    from pinquad.sim import effects

    com = np.array([0.004, -0.003, 0.0])
    inertia = np.diag(np.diag(INERTIA))
    obs = _observations(3)
    obs = replace(obs, inputs=np.tile([1.8, 0.0, 0.0, 0.0], (3, 1)))
    x = np.zeros((obs.n, 12))
    full = full_model.FullQuadSSM(obs, _theta(obs, com, inertia))
    shifted = corrected_observations(obs, x, {"com_offset": com[:2]})
    plain = QuadSSM(shifted, _theta(shifted, np.zeros(3), inertia))
    rate_full = full.transition(x[0], 0)[0][9:12]
    rate_plain = plain.transition(x[0], 0)[0][9:12]
    assert np.all(np.abs(rate_full[:2]) > 1e-3)
    np.testing.assert_allclose(rate_plain, rate_full, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(effects.com_offset(com[:2]).wrench(x[0], obs.inputs[0], 0.0)[3:5],
                               shifted.inputs[0, 1:3] - obs.inputs[0, 1:3], rtol=1e-12)


def test_compiled_e_step_equals_the_generic_one_on_the_full_model():
    """The compiled EKF + RTS (pinquad.fast_smoother) takes FullQuadSSM too: on a
    simulated sensor-B log with the CoM off the thrust centre and products of inertia,
    its log-likelihood and smoothed moments equal the generic estimators' to rounding,
    with no warning (a warning means the kernels disagreed with the model and fell back)."""
    import warnings

    from estimators.ekf import run_filter
    from estimators.rts import smooth
    from pinquad.estep.fast_smoother import loglik_quad, smooth_quad
    from pinquad.models.sources import observations

    flight = simulate(SimConfig(vehicle=VEHICLE, sensor="B"), np.random.default_rng(5))
    obs = observations(flight_log(flight).slice(0, 600), "B")
    theta = _theta(obs, COM, INERTIA)
    theta = replace(theta, noise=replace(theta.noise, meas=np.full(obs.ys.shape[1], 1e-4)))
    model = full_model.FullQuadSSM(obs, theta)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fast = smooth_quad(model, obs.ys)
        fast_ll = loglik_quad(model, obs.ys)
    slow = smooth(model, obs.ys)
    assert fast_ll == pytest.approx(run_filter(model, obs.ys).loglik, rel=1e-9)
    assert fast.loglik == pytest.approx(slow.loglik, rel=1e-9)
    np.testing.assert_allclose(fast.mean, slow.mean, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(fast.cov, slow.cov, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.cross_cov, slow.cross_cov, rtol=1e-9, atol=1e-12)


def test_full_mstep_recovers_all_ten_parameters_from_noise_free_transitions():
    """States propagated exactly by the ten-parameter model with rich inputs, used as a
    posterior with zero covariance: the M-step returns the true mass, CoM and inertia
    to 1e-6 relative (from the diagonal, CoM-free start)."""
    rng = np.random.default_rng(3)
    n = 200
    obs = _observations(n)
    thrust = 1.8 + 0.3 * rng.normal(size=n)
    # torques that balance the moment of the CoM offset at hover (M = F c x e3), plus
    # excitation
    offset_moment = thrust[:, None] * np.array([COM[1], -COM[0], 0.0])
    obs = replace(obs, inputs=np.column_stack([thrust, offset_moment
                                               + 5e-4 * rng.normal(size=(n, 3))]))
    truth = _theta(obs, COM, INERTIA)
    model = full_model.FullQuadSSM(obs, truth)
    xs = np.zeros((n, 12))
    xs[0, 9:12] = [0.3, -0.2, 0.5]
    for k in range(n - 1):
        xs[k + 1] = model.transition(xs[k], k)[0]
    post = Posterior(xs, np.zeros((n, 12, 12)), np.zeros((n - 1, 12, 12)), 0.0, "rts",
                     np.zeros((n, 6), dtype=bool))
    start = _theta(obs, np.zeros(3), np.diag(np.diag(INERTIA)) * 1.3)
    new = fi.full_mstep(post, obs, start).theta
    assert abs(new.mass / VEHICLE.mass - 1.0) < 1e-6
    np.testing.assert_allclose(new.com, COM, rtol=1e-6, atol=1e-6 * np.abs(COM).max())
    np.testing.assert_allclose(new.inertia, INERTIA, rtol=1e-6,
                               atol=1e-6 * np.abs(INERTIA).max())
    assert pin.Inertia(new.mass, new.com, new.inertia).isValid() if hasattr(
        pin.Inertia, "isValid") else np.all(np.linalg.eigvalsh(new.inertia) > 0)


def test_spatial_inertia_is_linear_in_pi():
    pi = full_model.dynamic_parameters(VEHICLE.mass, COM, INERTIA)
    np.testing.assert_allclose(np.einsum("p,pij->ij", pi, fi._M_BASIS), full_model.spatial_inertia(pi),
                               rtol=1e-12, atol=1e-18)


def test_standard_errors_recover_the_information_of_a_quadratic_log_likelihood():
    """A log-likelihood quadratic in pi, L = -(pi - pi0)^T A (pi - pi0) / 2, with a dense
    A: the observed information must be A itself, off-diagonal terms included (the finite
    differences are exact on a quadratic up to rounding), and the mass standard error
    sqrt((A^-1)_00)."""
    rng = np.random.default_rng(7)
    obs = _observations(3)
    theta = _theta(obs, COM, INERTIA)
    pi0 = full_model.dynamic_parameters(theta.mass, theta.com, theta.inertia)
    scale = np.abs(pi0) + 1e-3 * np.abs(pi0).max()
    root = rng.normal(size=(10, 10))
    a = (root @ root.T + 10 * np.eye(10)) / np.outer(scale, scale) * 1e6
    calls = []

    def quadratic(model: full_model.FullQuadSSM, ys: np.ndarray) -> float:
        calls.append(1)
        d = model.pi - pi0
        return -0.5 * float(d @ a @ d)

    se_mass, _, _, info = fi.standard_errors(obs, theta, quadratic)
    np.testing.assert_allclose(info, a, rtol=1e-6, atol=1e-6 * np.abs(a).max())
    assert se_mass == pytest.approx(np.sqrt(np.linalg.inv(a)[0, 0]), rel=1e-5)
    assert len(calls) == 111


def test_offline_log_identifies_all_ten_parameters(tmp_path):
    """`offline --log --mstep full` on a simulated 20 s CSV log of a vehicle with its CoM
    4 mm / -3 mm / 2 mm off the thrust centre and products of inertia: mass, CoM and
    every inertia entry within 3 standard errors (observed information) of the truth
    and the products of inertia found (within 3e-6 of truth, where zero would be 5-12e-6
    off). The vertical CoM is the weakly determined direction (thrust through the body z
    axis and no drag: it enters only through omega' x h and the centripetal terms): its
    standard error is over ten times the horizontal ones (40 E-steps from the staged
    start: 1.66 +- 2.12 mm). The run's start is the staged one, and its EM ends above the
    likelihood the paper's start reached on the same log (that start's two outcomes,
    43288 and 42800, depended on 1e-13 perturbations of the data)."""
    flight = simulate(SimConfig(vehicle=VEHICLE, sensor="B"), np.random.default_rng(5))
    out = tmp_path / "run"
    proc = offline_on_csv(flight_log(flight).slice(0, 2000), tmp_path / "offset.csv", out,
                          "--sensor", "B", "--mstep", "full", "--max-iterations", "40")
    # 40 E-steps do not converge: the estimates are reported, never trusted (exit 3)
    assert proc.returncode == 3, proc.stderr[-2000:]
    assert "  centre of mass: c_x " in proc.stdout and "  products of inertia: I_xy " in proc.stdout
    report = json.loads((out / "report.json").read_text())
    est = report["estimates"]
    run = report["runs"][0]
    assert all("did not converge" in r for r in report["verdict"]["reasons"])
    assert report["source"]["mstep"] == "full" and run["em_failure"] is None
    se_com = np.asarray(run["stderr_full"]["com"])
    se_i = np.asarray(run["stderr_full"]["inertia"])
    assert np.all(np.isfinite(se_com)) and np.all(se_com > 0)
    assert np.all(np.isfinite(se_i)) and np.all(se_i > 0)
    assert abs(est["mass"] - VEHICLE.mass) < 3 * est["stderr"]["mass"]
    com = np.asarray(est["com"])
    assert np.all(np.abs(com - COM) < 3 * se_com)
    assert run["start"]["com"][0] == pytest.approx(COM[0], abs=3e-4)
    assert run["em"]["loglik"][-1] > 43300.0
    assert se_com[2] > 10 * se_com[:2].max()
    inertia = np.asarray(est["inertia"])
    assert np.all(np.abs(inertia - INERTIA) < 3 * se_i)
    off = ~np.eye(3, dtype=bool)
    assert np.all(np.abs(inertia - INERTIA)[off] < 3e-6)
    print(proc.stdout)  # the identification table, shown with pytest -s


@pytest.mark.parametrize("continuous", [False, True])
def test_full_force_rows_equal_the_diagonal_m_steps(continuous):
    """The ten-parameter M-step's force rows are the diagonal M-step's (the mass column
    a_O, the applied force and their first-order covariance terms): on a posterior of a
    few EM steps, full_stats' a[j, 0, 0], b[j, 0] and c[j] (j = body x, y, z) equal
    ``regressor_stats``' to 1e-7 (central differences against the analytic derivative).
    On a continuous flight that includes the thrust turned along the interval's mean
    direction, whose lateral component the held force lacks."""
    from pinquad.identification.em import initial_theta, run_em
    from pinquad.identification.identify import get_smoother
    from pinquad.models.sources import observations
    from pinquad.mstep.protocol import REGRESSOR
    from pinquad.mstep.updates import regressor_stats

    flight = simulate(SimConfig(sensor="B"), np.random.default_rng(7))
    obs = replace(observations(flight_log(flight).slice(0, 600), "B"), continuous=continuous)
    theta0 = initial_theta(obs, PAPER_VEHICLE.mass * 0.9, PAPER_VEHICLE.inertia * 1.2, 9.81)
    post = run_em(obs, theta0, get_smoother("rts"), REGRESSOR, max_iterations=3).posterior
    full = fi.full_stats(post, obs, 9.81)
    diag = regressor_stats(post, obs, 9.81)
    assert full.n == diag.n
    np.testing.assert_allclose(full.a[0:3, 0, 0], diag.a[0:3, 0, 0], rtol=1e-7)
    np.testing.assert_allclose(full.b[0:3, 0], diag.b[0:3, 0], rtol=1e-7)
    np.testing.assert_allclose(full.c, diag.c, rtol=1e-9)
    held = fi.full_stats(post, replace(obs, continuous=False), 9.81)
    assert np.all(held.c[0:2] == 0.0)  # a held thrust has no lateral component
    if continuous:
        assert np.all(full.c[0:2] > 1e-8 * full.c[2])
    else:
        np.testing.assert_array_equal(full.c, held.c)


def test_ten_parameter_em_converges_on_a_continuous_flight(tmp_path):
    """A clean 20 s, 100 Hz flight of the independent generator (its thrust turns within
    each logged interval): with the force rows along the interval's mean thrust
    direction, as the E-step moves the vehicle, the ten-parameter EM converges (8
    E-steps measured; the held force rows of stop 28 ran the 60 allowed without
    converging) to the mass within 0.1 % and the roll and pitch inertia within 2 %, and the
    horizontal CoM keeps a standard error (sub-micrometre here) where the vertical one may
    be left undetermined (``fisher.determined_covariance``)."""
    from flightgen import CRAZYFLIE, generate, write_csv
    from pinquad.experiments.discovery_mc_flightgen import flight_spec
    from pinquad.io.read import read_log
    from pinquad.pipeline.identify import LogOptions, identify_log

    log = read_log(write_csv(generate(flight_spec("none", 2, 2, 100)), tmp_path / "f.csv"))
    run = identify_log(log, LogOptions(msteps=("full",), estep="rts", max_iterations=60,
                                       information=True)).runs[0]
    assert run.converged and run.e_steps <= 30
    assert abs(run.mass / CRAZYFLIE.mass - 1.0) < 1e-3
    truth = np.diag(CRAZYFLIE.inertia_matrix)
    assert np.all(np.abs(np.diag(run.inertia)[0:2] / truth[0:2] - 1.0) < 0.02)
    se_com = run.full.stderr_com
    assert np.all(np.isfinite(se_com[0:2])) and np.all(se_com[0:2] < 1e-5)
    assert np.all(np.abs(run.full.com[0:2]) < 3 * se_com[0:2] + 1e-6)
