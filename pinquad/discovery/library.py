"""The estimator's side of the effect vocabulary (``pinquad.core.effect_vocabulary``): what discovery fits.

An :class:`EffectSpec` names an effect's coefficients and the residual rows it explains;
``wrench_features`` give the extra body wrench the effect adds to one transition
k -> k+1 as a linear function of its coefficients (``wrench_k = Phi_k c``), evaluated at
the smoothed state and the logged command; ``lag_wrench`` / ``lagged_inputs`` are the
nonlinear ``motor_lag``; ``explaining_feature`` is what a figure plots a residual
against. The simulator's side (the injected disturbances) is ``pinquad.sim.effects``; the
names and constants both use are ``pinquad.core.effect_vocabulary``.

The forms and coefficients of each effect are tabled in ``pinquad.core.effect_vocabulary``.

``motor_lag`` (tau_m u' = u_cmd - u) is discretised by how the log's inputs were read
(``applied_lag``). Held inputs (pinquad's simulator, whose truth is this very step): backward
Euler, u_k = u_{k-1} + dt / (tau_m + dt) (u_cmd,k - u_{k-1}). Sampled inputs (the command
of a faster controller at each row's instant; the transition applies the interval mean):
the exact lag of the command interpolated linearly between the samples, averaged over each
interval (``sampled_lag_means``). Backward Euler on a sampled log's interval means has too
little phase lag at frequencies near 1/dt (at 7 Hz and 100 Hz, 45 degrees where a 30 ms lag
has 54): where the torque is dominated by such a frequency (flightgen's lagged attitude
loop rings at about 7 Hz), the fit matched the phase with a 42 ms lag and made up the
gain with an inertia 28 % low (docs/discovery.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from pinquad.core.conventions import rotation_from_euler
from pinquad.core.effect_vocabulary import COEFFICIENT_NAMES, ground_effect_gain
from pinquad.models.ssm import Observations

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TransitionData:
    """What an effect's features see of the transitions k -> k+1 used for fitting.

    x (K, 12): smoothed state at k; inputs (K, 4): logged command [F (N), M (N m)] at k;
    applied_history (N, 4): the whole input sequence the transitions apply (for lags);
    index (K,): the step k of each row; dt [s]; ground_radius [m]: the vehicle's
    ground-effect radius (``Observations.ground_radius``); samples (N, 4) or None: the
    logged command at each row's instant when ``applied_history`` holds its interval
    means (``Observations.samples``; None: held inputs); floor_height z_f [m, world]:
    where the log shows the floor (``Observations.floor``), the ground-effect law's zero.
    """

    x: Array
    inputs: Array
    applied_history: Array
    index: NDArray[np.int64]
    dt: float
    ground_radius: float
    samples: Array | None = None
    floor_height: float = 0.0

    @property
    def height(self) -> Array:
        """(K,) [m] the height above the floor the log shows, z - z_f, that the
        ground-effect law takes (``Observations.floor``)."""
        return self.x[:, 2] - self.floor_height

    @classmethod
    def of(cls, obs: Observations, x_now: Array, idx: NDArray[np.int64]) -> TransitionData:
        """The transitions idx (K,) of ``obs`` at the states x_now (K, 12): the logged
        inputs of those steps, the whole input history, the vehicle's ground-effect
        radius, the log's samples and its floor, as ``obs`` carries them."""
        return cls(x=x_now, inputs=obs.inputs[idx], applied_history=obs.inputs, index=idx,
                   dt=obs.dt, ground_radius=obs.ground_radius, samples=obs.samples,
                   floor_height=obs.floor.height)


def lagged_inputs(inputs: Array, time_constant: float, dt: float) -> Array:
    """u_k = u_{k-1} + dt/(tau_m + dt) (u_cmd,k - u_{k-1}), u_0 = u_cmd,0: (N, 4)."""
    a = dt / (max(time_constant, 0.0) + dt)
    u = np.asarray(inputs, dtype=float)
    if u.shape[0] == 0:
        return u.copy()
    # the recursion u_k = (1 - a) u_{k-1} + a u_cmd,k as a first-order IIR filter (the
    # selection's grid search runs it dozens of times on logs of 30,000 rows); the
    # initial state (1 - a) u_cmd,0 makes u_0 = u_cmd,0
    return lfilter([a], [1.0, a - 1.0], u, axis=0, zi=(1.0 - a) * u[0:1])[0]


