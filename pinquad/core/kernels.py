"""Numba kernels shared by the compiled E-step (``pinquad.estep``) and M-step
(``pinquad.mstep.compiled``): angle wrap, R = Rz(psi) Ry(theta) Rx(phi) and its Euler
derivatives, element for element the same arithmetic as ``pinquad.core.conventions``
(which owns the convention; these are its compiled twins)."""

from __future__ import annotations

import math

import numpy as np
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
    sf, cf = math.sin(phi), math.cos(phi)
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
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
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cf, -sf], [0.0, sf, cf]])
    ry = np.array([[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]])
    rz = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    drx = np.array([[0.0, 0.0, 0.0], [0.0, -sf, -cf], [0.0, cf, -sf]])
    dry = np.array([[-st, 0.0, ct], [0.0, 0.0, 0.0], [-ct, 0.0, -st]])
    drz = np.array([[-sp, -cp, 0.0], [cp, -sp, 0.0], [0.0, 0.0, 0.0]])
    zy = rz @ ry
    rot[:, :] = zy @ rx
    d0 = zy @ drx
    d1 = rz @ dry @ rx
    d2 = drz @ ry @ rx
    for r in range(3):
        for c in range(3):
            d_rot[r, c, 0] = d0[r, c]
            d_rot[r, c, 1] = d1[r, c]
            d_rot[r, c, 2] = d2[r, c]
