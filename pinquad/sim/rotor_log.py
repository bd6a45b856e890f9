"""A simulated flight logged as a measured one: rotor speeds instead of thrust and torques.

The simulator flies the commanded wrench u = [F, tau] (plus process noise); a vehicle's
rotors produce it through the mixer of its file (``vehicle.actuators.ActuatorModel``),

    [F, tau_x, tau_y, tau_z] = A [T_1 .. T_n],   T_i = kf omega_i^2,

so the logged rotor speeds are the commanded wrench through the inverse mixer,

    T = A^+ u,   omega_i = sqrt(max(T_i, 0) / kf)   [rad/s], logged in rev/min

(A^+ the pseudo-inverse: A^-1 for four rotors). The process noise stays unlogged, as
in the paper's experiment, where the log records the command. A log made this way goes
through the same path as a user's rotor-speed log (``pinquad.offline --log FILE
--vehicle FILE.toml``): rotor speeds back to a wrench through the file's geometry and
constants.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.io.logs import FlightLog, LogMeta
from pinquad.sim.simulator import Flight
from pinquad.vehicle.actuators import RPM_TO_RAD_S, ActuatorModel

Array = NDArray[np.float64]


def rotor_speeds(wrench: Array, actuator: ActuatorModel) -> Array:
    """Rotor speeds (N, n) [rev/min] that produce the wrench (N, 4) [N, N m] through the
    actuator's mixer (module docstring); a rotor asked for negative thrust stops (0)."""
    thrust = np.asarray(wrench, dtype=float) @ np.linalg.pinv(actuator.allocation()).T
    return np.sqrt(np.maximum(thrust, 0.0) / actuator.kf) / RPM_TO_RAD_S


def rotor_speed_log(flight: Flight, actuator: ActuatorModel, vehicle: str) -> FlightLog:
    """The flight's log with rotor speeds ``rpm_1..rpm_n`` (from the commanded wrench,
    :func:`rotor_speeds`) in place of thrust and torques; the samples of the sensor set
    it flew with (sensor B: position, velocity, Euler angles, gyro), simulator truth in
    ``true_*``; ``vehicle`` (a vehicle file's path) goes into the sidecar.
    A command that needs a negative rotor thrust (the controller's first steps on the
    floor) is logged with that rotor stopped, and the log's notes count such rows."""
    cfg = flight.config
    buf = flight.onboard
    asked = np.asarray(flight.inputs, dtype=float) @ np.linalg.pinv(actuator.allocation()).T
    clipped = (asked < 0.0).any(axis=1)
    notes = ()
    if clipped.any():
        airborne = clipped & ~flight.contact
        notes = (f"{int(clipped.sum())} rows ({int(airborne.sum())} of them airborne) command "
                 "a negative rotor thrust: logged with that rotor stopped",)
    meta = LogMeta(vehicle=vehicle, gravity=cfg.vehicle.gravity,
                   source=f"simulation of {cfg.vehicle.name} (sensor {cfg.sensor}, rotor speeds)",
                   actuation="held", notes=notes)
    # No contact column: a measured log has none, the pipeline finds contact from the data.
    return FlightLog(t=flight.t.copy(), position=buf.position.copy(),
                    velocity=buf.velocity.copy(), euler=buf.euler.copy(), gyro=buf.gyro.copy(),
                    accel=buf.accel.copy(), rpm=rotor_speeds(flight.inputs, actuator),
                    truth=flight.states.copy(), meta=meta)
