"""Residual statistics of a base-model fit at one posterior: the body-wrench residual
rho_k = Y_k pi - tau_k (6,) [N, N m] of each used transition, the gyro residual
y_gyro,k - omega_k|N [rad/s], the attitude-kinematics residual [rad/s], their blocks
(alternating train / held-out), per-block expected Gram matrices, and held-out RMS per
axis of window means. The method is in ``pinquad.discovery.discover``'s docstring."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.conventions import euler_rate_matrix_inv, rotation_from_euler, wrap_angle
from pinquad.discovery.library import TransitionData, lag_wrench, wrench_features
from pinquad.discovery.result import ATT_AXES, AXES, GYRO_AXES, DiscoveryConfig
from pinquad.models.ssm import Observations
from pinquad.mstep.stats import transition_mask
from pinquad.mstep.updates import covariance_terms, regressor_stats

Array = NDArray[np.float64]


def window_steps(cfg: DiscoveryConfig, dt: float) -> int:
    """Steps per averaging window of the residual RMS (``cfg.window_seconds`` / dt, >= 1)."""
    return max(int(round(cfg.window_seconds / dt)), 1)


@dataclass(frozen=True)
class Residuals:
    """Per-transition quantities at one posterior.

    idx (K,): steps k of the used transitions; block (K,): block number; y (K, 6, 4);
    tau (K, 6); corr (B, 6, 4, 4): posterior-covariance part of E[Y^T Y] per block;
    data: effect features' view; gyro_res (N, 3) with NaN where unobserved;
    gyro_block (N,): block of each step; att_res (N, 3) [rad/s]: the attitude-kinematics
    residual (``ATT_AXES``) of transition k -> k+1, NaN on the last step and on excluded
    transitions; sampling (K, 6, 3): the intra-interval change of the known wrench
    (``sampling_columns``), the nuisance columns of the selection's model comparisons.
    """

    idx: NDArray[np.int64]
    block: NDArray[np.int64]
    y: Array
    tau: Array
    corr: Array
    data: TransitionData
    gyro_res: Array
    gyro_block: NDArray[np.int64]
    n_blocks: int
    att_res: Array
    sampling: Array


def step_blocks(obs: Observations, seconds: float) -> NDArray[np.int64]:
    """(N,) block number of each step."""
    return np.floor((obs.t - obs.t[0]) / seconds).astype(np.int64)


def compute_residuals(obs: Observations, post: Posterior, gravity: float, block_seconds: float
                      ) -> Residuals:
    """The ``Residuals`` of ``post`` on ``obs`` (gravity [m/s^2]; blocks of
    ``block_seconds`` [s] from the first step)."""
    steps_block = step_blocks(obs, block_seconds)
    n_blocks = int(steps_block.max()) + 1
    stats = regressor_stats(post, obs, gravity)
    idx = np.flatnonzero(transition_mask(obs))
    block = steps_block[idx]
    # the covariance part of E[Y^T Y], summed per block from the per-transition terms
    corr = group_sums(covariance_terms(post, obs, gravity), block, n_blocks)
    data = TransitionData.of(obs, post.mean[idx], idx)
    gyro_res = np.full((obs.n, 3), np.nan)
    if "gyro" in obs.channels:
        i = obs.channels.index("gyro")
        gyro_res = obs.ys[:, 3 * i:3 * i + 3] - post.mean[:, 9:12]
    euler, rates = post.mean[:, 6:9], post.mean[:, 9:12]
    att_res = np.full((obs.n, 3), np.nan)
    att_res[idx] = (wrap_angle(euler[idx + 1] - euler[idx]) / obs.dt
                    - np.einsum("kij,kj->ki", euler_rate_matrix_inv(euler[idx]), rates[idx]))
    sampling = sampling_columns(post.mean, obs.inputs, idx)
    return Residuals(idx, block, stats.y, stats.tau, corr, data, gyro_res, steps_block, n_blocks,
                     att_res, sampling)


def sampling_columns(state: Array, inputs: Array, idx: NDArray[np.int64]) -> Array:
    """Delta (K, 6, 3) [N, N m]: half the change of the known wrench over each used
    transition k -> k+1, in the body frame at k, as three nuisance columns.

    With the world thrust force f_k = R(Theta_k) [0, 0, F_k] [N] and
    Delta_F,k = R_k^T (f_{k+1} - f_k) / 2: column 0 holds Delta_F,k's horizontal rows
    (body x, y: the thrust DIRECTION's move, about dt F (omega_y, -omega_x) / 2), column 1
    its vertical row (mostly the magnitude's change (F_{k+1} - F_k) / 2), column 2 the
    torque rows (M_{k+1} - M_k) / 2 [N m].

    Why: every model of pinquad integrates x_{k+1} = x_k + dt f(x_k, u_k), the input
    held over the interval (pinquad's simulator does hold it). A log whose actuation is
    the command SAMPLED at each row of a faster controller applied, over the interval,
    about the trapezoid (w_k + w_{k+1}) / 2 = w_k + Delta_k; on a smooth trajectory the
    missing Delta_k lines up with velocity (a sinusoid's jerk is -Omega^2 v) and reads as
    drag of order m dt Omega^2 / 2. ``selection.fit_model`` fits columns 0 and 1 (by
    default) in every model the selection compares; column 2 is left out because the
    torque rows' change is what ``motor_lag`` explains, and a free coefficient there took
    a 30 ms lag's torque signature away from it (docs/discovery.md, "Actuation between
    samples"). A continuous flight's E-step and M-step turn the
    thrust with the interval's mean rotation themselves (``models.continuous``,
    ``mstep.updates.applied_force``); column 0 then fits what that model leaves.
    """
    rot = rotation_from_euler(state[:, 6:9])
    thrust_world = rot[:, :, 2] * inputs[:, 0:1]   # R e3 F, (N, 3)
    d_world = thrust_world[idx + 1] - thrust_world[idx]
    d_body = 0.5 * np.einsum("kji,kj->ki", rot[idx], d_world)
    out = np.zeros((idx.size, 6, 3))
    out[:, 0:2, 0] = d_body[:, 0:2]
    out[:, 2, 1] = d_body[:, 2]
    out[:, 3:6, 2] = 0.5 * (inputs[idx + 1, 1:4] - inputs[idx, 1:4])
    return out


def effect_columns(res: Residuals, effects: Sequence[str], lag: float | None
                   ) -> tuple[Array, Array]:
    """Linear feature columns Phi (K, 6, p) of ``effects`` (wrench effects only) and the
    fixed extra wrench (K, 6) of motor_lag at time constant ``lag`` (zero if absent)."""
    cols = [wrench_features(e, res.data) for e in effects
            if e not in ("motor_lag", "gyro_bias")]
    k = res.y.shape[0]
    phi = np.concatenate(cols, axis=2) if cols else np.zeros((k, 6, 0))
    fixed = lag_wrench(res.data, lag) if lag is not None and lag > 0 else np.zeros((k, 6))
    return phi, fixed


def _groups(labels: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                                   NDArray[np.int64]]:
    """(order, first, label): the rows in stable label order, the start of each run of one
    label in that order, and that label (labels (K,), e.g. blocks, sorted or not)."""
    order = np.argsort(labels, kind="stable")
    sorted_labels = labels[order]
    first = np.flatnonzero(np.r_[True, sorted_labels[1:] != sorted_labels[:-1]]) \
        if labels.size else np.zeros(0, dtype=np.int64)
    return order, first, sorted_labels[first]


def group_sums(values: Array, labels: NDArray[np.int64], n_groups: int) -> Array:
    """(n_groups, ...) sums of ``values`` (K, ...) over the rows of each label (K,) in
    0..n_groups-1 (zero where a label has no row); ``np.add.at`` at a fraction of its cost."""
    out = np.zeros((n_groups, *values.shape[1:]))
    order, first, label = _groups(labels)
    if first.size:
        out[label] = np.add.reduceat(values[order], first, axis=0)
    return out


def _gram_sums(z: Array, labels: NDArray[np.int64], n_groups: int) -> Array:
    """(n_groups, 6, q, q): sum over the rows of each label of z_k^T z_k per wrench row,
    z (K, 6, q)."""
    out = np.zeros((n_groups, z.shape[1], z.shape[2], z.shape[2]))
    order, first, label = _groups(labels)
    bounds = np.r_[first, labels.size]
    zs = z[order]
    for b, lo, hi in zip(label, bounds[:-1], bounds[1:], strict=True):
        part = zs[lo:hi].transpose(1, 2, 0)              # (6, q, rows)
        out[b] = part @ part.transpose(0, 2, 1)
    return out


def block_grams(res: Residuals, phi: Array, fixed: Array, window: int = 0) -> Array:
    """Per-block expected Gram matrices G (B, 6, q, q), q = 4 + p + 1, of
    z = [Y, -Phi, -(tau + fixed)] so that rho - Phi c = z [pi, c, 1].

    window > 0: Gram matrices of the means of z over ``window`` consecutive steps (the
    low-frequency part the selection gain is measured on; no covariance correction)."""
    z = np.concatenate([res.y, -phi, -(res.tau + fixed)[:, :, None]], axis=2)
    if window > 0:
        key = res.block * 1_000_000 + res.idx // window
        uniq, inv = np.unique(key, return_inverse=True)
        zs = group_sums(z, inv, uniq.size) / np.bincount(inv)[:, None, None]
        return _gram_sums(zs, uniq // 1_000_000, res.n_blocks)
    g = _gram_sums(z, res.block, res.n_blocks)
    g[:, :, 0:4, 0:4] += res.corr
    return g


def window_rms(values: Array, block: NDArray[np.int64], steps: NDArray[np.int64], window: int
               ) -> float:
    """RMS of means over windows of ``window`` consecutive steps (within one block)."""
    ok = ~np.isnan(values)
    if not ok.any():
        return float("nan")
    key = block[ok] * 100000 + steps[ok] // max(window, 1)
    _, inv = np.unique(key, return_inverse=True)
    sums = np.bincount(inv, values[ok])
    counts = np.bincount(inv)
    return float(np.sqrt(np.mean((sums / counts) ** 2)))


def heldout_rms(res: Residuals, pi: Array, coeffs: dict[str, Array], test: NDArray[np.bool_],
                 window: int, steps_mask: NDArray[np.bool_] | None = None) -> dict[str, float]:
    """RMS per axis of ``window``-step means of the residual on the blocks in ``test``
    (and, if given, only on the steps k with steps_mask[k])."""
    wrench = [e for e in coeffs if e not in ("motor_lag", "gyro_bias")]
    phi, fixed = effect_columns(res, wrench, float(coeffs["motor_lag"][0]) if "motor_lag" in coeffs
                                 else None)
    c = np.concatenate([coeffs[e] for e in wrench]) if wrench else np.zeros(0)
    rho = (np.einsum("kap,p->ka", res.y, pi) - res.tau - fixed
           - np.einsum("kap,p->ka", phi, c))
    sel = test[res.block]
    if steps_mask is not None:
        sel = sel & steps_mask[res.idx]
    out = {a: window_rms(rho[sel, i], res.block[sel], res.idx[sel], window)
           for i, a in enumerate(AXES)}
    g = res.gyro_res - (coeffs["gyro_bias"] if "gyro_bias" in coeffs else 0.0)
    gsel = test[res.gyro_block]
    steps = np.arange(g.shape[0])
    if steps_mask is not None:
        gsel = gsel & steps_mask
    for i, a in enumerate(GYRO_AXES):
        out[a] = window_rms(g[gsel, i], res.gyro_block[gsel], steps[gsel], window)
    for i, a in enumerate(ATT_AXES):
        out[a] = window_rms(res.att_res[gsel, i], res.gyro_block[gsel], steps[gsel], window)
    return out
