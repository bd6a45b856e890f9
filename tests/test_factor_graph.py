"""The GTSAM batch smoother against RTS, the dense joint posterior, and a nonlinear
constant-turn model with a wrapped bearing measurement; the iterated EKF + RTS smoother
against both.

Timing (not a test): ``PYTHONPATH=. python tests/test_factor_graph.py`` prints the
wall-clock time of 2,000- and 6,000-step 12-state solves, GTSAM vs RTS.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from conftest import random_stable_model

from estimators import factor_graph as fg
from estimators import iterated, rts
from estimators.ekf import run_filter
from estimators.linear import LinearGaussianModel, dense_posterior
from estimators.protocol import Array, StateSpaceModel


def _assert_close(actual: Array, expected: Array, rtol: float = 1e-8) -> None:
    """rtol on every entry; the atol only keeps entries that are zero up to rounding
    (a 1e-12 fraction of the array's largest entry) from failing a relative test."""
    atol = 1e-12 * float(np.abs(expected).max())
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=atol)


def _linear_case(n_steps: int, seed: int) -> tuple[LinearGaussianModel, Array]:
    rng = np.random.default_rng(seed)
    model = random_stable_model(rng)
    _, ys = model.simulate(n_steps, rng)
    ys[rng.random(ys.shape) < 0.2] = np.nan
    ys[n_steps // 3] = np.nan  # one step with nothing observed
    return model, ys


def test_linear_equals_rts_500_steps():
    model, ys = _linear_case(500, seed=11)
    post, info = fg.smooth_with_info(model, ys)
    ref = rts.smooth(model, ys)
    assert info.converged
    assert post.method == "gtsam"
    assert post.mean.shape == ref.mean.shape
    assert post.cross_cov.shape == ref.cross_cov.shape
    _assert_close(post.mean, ref.mean)
    _assert_close(post.cov, ref.cov)
    _assert_close(post.cross_cov, ref.cross_cov)
    # loglik is by definition the EKF's, so it is the same number as RTS's.
    assert post.loglik == ref.loglik
    assert not post.rejected.any()


@pytest.mark.parametrize("route", ["bayes_net", "marginals"])
def test_linear_equals_dense_posterior(linear_case, route):
    model, ys = linear_case
    post = fg.smooth(model, ys, covariance=route)
    dense = dense_posterior(model, ys)
    _assert_close(post.mean, dense.mean)
    for k in range(ys.shape[0]):
        _assert_close(post.cov[k], dense.block(k, k))
    for k in range(ys.shape[0] - 1):
        # Posterior.cross_cov[k] is Cov(x_{k+1}, x_k): row block k+1, column block k.
        _assert_close(post.cross_cov[k], dense.block(k + 1, k))
    assert abs(post.loglik - dense.loglik) < 1e-8 * abs(dense.loglik)


def test_negative_log_posterior_is_the_joint_density(linear_case):
    """At the exact mode, -log p(x, y) = 1/2 log det(2 pi Sigma_post) - log p(y)."""
    model, ys = linear_case
    dense = dense_posterior(model, ys)
    _, logdet = np.linalg.slogdet(dense.joint_cov)
    expected = 0.5 * (logdet + dense.joint_cov.shape[0] * math.log(2.0 * math.pi)) - dense.loglik
    value = fg.negative_log_posterior(model, ys, dense.mean)
    assert abs(value - expected) < 1e-9 * abs(expected)


def test_caller_trajectory_and_single_step():
    model, ys = _linear_case(80, seed=3)
    post, info = fg.smooth_with_info(model, ys, initial=np.zeros((80, model.state_dim)))
    assert info.converged and info.iterations >= 1
    assert np.all(np.diff(info.cost_history) < 0.0)
    ref = rts.smooth(model, ys)
    _assert_close(post.mean, ref.mean)
    _assert_close(post.cov, ref.cov)
    one = fg.smooth(model, ys[:1])
    ref_one = rts.smooth(model, ys[:1])
    _assert_close(one.mean, ref_one.mean)
    _assert_close(one.cov, ref_one.cov)
    assert one.cross_cov.shape == (0, model.state_dim, model.state_dim)


@pytest.mark.parametrize("smoother", [fg.smooth, iterated.smooth], ids=["gtsam", "ieks"])
def test_outlier_gate_matches_rts(smoother):
    """Both MAP smoothers keep the rows the first EKF pass's gate rejected out."""
    model, ys = _linear_case(120, seed=5)
    ys[40] = 1e3
    post = smoother(model, ys, gate_sigma=6.0)
    ref = rts.smooth(model, ys, gate_sigma=6.0)
    assert post.rejected[40].all()
    np.testing.assert_array_equal(post.rejected, ref.rejected)
    _assert_close(post.mean, ref.mean)
    _assert_close(post.cov, ref.cov)


def test_bad_inputs_are_clear_errors():
    model, ys = _linear_case(20, seed=2)
    with pytest.raises(ValueError, match="trajectory must have shape"):
        fg.smooth(model, ys, initial=np.zeros((19, model.state_dim)))
    with pytest.raises(ValueError, match="ys must have shape"):
        fg.smooth(model, ys[:, :2])
    q_bad = model.q.copy()
    q_bad[0, 0] = -1.0
    singular = LinearGaussianModel(a=model.a, c=model.c, q=q_bad, r=model.r, m0=model.m0,
                                   p0=model.p0)
    with pytest.raises(ValueError, match="process covariance Q_k at step 0"):
        fg.negative_log_posterior(singular, ys, np.zeros((20, model.state_dim)))


class ConstantTurnModel:
    """2-D constant-turn vehicle seen from a beacon at the origin.

    x = [p_x, p_y (m), speed v (m/s), heading psi (rad), turn rate w (rad/s)];
    f(x) = x + dt [v cos psi, v sin psi, 0, w, 0];
    y = [range (m), bearing atan2(p_y, p_x) (rad)], bearing residual wrapped to (-pi, pi].
    """

    state_dim = 5
    meas_dim = 2

    def __init__(self, dt: float, m0: Array, p0: Array, q: Array, r: Array) -> None:
        self.dt, self.m0, self.p0, self.q, self.r = dt, m0, p0, q, r

    def initial(self) -> tuple[Array, Array]:
        return self.m0, self.p0

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        _, _, v, psi, w = x
        c, s = math.cos(psi), math.sin(psi)
        nxt = x + self.dt * np.array([v * c, v * s, 0.0, w, 0.0])
        jac = np.eye(5)
        jac[0, 2], jac[0, 3] = self.dt * c, -self.dt * v * s
        jac[1, 2], jac[1, 3] = self.dt * s, self.dt * v * c
        jac[3, 4] = self.dt
        return nxt, jac

    def process_cov(self, x: Array, k: int) -> Array:
        return self.q

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        px, py = x[0], x[1]
        r2 = px * px + py * py
        rng = math.sqrt(r2)
        jac = np.zeros((2, 5))
        jac[0, :2] = px / rng, py / rng
        jac[1, :2] = -py / r2, px / r2
        return np.array([rng, math.atan2(py, px)]), jac

    def meas_cov(self, k: int) -> Array:
        return self.r

    def residual(self, y: Array, y_pred: Array) -> Array:
        d = np.asarray(y - y_pred, dtype=float).copy()
        d[1] = -((-d[1] + math.pi) % (2.0 * math.pi) - math.pi)  # wrap to (-pi, pi]
        return d


def _constant_turn_case(n_steps: int = 300, seed: int = 4
                        ) -> tuple[ConstantTurnModel, Array]:
    rng = np.random.default_rng(seed)
    # A 10 m circle around the beacon: the bearing sweeps through +-pi at about step 157.
    truth0 = np.array([10.0, 0.0, 2.0, math.pi / 2, 0.2])
    p0 = np.diag([0.05, 0.05, 0.02, 0.01, 0.005]) ** 2
    q = np.diag([1e-3, 1e-3, 5e-3, 5e-4, 1e-3]) ** 2
    r = np.diag([0.05, 0.01]) ** 2
    model = ConstantTurnModel(0.1, truth0 + rng.multivariate_normal(np.zeros(5), p0), p0, q, r)
    x = truth0
    ys = np.empty((n_steps, 2))
    for k in range(n_steps):
        y, _ = model.measure(x, k)
        y = y + rng.multivariate_normal(np.zeros(2), r)
        y[1] = math.atan2(math.sin(y[1]), math.cos(y[1]))
        ys[k] = y
        x = model.transition(x, k)[0] + rng.multivariate_normal(np.zeros(5), q)
    ys[rng.random(ys.shape) < 0.2] = np.nan
    return model, ys


def test_constant_turn_jacobians_match_finite_differences():
    model, _ = _constant_turn_case(5)
    x = np.array([3.0, -4.0, 1.5, 2.0, 0.3])
    eps = 1e-6
    for fun in (model.transition, model.measure):
        value, jac = fun(x, 0)
        num = np.column_stack([(fun(x + eps * e, 0)[0] - fun(x - eps * e, 0)[0]) / (2 * eps)
                               for e in np.eye(5)])
        np.testing.assert_allclose(jac, num, rtol=1e-6, atol=1e-8)
    wrapped = model.residual(np.array([0.0, math.pi - 0.01]), np.array([0.0, -math.pi + 0.01]))
    assert wrapped[1] == pytest.approx(-0.02)


def test_constant_turn_map_beats_rts_means():
    model, ys = _constant_turn_case()
    bearings = ys[~np.isnan(ys[:, 1]), 1]
    assert np.abs(np.diff(bearings)).max() > math.pi  # the data crosses the branch cut
    post, info = fg.smooth_with_info(model, ys)
    ref = rts.smooth(model, ys)
    assert info.converged, info.reason
    assert np.all(np.diff(info.cost_history) < 0.0)
    j_map = fg.negative_log_posterior(model, ys, post.mean)
    j_rts = fg.negative_log_posterior(model, ys, ref.mean)
    assert j_map == pytest.approx(info.cost_history[-1], rel=1e-12)
    assert j_map <= j_rts
    assert np.all(np.abs(post.mean - ref.mean) <= 0.1 * ref.std)
    # The Laplace and RTS covariances differ only by linearisation point.
    np.testing.assert_allclose(post.std, ref.std, rtol=0.05)


class RigidBodyToy:
    """12-state nonlinear benchmark model (not a test oracle): x = [p (3), v (3, world),
    roll/pitch/yaw (3), body rates (3)], dt = 0.01 s; hover thrust along body z against
    gravity, angles integrated straight from the rates (a small-angle stand-in for the
    Euler-rate matrix); y = [p, yaw (wrapped), rates]. Jacobians by central differences,
    as a quickly written Python model would have them. Roll and pitch are seen only
    through the second-order vertical acceleration, so over the first steps the EKF
    linearises at poor points and its RTS means sit up to ~2 std from the MAP (which has
    the lower J): a real difference between the two smoothers, not an error."""

    state_dim = 12
    meas_dim = 7
    dt = 0.01

    def __init__(self) -> None:
        self.m0 = np.zeros(12)
        self.m0[11] = 0.5  # yaw rate: the yaw measurement crosses +-pi
        self.p0 = np.diag(np.full(12, 0.05)) ** 2
        self.q = np.diag(np.repeat([1e-4, 1e-3, 1e-4, 2e-2], 3)) ** 2
        self.r = np.diag([0.02, 0.02, 0.02, 0.02, 0.01, 0.01, 0.01]) ** 2
        self.c = np.zeros((7, 12))
        self.c[[0, 1, 2, 3, 4, 5, 6], [0, 1, 2, 8, 9, 10, 11]] = 1.0

    def _f(self, x: Array) -> Array:
        roll, pitch, yaw = x[..., 6], x[..., 7], x[..., 8]
        z_body = np.stack([
            np.cos(yaw) * np.sin(pitch) * np.cos(roll) + np.sin(yaw) * np.sin(roll),
            np.sin(yaw) * np.sin(pitch) * np.cos(roll) - np.cos(yaw) * np.sin(roll),
            np.cos(pitch) * np.cos(roll)], axis=-1)
        acc = 9.81 * (z_body - np.array([0.0, 0.0, 1.0]))
        dx = np.concatenate([x[..., 3:6], acc, x[..., 9:12], np.zeros_like(acc)], axis=-1)
        return x + self.dt * dx

    def initial(self) -> tuple[Array, Array]:
        return self.m0, self.p0

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        eps = 1e-6
        pert = np.concatenate([x + eps * np.eye(12), x - eps * np.eye(12)])
        vals = self._f(pert)
        return self._f(x), ((vals[:12] - vals[12:]) / (2.0 * eps)).T

    def process_cov(self, x: Array, k: int) -> Array:
        return self.q

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        return self.c @ x, self.c

    def meas_cov(self, k: int) -> Array:
        return self.r

    def residual(self, y: Array, y_pred: Array) -> Array:
        d = np.asarray(y - y_pred, dtype=float).copy()
        d[3] = -((-d[3] + math.pi) % (2.0 * math.pi) - math.pi)
        return d

    def simulate(self, n_steps: int, rng: np.random.Generator) -> Array:
        x = rng.multivariate_normal(self.m0, self.p0)
        ys = np.empty((n_steps, 7))
        for k in range(n_steps):
            ys[k] = self.c @ x + rng.multivariate_normal(np.zeros(7), self.r)
            ys[k, 3] = math.atan2(math.sin(ys[k, 3]), math.cos(ys[k, 3]))
            x = self._f(x) + rng.multivariate_normal(np.zeros(12), self.q)
        return ys


# ------------------------------------------------------- iterated EKF + RTS (IEKS)


def test_iterated_smoother_on_a_linear_model_is_rts():
    """On a linear-Gaussian model the first RTS pass is already the posterior: the
    Gauss-Newton step is zero and the iterated smoother returns RTS's answer."""
    model, ys = _linear_case(500, seed=11)
    post, info = iterated.smooth_with_info(model, ys)
    ref = rts.smooth(model, ys)
    assert info.converged and info.iterations == 0, info.reason
    assert post.method == "ieks"
    _assert_close(post.mean, ref.mean)
    _assert_close(post.cov, ref.cov)
    _assert_close(post.cross_cov, ref.cross_cov)
    assert post.loglik == ref.loglik


@pytest.mark.parametrize("case", ["constant_turn", "rigid_body_toy"])
def test_iterated_smoother_reaches_the_gtsam_map(case):
    """Two independent routes to the MAP of the same factor graph: Gauss-Newton by RTS
    passes over the re-linearised model, and Gauss-Newton by GTSAM's elimination. On the
    rigid-body toy the single EKF + RTS pass is up to ~2 std off the MAP; iterated, the
    means agree to a hundredth of a std and the Laplace covariances to 1 %."""
    if case == "constant_turn":
        model, ys = _constant_turn_case()
    else:
        rng = np.random.default_rng(3)
        model = RigidBodyToy()
        ys = model.simulate(400, rng)
        ys[rng.random(ys.shape) < 0.2] = np.nan
    post, info = iterated.smooth_with_info(model, ys, tolerance=1e-4)
    ref = fg.smooth(model, ys)
    single = rts.smooth(model, ys)
    assert info.converged, info.reason
    assert np.all(np.diff(info.cost_history) < 0.0)
    assert info.cost_history[0] == pytest.approx(
        fg.negative_log_posterior(model, ys, single.mean), rel=1e-12)
    assert np.all(np.abs(post.mean - ref.mean) <= 0.01 * ref.std)
    np.testing.assert_allclose(post.std, ref.std, rtol=0.01)
    scale = ref.std[1:, :, None] * ref.std[:-1, None, :]
    assert np.max(np.abs(post.cross_cov - ref.cross_cov) / scale) < 0.01
    if case == "rigid_body_toy":
        assert np.max(np.abs(single.mean - ref.mean) / ref.std) > 0.5  # a real gap closed


def test_iterated_smoother_checks_its_inputs():
    model, ys = _linear_case(20, seed=2)
    with pytest.raises(ValueError, match="tolerance positive"):
        iterated.smooth(model, ys, tolerance=0.0)
    with pytest.raises(ValueError, match="ys must have shape"):
        iterated.smooth(model, ys[:, :2])


def benchmark(n_steps: int = 2000, seed: int = 0) -> None:
    """Print wall-clock times of GTSAM and RTS on 12-state models with about 20 % missing
    entries: a linear-Gaussian one (6 outputs) and the nonlinear rigid-body toy."""
    rng = np.random.default_rng(seed)
    linear = random_stable_model(rng, n=12, m=6)
    _, ys_lin = linear.simulate(n_steps, rng)
    toy = RigidBodyToy()
    ys_toy = toy.simulate(n_steps, rng)
    cases: list[tuple[str, StateSpaceModel, Array]] = [
        ("linear 12-state", linear, ys_lin), ("rigid-body toy 12-state", toy, ys_toy)]
    for name, mdl, obs in cases:
        obs[rng.random(obs.shape) < 0.2] = np.nan
        t0 = time.perf_counter()
        ref = rts.smooth(mdl, obs)
        t1 = time.perf_counter()
        post, info = fg.smooth_with_info(mdl, obs)
        t2 = time.perf_counter()
        run_filter(mdl, obs)
        t3 = time.perf_counter()
        line = (f"{name}, N={n_steps}: RTS {t1 - t0:.3f} s, GTSAM {t2 - t1:.3f} s "
                f"({info.iterations} Gauss-Newton steps, converged={info.converged}; "
                f"the EKF alone {t3 - t2:.3f} s); max |mean diff| / std "
                f"{float(np.max(np.abs(post.mean - ref.mean) / ref.std)):.2e}, "
                f"J(MAP) - J(RTS means) "
                f"{info.cost_history[-1] - fg.negative_log_posterior(mdl, obs, ref.mean):.3g}")
        if n_steps <= 2000:
            t4 = time.perf_counter()
            fg.smooth(mdl, obs, covariance="marginals")
            line += f"; with gtsam.Marginals {time.perf_counter() - t4:.3f} s"
        print(line)


if __name__ == "__main__":
    for steps in (2000, 6000):
        benchmark(steps)
