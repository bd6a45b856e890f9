"""Shadow flights: the fitted base model flown along a recorded flight, at a fine rate,
and logged like the recorded log. They are the null hypothesis of effect discovery
(``pinquad.discovery.null``): flights of a vehicle that has no effect at all, with the
recorded flight's trajectory, length, sampling and noise.

Each shadow flight integrates the base model (mass m [kg], inertia J (3, 3) [kg m^2],
gravity g [m/s^2]; state x = [p (m), v (m/s), Theta (rad, ZYX Euler), omega (rad/s)])

    p' = v,   v' = R(Theta) e3 F / m - g e3 + R(Theta) n_F / m,
    Theta' = E^{-1}(Theta) omega,   omega' = J^{-1} (tau + n_tau - omega x J omega)

with classical RK4 at ``substeps`` steps h = dt / substeps per logged interval dt, the
wrench held over each h. The wrench is that of a controller running at the fine rate
(for a log whose input was held over each row, the command of the row's first instant,
held):
the recorded input u_k = (F, tau) interpolated linearly between log rows (feed-forward)
plus a tracking law that holds the shadow on the recorded flight's smoothed states
x_ref (interpolated the same way):

    f_des = R(Theta_ref) e3 F_ff + m (k_p (p_ref - p) + k_d (v_ref - v))       [N, world]
    F = f_des . R e3,   e_att = R^T (R e3 x f_des / |f_des|) + (psi_ref - psi) e3   [rad]
    tau = tau_ff + J (k_att e_att + k_rate (omega_ref - omega))                   [N m]

The process noise n = (n_F, n_tau) is white, drawn per fine step with variance S / h
(S: the fitted base model's wrench intensities ``NoiseModel.wrench`` [N^2 s, N^2 m^2 s]),
so the shadow's noise is the fit's whatever the substep. The log keeps the command
sampled at each log instant (as a controller faster than its log writes it: the input
moves within each logged interval), made as rough as the recorded input by white noise
where the recorded one is rougher (``input_roughness_gap``), and the measured channels
H x(t_k) plus white noise of the fit's measurement variances, with the recorded log's
gaps (NaN where it has none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numba
import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import wrap_angle
from pinquad.core.kernels import rotation_of_angles
from pinquad.models.sources import interval_inputs
from pinquad.models.ssm import Observations, Theta

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ShadowSettings:
    """How shadow flights are flown.

    max_substep [s]: the fine step is dt / ceil(dt / max_substep); pos_gains (k_p [1/s^2],
    k_d [1/s]) and att_gains (k_att [1/s^2], k_rate [1/s]) of the tracking law (module
    docstring): critically damped at 3 and 20 rad/s, slow enough to leave the recorded
    input's feed-forward doing the flying, fast enough to hold the shadow within
    centimetres of the recorded trajectory.
    """

    max_substep: float = 0.0005
    pos_gains: tuple[float, float] = (9.0, 6.0)
    att_gains: tuple[float, float] = (400.0, 40.0)

    def substeps(self, dt: float) -> int:
        return max(int(math.ceil(dt / self.max_substep - 1e-9)), 1)


@numba.njit(cache=True)
def _derivative(x, force, torque, mass, inertia, inertia_inv, gravity, out):  # pragma: no cover
    # the body force in the world frame, R = Rz(psi) Ry(theta) Rx(phi)
    rot = np.empty((3, 3))
    rotation_of_angles(x[6], x[7], x[8], rot)
    for a in range(3):
        out[a] = x[3 + a]
        out[3 + a] = (rot[a, 0] * force[0] + rot[a, 1] * force[1] + rot[a, 2] * force[2]) / mass
    out[5] -= gravity
    sf, cf = math.sin(x[6]), math.cos(x[6])
    st, ct = math.sin(x[7]), math.cos(x[7])
    wx, wy, wz = x[9], x[10], x[11]
    tt = st / ct
    out[6] = wx + sf * tt * wy + cf * tt * wz
    out[7] = cf * wy - sf * wz
    out[8] = (sf * wy + cf * wz) / ct
    hx = inertia[0, 0] * wx + inertia[0, 1] * wy + inertia[0, 2] * wz
    hy = inertia[1, 0] * wx + inertia[1, 1] * wy + inertia[1, 2] * wz
    hz = inertia[2, 0] * wx + inertia[2, 1] * wy + inertia[2, 2] * wz
    mx = torque[0] - (wy * hz - wz * hy)
    my = torque[1] - (wz * hx - wx * hz)
    mz = torque[2] - (wx * hy - wy * hx)
    out[9] = inertia_inv[0, 0] * mx + inertia_inv[0, 1] * my + inertia_inv[0, 2] * mz
    out[10] = inertia_inv[1, 0] * mx + inertia_inv[1, 1] * my + inertia_inv[1, 2] * mz
    out[11] = inertia_inv[2, 0] * mx + inertia_inv[2, 1] * my + inertia_inv[2, 2] * mz


@numba.njit(cache=True)
def _fly(x0, x_ref, euler_step, u_ff, dt, substeps, mass, inertia, inertia_inv, gravity,
         gains, noise, hold, states, logged):  # pragma: no cover
    n = x_ref.shape[0]
    h = dt / substeps
    x = x0.copy()
    ref = np.empty(12)
    u = np.empty(4)
    force = np.zeros(3)
    torque = np.zeros(3)
    k1 = np.empty(12)
    k2 = np.empty(12)
    k3 = np.empty(12)
    k4 = np.empty(12)
    tmp = np.empty(12)
    r_ref = np.empty((3, 3))
    r = np.empty((3, 3))
    kp, kd, katt, krate = gains[0], gains[1], gains[2], gains[3]
    j = 0
    for k in range(n):
        states[k] = x
        for i in range(substeps):
            s = i / substeps
            if k + 1 < n:
                for q in range(12):
                    ref[q] = x_ref[k, q] + s * (x_ref[k + 1, q] - x_ref[k, q])
                for q in range(3):
                    ref[6 + q] = x_ref[k, 6 + q] + s * euler_step[k, q]
                for q in range(4):
                    u[q] = u_ff[k, q] + s * (u_ff[k + 1, q] - u_ff[k, q])
            else:
                for q in range(12):
                    ref[q] = x_ref[k, q]
                for q in range(4):
                    u[q] = u_ff[k, q]
            if i == 0 or not hold:
                rotation_of_angles(ref[6], ref[7], ref[8], r_ref)
                rotation_of_angles(x[6], x[7], x[8], r)
                f_des = np.empty(3)
                for a in range(3):
                    f_des[a] = (r_ref[a, 2] * u[0]
                                + mass * (kp * (ref[a] - x[a]) + kd * (ref[3 + a] - x[3 + a])))
                thrust = f_des[0] * r[0, 2] + f_des[1] * r[1, 2] + f_des[2] * r[2, 2]
                # no desired force (motors off on the floor): no tilt to correct
                norm = max(math.sqrt(f_des[0] ** 2 + f_des[1] ** 2 + f_des[2] ** 2), 1e-300)
                # tilt error b3 x b3_des in the world frame, then into the body frame
                cx = (r[1, 2] * f_des[2] - r[2, 2] * f_des[1]) / norm
                cy = (r[2, 2] * f_des[0] - r[0, 2] * f_des[2]) / norm
                cz = (r[0, 2] * f_des[1] - r[1, 2] * f_des[0]) / norm
                e_att = np.empty(3)
                for a in range(3):
                    e_att[a] = r[0, a] * cx + r[1, a] * cy + r[2, a] * cz
                dpsi = ref[8] - x[8]
                dpsi = math.atan2(math.sin(dpsi), math.cos(dpsi))
                e_att[2] += dpsi
                cmd = np.empty(3)
                for a in range(3):
                    cmd[a] = katt * e_att[a] + krate * (ref[9 + a] - x[9 + a])
                if i == 0:
                    logged[k, 0] = thrust
                for a in range(3):
                    tq = u[1 + a]
                    for b in range(3):
                        tq += inertia[a, b] * cmd[b]
                    torque[a] = tq + noise[j, 3 + a]
                    if i == 0:
                        logged[k, 1 + a] = tq
            else:
                # a held log: the command of the interval's first instant acts throughout
                thrust = logged[k, 0]
                for a in range(3):
                    torque[a] = logged[k, 1 + a] + noise[j, 3 + a]
            force[0] = noise[j, 0]
            force[1] = noise[j, 1]
            force[2] = thrust + noise[j, 2]
            j += 1
            if k + 1 == n:
                break
            _derivative(x, force, torque, mass, inertia, inertia_inv, gravity, k1)
            for q in range(12):
                tmp[q] = x[q] + 0.5 * h * k1[q]
            _derivative(tmp, force, torque, mass, inertia, inertia_inv, gravity, k2)
            for q in range(12):
                tmp[q] = x[q] + 0.5 * h * k2[q]
            _derivative(tmp, force, torque, mass, inertia, inertia_inv, gravity, k3)
            for q in range(12):
                tmp[q] = x[q] + h * k3[q]
            _derivative(tmp, force, torque, mass, inertia, inertia_inv, gravity, k4)
            for q in range(12):
                x[q] += h / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])


@dataclass(frozen=True)
class ShadowFlight:
    """One shadow flight: its observations (the recorded log's layout: inputs = the
    commands sampled at the log instants, ys = measured channels with the recorded
    gaps) and its true states (N, 12) at the log instants."""

    obs: Observations
    states: Array


def second_difference_var(inputs: Array) -> Array:
    """(4,) variance of u_{k+1} - 2 u_k + u_{k-1} per input channel over the finite rows
    [N^2, (N m)^2]: white noise of variance s^2 on a smooth signal adds 6 s^2."""
    d2 = inputs[2:] - 2.0 * inputs[1:-1] + inputs[:-2]
    return np.array([np.mean(d2[np.isfinite(d2[:, i]), i] ** 2) if np.isfinite(d2[:, i]).any()
                     else 0.0 for i in range(inputs.shape[1])])


def input_roughness_gap(recorded: Array, shadow: Array) -> Array:
    """(4,) standard deviation of the white noise that makes the shadow's logged inputs
    as rough as the recorded ones: sqrt(max(0, (V2_rec - V2_shadow) / 6)) per channel,
    V2 the ``second_difference_var``. A logged input with noise the body never felt (an
    actuation channel read through a noisy sensor or a fast noisy controller) is so
    reproduced in the null; a smooth recorded input adds nothing."""
    gap = (second_difference_var(recorded) - second_difference_var(shadow)) / 6.0
    return np.sqrt(np.maximum(gap, 0.0))


def shadow_flight(obs: Observations, theta: Theta, reference: Array, rng: np.random.Generator,
                  settings: ShadowSettings = ShadowSettings(), actuation: str = "held"
                  ) -> ShadowFlight:
    """Fly the base model ``theta`` along ``reference`` (N, 12), the recorded flight's
    smoothed states, with the recorded inputs ``obs.inputs`` as feed-forward, and log it
    like ``obs`` (module docstring). actuation: the recorded log's (``LogMeta.actuation``):
    ``sampled``, the controller runs at the fine rate and the log keeps its command at each
    row, read as the recorded log's is (``models.sources.interval_inputs``); ``held``, the
    command of each row's instant acts over the row's interval, as in pinquad's simulator.
    Randomness (process and measurement noise) from ``rng`` only."""
    n = obs.n
    substeps = settings.substeps(obs.dt)
    h = obs.dt / substeps
    inertia = np.asarray(theta.inertia, dtype=float)
    wrench = np.asarray(theta.noise.wrench, dtype=float)
    noise = rng.standard_normal((n * substeps, 6)) * np.sqrt(np.maximum(wrench, 0.0) / h)
    euler_step = np.zeros((n, 3))
    euler_step[:-1] = wrap_angle(np.diff(reference[:, 6:9], axis=0))
    states = np.empty((n, 12))
    logged = np.empty((n, 4))
    gains = np.array([*settings.pos_gains, *settings.att_gains], dtype=float)
    _fly(np.ascontiguousarray(reference[0], dtype=float), np.ascontiguousarray(reference, dtype=float),
         euler_step, np.ascontiguousarray(obs.inputs, dtype=float), float(obs.dt), substeps,
         float(theta.mass), inertia, np.linalg.inv(inertia), float(theta.gravity), gains, noise,
         actuation == "held", states, logged)
    # as rough as the recorded inputs, then read as the recorded log is read; a log with
    # samples (``Observations.samples``) is roughened on its samples, so that the shadow's
    # samples and their interval means agree as the recorded log's do (the motor lag of
    # discovery is discretised on them)
    samples = None
    if actuation == "sampled" and obs.samples is not None:
        samples = logged + rng.standard_normal(logged.shape) * input_roughness_gap(obs.samples, logged)
        inputs = interval_inputs(samples, actuation)
    else:
        inputs = interval_inputs(logged, actuation)
        inputs = inputs + rng.standard_normal(inputs.shape) * input_roughness_gap(obs.inputs, inputs)
    clean = states @ obs.measurement_matrix().T
    meas_sd = np.sqrt(np.maximum(np.asarray(theta.noise.meas, dtype=float), 0.0))
    ys = clean + rng.standard_normal(clean.shape) * meas_sd
    angle_rows = obs.angle_rows()
    if angle_rows.size:
        ys[:, angle_rows] = wrap_angle(ys[:, angle_rows])
    ys[np.isnan(obs.ys)] = np.nan
    return ShadowFlight(replace(obs, inputs=inputs, ys=ys, samples=samples), states)
