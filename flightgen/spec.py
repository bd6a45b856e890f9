"""What to fly (FlightSpec) and what comes out (Flight)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from flightgen.contact import Floor
from flightgen.controller import Gains
from flightgen.effects import Effects
from flightgen.vehicle import CRAZYFLIE, Vehicle

Array = NDArray[np.float64]

LOG_RATES = (100, 250, 500)
MOCAP_RATE = 100


@dataclass(frozen=True)
class Noise:
    """Process noise on the applied wrench and sensor noise (all white, Gaussian).

    thrust [N], torque (3,) [N m]: standard deviation of the wrench noise averaged over
    ``reference_dt`` = 10 ms; an integrator step dt holds a fresh draw of standard
    deviation sigma sqrt(reference_dt / dt) (continuous intensity sigma^2 reference_dt,
    independent of dt). None: 1 % of m g, and J_ii x 0.2 rad/s^2.
    position [m], velocity [m/s], attitude [rad] (a random rotation vector applied to
    the true attitude): motion capture; gyro [rad/s], accel [m/s^2]: the IMU.
    """

    thrust: float | None = None
    torque: tuple[float, float, float] | None = None
    reference_dt: float = 0.01
    position: float = 0.001
    velocity: float = 0.01
    attitude: float = 0.005
    gyro: float = 0.01
    accel: float = 0.05

    def wrench_sigma(self, vehicle: Vehicle) -> Array:
        """(4,) sigma of thrust [N] and torques [N m] per reference_dt."""
        thrust = 0.01 * vehicle.weight if self.thrust is None else self.thrust
        torque = (0.2 * np.diag(vehicle.inertia_matrix) if self.torque is None
                  else np.asarray(self.torque, dtype=float))
        return np.concatenate([[thrust], torque])


CLEAN = Noise(thrust=0.0, torque=(0.0, 0.0, 0.0), position=0.0, velocity=0.0, attitude=0.0,
              gyro=0.0, accel=0.0)
"""No process or sensor noise at all (integrator and controller tests)."""


@dataclass(frozen=True)
class FlightSpec:
    """One flight to generate.

    duration [s] (20-60 typical); trajectory: ``sines`` or ``minsnap``; aggressive:
    peak reference acceleration 6 m/s^2 instead of 1.5; log_rate [Hz]: 100, 250 or 500;
    dt [s]: integrator and controller step (0.5 or 1 ms; a divisor of 1/log_rate and
    1/100); seed: of the numpy Generator that draws everything; vehicle; effects
    injected in the truth; noise; gains of the controller; hover_height [m];
    start_on_floor / land: take off from / land on the floor; floor_strikes: dips of
    the reference below the floor, evenly spaced; floor: contact constants (None: no
    floor at all, free space).
    """

    duration: float = 30.0
    trajectory: str = "sines"
    aggressive: bool = False
    log_rate: int = 500
    dt: float = 0.0005
    seed: int = 0
    vehicle: Vehicle = CRAZYFLIE
    effects: Effects = field(default_factory=Effects)
    noise: Noise = field(default_factory=Noise)
    gains: Gains = field(default_factory=Gains)
    hover_height: float = 1.0
    start_on_floor: bool = False
    land: bool = False
    floor_strikes: int = 0
    floor: Floor | None = field(default_factory=Floor)

    def __post_init__(self) -> None:
        if self.log_rate not in LOG_RATES:
            raise ValueError(f"log_rate must be one of {LOG_RATES} Hz; got {self.log_rate}")
        for rate in (self.log_rate, MOCAP_RATE):
            ratio = 1.0 / (rate * self.dt)
            if abs(ratio - round(ratio)) > 1e-9:
                raise ValueError(f"dt = {self.dt} s does not divide 1/{rate} s")
        if self.duration <= 0:
            raise ValueError(f"duration must be positive; got {self.duration}")


@dataclass(frozen=True)
class Flight:
    """A generated flight.

    spec; t (M,) [s] the integrator's times; state (M, 13): p [m], v [m/s], q (w, x, y,
    z), omega [rad/s] at t; command (M, 4): the controller's thrust [N] and torques
    [N m] held over each step; applied (M, 4): what reached the body over that step
    (after the motor lag, with the process noise); accel_world (M, 3): v' [m/s^2] at t;
    in_contact (M,) bool: the floor pushes at t (truth only: never written to the log);
    reference (M, 3) [m]: the reference position; columns: the log, column name ->
    (N,) values at the log rate (NaN: no sample), in the order ``write_csv`` writes
    them; sidecar: the JSON sidecar's content.
    """

    spec: FlightSpec
    t: Array
    state: Array
    command: Array
    applied: Array
    accel_world: Array
    in_contact: NDArray[np.bool_]
    reference: Array
    columns: dict[str, Array]
    sidecar: dict
