"""The transition of a continuous flight: the kinematic rows of an explicit-Euler step
moved by the mean of their rates over the interval.

pinquad's own simulator moves by explicit Euler at its log's step, x_{k+1} = x_k + dt f(x_k,
u_k), and so do the models on its logs. A recorded flight (or a simulator finer than its
log) moves continuously: over [t_k, t_k+1] the attitude turns with the mean body rate,
the thrust direction turns with it, and the position moves with the mean velocity. With
explicit Euler the smoother makes up the difference by taking each rate and velocity half
a step early or late, and on a smooth trajectory (jerk about -Omega^2 v) that timing error
leaves a force residual that reads as drag (docs/discovery.md, "Actuation between
samples"). In the order each row needs the next one's result:

    omega_{k+1}  the model's Euler step (the torques are already interval means)
    Theta_{k+1} = Theta_k + dt E^{-1}(Theta_k) w,          w = (omega_k + omega_{k+1}) / 2
    v_{k+1}     = the Euler step's v_{k+1} + dt (R_{k+1} - R_k) a_b / 2
                  (the thrust acceleration by the mean of R_k and R_{k+1})
    p_{k+1}     = p_k + dt (v_k + v_{k+1}) / 2

a_b (3,) [m/s^2]: the body-frame acceleration the model's wrench gives (a quadcopter's
[0, 0, F / m]); forces the Euler step adds besides (gravity, drag, wind) stay at t_k. Under a
constant acceleration the position moves exactly so; the attitude and the thrust
direction are right to second order in dt, where explicit Euler is right to first.

The process noise gets the matching shares (``kinematic_noise``). ``pinquad.estep``'s
kernels compute the same (``quad_kernels.continuous_rows``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import euler_rate_kinematics, rotation_and_derivatives

Array = NDArray[np.float64]


def continuous_step(x: Array, dt: float, x_next: Array, jac: Array, accel: Array,
                    d_accel: Array) -> tuple[Array, Array]:
    """An explicit-Euler step x_next (12,), jac (12, 12) = d x_next / d x with its
    kinematic rows replaced by the mean-rate ones of the module docstring, and their
    Jacobian by the chain rule through omega_{k+1}, Theta_{k+1} and v_{k+1}: accel = a_b
    (3,) [m/s^2] at x, d_accel = d a_b / d omega (3, 3); dt [s]. Returns new arrays."""
    half = 0.5 * dt
    nxt = x_next.copy()
    out = jac.copy()
    rates = 0.5 * (x[9:12] + x_next[9:12])
    d_rates = 0.5 * jac[9:12]
    d_rates[:, 9:12] += 0.5 * np.eye(3)
    sf, cf = math.sin(float(x[6])), math.cos(float(x[6]))
    st, ct = math.sin(float(x[7])), math.cos(float(x[7]))
    theta_dot, d_theta, e_inv = euler_rate_kinematics(sf, cf, st, ct, *(float(w) for w in rates))
    nxt[6:9] = x[6:9] + dt * theta_dot
    out[6:9] = dt * (e_inv @ d_rates)
    out[6:9, 6:9] += np.eye(3) + dt * d_theta
    rot0, d_rot0 = rotation_and_derivatives(x[6:9])
    rot1, d_rot1 = rotation_and_derivatives(nxt[6:9])
    nxt[3:6] += half * ((rot1 - rot0) @ accel)
    turn1 = np.einsum("ijk,j->ik", d_rot1, accel)   # d (R a) / d Theta at Theta_{k+1}
    turn0 = np.einsum("ijk,j->ik", d_rot0, accel)
    out[3:6] += half * (turn1 @ out[6:9])
    out[3:6, 6:9] -= half * turn0
    out[3:6, 9:12] += half * ((rot1 - rot0) @ d_accel)
    nxt[0:3] = x[0:3] + half * (x[3:6] + nxt[3:6])
    out[0:3] = half * out[3:6]
    out[0:3, 0:3] += np.eye(3)
    out[0:3, 3:6] += half * np.eye(3)
    return nxt, out


def kinematic_noise(q: Array, dt: float, e_inv: Array) -> Array:
    """Q (12, 12) with the kinematic rows' share of the noise of the rows that drive them:
    noise that accumulates as white noise over [t_k, t_k+1] in the velocity (the rates)
    moves the position (the Euler angles, through E^{-1}(Theta_k) = e_inv (3, 3)) by its
    integral, so, for the position and then the Euler block r driven by block s with map A,

        Cov(r, r) += (dt^2 / 3) A Q_ss A^T,  Cov(r, j) = (dt / 2) A Q_sj  (j outside r)

    dt [s]. Returns a new array."""
    out = q.copy()
    for rows, driver, gain in ((slice(0, 3), slice(3, 6), np.eye(3)),
                               (slice(6, 9), slice(9, 12), np.asarray(e_inv, dtype=float))):
        share = 0.5 * dt * (gain @ out[driver])            # (3, 12)
        own = out[rows, rows] + (dt * dt / 3.0) * (gain @ out[driver, driver] @ gain.T)
        out[rows] = share
        out[:, rows] = share.T
        out[rows, rows] = own
    return out
