"""Issue 23 part 3 (a minute of flight analysed in a minute): the faster paths of
discovery and the verdicts give the answers of the paths they replaced, and the worker
pool changes nothing but the wall time. The timing itself is the benchmark's
(``python -m pinquad.bench --only discovery``), not a test's."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np
import pytest

from flightgen import Effects, FlightSpec, generate, write_csv
from pinquad.discovery.calibrated import discover_calibrated, discovery_config, discovery_start
from pinquad.discovery.library import TransitionData, lagged_inputs, wrench_features
from pinquad.discovery.null import NullSettings
from pinquad.discovery.refit import effect_mstep
from pinquad.discovery.residuals import block_grams, compute_residuals, group_sums, step_blocks
from pinquad.discovery.result import DiscoveryConfig
from pinquad.estep import fast_smoother
from pinquad.identification import verdict_evidence
from pinquad.io.read import read_log
from pinquad.mstep.stats import transition_mask
from pinquad.mstep.updates import regressor_mstep, regressor_stats
from pinquad.pipeline.identify import LogOptions, identify_log

CFG = DiscoveryConfig()


@pytest.fixture(scope="module")
def drag_start(tmp_path_factory):
    flight = generate(FlightSpec(duration=12, log_rate=100, seed=5, floor=None,
                                 effects=Effects(drag=(0.006, 0.006, 0.007))))
    path = write_csv(flight, tmp_path_factory.mktemp("speed") / "drag.csv")
    result = identify_log(read_log(path), LogOptions(msteps=("regressor",), information=False))
    return discovery_start(result.runs[0])


def test_group_sums_equal_np_add_at_for_unsorted_labels():
    rng = np.random.default_rng(0)
    values = rng.standard_normal((500, 6, 3))
    labels = rng.integers(0, 7, 500)
    labels[labels == 4] = 5  # a group with no rows stays zero
    ref = np.zeros((7, 6, 3))
    np.add.at(ref, labels, values)
    np.testing.assert_allclose(group_sums(values, labels, 7), ref, rtol=1e-12, atol=1e-12)
    assert not group_sums(values, labels, 7)[4].any()


def test_block_covariance_and_grams_equal_the_per_block_reference(drag_start):
    obs, post, g = drag_start.obs, drag_start.posterior, drag_start.theta.gravity
    res = compute_residuals(obs, post, g, CFG.block_seconds)
    # reference: the covariance part of each block as regressor_stats on that block alone
    steps_block = step_blocks(obs, CFG.block_seconds)
    stats = regressor_stats(post, obs, g)
    for b in range(res.n_blocks):
        ex = steps_block != b
        a_b = regressor_stats(post, replace(obs, exclude=ex), g).a
        sel = res.block == b
        ref = a_b - np.einsum("kap,kaq->apq", stats.y[sel], stats.y[sel])
        np.testing.assert_allclose(res.corr[b], ref, rtol=1e-8, atol=1e-9 * np.abs(a_b).max())
    phi = wrench_features("drag", res.data)
    fixed = np.zeros((res.y.shape[0], 6))
    z = np.concatenate([res.y, -phi, -(res.tau + fixed)[:, :, None]], axis=2)
    ref = np.zeros((res.n_blocks, 6, z.shape[2], z.shape[2]))
    np.add.at(ref, res.block, np.einsum("kaq,kar->kaqr", z, z))
    ref[:, :, 0:4, 0:4] += res.corr
    got = block_grams(res, phi, fixed)
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    window = 10
    key = res.block * 1_000_000 + res.idx // window
    uniq, inv = np.unique(key, return_inverse=True)
    zs = np.zeros((uniq.size, 6, z.shape[2]))
    np.add.at(zs, inv, z)
    zs /= np.bincount(inv)[:, None, None]
    ref_w = np.zeros_like(ref)
    np.add.at(ref_w, uniq // 1_000_000, np.einsum("kaq,kar->kaqr", zs, zs))
    np.testing.assert_allclose(block_grams(res, phi, fixed, window), ref_w, rtol=1e-10,
                               atol=1e-12 * np.abs(ref_w).max())


def test_compiled_innovation_consistency_equals_the_generic_filters(drag_start, monkeypatch):
    obs, theta = drag_start.obs, drag_start.theta
    fast = verdict_evidence.innovation_consistency(obs, theta)
    assert fast_smoother.innovations_quad(verdict_evidence.QuadSSM(obs, theta), obs.ys) is not None
    monkeypatch.setattr(verdict_evidence, "innovations_quad", lambda model, ys: None)
    generic = verdict_evidence.innovation_consistency(obs, theta)
    assert set(fast) == set(generic) == set(obs.channels)
    for c in fast:
        assert fast[c] == pytest.approx(generic[c], rel=1e-9)


def test_the_worker_pool_changes_nothing_but_the_wall_time(drag_start):
    """Discovery with its null calibration in two worker processes (shadow flights scored
    there, the refit run there beside them) against everything in this process; a short
    refit (5 E-steps, 2 joint iterations) keeps the test cheap, the comparison does not
    depend on it."""
    start = drag_start
    cfg = replace(discovery_config("simulated", "sampled"), em_iterations=5, joint_iterations=2)
    null = NullSettings(replicates=19, seed=2)
    serial = discover_calibrated(start, cfg, null, "sampled")
    with ProcessPoolExecutor(2) as pool:
        pooled = discover_calibrated(start, cfg, null, "sampled", pool)
    assert serial.error is None and pooled.error is None
    assert serial.result.selected == pooled.result.selected == ("drag",)
    np.testing.assert_array_equal(serial.null.null_gains["drag"], pooled.null.null_gains["drag"])
    assert serial.null.null_passes == pooled.null.null_passes
    assert serial.null.p_value == pooled.null.p_value
    for e in serial.result.selected:
        np.testing.assert_allclose(pooled.result.coefficients[e], serial.result.coefficients[e],
                                   rtol=1e-12)
        np.testing.assert_allclose(pooled.result.stderr[e], serial.result.stderr[e], rtol=1e-12)
    assert pooled.result.mass == pytest.approx(serial.result.mass, rel=1e-12)


def test_effect_mstep_lateral_noise_equals_the_per_transition_residual(drag_start):
    """The effect M-step's lateral wrench noise from the expected quadratic forms equals the
    per-transition form it replaced: S_j = dt / n (sum_k (E[Y_k pi] - tau_k - f_k)_j^2 +
    the covariance part of q_j) with regressor_stats' arrays, j = x, y; the covariance
    part pi^T (A_j - sum_k Y_kj^T Y_kj) pi - 2 (b_j - sum_k tau_kj Y_kj) pi + c_j - sum_k
    tau_kj^2 (the last two nonzero on this continuous flight, whose applied force turns
    with the attitude)."""
    obs, post, theta = drag_start.obs, drag_start.posterior, drag_start.theta
    coefficients = {"drag": np.array([0.006, 0.006, 0.007]), "wind": np.array([0.01, -0.006])}
    new = effect_mstep(coefficients)(post, obs, theta).theta
    plain = regressor_mstep(post, obs, theta).theta
    assert new.mass == plain.mass and np.array_equal(new.inertia, plain.inertia)
    stats = regressor_stats(post, obs, theta.gravity)
    idx = np.flatnonzero(transition_mask(obs))
    data = TransitionData(x=post.mean[idx], inputs=obs.inputs[idx], applied_history=obs.inputs,
                          index=idx, dt=obs.dt, ground_radius=obs.ground_radius)
    force = sum(np.einsum("kap,p->ka", wrench_features(e, data), c)
                for e, c in coefficients.items())
    pi = np.r_[new.mass, np.diag(new.inertia)]
    rho = np.einsum("kap,p->ka", stats.y, pi) - stats.tau - force
    assert obs.continuous
    cov_part = (np.einsum("p,apq,q->a", pi,
                          stats.a - np.einsum("kap,kaq->apq", stats.y, stats.y), pi)
                - 2.0 * (stats.b - np.einsum("kap,ka->ap", stats.y, stats.tau)) @ pi
                + stats.c - np.einsum("ka,ka->a", stats.tau, stats.tau))
    ref = obs.dt * (np.sum(rho**2, axis=0) + cov_part)[0:2] / idx.size
    np.testing.assert_allclose(new.noise.wrench[0:2], ref, rtol=1e-10)
    # the flight's drag is what the lateral rows no longer count as noise
    drag_only = effect_mstep({"drag": coefficients["drag"]})(post, obs, theta).theta
    assert np.all(drag_only.noise.wrench[0:2] < plain.noise.wrench[0:2])


@pytest.mark.parametrize("time_constant", [0.0, 0.002, 0.03])
def test_lagged_inputs_is_the_first_order_recursion(time_constant):
    """lagged_inputs (an IIR filter) equals the recursion it replaced,
    u_k = u_{k-1} + dt/(tau + dt) (u_cmd,k - u_{k-1}) from u_0 = u_cmd,0."""
    dt = 0.002
    commands = 0.3 + 0.1 * np.random.default_rng(7).standard_normal((500, 4))
    a = dt / (time_constant + dt)
    ref = np.empty_like(commands)
    ref[0] = commands[0]
    for k in range(1, commands.shape[0]):
        ref[k] = ref[k - 1] + a * (commands[k] - ref[k - 1])
    np.testing.assert_allclose(lagged_inputs(commands, time_constant, dt), ref, rtol=0, atol=1e-14)
    assert lagged_inputs(commands[:0], time_constant, dt).shape == (0, 4)
