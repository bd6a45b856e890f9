"""Numba kernels shared by the compiled E-step (``pinquad.estep``) and M-step
(``pinquad.mstep.compiled``): angle wrap, R = Rz(psi) Ry(theta) Rx(phi) and its Euler
derivatives, the Euler-rate kinematics Theta' = E^{-1}(Theta) omega, element for element
the same arithmetic as ``pinquad.core.conventions`` (which owns the convention; these are
its compiled twins)."""

from __future__ import annotations

import math

from numba import njit

_TWO_PI = 2.0 * math.pi


@njit(cache=True)
def wrap(a):
    # Same arithmetic as conventions.wrap_angle (Python and NumPy float modulo agree).
    w = (a + math.pi) % _TWO_PI - math.pi
    if w == -math.pi:
        return math.pi
    return w


@njit(cache=True)
def rotation(x, rot):
    """R = Rz(psi) Ry(theta) Rx(phi) of the Euler angles x[6:9] into rot (3, 3)."""
    rotation_of_angles(x[6], x[7], x[8], rot)


@njit(cache=True)
def rotation_of_angles(phi, theta, psi, rot):
    """R = Rz(psi) Ry(theta) Rx(phi) (3, 3) into rot, as conventions.rotation_from_euler
    (also the compiled M-step's)."""
    _rotation_of_trig(math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta),
                      math.sin(psi), math.cos(psi), rot)


@njit(cache=True)
def _rotation_of_trig(sf, cf, st, ct, sp, cp, rot):
    """R = Rz(psi) Ry(theta) Rx(phi) (3, 3) into rot from the angles' sines and cosines."""
    rot[0, 0] = ct * cp
    rot[0, 1] = sf * st * cp - cf * sp
    rot[0, 2] = cf * st * cp + sf * sp
    rot[1, 0] = ct * sp
    rot[1, 1] = sf * st * sp + cf * cp
    rot[1, 2] = cf * st * sp - sf * cp
    rot[2, 0] = -st
    rot[2, 1] = sf * ct
    rot[2, 2] = cf * ct


@njit(cache=True)
def rotation_derivatives(phi, theta, psi, rot, d_rot):
    """R = Rz(psi) Ry(theta) Rx(phi) into rot (3, 3) and dR/d(phi, theta, psi) into
    d_rot (3, 3, 3), last axis the angle (``conventions.rotation_and_derivatives``)."""
    sf, cf = math.sin(phi), math.cos(phi)
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    # written out (no temporaries): a 3 x 3 product allocated per call cost the
    # compiled M-step most of its time
    _rotation_of_trig(sf, cf, st, ct, sp, cp, rot)
    d_rot[0, 0, 0] = 0.0
    d_rot[0, 1, 0] = cf * st * cp + sf * sp
    d_rot[0, 2, 0] = -sf * st * cp + cf * sp
    d_rot[1, 0, 0] = 0.0
    d_rot[1, 1, 0] = cf * st * sp - sf * cp
    d_rot[1, 2, 0] = -sf * st * sp - cf * cp
    d_rot[2, 0, 0] = 0.0
    d_rot[2, 1, 0] = cf * ct
    d_rot[2, 2, 0] = -sf * ct
    d_rot[0, 0, 1] = -st * cp
    d_rot[0, 1, 1] = sf * ct * cp
    d_rot[0, 2, 1] = cf * ct * cp
    d_rot[1, 0, 1] = -st * sp
    d_rot[1, 1, 1] = sf * ct * sp
    d_rot[1, 2, 1] = cf * ct * sp
    d_rot[2, 0, 1] = -ct
    d_rot[2, 1, 1] = -sf * st
    d_rot[2, 2, 1] = -cf * st
    d_rot[0, 0, 2] = -ct * sp
    d_rot[0, 1, 2] = -sf * st * sp - cf * cp
    d_rot[0, 2, 2] = -cf * st * sp + sf * cp
    d_rot[1, 0, 2] = ct * cp
    d_rot[1, 1, 2] = sf * st * cp - cf * sp
    d_rot[1, 2, 2] = cf * st * cp + sf * sp
    d_rot[2, 0, 2] = 0.0
    d_rot[2, 1, 2] = 0.0
    d_rot[2, 2, 2] = 0.0


@njit(cache=True)
def euler_rate_kinematics(sf, cf, st, ct, wx, wy, wz, scale, rates, d_euler, e_inv):
    """scale Theta' (3,) into rates, scale dTheta'/dTheta (3, 3) into d_euler and
    scale E^{-1}(Theta) (3, 3) into e_inv (every entry written), from the sines and cosines
    of roll and pitch and the body rates (wx, wy, wz) [rad/s]; Theta' = E^{-1} omega.
    The compiled twin of ``conventions.euler_rate_kinematics`` (equations there), the
    same arithmetic in the same order. The outputs may be views into a caller's state and
    Jacobian (rows 6-8), so that a step allocates nothing."""
    tt = st / ct
    a = sf * wy + cf * wz
    b = cf * wy - sf * wz
    rates[0] = scale * (wx + tt * a)
    rates[1] = scale * b
    rates[2] = scale * a / ct
    d_euler[0, 0] = scale * tt * b
    d_euler[0, 1] = scale * a / (ct * ct)
    d_euler[0, 2] = 0.0
    d_euler[1, 0] = scale * (-sf * wy - cf * wz)
    d_euler[1, 1] = 0.0
    d_euler[1, 2] = 0.0
    d_euler[2, 0] = scale * b / ct
    d_euler[2, 1] = scale * a * st / (ct * ct)
    d_euler[2, 2] = 0.0
    e_inv[0, 0] = scale
    e_inv[0, 1] = scale * sf * tt
    e_inv[0, 2] = scale * cf * tt
    e_inv[1, 0] = 0.0
    e_inv[1, 1] = scale * cf
    e_inv[1, 2] = -scale * sf
    e_inv[2, 0] = 0.0
    e_inv[2, 1] = scale * sf / ct
    e_inv[2, 2] = scale * cf / ct
