"""Floor contact (the plane z = 0): a penalty model, so the vehicle can start on, land
on or strike the floor. Nothing of it reaches the log (no contact flag).

With the body origin at height z < 0 and world velocity v:

    normal force   N = max(0, -k z - c v_z),   k = m w_c^2,  c = 2 zeta m w_c
    friction       f_t = -mu N v_t / sqrt(|v_t|^2 + v_eps^2)   (regularised Coulomb)
    levelling      tau = N L R^T (b3 x e3) - (N / m g) d J omega

w_c [rad/s] the contact's natural frequency, zeta its damping ratio, mu the friction
coefficient, L the vehicle's arm [m] (the feet's lever: weight on a tilted vehicle turns
it level), d [1/s] the rate damping of the feet on the floor, b3 = R e3 the thrust axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flightgen.vehicle import GRAVITY

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Floor:
    """Floor contact constants: natural_frequency w_c [rad/s], damping ratio zeta [-],
    friction mu [-], slip_speed v_eps [m/s], rate_damping d [1/s]."""

    natural_frequency: float = 200.0
    damping_ratio: float = 0.7
    friction: float = 0.5
    slip_speed: float = 0.01
    rate_damping: float = 20.0


def floor_wrench(p: Array, v: Array, rot: Array, omega: Array, mass: float,
                 inertia: Array, arm: float, floor: Floor) -> tuple[Array, Array]:
    """(world force [N] (3,), body torque [N m] (3,)) of the floor on the vehicle; zeros
    above the floor."""
    if p[2] >= 0.0:
        return np.zeros(3), np.zeros(3)
    wc = floor.natural_frequency
    normal = max(0.0, -mass * wc * wc * p[2] - 2.0 * floor.damping_ratio * mass * wc * v[2])
    if normal == 0.0:
        return np.zeros(3), np.zeros(3)
    vt = np.array([v[0], v[1], 0.0])
    scale = floor.friction * normal / np.sqrt(vt @ vt + floor.slip_speed**2)
    force = np.array([-scale * vt[0], -scale * vt[1], normal])
    b3 = rot[:, 2]
    level = np.array([b3[1], -b3[0], 0.0])  # b3 x e3
    torque = normal * arm * (rot.T @ level) - (normal / (mass * GRAVITY)) \
        * floor.rate_damping * (inertia @ omega)
    return force, torque
