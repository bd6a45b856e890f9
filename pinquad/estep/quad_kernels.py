"""Compiled transition, process covariance and F P product of
:class:`~pinquad.models.ssm.QuadSSM` and of its force-free warm-up
:class:`~pinquad.models.ssm.KinematicSSM` (numba; state x (12,) = [p, v, Theta, omega]
[m, m/s, rad, rad/s], world position and velocity, Euler roll-pitch-yaw, body rates).

QuadSSM (``pinquad.vehicle.model.state_derivative_and_jacobian``), explicit Euler:

    p' = v,  v' = R e3 F / m - g e3,  Theta' = E^{-1}(Theta) omega,
    omega' = I^{-1} (M - omega x I omega);  x_{k+1} = x_k + dt f,  F_k = I + dt df/dx
    Q = diag(fixed_q)  or  blockdiag(q_pos I3, dt (R/m) diag(S_f) (R/m)^T,
                                     q_euler I3, dt I^{-1} diag(S_tau) I^{-1})

KinematicSSM: p' = v, v' = 0, Theta' = E^{-1} omega, omega' = 0, Q = diag(fixed_q).

On a continuous flight (``KernelDescription.continuous``) ``continuous_rows`` and
``kinematic_noise`` then move the kinematic rows by their mean rates over the interval, as
``pinquad.models.continuous``'s ``continuous_step`` and ``kinematic_noise`` do, and
``f_times_dense_rows`` gives their product rows (which reach every column).

The kernels take the few constants they use (``passes.forward_into`` unpacks them from the
model's :class:`~pinquad.models.kernel.KernelDescription`) and write into given arrays:
x_next (12,), jac (12, 12), q (12, 12).
"""

from __future__ import annotations

import math

from numba import njit

from pinquad.core.kernels import euler_rate_kinematics, rotation, rotation_derivatives
from pinquad.estep.linalg import fill
from pinquad.models.kernel import STATE_DIM as _N


@njit(cache=True)
def transition_quad(x, u, dt, mass, inertia, inertia_inv, gravity, x_next, jac):
    """x_next = x + dt f(x, u), jac = I + dt df/dx, f as in
    pinquad.vehicle.model.state_derivative_and_jacobian (u (4,) = [F, M] [N, N m];
    dt [s], mass [kg], inertia and its inverse (3, 3), gravity [m/s^2])."""
    phi, theta, psi = x[6], x[7], x[8]
    wx, wy, wz = x[9], x[10], x[11]
    sf, cf = math.sin(phi), math.cos(phi)
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    f_over_m = u[0] / mass
    fill(jac, 0.0)
    f = x_next  # holds f until the last loop turns it into x + dt f
    f[0] = x[3]
    f[1] = x[4]
    f[2] = x[5]
    jac[0, 3] = 1.0
    jac[1, 4] = 1.0
    jac[2, 5] = 1.0

    f[3] = f_over_m * (cf * st * cp + sf * sp)
    f[4] = f_over_m * (cf * st * sp - sf * cp)
    f[5] = f_over_m * (cf * ct) - gravity
    jac[3, 6] = f_over_m * (-sf * st * cp + cf * sp)
    jac[3, 7] = f_over_m * (cf * ct * cp)
    jac[3, 8] = f_over_m * (-cf * st * sp + sf * cp)
    jac[4, 6] = f_over_m * (-sf * st * sp - cf * cp)
    jac[4, 7] = f_over_m * (cf * ct * sp)
    jac[4, 8] = f_over_m * (cf * st * cp + sf * sp)
    jac[5, 6] = f_over_m * (-sf * ct)
    jac[5, 7] = f_over_m * (-cf * st)

    euler_rate_kinematics(sf, cf, st, ct, wx, wy, wz, 1.0, f[6:9], jac[6:9, 6:9], jac[6:9, 9:12])

    iw0 = inertia[0, 0] * wx + inertia[0, 1] * wy + inertia[0, 2] * wz
    iw1 = inertia[1, 0] * wx + inertia[1, 1] * wy + inertia[1, 2] * wz
    iw2 = inertia[2, 0] * wx + inertia[2, 1] * wy + inertia[2, 2] * wz
    r0 = u[1] - (wy * iw2 - wz * iw1)
    r1 = u[2] - (wz * iw0 - wx * iw2)
    r2 = u[3] - (wx * iw1 - wy * iw0)
    for r in range(3):
        f[9 + r] = inertia_inv[r, 0] * r0 + inertia_inv[r, 1] * r1 + inertia_inv[r, 2] * r2
    # d(omega x I omega)/d omega = [omega]x I - [I omega]x, row by row
    for c in range(3):
        d0 = -wz * inertia[1, c] + wy * inertia[2, c]
        d1 = wz * inertia[0, c] - wx * inertia[2, c]
        d2 = -wy * inertia[0, c] + wx * inertia[1, c]
        if c == 0:
            d1 -= iw2
            d2 += iw1
        elif c == 1:
            d0 += iw2
            d2 -= iw0
        else:
            d0 -= iw1
            d1 += iw0
        for r in range(3):
            jac[9 + r, 9 + c] = -(inertia_inv[r, 0] * d0 + inertia_inv[r, 1] * d1
                                  + inertia_inv[r, 2] * d2)
    for r in range(_N):
        x_next[r] = x[r] + dt * f[r]
        for c in range(_N):
            jac[r, c] = dt * jac[r, c]
        jac[r, r] += 1.0


