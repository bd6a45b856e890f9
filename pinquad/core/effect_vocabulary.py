"""The effect vocabulary shared by the simulator and the estimator (DESIGN 4.4).

The simulator injects effects (``pinquad.sim.effects``) and discovery names and fits them
(``pinquad.discovery.library``); both speak through this module, so neither imports the
other: the names, each effect's coefficient names (the estimator's order, which scores
the injected coefficients of a simulated flight), the Crazyflie 2.x constants both sides
use, and the ground-effect law both evaluate.

Forms (body frame: x forward, y left, z up; v_b = R^T v the body velocity [m/s]; F the
collective thrust [N]; all wrenches at the body origin):

====================  ===========================================  ==========================
name                  extra body wrench / effect                   coefficients (units)
====================  ===========================================  ==========================
``drag``              f = -diag(D) v_b                             D (3,) [N s/m]
``ground_effect``     f_z = k_ge F (r / (4 max(z, r/2)))^2         k_ge [-], r [m] fixed
``com_offset``        tau = (-c) x (F e3) = F [-c_y, c_x, 0]       c_x, c_y [m] (CoM)
``wind``              f = R^T [w_x, w_y, 0]                        w_x, w_y [N] (world)
``motor_lag``         tau_m du/dt = u_cmd - u  (all 4 channels)    tau_m [s]
``gyro_bias``         gyro = omega + b                             b (3,) [rad/s]
====================  ===========================================  ==========================
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

EFFECT_NAMES = ("drag", "ground_effect", "com_offset", "wind", "motor_lag", "gyro_bias")
"""The discovery vocabulary of DESIGN 4.4."""

COEFFICIENT_NAMES: dict[str, tuple[str, ...]] = {
    "drag": ("D_x", "D_y", "D_z"),
    "ground_effect": ("k_ge",),
    "com_offset": ("c_x", "c_y"),
    "wind": ("w_x", "w_y"),
    "motor_lag": ("tau_m",),
    "gyro_bias": ("b_x", "b_y", "b_z"),
}
"""Effect name -> its coefficients' names, in the order of the estimator's coefficient
vector c and of the simulator factory's first argument: D [N s/m], k_ge [-], c [m],
w [N], tau_m [s], b [rad/s]."""

CRAZYFLIE_DRAG = (0.0062, 0.0062, 0.0070)
"""Linear rotor-drag coefficients of a hovering Crazyflie 2.x [N s/m]: Foerster's k_aero
(-9.18e-7, -9.18e-7, -10.3e-7) N s/m per rad/s times the summed hover rotor speed
(about 4 x 1700 rad/s)."""
CRAZYFLIE_ROTOR_RADIUS = 0.0235
"""Crazyflie 2.x propeller radius [m]."""
GROUND_EFFECT_RADIUS = 0.046
"""Effective radius r [m] of the ground-effect law: the Crazyflie's arm, i.e. the
footprint of the four rotors together (a single rotor's 0.0235 m reaches only ~1 cm)."""


def ground_effect_gain(z: Array | float, radius: float = GROUND_EFFECT_RADIUS) -> Array:
    """g(z) = (r / (4 max(z, r/2)))^2 [-], the relative thrust gain per unit k_ge at the
    height z [m] (first-order Cheeseman-Bennett law T/T_inf = 1 + (r/4z)^2, the height
    clipped at r/2)."""
    zc = np.maximum(np.asarray(z, dtype=float), 0.5 * radius)
    return (radius / (4.0 * zc)) ** 2
