"""Typed, frozen parameter sets: vehicles, process noise, sensor noise, scenarios.

The simulated noise levels below are chosen once and frozen (see README, "Noise
levels"): every accuracy claim of the project is made at these levels.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import GRAVITY
from pinquad.core.vehicle_file import VehicleSpec, load_vehicle

Array = NDArray[np.float64]


@dataclass(frozen=True)
class VehicleRange:
    """What the vehicle can physically be: mass [kg] (lo, hi) and the inertia diagonal
    [kg m^2] lo (3,), hi (3,); source: where the nominal values came from, in words. The
    verdict judges estimates against it, and EM searches inside it."""

    mass: tuple[float, float]
    inertia_lo: Array
    inertia_hi: Array
    source: str

    def clip_mass(self, mass: float) -> float:
        """mass [kg] projected onto [lo, hi]."""
        return float(min(max(mass, self.mass[0]), self.mass[1]))

    def clip_inertia(self, inertia_diag: Array) -> Array:
        """inertia diagonal (3,) [kg m^2] projected onto [lo, hi]."""
        return np.clip(np.asarray(inertia_diag, dtype=float), self.inertia_lo, self.inertia_hi)


@dataclass(frozen=True)
class Vehicle:
    """Rigid-body parameters of a quadcopter.

    name: the vehicle's name (URDF stem in ``pinquad/data`` for ``paper`` and ``crazyflie21``).
    mass: total mass m [kg].
    inertia: (3, 3) rotational inertia about the centre of mass, body axes [kg m^2].
    arm: centre to motor axis [m].
    com: (3,) centre of mass in the body (thrust) frame [m].
    gravity: [m/s^2].
    ground_radius: effective radius of the ground-effect law [m], or None: the arm (the
    rotor footprint; ``VehicleSpec.ground_effect_radius``).
    """

    name: str
    mass: float
    inertia: Array
    arm: float
    com: Array = field(default_factory=lambda: np.zeros(3))
    gravity: float = GRAVITY
    ground_radius: float | None = None

    @property
    def ground_effect_radius(self) -> float:
        """r [m] of the ground-effect law for this vehicle (``ground_radius`` or the arm)."""
        return self.arm if self.ground_radius is None else self.ground_radius

    @property
    def inertia_diag(self) -> Array:
        """(3,) Ixx, Iyy, Izz [kg m^2]."""
        return np.diag(self.inertia).copy()

    def with_mass_inertia(self, mass: float, inertia: Array) -> Vehicle:
        """Copy with another mass [kg] and (3, 3) inertia [kg m^2]."""
        return replace(self, mass=float(mass), inertia=np.array(inertia, dtype=float))


def vehicle_from_spec(spec: VehicleSpec) -> Vehicle:
    """The rigid body of a vehicle file (``core.vehicle_file``): name, mass, inertia, arm
    and the ground-effect radius."""
    return Vehicle(name=spec.name, mass=spec.mass, inertia=np.array(spec.inertia, dtype=float),
                   arm=spec.arm, ground_radius=spec.ground_effect_radius)


PAPER_VEHICLE = vehicle_from_spec(load_vehicle("paper"))
"""The paper's quadcopter (Section "Parameters for the quadcopter system"), read from the
shipped ``pinquad/data/paper.toml``."""

CRAZYFLIE21 = vehicle_from_spec(load_vehicle("crazyflie21"))
"""Crazyflie 2.x (``pinquad/data/crazyflie21.toml``): inertia from Foerster's
bifilar-pendulum measurement, the mass on a scale."""

VEHICLES = {"paper": PAPER_VEHICLE, "crazyflie21": CRAZYFLIE21}

PAPER_INITIAL_MASS = load_vehicle("paper").guess_mass
"""The paper's initial mass guess m0 [kg] (``paper.toml`` [guess])."""
PAPER_INITIAL_INERTIA = np.array(load_vehicle("paper").guess_inertia, dtype=float)
"""The paper's initial inertia guess I0 [kg m^2] (``paper.toml`` [guess])."""


@dataclass(frozen=True)
class ProcessNoise:
    """White-noise intensities on the applied wrench (the paper's SDE noise n).

    thrust: standard deviation of the thrust noise averaged over one step of length
        ``reference_dt`` [N]; torque: (3,) the same for the body torques [N m].
    The continuous-time intensity is sigma^2 * reference_dt, so a step of length dt
    sees a wrench noise of standard deviation sigma * sqrt(reference_dt / dt).
    """

    thrust: float
    torque: Array
    reference_dt: float = 0.01

    def wrench_intensity(self) -> Array:
        """(6,) spectral densities of body force (x, y, z) and torque [N^2 s, N^2 m^2 s].

        Only the thrust axis (body z) carries force noise, as in the paper's SDE.
        """
        s = np.zeros(6)
        s[2] = self.thrust**2 * self.reference_dt
        s[3:] = np.asarray(self.torque, dtype=float) ** 2 * self.reference_dt
        return s

    def scaled(self, factor_force: float, factor_torque: float) -> ProcessNoise:
        """Copy with force and torque noise multiplied by the given factors."""
        return replace(
            self, thrust=self.thrust * factor_force, torque=np.asarray(self.torque) * factor_torque
        )


PAPER_PROCESS_NOISE = ProcessNoise(thrust=0.02, torque=np.full(3, 2.0e-4))
"""About 1 % of hover thrust (1.77 N) and 1 % of full control torque, per 10 ms step."""


def process_noise_for(vehicle: Vehicle) -> ProcessNoise:
    """The frozen process-noise level scaled to a vehicle by weight and inertia."""
    ref = PAPER_VEHICLE
    return PAPER_PROCESS_NOISE.scaled(
        vehicle.mass / ref.mass, float(np.mean(vehicle.inertia_diag / ref.inertia_diag))
    )


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of each measured quantity (white, Gaussian).

    position [m] (motion capture), velocity [m/s], euler [rad], gyro [rad/s],
    accel [m/s^2] (accelerometer specific force).
    """

    position: float = 0.005
    velocity: float = 0.02
    euler: float = 0.01
    gyro: float = 0.015
    accel: float = 0.08


FROZEN_SENSOR_NOISE = SensorNoise()


@dataclass(frozen=True)
class Scenario:
    """A flight: start point and waypoints [m, world], and the timing.

    dt: simulation, control and logging step [s]; hover_time: time spent settling on
    each waypoint before heading to the next [s]; cruise_speed: nominal speed [m/s].
    """

    start: Array
    waypoints: Array
    dt: float = 0.01
    cruise_speed: float = 1.0
    hover_time: float = 1.5
    yaw: float = 0.0
    scale: float = 1.0

    def scaled(self, factor: float) -> Scenario:
        """The same scenario with all positions (and speeds) scaled by ``factor``."""
        return replace(
            self,
            start=np.asarray(self.start) * factor,
            waypoints=np.asarray(self.waypoints) * factor,
            cruise_speed=self.cruise_speed * factor,
            scale=self.scale * factor,
        )


PAPER_SCENARIO = Scenario(
    start=np.array([0.5, 1.0, 0.0]),
    waypoints=np.array([[4, 3, 3], [3, 5, 4], [6, 4, 5], [4, 3, 4], [2, 1, 5]], dtype=float),
)
"""Start [0.5, 1, 0] and the paper's five waypoints."""
