"""Numba kernels shared by the compiled E-step (``pinquad.estep``) and M-step
(``pinquad.mstep.compiled``): angle wrap, R = Rz(psi) Ry(theta) Rx(phi) and its Euler
derivatives, element for element the same arithmetic as ``pinquad.core.conventions``
(which owns the convention; these are its compiled twins)."""

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