@njit(cache=True)
def transition_kinematic(x, dt, x_next, jac):
    """KinematicSSM.transition (the force-free warm-up model: p' = v, v' = 0,
    Theta' = E^{-1} omega, omega' = 0), the Euler rows from the compiled twin of the
    ``conventions.euler_rate_kinematics`` that pinquad.models.ssm calls, so the two agree
    to the last bit (dt [s])."""
    phi, theta = x[6], x[7]
    fill(jac, 0.0)
    # the Euler rows' increments straight into place, then the state and identity added
    euler_rate_kinematics(math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta),
                          x[9], x[10], x[11], dt, x_next[6:9], jac[6:9, 6:9], jac[6:9, 9:12])
    for r in range(3):
        x_next[r] = x[r] + dt * x[3 + r]
        x_next[3 + r] = x[3 + r]
        x_next[6 + r] = x[6 + r] + x_next[6 + r]
        x_next[9 + r] = x[9 + r]
    for r in range(_N):
        jac[r, r] += 1.0
    jac[0, 3] = dt
    jac[1, 4] = dt
    jac[2, 5] = dt


@njit(cache=True)
def process_cov_start(use_fixed, fixed_q, q_kin, q):
    """q = diag(fixed_q (12,)) (returns True: Q is complete), or zero but for the
    position and Euler rows' kinematic variances q_kin (6,) (returns False: the dynamic
    blocks follow)."""
    fill(q, 0.0)
    if use_fixed:
        for i in range(_N):
            q[i, i] = fixed_q[i]
        return True
    for i in range(3):
        q[i, i] = q_kin[i]
        q[6 + i, 6 + i] = q_kin[3 + i]
    return False


@njit(cache=True)
def process_cov_quad(x, dt, mass, use_fixed, fixed_q, q_kin, s_f, q_tau, q, g):
    """Q (12, 12) of QuadSSM's flight process covariance at x (no reset term): fixed, or
    structured from q_kin (6,), S_f = s_f (3,) and q_tau (3, 3) (module docstring); g
    (3, 3): scratch (the caller's, so that a step allocates nothing)."""
    if process_cov_start(use_fixed, fixed_q, q_kin, q):
        return
    rotation(x, g)
    for r in range(3):
        for c in range(3):
            g[r, c] = g[r, c] / mass
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for j in range(3):
                acc += (g[r, j] * s_f[j]) * g[c, j]
            q[3 + r, 3 + c] = dt * acc
            q[9 + r, 9 + c] = q_tau[r, c]


@njit(cache=True)
def f_times_quad(f, p, out):
    """out = F p for a transition Jacobian F (12 x 12) with the block pattern of
    ``transition_quad`` / ``transition_kinematic`` (rows 0-2: columns r, r+3; rows 3-5: r,
    6-8; rows 6-8: 6-11; rows 9-11: 9-11; every other entry is an exact zero, so leaving
    it out of the sums changes nothing)."""
    for r in range(3):
        f0 = f[r, r]
        f1 = f[r, r + 3]
        for c in range(_N):
            out[r, c] = f0 * p[r, c] + f1 * p[r + 3, c]
    for r in range(3, 6):
        f0 = f[r, r]
        f6, f7, f8 = f[r, 6], f[r, 7], f[r, 8]
        for c in range(_N):
            out[r, c] = f0 * p[r, c] + f6 * p[6, c] + f7 * p[7, c] + f8 * p[8, c]
    for r in range(6, 9):
        f6, f7, f8 = f[r, 6], f[r, 7], f[r, 8]
        f9, f10, f11 = f[r, 9], f[r, 10], f[r, 11]
        for c in range(_N):
            out[r, c] = (f6 * p[6, c] + f7 * p[7, c] + f8 * p[8, c] + f9 * p[9, c]
                         + f10 * p[10, c] + f11 * p[11, c])
    for r in range(9, 12):
        f9, f10, f11 = f[r, 9], f[r, 10], f[r, 11]
        for c in range(_N):
            out[r, c] = f9 * p[9, c] + f10 * p[10, c] + f11 * p[11, c]


