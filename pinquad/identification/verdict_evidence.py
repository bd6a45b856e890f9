"""The evidence a verdict (``pinquad.identification.verdict``) is judged from, gathered
from a fit: how much of the angular acceleration the logged torques explain
(``torque_share``), how far the torques stand out from the process noise
(``torque_excitation``) and how large the EKF's innovations are against what the model
predicts (``innovation_consistency``), all at the fit's parameters; ``data_evidence``
puts them in one ``VerdictEvidence``. The rules that turn the evidence into verdict
words are ``verdict``'s alone (unlike ``discovery.evidence``: an effect's evidence).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfiltfilt

from estimators.ekf import predict, update
from pinquad.core.filters import band_sos
from pinquad.estep.fast_smoother import Innovations, innovations_quad
from pinquad.identification.verdict import VerdictEvidence
from pinquad.models.ssm import Observations, QuadSSM, Theta
from pinquad.mstep.stats import transition_mask

Array = NDArray[np.float64]


def mstep_transitions(obs: Observations) -> NDArray[np.bool_]:
    """(N - 1,) the transitions k -> k+1 the M-step uses (``mstep.stats.transition_mask``)
    that were not reset either."""
    used = transition_mask(obs)
    if obs.resets.size:
        used &= ~np.asarray(obs.resets[: obs.n - 1], dtype=bool)
    return used


def torque_share(obs: Observations, mean: Array, inertia: Array,
                 band: tuple[float, float] | None = None, com: Array | None = None) -> Array:
    """Share of the angular-acceleration variance the torques explain, per body axis (3,).

    On the transitions k -> k+1 the M-step uses (not excluded, not reset): the angular
    acceleration a_k = (omega_{k+1} - omega_k) / dt [rad/s^2] of the smoothed rates
    mean[:, 9:12] against the model's u_k = J^{-1} (tau_k - omega_k x J omega_k) with the
    logged torques tau_k = inputs[k, 1:4] [N m] and the estimate J (3, 3) [kg m^2];
    R^2_i = max(corr(a_i, u_i), 0)^2 (a free scale and offset: the share any inertia
    could explain). band (lo, hi) [Hz]: both series band-passed first (zero-phase
    Butterworth), for an M-step that reads the inertia from that band only. com (3,) [m]:
    the centre of mass from the thrust centre (the ten-parameter model), whose thrust
    moment -c x (0, 0, F_k) joins the torques about the CoM.
    """
    inertia = np.asarray(inertia, dtype=float).reshape(3, 3)
    omega = np.asarray(mean, dtype=float)[:, 9:12]
    accel = np.diff(omega, axis=0) / obs.dt
    tau = obs.inputs[:-1, 1:4]
    if com is not None:
        thrust = np.zeros((obs.n - 1, 3))
        thrust[:, 2] = obs.inputs[:-1, 0]
        tau = tau - np.cross(np.asarray(com, dtype=float), thrust)
    u = (tau - np.cross(omega[:-1], omega[:-1] @ inertia.T)) @ np.linalg.inv(inertia).T
    if band is not None:
        sos = band_sos(band, 1.0 / obs.dt, top=0.495)
        accel, u = sosfiltfilt(sos, accel, axis=0), sosfiltfilt(sos, u, axis=0)
    used = mstep_transitions(obs) & np.isfinite(accel).all(axis=1) & np.isfinite(u).all(axis=1)
    out = np.full(3, np.nan)
    if used.sum() < 10:
        return out
    for i in range(3):
        a, b = accel[used, i], u[used, i]
        if np.std(a) > 0 and np.std(b) > 0:
            out[i] = max(float(np.corrcoef(a, b)[0, 1]), 0.0) ** 2
    return out


EXCITATION_BAND = 50.0
"""Upper edge [Hz] of the band in which ``torque_excitation`` compares the torques with the
process noise when the M-step reads every frequency: the noise averaged over 10 ms, about
the time an attitude loop takes to answer a disturbance. A fixed edge keeps the ratio the
same for the same flight logged at 100 or 500 Hz (the torques recorded barely change, the
noise's bandwidth up to the Nyquist frequency would grow with the rate)."""


def torque_excitation(obs: Observations, theta: Theta,
                      band: tuple[float, float] | None = None, *,
                      actuation: str) -> tuple[Array, str]:
    """How far the logged torques stand out from the process noise, per body axis (3,) [-],
    and the band it was measured on (in words).

    r_i = rms(tau_i - mean(tau_i)) / sqrt(2 S_i B): tau = inputs[:, 1:4] [N m] low-passed
    to B = min(``EXCITATION_BAND``, Nyquist) (zero-phase Butterworth) on the transitions the
    M-step uses; S_i [N^2 m^2 s] the torque noise intensity of theta (EM's estimate; white
    noise of intensity S has variance 2 S B in a band of width B). A ratio near 1 means the
    torques are the size of the disturbances, i.e. mostly a controller's answer to them.

    Measured only for a log whose input is a faster controller's command sampled at each
    row (``actuation`` ``sampled``, ``LogMeta.actuation``): there the command moved within
    each interval in answer to the disturbances, unrecorded. A held input (``held``: what
    acted over the whole interval, as pinquad's simulator logs it) leaves no such answer
    unrecorded, and EM's inertia stays right at small ratios (pinquad's CoM-offset
    flight, seed 7: 1.35 about z, 2 % off), so the ratio is NaN there.

    NaN too when theta's noise is the fixed one (``NoiseModel.fixed_q``: not estimated from
    this log) or not positive, and for an M-step that reads one band (lo, hi) [Hz] only
    (the measured flights'): EM fits one white intensity over all frequencies, which on
    those flights also holds the unmodelled low-frequency moments the band M-step leaves
    out, so the ratio would not compare like with like (jana01, whose I_xx is within 1 %
    of the published value, has 1.8 there).
    """
    out = np.full(3, np.nan)
    if band is not None:
        return out, f"not measured on an M-step that reads {band[0]:g}-{band[1]:g} Hz only"
    if actuation != "sampled":
        return out, "not measured: the log's input is held over each row"
    if theta.noise.fixed_q is not None:
        return out, "not measured: the noise model is fixed, not estimated from this log"
    nyquist = 0.5 / obs.dt
    tau = np.asarray(obs.inputs[:-1, 1:4], dtype=float)
    width = min(EXCITATION_BAND, nyquist)
    words = f"0-{width:g} Hz"
    if EXCITATION_BAND < 0.99 * nyquist:
        tau = sosfiltfilt(butter(2, EXCITATION_BAND / nyquist, output="sos"), tau, axis=0)
    intensity = np.asarray(theta.noise.wrench, dtype=float)[3:6]
    used = mstep_transitions(obs) & np.isfinite(tau).all(axis=1)
    if used.sum() < 10:
        return out, words
    rms = np.std(tau[used], axis=0)
    for i in range(3):
        if intensity[i] > 0:
            out[i] = float(rms[i] / np.sqrt(2.0 * intensity[i] * width))
    return out, words


def innovation_consistency(obs: Observations, theta: Theta, model=None) -> dict[str, float]:
    """Mean normalised innovation squared per row of each channel (channel -> [-]) of the
    EKF at theta: for every sample of channel c, nu_c^T S_cc^{-1} nu_c / (rows of c) with
    nu the one-step-ahead innovation and S its covariance (the channel's block). 1 when the
    innovations are as large as the model predicts. model: the state-space model (default
    ``QuadSSM(obs, theta)``)."""
    model = model if model is not None else QuadSSM(obs, theta)
    fast = innovations_quad(model, obs.ys)
    if fast is not None:
        return _mean_nis(fast, obs.channels)
    mean, cov = model.initial()
    mean, cov = np.array(mean, dtype=float), np.array(cov, dtype=float)
    blocks = {c: np.arange(3 * i, 3 * i + 3) for i, c in enumerate(obs.channels)}
    sums = {c: 0.0 for c in blocks}
    counts = {c: 0 for c in blocks}
    for k in range(obs.n):
        y = obs.ys[k]
        seen = ~np.isnan(y)
        if seen.any():
            y_pred, h = model.measure(mean, k)
            nu = model.residual(np.where(seen, y, y_pred), y_pred)
            s = h @ cov @ h.T + model.meas_cov(k)
            for c, rows in blocks.items():
                rows = rows[seen[rows]]
                if rows.size:
                    v = nu[rows]
                    sums[c] += float(v @ np.linalg.solve(s[np.ix_(rows, rows)], v))
                    counts[c] += rows.size
            upd = update(model, k, mean, cov, y)
            mean, cov = upd.mean, upd.cov
        if k + 1 < obs.n:
            mean, cov, _ = predict(model, k, mean, cov)
    return {c: sums[c] / counts[c] for c in blocks if counts[c]}


def _mean_nis(inn: Innovations, channels: Sequence[str]) -> dict[str, float]:
    """``innovation_consistency`` from the innovations of the whole pass at once: per
    channel, the samples grouped by which of its rows were observed."""
    out = {}
    for i, c in enumerate(channels):
        rows = np.arange(3 * i, 3 * i + 3)
        nu = inn.nu[:, rows]
        seen = ~np.isnan(nu)
        total, count = 0.0, 0
        for pattern in np.unique(seen, axis=0):
            if not pattern.any():
                continue
            steps = np.all(seen == pattern, axis=1)
            r = rows[pattern]
            v = inn.nu[np.ix_(steps, r)]
            s_blk = inn.s[steps][:, r][:, :, r]
            total += float(np.sum(v * np.linalg.solve(s_blk, v[:, :, None])[:, :, 0]))
            count += int(steps.sum()) * r.size
        if count:
            out[c] = total / count
    return out


def data_evidence(obs: Observations, theta: Theta, mean: Array,
                  band: tuple[float, float] | None = None, model=None,
                  actuation: str = "held") -> VerdictEvidence:
    """The evidence of a fit at theta: torque shares on the smoothed means (N, 12) (on the
    M-step's band when it reads the inertia from one), the torques against the process
    noise (``torque_excitation``, for a log whose ``actuation`` is ``sampled``) and the
    EKF's innovation consistency (``model``: default ``QuadSSM(obs, theta)``; the
    ten-parameter model's ``FullQuadSSM`` for a fit with a centre of mass)."""
    words = "all frequencies" if band is None else f"{band[0]:g}-{band[1]:g} Hz, the M-step's band"
    com = np.asarray(theta.com, dtype=float)
    excitation, excitation_words = torque_excitation(obs, theta, band, actuation=actuation)
    return VerdictEvidence(torque_share(obs, mean, theta.inertia, band, com if com.any() else None),
                           words, innovation_consistency(obs, theta, model),
                           torque_excitation=excitation, excitation_band=excitation_words)