def sampled_lag_means(samples: Array, time_constant: float, dt: float) -> Array:
    """(N, 4) interval means of the lag tau_m u' = u_cmd - u driven by the command
    interpolated linearly between its samples u_cmd,k (N, 4) at t_k = k dt [s].

    Exact for that command. With E = exp(-dt/tau_m), beta = tau_m / dt,
    Delta_k = u_cmd,k+1 - u_cmd,k and u_0 = u_cmd,0 (at rest on the first sample):

        u_k+1 = E u_k + (1 - beta (1 - E)) u_cmd,k+1 + (beta (1 - E) - E) u_cmd,k
        mean over [t_k, t_k+1] = (u_cmd,k + u_cmd,k+1) / 2 - beta Delta_k
                                 + (u_k - u_cmd,k + beta Delta_k) beta (1 - E)

    The last row, with no next sample, holds its command (as ``interval_inputs`` does).
    tau_m <= 0: the command's interval means themselves."""
    u = np.asarray(samples, dtype=float)
    delta = np.zeros_like(u)
    delta[:-1] = u[1:] - u[:-1]
    if time_constant <= 0.0:
        return u + 0.5 * delta
    decay = float(np.exp(-dt / time_constant))
    beta = time_constant / dt
    gain = beta * (1.0 - decay)              # the mean of exp(-s / tau_m) over the interval
    lagged = np.empty_like(u)
    lagged[0] = u[0]
    if u.shape[0] > 1:
        b = [1.0 - gain, gain - decay]
        zi = (decay * u[0] + b[1] * u[0])[None, :]
        lagged[1:], _ = lfilter(b, [1.0, -decay], u[1:], axis=0, zi=zi)
    return u + 0.5 * delta - beta * delta + (lagged - u + beta * delta) * gain


def applied_lag(inputs: Array, samples: Array | None, time_constant: float, dt: float) -> Array:
    """(N, 4) what each transition applies through the motor lag tau_m [s]: backward Euler
    on held ``inputs`` (``lagged_inputs``), or, when the log's ``samples`` are given (the
    inputs are their interval means), ``sampled_lag_means`` of the samples."""
    if samples is None:
        return lagged_inputs(inputs, time_constant, dt)
    return sampled_lag_means(samples, time_constant, dt)


@dataclass(frozen=True)
class EffectSpec:
    """Estimator side of one effect.

    name: the effect vocabulary's name; coefficient_names / units: one per coefficient; rows: the
    residual rows it explains (0-5: body force x, y, z, torque x, y, z; "gyro" effects
    use the gyro measurement residuals instead); feature_name: the explaining feature
    (for figures); nonlinear: coefficient enters nonlinearly (motor_lag: searched on a
    grid, ``features`` then takes the coefficient and returns the wrench itself).
    """

    name: str
    coefficient_names: tuple[str, ...]
    units: tuple[str, ...]
    rows: tuple[int, ...]
    feature_name: str
    nonlinear: bool = False

    @property
    def n_coefficients(self) -> int:
        return len(self.coefficient_names)


SPECS: dict[str, EffectSpec] = {
    "drag": EffectSpec("drag", COEFFICIENT_NAMES["drag"], ("N s/m",) * 3, (0, 1, 2),
                       "body velocity [m/s]"),
    "ground_effect": EffectSpec("ground_effect", COEFFICIENT_NAMES["ground_effect"], ("-",), (2,),
                                "thrust x ground gain F g(z) [N]"),
    "com_offset": EffectSpec("com_offset", COEFFICIENT_NAMES["com_offset"], ("m", "m"), (3, 4),
                             "thrust [N]"),
    "wind": EffectSpec("wind", COEFFICIENT_NAMES["wind"], ("N", "N"), (0, 1, 2),
                       "world x/y axis in body frame [-]"),
    "motor_lag": EffectSpec("motor_lag", COEFFICIENT_NAMES["motor_lag"], ("s",), (2, 3, 4, 5),
                            "command rate du/dt", nonlinear=True),
    "gyro_bias": EffectSpec("gyro_bias", COEFFICIENT_NAMES["gyro_bias"], ("rad/s",) * 3, (),
                            "time [s]"),
}
"""Effect name -> its estimator-side description (every name of ``EFFECT_NAMES``)."""