@njit(cache=True)
def continuous_rows(x, dt, accel, d_accel, x_next, jac, s33, d_rot, d_rates):
    """continuous.continuous_step in place: the kinematic rows of an explicit-Euler step
    x_next (12,), jac (12, 12) moved by their mean rates over the interval (the attitude by
    the mean body rate, the thrust acceleration accel = a_b (3,) [m/s^2] (d_accel = d a_b /
    d omega (3, 3)) by the mean of R_k and R_{k+1}, the position by the mean velocity;
    dt [s]). s33 (6, 3, 3), d_rot (2, 3, 3, 3), d_rates (3, 12): scratch (the caller's, so
    that a step allocates nothing)."""
    half = 0.5 * dt
    e_inv, d_theta, rot0, rot1, turn0, turn1 = s33[0], s33[1], s33[2], s33[3], s33[4], s33[5]
    for r in range(3):
        for c in range(_N):
            d_rates[r, c] = 0.5 * jac[9 + r, c]
        d_rates[r, 9 + r] += 0.5
    wx = 0.5 * (x[9] + x_next[9])
    wy = 0.5 * (x[10] + x_next[10])
    wz = 0.5 * (x[11] + x_next[11])
    sf, cf = math.sin(x[6]), math.cos(x[6])
    st, ct = math.sin(x[7]), math.cos(x[7])
    # x_next[6:9] first holds the mean-rate Euler rates, then the step they make
    euler_rate_kinematics(sf, cf, st, ct, wx, wy, wz, 1.0, x_next[6:9], d_theta, e_inv)
    for r in range(3):
        x_next[6 + r] = x[6 + r] + dt * x_next[6 + r]
    for r in range(3):
        for c in range(_N):
            acc = 0.0
            for j in range(3):
                acc += e_inv[r, j] * d_rates[j, c]
            jac[6 + r, c] = dt * acc
        for c in range(3):
            jac[6 + r, 6 + c] += dt * d_theta[r, c]
        jac[6 + r, 6 + r] += 1.0
    rotation_derivatives(x[6], x[7], x[8], rot0, d_rot[0])
    rotation_derivatives(x_next[6], x_next[7], x_next[8], rot1, d_rot[1])
    for r in range(3):
        acc = 0.0
        for j in range(3):
            acc += (rot1[r, j] - rot0[r, j]) * accel[j]
        x_next[3 + r] += half * acc
        for k in range(3):
            t0 = 0.0
            t1 = 0.0
            for j in range(3):
                t0 += d_rot[0, r, j, k] * accel[j]
                t1 += d_rot[1, r, j, k] * accel[j]
            turn0[r, k] = t0
            turn1[r, k] = t1
    for r in range(3):
        for c in range(_N):
            acc = 0.0
            for k in range(3):
                acc += turn1[r, k] * jac[6 + k, c]
            jac[3 + r, c] += half * acc
        for c in range(3):
            jac[3 + r, 6 + c] -= half * turn0[r, c]
            acc = 0.0
            for j in range(3):
                acc += (rot1[r, j] - rot0[r, j]) * d_accel[j, c]
            jac[3 + r, 9 + c] += half * acc
    for r in range(3):
        x_next[r] = x[r] + half * (x[3 + r] + x_next[3 + r])
        for c in range(_N):
            jac[r, c] = half * jac[3 + r, c]
        jac[r, r] += 1.0
        jac[r, 3 + r] += half


@njit(cache=True)
def kinematic_noise(x, dt, q, gain, share, own):
    """continuous.kinematic_noise in place on q (12, 12) at x (12,): the position rows'
    share of the velocity noise, then the Euler rows' share of the rate noise through
    E^{-1}(Theta) (dt [s]); gain (3, 3), share (3, 12), own (3, 3): scratch."""
    fill(gain, 0.0)
    for i in range(3):
        gain[i, i] = 1.0
    _integrated_share(q, 0, 3, gain, dt, share, own)
    # E^{-1} into gain; share's first row and own take the unused rates and their
    # derivative (both are overwritten by _integrated_share before they are read)
    euler_rate_kinematics(math.sin(x[6]), math.cos(x[6]), math.sin(x[7]), math.cos(x[7]),
                          0.0, 0.0, 0.0, 1.0, share[0, 0:3], own, gain)
    _integrated_share(q, 6, 9, gain, dt, share, own)


@njit(cache=True)
def _integrated_share(q, rows, driver, gain, dt, share, own):
    """Rows rows..rows+2 of q (12, 12) driven by rows driver..driver+2 through gain A
    (3, 3): Cov(r, r) += (dt^2 / 3) A Q_ss A^T, Cov(r, j) = (dt / 2) A Q_sj (j outside r)."""
    half = 0.5 * dt
    third = dt * dt / 3.0
    for i in range(3):
        for c in range(_N):
            acc = 0.0
            for j in range(3):
                acc += gain[i, j] * q[driver + j, c]
            share[i, c] = half * acc
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    acc += gain[i, a] * q[driver + a, driver + b] * gain[j, b]
            own[i, j] = q[rows + i, rows + j] + third * acc
    for i in range(3):
        for c in range(_N):
            q[rows + i, c] = share[i, c]
            q[c, rows + i] = share[i, c]
    for i in range(3):
        for j in range(3):
            q[rows + i, rows + j] = own[i, j]


@njit(cache=True)
def f_times_dense_rows(f, p, out, first, last):
    """Rows first..last-1 of out = F p summed over every column of F (after a
    block-pattern product: on a continuous flight the position and velocity rows reach
    every column the rows that drive them reach)."""
    for r in range(first, last):
        for c in range(_N):
            acc = 0.0
            for j in range(_N):
                acc += f[r, j] * p[j, c]
            out[r, c] = acc
