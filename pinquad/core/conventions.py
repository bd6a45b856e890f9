"""The one place that owns frames, Euler order and quaternion order.

World frame: z up, gravity ``GRAVITY`` [m/s^2] along -z. Body frame: x forward, y left,
z up (thrust axis).

Euler angles ``(roll phi, pitch theta, yaw psi)`` [rad] follow the paper's Euler-rate
matrix ``E^{-1}`` and its flatness extraction (``theta = asin(-R[2,0])``,
``phi = atan2(R[2,1], R[2,2])``, ``psi = atan2(R[1,0], R[0,0])``). Both are those of the
intrinsic z-y-x sequence, whose body-to-world rotation is

    R(phi, theta, psi) = Rz(psi) @ Ry(theta) @ Rx(phi).

The paper prints the transpose of this matrix (world-to-body) under the name R^E_B; we
use the matrix that agrees with its Euler-rate matrix and its flatness equations.

Quaternions: Pinocchio stores ``(x, y, z, w)``; viser and GTSAM take ``(w, x, y, z)``;
log files use ``quat_w, quat_x, quat_y, quat_z``. Convert only through this module.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

GRAVITY = 9.81
"""Standard gravity used throughout [m/s^2]."""

Array = NDArray[np.float64]


def wrap_angle(angle: Array | float) -> Array | float:
    """Wrap angles [rad] to (-pi, pi]."""
    wrapped = np.mod(np.asarray(angle, dtype=float) + math.pi, 2.0 * math.pi) - math.pi
    wrapped = np.where(wrapped == -math.pi, math.pi, wrapped)
    if np.ndim(wrapped) == 0:
        return float(wrapped)
    return wrapped


def rotation_from_euler(euler: Array) -> Array:
    """Body-to-world rotation ``R = Rz(psi) Ry(theta) Rx(phi)``.

    euler: (..., 3) roll, pitch, yaw [rad]. Returns (..., 3, 3).
    """
    euler = np.asarray(euler, dtype=float)
    phi, theta, psi = euler[..., 0], euler[..., 1], euler[..., 2]
    cf, sf = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cp, sp = np.cos(psi), np.sin(psi)
    rot = np.empty(euler.shape[:-1] + (3, 3))
    rot[..., 0, 0] = ct * cp
    rot[..., 0, 1] = sf * st * cp - cf * sp
    rot[..., 0, 2] = cf * st * cp + sf * sp
    rot[..., 1, 0] = ct * sp
    rot[..., 1, 1] = sf * st * sp + cf * cp
    rot[..., 1, 2] = cf * st * sp - sf * cp
    rot[..., 2, 0] = -st
    rot[..., 2, 1] = sf * ct
    rot[..., 2, 2] = cf * ct
    return rot


def rotation_and_derivatives(euler: Array) -> tuple[Array, Array]:
    """R = Rz(psi) Ry(theta) Rx(phi) (..., 3, 3) and dR/d(phi, theta, psi) (..., 3, 3, 3),
    last axis the angle, for Euler angles euler (..., 3) [rad]:

        dR/dphi = Rz Ry dRx,  dR/dtheta = Rz dRy Rx,  dR/dpsi = dRz Ry Rx.
    """
    e = np.asarray(euler, dtype=float)
    sf, cf = np.sin(e[..., 0]), np.cos(e[..., 0])
    st, ct = np.sin(e[..., 1]), np.cos(e[..., 1])
    sp, cp = np.sin(e[..., 2]), np.cos(e[..., 2])
    zero, one = np.zeros_like(sf), np.ones_like(sf)

    def mat(*rows: tuple) -> Array:
        return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)

    rx = mat((one, zero, zero), (zero, cf, -sf), (zero, sf, cf))
    ry = mat((ct, zero, st), (zero, one, zero), (-st, zero, ct))
    rz = mat((cp, -sp, zero), (sp, cp, zero), (zero, zero, one))
    drx = mat((zero, zero, zero), (zero, -sf, -cf), (zero, cf, -sf))
    dry = mat((-st, zero, ct), (zero, zero, zero), (-ct, zero, -st))
    drz = mat((-sp, -cp, zero), (cp, -sp, zero), (zero, zero, zero))
    d = np.stack([rz @ ry @ drx, rz @ dry @ rx, drz @ ry @ rx], axis=-1)
    return rz @ ry @ rx, d


def euler_from_rotation(rot: Array) -> Array:
    """Inverse of :func:`rotation_from_euler` (paper's flatness extraction).

    rot: (..., 3, 3) body-to-world. Returns (..., 3) roll, pitch, yaw [rad];
    pitch in [-pi/2, pi/2].
    """
    rot = np.asarray(rot, dtype=float)
    theta = np.arcsin(np.clip(-rot[..., 2, 0], -1.0, 1.0))
    phi = np.arctan2(rot[..., 2, 1], rot[..., 2, 2])
    psi = np.arctan2(rot[..., 1, 0], rot[..., 0, 0])
    return np.stack([phi, theta, psi], axis=-1)


def euler_rate_matrix_inv(euler: Array) -> Array:
    """The paper's ``E^{-1}(Theta)``: Euler rates = E^{-1} @ body rates.

    euler: (..., 3) [rad]. Returns (..., 3, 3) [1].
    """
    euler = np.asarray(euler, dtype=float)
    phi, theta = euler[..., 0], euler[..., 1]
    sf, cf = np.sin(phi), np.cos(phi)
    tt, ct = np.tan(theta), np.cos(theta)
    out = np.zeros(euler.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1.0
    out[..., 0, 1] = sf * tt
    out[..., 0, 2] = cf * tt
    out[..., 1, 1] = cf
    out[..., 1, 2] = -sf
    out[..., 2, 1] = sf / ct
    out[..., 2, 2] = cf / ct
    return out


def euler_rate_kinematics(sf: float, cf: float, st: float, ct: float, wx: float, wy: float,
                          wz: float, scale: float = 1.0) -> tuple[Array, Array, Array]:
    """Euler-angle kinematics Theta' = E^{-1}(Theta) omega and its two Jacobians, each
    times ``scale``, from the sines and cosines of roll and pitch (sf, cf, st, ct) and the
    body rates omega = (wx, wy, wz) [rad/s]. With t = tan(theta), a = sf wy + cf wz,
    b = cf wy - sf wz:

        Theta'         = [wx + t a,  b,  a / ct]                          [rad/s]
        dTheta'/dTheta = [[t b, a / ct^2, 0], [-a, 0, 0], [b / ct, a st / ct^2, 0]]
        dTheta'/domega = E^{-1} = [[1, sf t, cf t], [0, cf, -sf], [0, sf / ct, cf / ct]]

    Returns (scale Theta' (3,), scale dTheta'/dTheta (3, 3), scale E^{-1} (3, 3)).
    scale = 1 gives the rates [rad/s]; scale = dt [s] one explicit-Euler step's increment
    [rad] (the scale multiplies first, so both uses keep the same rounding as the models
    that wrote them out). ``pinquad.core.kernels.euler_rate_kinematics`` is its compiled
    twin, the same arithmetic in the same order (equal to the last bit);
    :func:`euler_rate_matrix_inv` is E^{-1} for arrays of angles (t from tan).
    """
    tt = st / ct
    a = sf * wy + cf * wz
    b = cf * wy - sf * wz
    rates = np.array([scale * (wx + tt * a), scale * b, scale * a / ct])
    d_euler = np.array([[scale * tt * b, scale * a / (ct * ct), 0.0],
                        [scale * (-sf * wy - cf * wz), 0.0, 0.0],
                        [scale * b / ct, scale * a * st / (ct * ct), 0.0]])
    e_inv = np.array([[scale, scale * sf * tt, scale * cf * tt],
                      [0.0, scale * cf, -scale * sf],
                      [0.0, scale * sf / ct, scale * cf / ct]])
    return rates, d_euler, e_inv


def euler_rate_matrix(euler: Array) -> Array:
    """The paper's ``E(Theta)``: body rates = E @ Euler rates. (..., 3) -> (..., 3, 3)."""
    euler = np.asarray(euler, dtype=float)
    phi, theta = euler[..., 0], euler[..., 1]
    sf, cf = np.sin(phi), np.cos(phi)
    st, ct = np.sin(theta), np.cos(theta)
    out = np.zeros(euler.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1.0
    out[..., 0, 2] = -st
    out[..., 1, 1] = cf
    out[..., 1, 2] = ct * sf
    out[..., 2, 1] = -sf
    out[..., 2, 2] = ct * cf
    return out


def quat_wxyz_from_rotation(rot: Array) -> Array:
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix (..., 3, 3)."""
    rot = np.asarray(rot, dtype=float)
    flat = rot.reshape(-1, 3, 3)
    out = np.empty((flat.shape[0], 4))
    for i, r in enumerate(flat):
        tr = r[0, 0] + r[1, 1] + r[2, 2]
        if tr > 0.0:
            s = 2.0 * math.sqrt(tr + 1.0)
            q = (0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s)
        elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
            s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
            q = ((r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s)
        elif r[1, 1] > r[2, 2]:
            s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
            q = ((r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s)
        else:
            s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
            q = ((r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s)
        qa = np.asarray(q)
        out[i] = qa / np.linalg.norm(qa) * (1.0 if qa[0] >= 0 else -1.0)
    return out.reshape(rot.shape[:-2] + (4,))


def rotation_from_quat_wxyz(quat: Array) -> Array:
    """Rotation matrix (..., 3, 3) of quaternions (..., 4) in (w, x, y, z) order."""
    q = np.asarray(quat, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rot = np.empty(q.shape[:-1] + (3, 3))
    rot[..., 0, 0] = 1 - 2 * (y * y + z * z)
    rot[..., 0, 1] = 2 * (x * y - z * w)
    rot[..., 0, 2] = 2 * (x * z + y * w)
    rot[..., 1, 0] = 2 * (x * y + z * w)
    rot[..., 1, 1] = 1 - 2 * (x * x + z * z)
    rot[..., 1, 2] = 2 * (y * z - x * w)
    rot[..., 2, 0] = 2 * (x * z - y * w)
    rot[..., 2, 1] = 2 * (y * z + x * w)
    rot[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return rot


def euler_from_quat_wxyz(quat: Array) -> Array:
    """Euler angles (..., 3) of quaternions (..., 4) in (w, x, y, z) order."""
    return euler_from_rotation(rotation_from_quat_wxyz(quat))


def quat_wxyz_from_euler(euler: Array) -> Array:
    """Quaternions (..., 4) in (w, x, y, z) order of Euler angles (..., 3)."""
    return quat_wxyz_from_rotation(rotation_from_euler(euler))


def wxyz_to_xyzw(quat: Array) -> Array:
    """Reorder (w, x, y, z) -> Pinocchio's (x, y, z, w)."""
    quat = np.asarray(quat, dtype=float)
    return np.concatenate([quat[..., 1:], quat[..., :1]], axis=-1)


def xyzw_to_wxyz(quat: Array) -> Array:
    """Reorder Pinocchio's (x, y, z, w) -> (w, x, y, z)."""
    quat = np.asarray(quat, dtype=float)
    return np.concatenate([quat[..., 3:], quat[..., :3]], axis=-1)


def skew(vec: Array) -> Array:
    """Cross-product matrix [v]x with [v]x @ w = v x w. (..., 3) -> (..., 3, 3)."""
    v = np.asarray(vec, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


# State layout of the paper's 12-dimensional model.
POS = slice(0, 3)
VEL = slice(3, 6)
EULER = slice(6, 9)
RATE = slice(9, 12)
STATE_DIM = 12
STATE_NAMES = (
    "pos_x", "pos_y", "pos_z", "vel_x", "vel_y", "vel_z",
    "roll", "pitch", "yaw", "gyro_x", "gyro_y", "gyro_z",
)


# PX4 logs: NED world (x north, y east, z down) and FRD body (x forward, y right, z down).
# Both differ from pinquad's frames by the half turn about x, D = diag(1, -1, -1), so
# a vector maps as v = D v_ned (v_b = D v_frd) and the body-to-world rotation as
# R = D R_ned_frd D. Conjugating by a half turn about x keeps the rotation angle and maps
# its axis through D, hence the quaternion rule below.
NED_FRD_FLIP = np.array([1.0, -1.0, -1.0])
"""The diagonal of D = diag(1, -1, -1) [1]: NED -> world, FRD -> body, and back."""


def vector_from_ned_frd(vec: Array) -> Array:
    """A world vector from NED components, or a body vector from FRD components:
    ``D v`` (D = diag(1, -1, -1)). (..., 3) -> (..., 3), units unchanged."""
    return np.asarray(vec, dtype=float) * NED_FRD_FLIP


def quat_wxyz_from_ned_frd(quat: Array) -> Array:
    """pinquad's body-to-world quaternion (w, x, y, z) of a PX4 FRD-body-to-NED-world
    quaternion (w, x, y, z): R = D R_ned_frd D, i.e. (w, x, -y, -z). (..., 4) -> (..., 4)."""
    q = np.asarray(quat, dtype=float)
    return q * np.array([1.0, 1.0, -1.0, -1.0])
