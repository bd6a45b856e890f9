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

from dataclasses import dataclass, replace

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

    @property
    def imu_only(self) -> bool:
        """Whether the log has neither velocity nor attitude in any row (onboard IMU and
        motor commands only)."""
        return not (np.isfinite(self.log.velocity).any() or np.isfinite(self.log.euler).any())


def between(flight: CommandLog, lo: float, hi: float) -> CommandLog:
    """The rows of ``flight`` whose time on the log's own clock, ``meta.t_origin + t``
    [s], lies in [lo, hi]; t restarts at 0 at the first kept row (``t_origin`` moved
    with it). Raises ValueError naming the log and its span when fewer than two rows
    remain."""
    log = flight.log
    clock = log.meta.t_origin + log.t
    keep = (clock >= lo) & (clock <= hi)
    if int(keep.sum()) < 2:
        raise ValueError(f"{log.meta.source}: --range {lo:g} {hi:g} s holds no rows; the log "
                         f"runs from {clock[0]:.2f} to {clock[-1]:.2f} s on its own clock")
    start = int(np.argmax(keep))
    stop = start + int(keep.sum())  # t increases: the kept rows are contiguous
    return slice_rows(flight, start, stop)


def slice_rows(flight: CommandLog, start: int, stop: int) -> CommandLog:
    """Rows start..stop-1 of ``flight``, t restarting at 0 (``meta.t_origin`` moved to
    the first kept row's time on the log's clock), noted."""
    log = flight.log
    cut = log.slice(start, stop)
    origin = log.meta.t_origin + float(log.t[start])
    cut = replace(cut, t=cut.t - cut.t[0], meta=replace(log.meta, t_origin=origin))
    note = (f"rows {origin:.2f}-{log.meta.t_origin + float(log.t[stop - 1]):.2f} s of the "
            "log's clock")
    return replace(flight, log=cut, command=flight.command[start:stop],
                   command_raw=flight.command_raw[start:stop],
                   vbat=None if flight.vbat is None else flight.vbat[start:stop],
                   notes=(*flight.notes, note))


def command_log(t_us: Array, velocity: Array, quat_world_body: Array | None, gyro_body: Array,
                accel_body: Array, command_raw: Array, command_range: tuple[float, float],
                source: str, position: Array | None = None, vbat: Array | None = None,
                notes: tuple[str, ...] = (), vehicle: str = "px4") -> CommandLog:
    """A CommandLog from columns already in pinquad's frames (world z up, body z up;
    velocity (N, 3) [m/s, world], quat (N, 4) (w, x, y, z) body to world, or None for a
    log without attitude: Euler angles NaN) and time
    stamps t_us (N,) [us from boot]: t = (t_us - t_us[0]) * 1e-6 [s]; the commands
    normalized as u = (raw - lo) / (hi - lo). ``meta.t_origin`` keeps the first stamp [s];
    ``meta.vehicle`` is ``vehicle`` (a name only: the rotors come from --vehicle)."""
    t = (t_us - t_us[0]) * MICROSECONDS
    n = t.shape[0]
    lo, hi = command_range
    log = FlightLog(
        t=t, position=np.full((n, 3), np.nan) if position is None else position,
        velocity=velocity, gyro=gyro_body,
        euler=(np.full((n, 3), np.nan) if quat_world_body is None
               else euler_from_quat_wxyz(quat_world_body)),
        accel=accel_body, vbat=vbat,
        meta=LogMeta(vehicle=vehicle, source=source, notes=notes, actuation="sampled",
                     vehicle_named=False, t_origin=float(t_us[0]) * MICROSECONDS))
    return CommandLog(log=log, command=(command_raw - lo) / (hi - lo),
                      command_raw=command_raw, command_range=command_range, vbat=vbat,
                      notes=notes)
