"""The vehicles the generator flies: rigid bodies with a collective thrust along body z
and body torques, and the limits of their actuators."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Vehicle:
    """A quadcopter as a rigid body.

    name: written to the sidecar's ``vehicle`` (``crazyflie21`` is the name pinquad
    knows the Crazyflie by); mass m [kg]; inertia J (3 x 3 rows) [kg m^2] about the
    centre of mass in body axes (full tensor allowed); arm: rotor distance from the
    centre [m] (the floor contact's lever); thrust_max [N]: the collective thrust is
    clipped to [0, thrust_max]; torque_max (3,) [N m]: body torques are clipped to
    +-torque_max; ground_radius r [m]: the rotor-footprint radius of the ground-effect
    law g(z) = (r / (4 max(z, r/2)))^2.
    """

    name: str
    mass: float
    inertia: tuple[tuple[float, float, float], ...]
    arm: float
    thrust_max: float
    torque_max: tuple[float, float, float]
    ground_radius: float

    @property
    def inertia_matrix(self) -> Array:
        """J (3, 3) [kg m^2]."""
        return np.array(self.inertia, dtype=float)

    @property
    def weight(self) -> float:
        """m g [N] with g = 9.81 m/s^2."""
        return self.mass * GRAVITY


GRAVITY = 9.81
"""Gravity [m/s^2], along world -z."""

CRAZYFLIE = Vehicle(
    name="crazyflie21", mass=0.035,
    inertia=((16.6e-6, 0.0, 0.0), (0.0, 16.7e-6, 0.0), (0.0, 0.0, 29.3e-6)),
    arm=0.046, thrust_max=0.6, torque_max=(0.01, 0.01, 0.003), ground_radius=0.046)
"""A Crazyflie 2.x-class vehicle: 35 g, I = diag(16.6, 16.7, 29.3) e-6 kg m^2, 92 mm
motor-to-motor diagonal, about 1.75 m g of thrust."""

QUAD_250 = Vehicle(
    name="quad250", mass=0.5,
    inertia=((2.4e-3, 0.0, 0.0), (0.0, 2.6e-3, 0.0), (0.0, 0.0, 4.5e-3)),
    arm=0.125, thrust_max=12.0, torque_max=(0.5, 0.5, 0.1), ground_radius=0.125)
"""A 0.5 kg, 250 mm (motor-to-motor diagonal) racing-class quadcopter, about 2.4 m g of
thrust."""