NON_NEGATIVE = {"drag": (0, 1, 2), "ground_effect": (0,), "motor_lag": (0,)}
"""Effect -> the indices of its coefficients that cannot be negative (their physical
domain, ``pinquad.discovery.domain``); the others are unbounded."""


def lower_bounds(effect: str) -> Array:
    """(p,) each coefficient's lower bound for ``effect`` (0, or -inf: none), in the order
    of ``COEFFICIENT_NAMES``."""
    lo = np.full(len(COEFFICIENT_NAMES[effect]), -np.inf)
    lo[list(NON_NEGATIVE.get(effect, ()))] = 0.0
    return lo


def domain_text(effect: str) -> dict[str, str]:
    """Coefficient name -> its domain in words (``">= 0"`` or ``"unbounded"``)."""
    return {n: (">= 0" if np.isfinite(b) else "unbounded")
            for n, b in zip(COEFFICIENT_NAMES[effect], lower_bounds(effect), strict=True)}


def wrench_features(name: str, data: TransitionData) -> Array:
    """Phi (K, 6, p) with the effect's extra body wrench [N, N m] = Phi @ c (linear effects)."""
    k = data.x.shape[0]
    if name == "drag":
        v_b = np.einsum("kji,kj->ki", rotation_from_euler(data.x[:, 6:9]), data.x[:, 3:6])
        phi = np.zeros((k, 6, 3))
        for i in range(3):
            phi[:, i, i] = -v_b[:, i]
        return phi
    if name == "ground_effect":
        phi = np.zeros((k, 6, 1))
        phi[:, 2, 0] = data.inputs[:, 0] * ground_effect_gain(data.height, data.ground_radius)
        return phi
    if name == "com_offset":
        phi = np.zeros((k, 6, 2))
        phi[:, 4, 0] = data.inputs[:, 0]
        phi[:, 3, 1] = -data.inputs[:, 0]
        return phi
    if name == "wind":
        rot = rotation_from_euler(data.x[:, 6:9])
        phi = np.zeros((k, 6, 2))
        phi[:, 0:3, 0] = rot[:, 0, :]  # R^T e_x: row 0 of R as a column
        phi[:, 0:3, 1] = rot[:, 1, :]
        return phi
    raise ValueError(f"{name!r} is not a linear wrench effect")


def lag_wrench(data: TransitionData, time_constant: float) -> Array:
    """(K, 6) extra wrench u_lagged - u_applied of ``motor_lag`` (thrust and torque rows):
    the lagged input (``applied_lag``) minus what the transition applies without the lag."""
    lagged = applied_lag(data.applied_history, data.samples, time_constant, data.dt)
    out = np.zeros((data.index.size, 6))
    out[:, 2:6] = lagged[data.index] - data.applied_history[data.index]
    return out


def explaining_feature(name: str, data: TransitionData, row: int) -> Array:
    """(K,) the scalar a figure plots residual row ``row`` against."""
    if name == "drag":
        v_b = np.einsum("kji,kj->ki", rotation_from_euler(data.x[:, 6:9]), data.x[:, 3:6])
        return v_b[:, min(row, 2)]
    if name == "ground_effect":
        return data.height
    if name == "com_offset":
        return data.inputs[:, 0]
    if name == "wind":
        rot = rotation_from_euler(data.x[:, 6:9])
        return rot[:, 0, min(row, 2)]
    if name == "motor_lag":
        hist = data.applied_history
        rate = np.gradient(hist, data.dt, axis=0)
        return rate[data.index, max(row - 2, 0)]
    return data.index * data.dt
