"""PX4 ULog files, read with pyulog (the PX4 project's reader) into a
:class:`pinquad.io.command_log.CommandLog`.

Topics (the first instance of each, as a default PX4 log carries them):
``vehicle_attitude`` (q, FRD body to NED), ``vehicle_angular_velocity`` (xyz) or else
``sensor_combined`` (gyro_rad), ``vehicle_acceleration`` (xyz) or else
``sensor_combined`` (accelerometer_m_s2), ``vehicle_local_position`` (vx, vy, vz and,
when valid, x, y, z; NED), ``actuator_motors`` (control, normalized 0..1) or else
``actuator_outputs`` (output, PWM [us] mapped through the log's PWM_MAIN_MIN/MAX or
PWM_MIN/MAX parameters), ``battery_status`` (voltage_v), and the arming state from
``vehicle_status`` (arming_state = 2) or ``actuator_armed`` (armed).

Only the longest armed segment is read; every topic is interpolated linearly onto a
uniform time base at ``rate`` [Hz] inside it (the attitude quaternion component-wise with
its sign kept continuous, then normalized). Time stamps are microseconds from boot.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pyulog import ULog

from pinquad.core.conventions import quat_wxyz_from_ned_frd, vector_from_ned_frd
from pinquad.io.command_log import CommandLog, command_log
from pinquad.io.errors import LogFormatError

Array = NDArray[np.float64]

TOPICS = ("vehicle_attitude", "vehicle_angular_velocity", "sensor_combined",
          "vehicle_acceleration", "vehicle_local_position", "actuator_motors",
          "actuator_outputs", "battery_status", "vehicle_status", "actuator_armed")
"""The topics read (module docstring)."""

ARMED = 2
"""vehicle_status.arming_state of an armed vehicle (ARMING_STATE_ARMED)."""

DEFAULT_RATE = 100.0
"""Rows per second of the resampled log [Hz]."""

MIN_SEGMENT = 1.0
"""Shortest armed segment worth reading [s]."""


def is_ulog(path: Path) -> bool:
    """Whether the file starts with the ULog magic bytes ``ULog\\x01\\x12\\x35``."""
    try:
        with path.open("rb") as fh:
            return fh.read(7) == b"ULog\x01\x12\x35"
    except OSError:
        return False


def _open(path: Path) -> ULog:
    try:
        return ULog(str(path), list(TOPICS))
    except Exception as exc:  # pyulog raises several types on a damaged file
        raise LogFormatError(f"{path}: not a readable ULog file ({type(exc).__name__}: "
                             f"{exc}); expected a PX4 .ulg log") from None


def _topic(ulog, name: str) -> dict[str, Array] | None:
    for data in ulog.data_list:
        if data.name == name and data.multi_id == 0:
            return {k: np.asarray(v, dtype=float) for k, v in data.data.items()}
    return None


def _need(path: Path, ulog, names: tuple[str, ...], fields: tuple[str, ...]
          ) -> dict[str, Array]:
    """The first of ``names`` present holding ``fields``, else a LogFormatError."""
    for name in names:
        topic = _topic(ulog, name)
        if topic is not None and all(f in topic for f in fields):
            return topic
    raise LogFormatError(f"{path}: no topic {' or '.join(names)} with fields "
                         f"{', '.join(fields)}; expected a default PX4 log")


def armed_segments(path: Path, ulog) -> list[tuple[float, float]]:
    """(start, stop) [us] of every span the log says the vehicle was armed."""
    status = _topic(ulog, "vehicle_status")
    if status is not None and "arming_state" in status:
        t, armed = status["timestamp"], status["arming_state"] == ARMED
    else:
        topic = _need(path, ulog, ("actuator_armed",), ("armed",))
        t, armed = topic["timestamp"], topic["armed"] > 0.5
    end = float(ulog.last_timestamp)
    spans, start = [], None
    for ti, a in zip(t, armed, strict=True):
        if a and start is None:
            start = float(ti)
        elif not a and start is not None:
            spans.append((start, float(ti)))
            start = None
    if start is not None:
        spans.append((start, end))
    return spans


def _pwm_range(ulog) -> tuple[float, float]:
    params = ulog.initial_parameters
    for lo, hi in (("PWM_MAIN_MIN", "PWM_MAIN_MAX"), ("PWM_MIN", "PWM_MAX")):
        if lo in params and hi in params:
            return float(params[lo]), float(params[hi])
    return 1000.0, 2000.0


def _interp(t: Array, topic: dict[str, Array], fields: list[str]) -> Array:
    return np.column_stack([np.interp(t, topic["timestamp"], topic[f]) for f in fields])


def _quat(t: Array, att: dict[str, Array]) -> Array:
    q = np.column_stack([att[f"q[{i}]"] for i in range(4)])
    # q and -q are one rotation: keep neighbours on one side before interpolating
    flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))
    q[1:] *= flip[:, None]
    out = np.column_stack([np.interp(t, att["timestamp"], q[:, i]) for i in range(4)])
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def read_ulog(path: str | Path, rate: float = DEFAULT_RATE) -> CommandLog:
    """The longest armed segment of a ULog (module docstring), resampled at ``rate``
    [Hz]. Raises LogFormatError naming the file and what is missing, e.g. "no armed
    flight segment" for a log of a vehicle that never armed."""
    path = Path(path)
    ulog = _open(path)
    spans = [s for s in armed_segments(path, ulog) if s[1] - s[0] >= MIN_SEGMENT * 1e6]
    if not spans:
        raise LogFormatError(f"{path}: no armed flight segment (the vehicle is never armed "
                             f"for {MIN_SEGMENT:.0f} s or more); expected a log of a flight")
    start, stop = max(spans, key=lambda s: s[1] - s[0])
    att = _need(path, ulog, ("vehicle_attitude",), tuple(f"q[{i}]" for i in range(4)))
    gyro_topic = _topic(ulog, "vehicle_angular_velocity")
    gyro_fields = [f"xyz[{i}]" for i in range(3)]
    if gyro_topic is None:
        gyro_topic = _need(path, ulog, ("sensor_combined",), ("gyro_rad[0]",))
        gyro_fields = [f"gyro_rad[{i}]" for i in range(3)]
    acc_topic = _topic(ulog, "vehicle_acceleration")
    acc_fields = [f"xyz[{i}]" for i in range(3)]
    if acc_topic is None:
        acc_topic = _need(path, ulog, ("sensor_combined",), ("accelerometer_m_s2[0]",))
        acc_fields = [f"accelerometer_m_s2[{i}]" for i in range(3)]
    lpos = _need(path, ulog, ("vehicle_local_position",), ("vx", "vy", "vz"))
    motors = _topic(ulog, "actuator_motors")
    notes: list[str] = []
    if motors is not None and "control[0]" in motors:
        fields = [f"control[{i}]" for i in range(4)]
        command_range = (0.0, 1.0)
    else:
        motors = _need(path, ulog, ("actuator_motors", "actuator_outputs"), ("output[0]",))
        fields = [f"output[{i}]" for i in range(4)]
        command_range = _pwm_range(ulog)
        notes.append(f"motor outputs read as PWM, {command_range[0]:.0f}-"
                     f"{command_range[1]:.0f} us = 0-1 (the log's PWM parameters)")
    # the uniform grid lies where every topic has samples on both sides
    first = max(start, *(tp["timestamp"][0] for tp in (att, gyro_topic, acc_topic, lpos, motors)))
    last = min(stop, *(tp["timestamp"][-1] for tp in (att, gyro_topic, acc_topic, lpos, motors)))
    if last - first < MIN_SEGMENT * 1e6:
        raise LogFormatError(f"{path}: no armed flight segment with attitude, rates, "
                             "acceleration, velocity and motor outputs together")
    t_us = np.arange(first, last, 1e6 / rate)
    inside = (motors["timestamp"] >= first) & (motors["timestamp"] <= last)
    for name in fields:
        bad = np.flatnonzero(~np.isfinite(motors[name][inside]))
        if bad.size:
            when = (motors["timestamp"][inside][bad[0]] - first) * 1e-6
            raise LogFormatError(f"{path}: motor output {name} is not a number {when:.3f} s "
                                 "into the armed segment; expected a command in every sample")
    position = None
    if "xy_valid" in lpos and (lpos["xy_valid"] > 0.5).all() and (lpos["z_valid"] > 0.5).all():
        position = vector_from_ned_frd(_interp(t_us, lpos, ["x", "y", "z"]))
    else:
        notes.append("no valid position (vehicle_local_position xy/z not valid): velocity only")
    battery = _topic(ulog, "battery_status")
    vbat = None if battery is None or "voltage_v" not in battery else _interp(
        t_us, battery, ["voltage_v"])[:, 0]
    return command_log(
        t_us, vector_from_ned_frd(_interp(t_us, lpos, ["vx", "vy", "vz"])),
        quat_wxyz_from_ned_frd(_quat(t_us, att)),
        vector_from_ned_frd(_interp(t_us, gyro_topic, gyro_fields)),
        vector_from_ned_frd(_interp(t_us, acc_topic, acc_fields)),
        _interp(t_us, motors, fields), command_range, str(path), position=position,
        vbat=vbat, notes=tuple(notes))
