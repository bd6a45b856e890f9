"""A flight whose actuation is the motor commands (a PX4 log): no thrust, torques or
rotor speeds, only what the flight controller sent to each motor.

PX4 logs are read by ``pinquad.io.ulog`` (ULog files) and ``pinquad.io.ddd_csv`` (the
CSV layout of PX4's data-driven-dynamics pipeline); both convert NED / FRD to pinquad's
frames (``pinquad.core.conventions``) and microseconds from boot to seconds once, here
at the file boundary. What turns a command into thrust is the vehicle's actuator curve
(``pinquad.core.actuator_curve``), identified with the mass known
(``pinquad.identification.known_mass``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import euler_from_quat_wxyz
from pinquad.io.logs import FlightLog, LogMeta

Array = NDArray[np.float64]

MICROSECONDS = 1e-6
"""Seconds per PX4 time stamp unit (microseconds from boot) [s]."""


@dataclass(frozen=True)
class CommandLog:
    """One flight with motor commands as its actuation, on a uniform time base.

    log: the kinematics (``FlightLog``: t (N,) [s] from the first row, velocity (N, 3)
    [m/s, world], euler (N, 3) [rad], gyro (N, 3) [rad/s, body], accel (N, 3) [m/s^2,
    body specific force, +9.81 on z at hover]; position NaN when the log has none;
    thrust, torque and rpm None); command (N, k) [1]: each motor's command normalized to
    0 (idle range end) .. 1 (full), in the log's motor order; command_raw (N, k): the
    command as logged (PWM [us] or already normalized); command_range (lo, hi): the raw
    values mapped to 0 and 1; vbat (N,) [V] or None; notes: what the reader assumed.
    """

    log: FlightLog
    command: Array
    command_raw: Array
    command_range: tuple[float, float]
    vbat: Array | None = None
    notes: tuple[str, ...] = ()

    @property
    def n_motors(self) -> int:
        """Number of motor command columns."""
        return int(self.command.shape[1])


def command_log(t_us: Array, velocity: Array, quat_world_body: Array, gyro_body: Array,
                accel_body: Array, command_raw: Array, command_range: tuple[float, float],
                source: str, position: Array | None = None, vbat: Array | None = None,
                notes: tuple[str, ...] = ()) -> CommandLog:
    """A CommandLog from columns already in pinquad's frames (world z up, body z up;
    velocity (N, 3) [m/s, world], quat (N, 4) (w, x, y, z) body to world) and time
    stamps t_us (N,) [us from boot]: t = (t_us - t_us[0]) * 1e-6 [s]; the commands
    normalized as u = (raw - lo) / (hi - lo). ``meta.t_origin`` keeps the first stamp [s]."""
    t = (t_us - t_us[0]) * MICROSECONDS
    n = t.shape[0]
    lo, hi = command_range
    log = FlightLog(
        t=t, position=np.full((n, 3), np.nan) if position is None else position,
        velocity=velocity, euler=euler_from_quat_wxyz(quat_world_body), gyro=gyro_body,
        accel=accel_body, vbat=vbat,
        meta=LogMeta(vehicle="px4", source=source, notes=notes, actuation="sampled",
                     vehicle_named=False, t_origin=float(t_us[0]) * MICROSECONDS))
    return CommandLog(log=log, command=(command_raw - lo) / (hi - lo),
                      command_raw=command_raw, command_range=command_range, vbat=vbat,
                      notes=notes)
