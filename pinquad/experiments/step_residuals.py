"""Where a recorded log's identified model fails, step by step: the size of the body-wrench
residual of each transition under the base fit and under discovery's refit, for the
viewer's colouring of the flight path (the viewer itself runs no estimation).

The residual of transition k -> k+1 is the M-step's (``pinquad.mstep.updates``):

    rho_k = Y_k pi - tau_k - Phi_k c - w_lag,k        (6,) [N, N m]

Y_k (6, 4) the body regressor at the smoothed states, pi = [m, I_xx, I_yy, I_zz], tau_k
the logged thrust and torques, Phi_k c the selected effects' extra wrench and w_lag,k the
motor lag's (both zero for the base fit). Its size per step is the norm of the force rows
[N] and of the torque rows [N m] of the mean of rho over a centred window of
``DiscoveryConfig.window_seconds`` (0.1 s): the same averaging as discovery's residual RMS,
which takes off the differentiation noise of single steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.discovery.calibrated import DiscoveryOutcome, discovery_config, discovery_start
from pinquad.discovery.library import TransitionData, lag_wrench, wrench_features
from pinquad.models.ssm import Observations
from pinquad.mstep.stats import transition_mask
from pinquad.mstep.updates import body_regressor
from pinquad.pipeline.identify import LogResult

Array = NDArray[np.float64]

NON_WRENCH_EFFECTS = ("motor_lag", "gyro_bias")
"""Effects whose coefficients are not a linear extra wrench (``wrench_features``)."""


@dataclass(frozen=True)
class StepResiduals:
    """The residual size per step of a log (module docstring).

    t (N,) [s]: the observations' times; force_before / torque_before (N,) [N, N m]: under
    the base fit; force_after / torque_after (N,): under discovery's refit (equal to the
    base's when discovery selected nothing or did not run: ``refitted`` False); NaN on
    steps with no used transition in the window. window_seconds [s]: the averaging
    window; after_model: the model of the ``after`` columns, in words.
    """

    t: Array
    force_before: Array
    torque_before: Array
    force_after: Array
    torque_after: Array
    window_seconds: float
    refitted: bool
    after_model: str


def wrench_residuals(obs: Observations, post: Posterior, gravity: float, pi: Array,
                     coefficients: dict[str, Array] | None = None) -> Array:
    """(N, 6) rho_k [N, N m] of every used transition k (module docstring), NaN on the
    last step and on excluded transitions. pi (4,): [m [kg], I_xx, I_yy, I_zz [kg m^2]];
    coefficients: the selected effects' (``DiscoveryResult.coefficients``), or None."""
    idx = np.flatnonzero(transition_mask(obs))
    x_now, x_next = post.mean[idx], post.mean[idx + 1]
    rho = np.einsum("kap,p->ka", body_regressor(x_now, x_next, obs.dt, gravity), pi)
    rho[:, 2] -= obs.inputs[idx, 0]
    rho[:, 3:6] -= obs.inputs[idx, 1:4]
    coeffs = coefficients or {}
    data = TransitionData.of(obs, x_now, idx)
    for name, c in coeffs.items():
        if name not in NON_WRENCH_EFFECTS:
            rho -= np.einsum("kap,p->ka", wrench_features(name, data), np.asarray(c))
    if "motor_lag" in coeffs:
        rho -= lag_wrench(data, float(coeffs["motor_lag"][0]))
    out = np.full((obs.n, 6), np.nan)
    out[idx] = rho
    return out


def window_mean(values: Array, steps: int) -> Array:
    """(N, C) mean of each column over the centred window of ``steps`` rows, NaN rows left
    out (NaN where the window holds none)."""
    ok = np.isfinite(values)
    filled = np.where(ok, values, 0.0)
    kernel = np.ones(max(int(steps), 1))
    sums = np.column_stack([np.convolve(filled[:, j], kernel, mode="same")
                            for j in range(values.shape[1])])
    counts = np.column_stack([np.convolve(ok[:, j].astype(float), kernel, mode="same")
                              for j in range(values.shape[1])])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1.0), np.nan)


def _sizes(rho: Array, steps: int) -> tuple[Array, Array]:
    mean = window_mean(rho, steps)
    return np.linalg.norm(mean[:, 0:3], axis=1), np.linalg.norm(mean[:, 3:6], axis=1)


def step_residuals(result: LogResult, outcome: DiscoveryOutcome | None) -> StepResiduals | None:
    """The residual sizes of the reported run of ``result`` before and after discovery's
    refit (``outcome``); None when the run kept no posterior or is the ten-parameter fit
    (its CoM offset is not in this diagonal residual)."""
    run = result.runs[0]
    if run.mstep == "full":
        return None
    try:
        start = discovery_start(run)
    except ValueError:
        return None
    obs, theta = start.obs, start.theta
    window = discovery_config(result.kind).window_seconds
    steps = max(int(round(window / obs.dt)), 1)
    pi0 = np.r_[theta.mass, np.diag(theta.inertia)]
    force0, torque0 = _sizes(wrench_residuals(obs, start.posterior, theta.gravity, pi0), steps)
    found = None if outcome is None else outcome.result
    if found is None or not found.selected:
        return StepResiduals(obs.t, force0, torque0, force0, torque0, window, False,
                             "base rigid-body model (discovery selected no effect)")
    pi1 = np.r_[found.mass, np.diag(found.inertia)]
    rho1 = wrench_residuals(obs, found.posterior, theta.gravity, pi1, found.coefficients)
    force1, torque1 = _sizes(rho1, steps)
    return StepResiduals(obs.t, force0, torque0, force1, torque1, window, True,
                         f"base model plus {', '.join(found.selected)} (discovery's refit)")
