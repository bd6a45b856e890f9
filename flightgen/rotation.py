"""Quaternion and rotation helpers of the generator (its own: nothing shared with pinquad).

Quaternions are (w, x, y, z), unit, body to world: a body vector b is the world vector
R(q) b. Euler angles follow the log format's convention (docs/architecture.md, Conventions): roll phi, pitch
theta, yaw psi of R = Rz(psi) Ry(theta) Rx(phi), so that

    phi = atan2(R[2,1], R[2,2]),  theta = asin(-R[2,0]),  psi = atan2(R[1,0], R[0,0]).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def hat(v: Array) -> Array:
    """[v]x (3, 3): hat(v) @ w = v x w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def vee(m: Array) -> Array:
    """Inverse of :func:`hat` on a skew-symmetric (3, 3) matrix: (3,)."""
    return np.array([m[2, 1], m[0, 2], m[1, 0]])


def quat_to_rot(q: Array) -> Array:
    """Rotation matrix (3, 3) of the unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def quats_to_rots(q: Array) -> Array:
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) (normalised first)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - z * w)
    r[:, 0, 2] = 2 * (x * z + y * w)
    r[:, 1, 0] = 2 * (x * y + z * w)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - x * w)
    r[:, 2, 0] = 2 * (x * z - y * w)
    r[:, 2, 1] = 2 * (y * z + x * w)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def quat_rate(q: Array, omega: Array) -> Array:
    """dq/dt = 0.5 q (x) (0, omega) for the body angular velocity omega [rad/s]: (4,)."""
    w, x, y, z = q
    p, r_, s = omega
    return 0.5 * np.array([
        -x * p - y * r_ - z * s,
        w * p + y * s - z * r_,
        w * r_ + z * p - x * s,
        w * s + x * r_ - y * p,
    ])


def quat_mul(a: Array, b: Array) -> Array:
    """Hamilton product a (x) b of (w, x, y, z) quaternions: (4,)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])


def quat_from_axis_angle(v: Array) -> Array:
    """Quaternion of the rotation vector v [rad] (axis * angle): (4,)."""
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.array([1.0, 0.5 * v[0], 0.5 * v[1], 0.5 * v[2]]) / np.sqrt(1 + 0.25 * angle**2)
    s = np.sin(0.5 * angle) / angle
    return np.array([np.cos(0.5 * angle), s * v[0], s * v[1], s * v[2]])


def euler_from_quats(q: Array) -> Array:
    """Roll, pitch, yaw [rad] (N, 3) of quaternions (N, 4), the log's convention."""
    r = quats_to_rots(q)
    roll = np.arctan2(r[:, 2, 1], r[:, 2, 2])
    pitch = np.arcsin(np.clip(-r[:, 2, 0], -1.0, 1.0))
    yaw = np.arctan2(r[:, 1, 0], r[:, 0, 0])
    return np.column_stack([roll, pitch, yaw])


def canonical(q: Array) -> Array:
    """Quaternions (N, 4) with w >= 0 (q and -q are the same rotation)."""
    return np.where(q[:, :1] < 0.0, -q, q)


def cross(a: Array, b: Array) -> Array:
    """a x b of two (3,) vectors (numpy.cross is slow on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def norm3(a: Array) -> float:
    """|a| of a (3,) or (4,) vector."""
    return float(np.sqrt(a @ a))
