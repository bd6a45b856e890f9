"""The compiled quadcopter E-step against the generic EKF + RTS smoother.

Agreement is measured on the scale each quantity lives on: a mean error in units of
the smoothed standard deviation (or of the mean itself where that is larger), a
covariance error in units of sqrt(P_ii P_jj) (the correlation scale, so that
off-diagonal entries that are zero up to cancellation are not compared against
themselves), the log-likelihood relative to itself. All to 1e-9. The differences seen
are rounding: up to ~1e-10 in the smoothed covariances, which is what the generic path
itself moves by when its LU solve of the predicted covariance (condition number ~2e5
without Euler measurements) is swapped for a Cholesky solve.

The paper's literal starting point (m = 1 g, 180 times too light) is compared on source
A only. On B and C that filter diverges (roll and pitch wind up to tens or thousands of
radians) and becomes chaotic: a one-ulp change of a single thrust sample changes the
generic path's own log-likelihood by several per cent, so no reordering of the
arithmetic can agree there to 1e-9; the paper's noise model itself (fixed Q0) is
compared on every source at the true mass and inertia instead.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import replace

import numpy as np
import pytest

from estimators.ekf import run_filter
from estimators.protocol import Posterior
from estimators.rts import smooth
from pinquad.core.conventions import euler_rate_matrix_inv
from pinquad.estep import fast_smoother as fs
from pinquad.estep.fast_smoother import loglik_quad, posterior_arrays, smooth_quad
from pinquad.estep.quad_kernels import f_times_quad, transition_kinematic, transition_quad
from pinquad.identification.em import initial_theta
from pinquad.models.effect import EffectSSM
from pinquad.models.full import FullQuadSSM
from pinquad.models.kernel import kernel_description, reset_mask
from pinquad.models.sources import observations
from pinquad.models.ssm import KinematicSSM, NoiseModel, Observations, QuadSSM, Theta, kinematic_floor
from pinquad.sim.simulator import SimConfig, flight_log, simulate

TOL = 1e-9
N_STEPS = 600
MEAS_VAR = {"pos": 2.5e-5, "vel": 4e-4, "euler": 1e-4, "gyro": 2.25e-4}
SEED = int(os.environ.get("PINQUAD_FAST_SMOOTHER_SEED", "3"))


@pytest.fixture(scope="module")
def flight():
    """One flight per sensor set, each flown with that sensor (SimConfig(sensor=...)), so
    that B's log carries velocity and Euler angles and C's velocity."""
    return {s: simulate(SimConfig(sensor=s), np.random.default_rng(SEED)) for s in "ABC"}


# the fraction of finite samples each source's channels carry on its own flight: B and
# C's pos, vel, Euler every 2nd step and gyro every step (sim/sensors.py); A's position
# and velocity are the onboard filter's estimate, every step (models/sources.py)
SAMPLED = {"A": {"pos": 1.0, "vel": 1.0, "gyro": 1.0},
           "B": {"pos": 0.5, "vel": 0.5, "euler": 0.5, "gyro": 1.0},
           "C": {"pos": 0.5, "vel": 0.5, "gyro": 1.0}}


def _observations(flight, source: str) -> Observations:
    """600 steps of a source's observations, with some extra gaps: a few steps with no
    sample at all and 5 % of the entries dropped, so that every update path (nothing,
    an arbitrary subset, everything observed) runs."""
    rng = np.random.default_rng(SEED + 100)
    log = flight_log(flight[source]).slice(0, N_STEPS)
    obs = observations(log, source)
    ys = obs.ys.copy()
    ys[rng.random(ys.shape) < 0.05] = np.nan
    ys[[7, 8, 250]] = np.nan
    return replace(obs, ys=ys)


def test_only_a_sampled_log_is_a_continuous_flight(flight):
    """pinquad's simulator writes held logs and moves by explicit Euler: their
    observations keep the Euler kinematics; the same log read as sampled (a faster
    controller's record of a continuous flight) moves continuously."""
    log = flight_log(flight["B"]).slice(0, N_STEPS)
    assert log.meta.actuation == "held"
    assert not observations(log, "B").continuous
    sampled = replace(log, meta=replace(log.meta, actuation="sampled"))
    assert observations(sampled, "B").continuous


@pytest.mark.parametrize("source", ["A", "B", "C"])
def test_each_source_carries_its_channels(flight, source):
    """The comparisons below are only as good as their data: each source's log holds
    every one of its channels at the sensor set's rate (no channel left all-NaN)."""
    obs = observations(flight_log(flight[source]).slice(0, N_STEPS), source)
    assert obs.channels == tuple(SAMPLED[source])
    finite = np.isfinite(obs.ys).mean(axis=0)
    for i, ch in enumerate(obs.channels):
        np.testing.assert_allclose(finite[3 * i:3 * i + 3], SAMPLED[source][ch], atol=0.01,
                                   err_msg=f"{source}: {ch}")


def _theta(obs: Observations, kind: str) -> Theta:
    """paper_start: the paper's EM start (m0 = 1 g, fixed Q0 and R0); paper_noise: the
    same noise at the true mass and inertia; structured: the SDE noise model."""
    vehicle = SimConfig().vehicle
    if kind == "paper_start":
        return initial_theta(obs, 0.001, np.diag([1e-4, 2e-4, 1e-4]), 9.81)
    if kind == "paper_noise":
        return initial_theta(obs, vehicle.mass, vehicle.inertia, vehicle.gravity)
    meas = np.repeat([MEAS_VAR[ch] for ch in obs.channels], 3)
    noise = NoiseModel(wrench=np.array([4e-6, 4e-6, 4e-6, 4e-10, 4e-10, 4e-10]),
                       q_kin=kinematic_floor(obs.dt), meas=meas)
    return Theta(mass=vehicle.mass, inertia=np.asarray(vehicle.inertia, float), noise=noise,
                 gravity=vehicle.gravity)


def _assert_same_posterior(fast: Posterior, ref: Posterior) -> None:
    assert fast.method == "rts"
    assert fast.mean.shape == ref.mean.shape
    assert fast.cov.shape == ref.cov.shape
    assert fast.cross_cov.shape == ref.cross_cov.shape
    assert fast.rejected.shape == ref.rejected.shape and not fast.rejected.any()
    std = np.sqrt(np.einsum("kii->ki", ref.cov))
    mean_err = np.abs(fast.mean - ref.mean) / np.maximum(std, np.abs(ref.mean))
    cov_err = np.abs(fast.cov - ref.cov) / (std[:, :, None] * std[:, None, :])
    cross_err = (np.abs(fast.cross_cov - ref.cross_cov)
                 / (std[1:, :, None] * std[:-1, None, :]))
    ll_err = abs(fast.loglik - ref.loglik) / abs(ref.loglik)
    worst = {"mean": mean_err.max(), "cov": cov_err.max(), "cross_cov": cross_err.max(),
             "loglik": ll_err}
    assert max(worst.values()) <= TOL, worst


# The dynamic model at the paper's 1 g start diverges on every source now (the EKF winds
# roll and pitch up, and one-ulp input changes move the result), so EM's first E-step
# uses the force-free warm-up model there; the compiled path is compared where the
# problem is well posed.
@pytest.mark.parametrize(("source", "kind"), [
    ("A", "paper_noise"), ("B", "paper_noise"), ("C", "paper_noise"),
    ("A", "structured"), ("B", "structured"), ("C", "structured"),
])
def test_matches_generic_smoother(flight, source, kind):
    obs = _observations(flight, source)
    model = QuadSSM(obs, _theta(obs, kind))
    assert (model.theta.noise.fixed_q is not None) == kind.startswith("paper")
    _assert_same_posterior(smooth_quad(model, obs.ys), smooth(model, obs.ys))


def test_out_arrays_hold_the_same_posterior(flight):
    """smooth_quad(..., out=...) writes into the given arrays (reused window after window
    by the online estimator) and returns exactly what a call without them returns, also
    when the arrays held another window's posterior before; wrong arrays are refused."""
    obs = _observations(flight, "B")
    model = QuadSSM(obs, _theta(obs, "structured"))
    ref = smooth_quad(model, obs.ys)
    out = posterior_arrays(obs.n)
    for a in out:
        a.fill(np.nan)
    for _ in range(2):
        post = smooth_quad(model, obs.ys, out=out)
        assert post.mean is out[0] and post.cov is out[1] and post.cross_cov is out[2]
        assert np.array_equal(post.mean, ref.mean) and np.array_equal(post.cov, ref.cov)
        assert np.array_equal(post.cross_cov, ref.cross_cov) and post.loglik == ref.loglik
    short = replace(obs, ys=obs.ys[:300])
    with pytest.raises(ValueError, match="posterior_arrays"):
        smooth_quad(QuadSSM(short, model.theta), short.ys, out=out)
    with pytest.raises(ValueError, match="posterior_arrays"):
        smooth_quad(model, obs.ys, out=(out[0], out[1][:, :, ::-1].copy(order="F"), out[2]))


def test_filter_arrays_kept_only_for_short_logs(flight, monkeypatch):
    """The forward pass's arrays are reused from call to call, but not held after the
    E-step of a log longer than _KEEP_STEPS."""
    obs = _observations(flight, "B")
    model = QuadSSM(obs, _theta(obs, "structured"))
    ref = smooth_quad(model, obs.ys)
    kept = fs._workspace.arrays
    assert kept is not None and kept[0].shape[0] == obs.n
    post = smooth_quad(model, obs.ys)
    assert fs._workspace.arrays is kept and np.array_equal(post.cov, ref.cov)
    monkeypatch.setattr(fs, "_KEEP_STEPS", obs.n - 1)
    post = smooth_quad(QuadSSM(replace(obs, ys=obs.ys[:-1]), model.theta), obs.ys[:-1])
    assert fs._workspace.arrays is not kept
    post = smooth_quad(model, obs.ys)
    assert fs._workspace.arrays is None and np.array_equal(post.cov, ref.cov)


@pytest.mark.parametrize("kinematic", [False, True])
def test_structured_jacobian_product(flight, kinematic):
    """The predict step's F P skips the entries of F outside its block pattern; the
    transition kernels leave every one of them exactly zero, at random states too, and
    the structured product equals the dense one."""
    obs = _observations(flight, "B")
    desc = kernel_description(QuadSSM(obs, _theta(obs, "structured")))
    pattern = np.zeros((12, 12), dtype=bool)
    for r in range(3):
        pattern[r, [r, r + 3]] = True
        pattern[3 + r, [3 + r, 6, 7, 8]] = True
        pattern[6 + r, 6:12] = True
        pattern[9 + r, 9:12] = True
    rng = np.random.default_rng(7)
    x_next, jac, out = np.empty(12), np.empty((12, 12)), np.empty((12, 12))
    for _ in range(50):
        x = rng.normal(size=12)
        if kinematic:
            transition_kinematic(x, desc.dt, x_next, jac)
        else:
            transition_quad(x, rng.normal(size=4), desc.dt, desc.mass, desc.inertia,
                            desc.inertia_inv, desc.gravity, x_next, jac)
        assert not np.any(jac[~pattern])
        a = rng.normal(size=(12, 12))
        p = a @ a.T
        f_times_quad(jac, p, out)
        assert np.allclose(out, jac @ p, rtol=1e-14, atol=1e-14 * np.abs(jac @ p).max())


@pytest.mark.parametrize("source", ["A", "B", "C"])
def test_kinematic_warm_up_matches_generic_smoother(flight, source):
    """EM's first E-step: the force-free KinematicSSM at the paper's 1 g start with the
    fixed Q0 (well posed there: no force term to diverge)."""
    obs = _observations(flight, source)
    model = KinematicSSM(obs, _theta(obs, "paper_start"))
    _assert_same_posterior(smooth_quad(model, obs.ys), smooth(model, obs.ys))


@pytest.mark.parametrize("kind", ["structured", "paper_noise", "kinematic"])
def test_reset_transitions_match_generic_smoother(flight, kind):
    """Transitions marked as resets (touch-down; ssm.RESET_VAR added to Q) give the
    generic smoother's posterior, and the widening is applied (the posterior moves)."""
    obs = _observations(flight, "C")
    resets = np.zeros(obs.n, dtype=bool)
    resets[[120, 121, 400]] = True
    marked = replace(obs, resets=resets)
    unmarked = replace(obs, resets=np.zeros(0, dtype=bool))
    theta = _theta(obs, "paper_start" if kind == "kinematic" else kind)
    cls = KinematicSSM if kind == "kinematic" else QuadSSM
    model = cls(marked, theta)
    fast = smooth_quad(model, obs.ys)
    _assert_same_posterior(fast, smooth(model, obs.ys))
    plain = smooth_quad(cls(unmarked, theta), obs.ys)
    rates = slice(9, 12)
    # just after the reset the rates are known from the gyro alone: wider than when the
    # dynamics carry information across
    assert np.all(np.diag(fast.cov[122][rates, rates]) > np.diag(plain.cov[122][rates, rates]))
    assert fast.loglik != plain.loglik


def test_kinematic_without_fixed_q_uses_the_generic_path(flight):
    obs = _observations(flight, "B")
    model = KinematicSSM(obs, _theta(obs, "structured"))
    with pytest.raises(ValueError, match="fixed process covariance"):
        smooth_quad(model, obs.ys)


@pytest.mark.parametrize(("source", "kind"), [
    ("A", "structured"), ("B", "structured"), ("C", "structured"), ("B", "paper_noise"),
])
def test_loglik_only_matches_generic_filter(flight, source, kind):
    """The forward pass alone (observed information) against the generic EKF and against
    the full compiled smoother's log-likelihood."""
    obs = _observations(flight, source)
    for scale in (1.0, 1.01):
        theta = _theta(obs, kind)
        theta = replace(theta, mass=theta.mass * scale, inertia=theta.inertia / scale)
        model = QuadSSM(obs, theta)
        ref = run_filter(model, obs.ys).loglik
        assert abs(loglik_quad(model, obs.ys) - ref) <= TOL * abs(ref)
        assert loglik_quad(model, obs.ys) == smooth_quad(model, obs.ys).loglik


def test_wrapped_euler_residuals(flight):
    """Euler measurements shifted by whole turns (and yaw across +-pi) give the generic
    answer, which wraps every angle residual to (-pi, pi]."""
    obs = _observations(flight, "B")
    assert obs.channels[2] == "euler"
    ys = obs.ys.copy()
    euler = slice(6, 9)
    ys[::3, euler] += 2.0 * np.pi
    ys[1::5, euler] -= 4.0 * np.pi
    shifted = np.isfinite(ys[:, euler]) & ((np.arange(obs.n) % 3 == 0)
                                          | (np.arange(obs.n) % 5 == 1))[:, None]
    assert shifted.sum() > 100  # finite angles really moved by whole turns
    wrapped = replace(obs, ys=ys)
    model = QuadSSM(wrapped, _theta(obs, "structured"))
    fast = smooth_quad(model, wrapped.ys)
    _assert_same_posterior(fast, smooth(model, wrapped.ys))
    assert np.all(np.abs(fast.mean[:, 6:9]) < np.pi)
    # a whole turn is no change: the posterior is that of the unshifted angles
    plain = smooth_quad(QuadSSM(obs, model.theta), obs.ys)
    np.testing.assert_allclose(fast.mean, plain.mean, rtol=0, atol=1e-9)
    assert fast.loglik == pytest.approx(plain.loglik, rel=1e-9)


def test_other_models_use_the_generic_smoother(linear_case):
    model, ys = linear_case
    fast = smooth_quad(model, ys)
    ref = smooth(model, ys)
    np.testing.assert_array_equal(fast.mean, ref.mean)
    np.testing.assert_array_equal(fast.cov, ref.cov)
    assert fast.loglik == ref.loglik


def test_gate_uses_the_generic_smoother(flight):
    obs = _observations(flight, "C")
    model = QuadSSM(obs, _theta(obs, "structured"))
    fast = smooth_quad(model, obs.ys, gate_sigma=3.0)
    ref = smooth(model, obs.ys, gate_sigma=3.0)
    np.testing.assert_array_equal(fast.rejected, ref.rejected)
    np.testing.assert_array_equal(fast.mean, ref.mean)


def test_subclass_uses_the_generic_smoother(flight):
    """A subclass may change the dynamics the kernels hard-code."""

    class Heavier(QuadSSM):
        def process_cov(self, x, k):
            return 2.0 * super().process_cov(x, k)

    obs = _observations(flight, "C")
    model = Heavier(obs, _theta(obs, "structured"))
    np.testing.assert_array_equal(smooth_quad(model, obs.ys).cov, smooth(model, obs.ys).cov)


def test_changed_model_warns_and_uses_the_generic_smoother(flight):
    """If QuadSSM's behaviour moves away from the kernels, the answer stays right."""
    obs = _observations(flight, "B")
    model = QuadSSM(obs, _theta(obs, "structured"))
    plain = model.process_cov
    model.process_cov = lambda x, k: 3.0 * plain(x, k)
    with pytest.warns(RuntimeWarning, match="no longer matches"):
        fast = smooth_quad(model, obs.ys)
    np.testing.assert_array_equal(fast.cov, smooth(model, obs.ys).cov)


def test_rejects_wrongly_shaped_measurements(flight):
    obs = _observations(flight, "C")
    model = QuadSSM(obs, _theta(obs, "structured"))
    with pytest.raises(ValueError, match="expected"):
        smooth_quad(model, obs.ys[:, :6])


def _continuous_models(obs: Observations, theta: Theta) -> dict[str, QuadSSM]:
    """Every kind the kernels cover, on a continuous flight (trapezoid positions): the
    plain model, drag and wind, and the ten-parameter model with a CoM offset."""
    flowing = replace(obs, continuous=True)
    offset = replace(theta, com=np.array([0.004, -0.003, 0.002]))
    return {"quad": QuadSSM(flowing, theta),
            "effect": EffectSSM(flowing, theta, drag=np.array([0.02, 0.03, 0.0]),
                                wind=np.array([0.01, -0.02])),
            "full": FullQuadSSM(flowing, offset)}


@pytest.mark.parametrize("name", ["quad", "effect", "full"])
def test_continuous_positions_match_generic_smoother(flight, name):
    """On a continuous flight (``Observations.continuous``) the compiled pass gives the
    generic smoother's posterior for every kind, without falling back to it (no
    warning), and the trapezoid changes the answer (it is applied)."""
    obs = _observations(flight, "C")
    theta = _theta(obs, "structured")
    model = _continuous_models(obs, theta)[name]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fast = smooth_quad(model, obs.ys)
    _assert_same_posterior(fast, smooth(model, obs.ys))
    euler = type(model)(obs, model.theta) if name != "effect" else EffectSSM(
        obs, theta, drag=model.drag, wind=model.wind[:2])
    assert np.max(np.abs(smooth_quad(euler, obs.ys).mean[:, 3:6] - fast.mean[:, 3:6])) > 1e-4


def test_continuous_step_moves_constant_rates_exactly():
    """A body whose rates are constant over the interval: with a constant acceleration
    p_{k+1} = p_k + dt v_k + dt^2 a / 2 (explicit Euler leaves out the last term); and the
    Jacobian of the whole continuous step (every row, every kind) equals central
    differences of the transition (the entries EffectSSM leaves out of its Jacobian
    aside)."""
    dt, mass = 0.01, 0.03
    t = np.arange(3) * dt
    obs = Observations(t=t, dt=dt, inputs=np.tile([0.5, 2e-5, -1e-5, 3e-6], (3, 1)),
                       channels=("pos",), ys=np.zeros((3, 3)), x0=np.zeros(12),
                       p0=np.ones(12), continuous=True)
    noise = NoiseModel(wrench=np.full(6, 1e-6), q_kin=kinematic_floor(dt), meas=np.ones(3))
    theta = Theta(mass=mass, inertia=np.diag([1.6e-5, 1.6e-5, 2.9e-5]), noise=noise)
    level = replace(obs, inputs=np.tile([0.5, 0.0, 0.0, 0.0], (3, 1)))
    x = np.zeros(12)
    x[3:6] = [0.4, -0.2, 0.3]
    nxt, _ = QuadSSM(level, theta).transition(x, 0)
    expect = x[0:3] + dt * x[3:6] + np.array([0.0, 0.0, 0.5 * dt * dt * (0.5 / mass - 9.81)])
    np.testing.assert_allclose(nxt[0:3], expect, rtol=0, atol=1e-15)
    rng = np.random.default_rng(11)
    for name, model in _continuous_models(obs, theta).items():
        x = rng.normal(scale=0.3, size=12)
        _, jac = model.transition(x, 0)
        eps = 1e-6
        numeric = np.empty((12, 12))
        for c in range(12):
            step = np.zeros(12)
            step[c] = eps
            numeric[:, c] = (model.transition(x + step, 0)[0]
                             - model.transition(x - step, 0)[0]) / (2 * eps)
        if name == "effect":
            # EffectSSM leaves the drag and wind forces' attitude dependence out of its
            # Jacobian (as on an Euler step): those entries are not compared
            jac[0:6, 6:9] = numeric[0:6, 6:9]
        np.testing.assert_allclose(jac, numeric, rtol=1e-6, atol=1e-8)


def test_continuous_noise_is_the_integrated_noise(flight):
    """Q of a continuous flight: the position rows carry (dt / 2) Q_v. and (dt^2 / 3) Q_vv
    of the velocity noise, the Euler rows (dt / 2) E^{-1} Q_w. and (dt^2 / 3) E^{-1} Q_ww
    E^{-T} of the rate noise; Q stays symmetric positive semi-definite, and the velocity
    and rate blocks are the Euler model's."""
    obs = _observations(flight, "C")
    theta = _theta(obs, "structured")
    x = obs.x0 + 0.1
    k = int(np.flatnonzero(~reset_mask(obs))[-2])  # a flight step (a reset widens Q after)
    q_euler = QuadSSM(obs, theta).process_cov(x, k)
    q = QuadSSM(replace(obs, continuous=True), theta).process_cov(x, k)
    dt = obs.dt
    e_inv = euler_rate_matrix_inv(x[6:9])
    for block in (slice(3, 6), slice(9, 12)):
        np.testing.assert_array_equal(q[block, block], q_euler[block, block])
    np.testing.assert_allclose(q[0:3, 3:6], 0.5 * dt * q_euler[3:6, 3:6], rtol=1e-14)
    np.testing.assert_allclose(q[0:3, 0:3], q_euler[0:3, 0:3] + dt * dt / 3 * q_euler[3:6, 3:6],
                               rtol=1e-14)
    np.testing.assert_allclose(q[6:9, 9:12], 0.5 * dt * e_inv @ q_euler[9:12, 9:12], rtol=1e-12)
    np.testing.assert_allclose(
        q[6:9, 6:9], q_euler[6:9, 6:9] + dt * dt / 3 * e_inv @ q_euler[9:12, 9:12] @ e_inv.T,
        rtol=1e-12)
    np.testing.assert_allclose(q, q.T, rtol=0, atol=1e-14 * np.abs(q).max())
    assert np.linalg.eigvalsh(q).min() >= -1e-12 * np.abs(q).max()


def test_a_log_gaps_restart_matches_the_generic_smoother(flight):
    """Two seconds of resets without a measurement (a log gap): the compiled pass
    restarts the filter where the generic one does (``ssm.restart_mask``: mean held,
    F = 0, P = diag(RESTART_VAR)), the lag-one cross-covariances over the restarts are
    exact zeros (the smoother runs on each side alone) and nothing grows past the prior."""
    from pinquad.models.ssm import RESTART_VAR, restart_mask

    obs = _observations(flight, "B")
    resets = np.zeros(obs.n, dtype=bool)
    resets[200:401] = True
    ys = obs.ys.copy()
    ys[201:401] = np.nan
    obs = replace(obs, ys=ys, resets=resets)
    restarts = restart_mask(obs)
    assert np.array_equal(np.flatnonzero(restarts), np.arange(200, 400))
    model = QuadSSM(obs, _theta(obs, "structured"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fast = smooth_quad(model, obs.ys)
    _assert_same_posterior(fast, smooth(model, obs.ys))
    assert not fast.cross_cov[200:400].any()
    assert np.abs(fast.cov).max() <= RESTART_VAR.max()
