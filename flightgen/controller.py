"""The generator's geometric tracking controller on SE(3) (Lee, Leok, McClamroch 2010,
"Geometric tracking control of a quadrotor UAV on SE(3)"), world z up, run at every
integrator step from the true state.

    e_x = p - p_d,  e_v = v - v_d
    F_d = -k_x e_x - k_v e_v + m g e3 + m a_d            (tilt-limited, F_d,z > 0)
    f   = F_d . R e3                                     thrust [N]
    b3_d = F_d / |F_d|,  b2_d = b3_d x b1_c / |.|,  b1_d = b2_d x b3_d,
    b1_c = (cos psi_d, sin psi_d, 0),  R_d = [b1_d b2_d b3_d]
    Omega_d = (-h . b2_d, h . b1_d, psi_d' e3 . b3_d),  h = m / f (j_d - (b3_d . j_d) b3_d)
    e_R = 0.5 vee(R_d^T R - R^T R_d),  e_W = Omega - R^T R_d Omega_d
    M = -k_R e_R - k_W e_W + Omega x J Omega - J (Omega x R^T R_d Omega_d)

(Omega_d' is taken as zero.) Gains from natural frequencies: k_x = m w_p^2,
k_v = 2 zeta m w_p, k_R = J w_a^2, k_W = 2 zeta J w_a.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flightgen.rotation import cross, norm3, vee
from flightgen.vehicle import GRAVITY, Vehicle

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Gains:
    """position_frequency w_p [rad/s], attitude_frequency w_a [rad/s], damping zeta [-],
    max_tilt [rad] of the commanded thrust direction."""

    position_frequency: float = 4.0
    attitude_frequency: float = 40.0
    damping: float = 0.8
    max_tilt: float = 1.0


class GeometricController:
    """Lee's SE(3) controller for one vehicle (the vehicle's true mass and inertia)."""

    def __init__(self, vehicle: Vehicle, gains: Gains) -> None:
        self.m = vehicle.mass
        self.j = vehicle.inertia_matrix
        wp, wa, z = gains.position_frequency, gains.attitude_frequency, gains.damping
        self.kx = self.m * wp * wp
        self.kv = 2 * z * self.m * wp
        self.kr = self.j * wa * wa
        self.kw = 2 * z * self.j * wa
        self.tan_tilt = float(np.tan(gains.max_tilt))
        self.f_max = vehicle.thrust_max
        self.tau_max = np.asarray(vehicle.torque_max, dtype=float)

    def __call__(self, p: Array, v: Array, rot: Array, omega: Array, ref_pos: Array,
                 yaw: float, yaw_rate: float) -> tuple[float, Array]:
        """(thrust [N], body torque (3,) [N m]) for the state (p, v, R, Omega) and the
        reference ref_pos (5, 3) (position .. snap) with yaw [rad], yaw rate [rad/s]."""
        m = self.m
        fd = -self.kx * (p - ref_pos[0]) - self.kv * (v - ref_pos[1]) + m * ref_pos[2]
        fd[2] += m * GRAVITY
        fd[2] = max(fd[2], 0.2 * m * GRAVITY)
        horiz = float(np.sqrt(fd[0] * fd[0] + fd[1] * fd[1]))
        if horiz > self.tan_tilt * fd[2]:
            fd[:2] *= self.tan_tilt * fd[2] / horiz
        b3 = rot[:, 2]
        f = min(max(float(fd @ b3), 0.0), self.f_max)
        b3d = fd / norm3(fd)
        b1c = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        b2d = cross(b3d, b1c)
        b2d /= norm3(b2d)
        b1d = cross(b2d, b3d)
        rd = np.array([b1d, b2d, b3d]).T
        f_ff = max(float(norm3(fd)), 0.2 * m * GRAVITY)
        jd = ref_pos[3]
        h = (m / f_ff) * (jd - (b3d @ jd) * b3d)
        wd = np.array([-h @ b2d, h @ b1d, yaw_rate * b3d[2]])
        rdr = rd.T @ rot
        er = 0.5 * vee(rdr - rdr.T)
        wd_body = rdr.T @ wd
        ew = omega - wd_body
        jw = self.j @ omega
        tau = -self.kr @ er - self.kw @ ew + cross(omega, jw) - self.j @ cross(omega, wd_body)
        return f, np.minimum(np.maximum(tau, -self.tau_max), self.tau_max)
