"""Inertia of a measured flight by direct maximum likelihood, one body axis at a time, with
the torques the model does not have as a coloured disturbance.

Why: in closed loop the controller answers every torque the model lacks, and a
regression of the rotor torque on the angular acceleration in a frequency band then
reads the controller as much as the inertia (``pinquad.realdata.response``; on simulated flights
``realdata``'s 3-8 Hz M-step reads the inertia 11-21 % high). The direct method, the
likelihood of the measured rates given the measured torques under a model that includes
the disturbance, is consistent in closed loop when that disturbance model is right.

Model of body axis j on the grid t_k = k dt (rates omega [rad/s], torques [N m]):

    omega_{k+1} = omega_k + (dt / I) (u_k + d_k) + w_k,       w_k ~ N(0, q_white)
    d_{k+1}     = phi d_k + e_k,                               e_k ~ N(0, q_colour')
    y_k         = omega_k + n_k,                               n_k ~ N(0, r)

with u_k the rotor torque of the bin [t_k, t_k + dt) minus the gyroscopic term
(omega x I_ref omega)_j from the gyro (I_ref: a reference inertia; the term is a few
percent of the torque), plus J_r sum_i spin_i omega_i' on yaw when a rotor inertia is
given, and y_k the gyro (bin centred on t_k; NaN: missing). d is written scaled,
d' = (dt / I) d, so that the model is linear-Gaussian in the state (omega, d') for fixed
parameters theta = (I, phi, q_white, q_colour, r); its exact log-likelihood comes from a
Kalman filter (:func:`axis_loglik`), maximised over theta by Nelder-Mead and Powell from
several starts. Transitions outside flight (``Observations.exclude``) get a wide process
variance (``GAP_VAR``) so that the filter does not carry the dynamics across them.
phi is kept in (0, 1) (a low-pass disturbance). Standard error of I: from the observed
information of (log I, log q_white, log q_colour, log r) at phi fixed (phi sits near 1
on the measured flights, where its own curvature is flat), pseudo-inverted.

``python -m pinquad.axis_inertia [LOG ...]`` (``pinquad.cli.axis_inertia``) prints the
table for measured logs (``--parts 2``: each half of each flight on its own);
``--simulate 1 10`` checks the estimator on simulated closed-loop flights with a known
inertia (:func:`simulated_axes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.optimize import minimize

from pinquad.core.params import CRAZYFLIE21
from pinquad.realdata.observations import RealObservations, simulated_observations
from pinquad.realdata.raw import simulated_crazyflie

Array = NDArray[np.float64]

GAP_VAR = (100.0, 0.1)
"""Process variances added across an excluded transition: rate [(rad/s)^2] and scaled
disturbance [(rad/s)^2]."""
UNRELIABLE_SE = 0.25
"""A fit whose inertia standard error is undefined or exceeds this fraction of the
estimate is flagged (:attr:`AxisFit.unreliable`) and left out of the summary."""


@dataclass(frozen=True)
class AxisFit:
    """The maximum-likelihood rate model of one body axis.

    axis: 0, 1, 2 (roll, pitch, yaw); inertia [kg m^2] and se [kg m^2] (NaN if the
    information is not positive definite); phi [-]: the disturbance's step-to-step
    correlation; q_white, q_colour [(rad/s)^2]: per-step variances of the white rate
    noise and of the scaled disturbance's innovation; gyro_var [(rad/s)^2]: measurement
    variance; loglik: the maximised log-likelihood; steps: grid steps used.
    """

    axis: int
    inertia: float
    se: float
    phi: float
    q_white: float
    q_colour: float
    gyro_var: float
    loglik: float
    steps: int

    @property
    def unreliable(self) -> bool:
        """The inertia's standard error is undefined or over ``UNRELIABLE_SE`` of the
        estimate (typically a fit that ran off: the disturbance explains the motion and
        the torque gets no say)."""
        return not (math.isfinite(self.se) and self.se <= UNRELIABLE_SE * self.inertia)


@njit(cache=True)
def axis_loglik(gain: float, phi: float, q_white: float, q_colour: float, gyro_var: float,
                u: Array, y: Array, gap: NDArray[np.bool_], gap_rate: float,
                gap_colour: float) -> float:
    """log p(y | u; theta) of the module's model by a Kalman filter over the state
    (omega, d') with gain = dt / I [rad/s per N m]; y NaN = missing; gap[k]: transition
    k -> k+1 widened by (gap_rate, gap_colour)."""
    n = u.shape[0]
    m0 = 0.0
    for k in range(n):
        if not math.isnan(y[k]):
            m0 = y[k]
            break
    m1 = 0.0
    p00 = 100.0 * gyro_var + 1e-6
    p01 = 0.0
    p11 = q_colour / max(1e-6, 1.0 - phi * phi) + 1e-12
    ll = 0.0
    for k in range(n):
        yk = y[k]
        if not math.isnan(yk):
            s = p00 + gyro_var
            nu = yk - m0
            ll -= 0.5 * (math.log(2.0 * math.pi * s) + nu * nu / s)
            k0 = p00 / s
            k1 = p01 / s
            m0 += k0 * nu
            m1 += k1 * nu
            p11 -= k1 * p01
            p01 -= k0 * p01
            p00 -= k0 * p00
        if k == n - 1:
            break
        # F = [[1, 1], [0, phi]]
        a00 = p00 + 2.0 * p01 + p11
        a01 = phi * (p01 + p11)
        a11 = phi * phi * p11
        m0 = m0 + gain * u[k] + m1
        m1 = phi * m1
        p00 = a00 + q_white
        p01 = a01
        p11 = a11 + q_colour
        if gap[k]:
            p00 += gap_rate
            p11 += gap_colour
    return ll


def _objective(u: Array, y: Array, gap: NDArray[np.bool_], dt: float):
    def negll(v: Array, phi: float | None = None) -> float:
        """v = (log I, z, log q_white, log q_colour, log r), phi = (1 + tanh z) / 2 in
        (0, 1): the disturbance is low-pass; ``phi`` overrides v[1]."""
        if not np.all(np.isfinite(v)) or np.any(np.abs(v[2:]) > 200.0):
            return 1e300
        ph = _phi(v[1]) if phi is None else phi
        val = -axis_loglik(dt / math.exp(v[0]), ph, math.exp(v[2]), math.exp(v[3]),
                           math.exp(v[4]), u, y, gap, GAP_VAR[0], GAP_VAR[1])
        return val if math.isfinite(val) else 1e300

    return negll


def _phi(z: float) -> float:
    return 0.5 * (1.0 + math.tanh(z))


def _se_log_inertia(negll, v: Array, phi: float, h: float = 1e-3) -> float:
    """sqrt of the (0, 0) entry of the inverse observed information of (log I,
    log q_white, log q_colour, log r) at phi fixed (central second differences)."""
    free = [0, 2, 3, 4]

    def f(w: Array) -> float:
        full = v.copy()
        full[free] = w
        return negll(full, phi)

    w0 = v[free]
    k = len(free)
    hess = np.zeros((k, k))
    f0 = f(w0)
    for i in range(k):
        ei = np.zeros(k)
        ei[i] = h
        hess[i, i] = (f(w0 + ei) - 2.0 * f0 + f(w0 - ei)) / (h * h)
        for j in range(i + 1, k):
            ej = np.zeros(k)
            ej[j] = h
            hess[i, j] = hess[j, i] = (f(w0 + ei + ej) - f(w0 + ei - ej) - f(w0 - ei + ej)
                                       + f(w0 - ei - ej)) / (4.0 * h * h)
    # pseudo-inverse: with a nearly white disturbance (phi ~ 0) its variance and the
    # white noise's trade off exactly, a direction the inertia does not share
    cov = np.linalg.pinv(hess, rcond=1e-10)
    return math.sqrt(cov[0, 0]) if cov[0, 0] > 0 else float("nan")


def fit_axis(u: Array, y: Array, gap: NDArray[np.bool_], dt: float, inertia0: float,
             axis: int = 0) -> AxisFit:
    """Maximum-likelihood :class:`AxisFit` of one axis: u (K,) [N m], y (K,) [rad/s],
    gap (K,) bool, from starts at inertia0 x (0.5, 1, 2) [kg m^2]."""
    u = np.ascontiguousarray(u, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    gap = np.ascontiguousarray(gap, dtype=np.bool_)
    negll = _objective(u, y, gap, dt)
    dy = np.diff(y)
    scale = float(np.nanstd(dy)) if np.isfinite(dy).any() else 1e-2
    best = None
    for factor in (1.0, 0.5, 2.0):
        v = np.array([math.log(inertia0 * factor), math.atanh(0.8), math.log((0.3 * scale) ** 2),
                      math.log((0.1 * scale) ** 2), math.log((0.3 * scale) ** 2)])
        for method in ("Nelder-Mead", "Powell", "Nelder-Mead"):
            opts = ({"maxiter": 4000, "xatol": 1e-7, "fatol": 1e-7} if method == "Nelder-Mead"
                    else {"maxiter": 4000, "xtol": 1e-7, "ftol": 1e-10})
            res = minimize(negll, v, method=method, options=opts)
            if res.fun <= negll(v):
                v = res.x
        if best is None or negll(v) < negll(best):
            best = v
    assert best is not None
    phi = _phi(best[1])
    se_log = _se_log_inertia(negll, best, phi)
    inertia = math.exp(best[0])
    return AxisFit(axis=axis, inertia=inertia, se=inertia * se_log, phi=phi,
                   q_white=math.exp(best[2]), q_colour=math.exp(best[3]),
                   gyro_var=math.exp(best[4]), loglik=-negll(best),
                   steps=int(np.isfinite(y).sum()))


def axis_signals(real: RealObservations, reference: Array, rotor_inertia: float = 0.0
                 ) -> tuple[Array, Array, NDArray[np.bool_], float]:
    """(u (K, 3) [N m], y (K, 3) [rad/s], gap (K,) bool, dt [s]) of a measured flight
    (``realdata.RealObservations``) over the span from its first to its last used
    transition: rotor torques minus omega x (I_ref omega) (gyro, gaps interpolated),
    plus J_r sum_i spin_i omega_i' on yaw; the gyro rows; the excluded transitions."""
    obs = real.obs
    used = np.flatnonzero(~obs.exclude[: obs.n - 1])
    if used.size < 2:
        raise ValueError(f"{real.source}: fewer than two used transitions")
    span = slice(int(used[0]), int(used[-1]) + 2)
    if "gyro" not in obs.channels:
        raise ValueError(f"{real.source}: no gyro channel (channels {', '.join(obs.channels)}); "
                         "the rate model needs the gyro")
    gi = 3 * list(obs.channels).index("gyro")
    y = np.asarray(obs.ys[span, gi:gi + 3], dtype=float)
    t = obs.t[span]
    seen = np.isfinite(y).all(axis=1)
    if seen.sum() < 2:
        raise ValueError(f"{real.source}: no gyro samples in the used span")
    rate = np.column_stack([np.interp(t, t[seen], y[seen, j]) for j in range(3)])
    reference = np.asarray(reference, dtype=float)
    u = np.asarray(obs.inputs[span, 1:4], dtype=float) - np.cross(rate, reference * rate)
    if rotor_inertia and real.rotor_acc is not None:
        u[:, 2] += rotor_inertia * np.nan_to_num(np.asarray(real.rotor_acc[span], float))
    gap = np.asarray(obs.exclude[span], dtype=bool).copy()
    return u, y, gap, float(obs.dt)


def identify_axes(real: RealObservations, reference: Array, rotor_inertia: float = 0.0,
                  part: int = 0, parts: int = 1) -> tuple[AxisFit, AxisFit, AxisFit]:
    """:class:`AxisFit` of roll, pitch and yaw of a measured flight, each started at the
    reference inertia (3,) [kg m^2]; with ``parts`` > 1, of the ``part``-th (0-based) of
    that many equal consecutive pieces of the used span alone (a consistency check: the
    pieces of one flight should agree within their standard errors)."""
    u, y, gap, dt = axis_signals(real, reference, rotor_inertia)
    if not 0 <= part < parts:
        raise ValueError(f"part {part} of {parts}: expected 0 <= part < parts")
    cut = np.linspace(0, y.shape[0], parts + 1).astype(int)
    piece = slice(cut[part], cut[part + 1])
    u, y, gap = u[piece], y[piece], gap[piece]
    fits = tuple(fit_axis(u[:, j], y[:, j], gap, dt, float(reference[j]), j) for j in range(3))
    return fits[0], fits[1], fits[2]


def simulated_axes(factor: float, seed: int) -> tuple[tuple[AxisFit, AxisFit, AxisFit], Array]:
    """:func:`identify_axes` of a simulated closed-loop Crazyflie 2.1 flight (sensor B,
    the torque noise x factor; ``realdata.simulated_crazyflie``) read as a measured log,
    and the true inertia diagonal (3,) [kg m^2]."""
    real = simulated_observations(simulated_crazyflie(factor, seed, "B"))
    truth = np.diag(CRAZYFLIE21.inertia).copy()
    return identify_axes(real, truth), truth
