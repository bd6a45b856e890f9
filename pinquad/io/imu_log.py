"""A Crazyflie micro-SD log read as an ordinary log: onboard IMU and motor commands only.

What most owners of a small drone can log without a motion-capture room: the
accelerometer (specific force), the gyro and what was sent to each motor, often at about
1 kHz. This reader takes exactly that from the ``fixedFrequency`` event of a micro-SD
log (``pinquad.io.sdlog``) and leaves out everything else a richer log may carry
(position, attitude, velocity, rotor speeds): the flight becomes a ``CommandLog`` whose
velocity, attitude and position are NaN, identified with the mass given
(``pinquad.identification.known_mass``).

Columns read (``fixedFrequency``):

- ``acc.x/y/z`` [g] -> specific force [m/s^2] (times 9.81), body FLU = pinquad's body;
- ``gyro.x/y/z`` [deg/s] -> [rad/s];
- the motor commands ``motor.m1..m4`` or, failing those, ``pwm.m1_pwm..m4_pwm``
  [0-65535] -> u = raw / 65535 [1], in the motor order M1..M4;
- ``pm.vbatMV`` [mV] -> battery voltage [V], when logged.

Time: the device clock is irregular (a 1 kHz stream has steps of 1 ms and gaps of
4-7 ms). The rows become means over a uniform grid of ``dt`` [s] (each interval's mean
of every sample inside it, its time the interval's centre): the known-mass regression
needs evenly spaced rows, and the mean is the interval's average actuation, as a
sampled command log is read. An interval without a sample is linearly interpolated
from its neighbours and counted in the notes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import GRAVITY
from pinquad.io.command_log import CommandLog, command_log
from pinquad.io.logs import LogFormatError
from pinquad.io.sdlog import GRID_EVENT, read_sdlog_raw

Array = NDArray[np.float64]

IMU_ROW = 0.004
"""Row spacing [s] of an IMU-only log: 250 Hz, fine against the Crazyflie's motor time
constant (tens of ms) and the torque band (Hz), coarse enough to keep the regression's
autocorrelation-consistent errors cheap."""
COMMAND_RANGE = (0.0, 65535.0)
"""Raw motor command of u = 0 and u = 1 on a Crazyflie (a 16-bit PWM ratio)."""
MOTOR_COLUMNS = (("motor.m1", "motor.m2", "motor.m3", "motor.m4"),
                 ("pwm.m1_pwm", "pwm.m2_pwm", "pwm.m3_pwm", "pwm.m4_pwm"))
"""The motor command columns read, first complete set wins (M1..M4)."""
IMU_COLUMNS = ("acc.x", "acc.y", "acc.z", "gyro.x", "gyro.y", "gyro.z")
DROPPED = ("stateEstimate.", "locSrv.", "rpm.")
"""Prefixes of columns a richer log may carry that an IMU-only reading leaves out."""


def interval_means(t: Array, columns: Array, dt: float) -> tuple[Array, Array, int]:
    """Means of ``columns`` (K, C) sampled at ``t`` (K,) [s, from 0, increasing] over
    the intervals [j dt, (j + 1) dt), j = 0 .. floor(t[-1] / dt) - 1 (the last partial
    interval dropped). Returns (centres (J,) [s], means (J, C), J0: intervals with no
    sample, filled by linear interpolation between their neighbours' means)."""
    n_bins = int(math.floor(t[-1] / dt))
    if n_bins < 2:
        raise ValueError("fewer than two intervals")
    idx = np.floor(t / dt).astype(np.int64)
    keep = idx < n_bins
    idx = idx[keep]
    counts = np.bincount(idx, minlength=n_bins).astype(float)
    sums = np.column_stack([np.bincount(idx, weights=c[keep], minlength=n_bins)
                            for c in columns.T])
    centres = (np.arange(n_bins) + 0.5) * dt
    full = counts > 0
    means = np.empty_like(sums)
    means[full] = sums[full] / counts[full, None]
    for c in range(means.shape[1]):
        means[~full, c] = np.interp(centres[~full], centres[full], means[full, c])
    return centres, means, int((~full).sum())


def read_imu_log(path: str | Path, dt: float = IMU_ROW) -> CommandLog:
    """The IMU-only flight of a Crazyflie micro-SD log (module docstring), on rows of
    ``dt`` [s]. Raises LogFormatError naming the file and what is missing (no
    ``fixedFrequency`` event, no accelerometer or gyro, no motor command)."""
    raw = read_sdlog_raw(path)
    src = raw.path
    grid = raw.events.get(GRID_EVENT)
    if grid is None or grid.count < 2:
        raise LogFormatError(f"{src}: byte offset {raw.data_offset}: no {GRID_EVENT!r} "
                             "records; expected the IMU and motor commands in that event")
    missing = [c for c in IMU_COLUMNS if not grid.has(c)]
    if missing:
        raise LogFormatError(f"{src}: event {GRID_EVENT!r} has no {', '.join(missing)}; "
                             "an IMU-only log needs the accelerometer acc.x/y/z [g] and the "
                             "gyro gyro.x/y/z [deg/s]")
    motors = next((m for m in MOTOR_COLUMNS if all(grid.has(c) for c in m)), None)
    if motor_signal_missing(motors, grid.values):
        raise LogFormatError(
            f"{src}: no motor signal: event {GRID_EVENT!r} has neither motor.m1..motor.m4 "
            "nor pwm.m1_pwm..pwm.m4_pwm (or they never leave 0); identifying a log without "
            "motion capture needs each motor's command as the input, besides acc.x/y/z "
            "and gyro.x/y/z")
    assert motors is not None
    t_dev = grid.time
    keep = np.concatenate([[True], t_dev[1:] > np.maximum.accumulate(t_dev)[:-1]])
    t_dev = t_dev[keep]
    names = [*IMU_COLUMNS, *motors] + (["pm.vbatMV"] if grid.has("pm.vbatMV") else [])
    cols = np.column_stack([grid.get(c)[keep] for c in names])
    bad = ~np.isfinite(cols).all(axis=1)
    if bad.any():
        cols, t_dev = cols[~bad], t_dev[~bad]
    try:
        centres, means, empty = interval_means(t_dev - t_dev[0], cols, dt)
    except ValueError:
        raise LogFormatError(f"{src}: {t_dev[-1] - t_dev[0]:.3f} s of {GRID_EVENT!r} "
                             f"records; expected at least two {dt * 1e3:g} ms rows") from None
    steps = np.diff(t_dev)
    notes = [f"IMU-only reading of a micro-SD log: {GRID_EVENT} {t_dev.size} samples "
             f"(median step {np.median(steps) * 1e3:.2f} ms, longest gap "
             f"{steps.max() * 1e3:.1f} ms) as means over {centres.size} rows of "
             f"{dt * 1e3:g} ms ({empty} without a sample, interpolated)",
             f"motor commands {motors[0]}..{motors[-1]} read as u = raw / "
             f"{COMMAND_RANGE[1]:.0f}"]
    dropped = sorted({p.rstrip(".") for v in grid.values for p in DROPPED if v.startswith(p)})
    if dropped:
        notes.append(f"left out (an IMU-only reading): {', '.join(dropped)} columns")
    if keep.size - int(keep.sum()) or bad.any():
        notes.append(f"{GRID_EVENT}: {keep.size - int(keep.sum())} samples whose time did not "
                     f"increase and {int(bad.sum())} with a missing value left out")
    n = centres.size
    t_us = (t_dev[0] + centres) * 1e6
    vbat = means[:, 10] / 1000.0 if means.shape[1] > 10 else None
    return command_log(t_us, np.full((n, 3), np.nan), None, means[:, 3:6] * math.pi / 180.0,
                       means[:, 0:3] * GRAVITY, means[:, 6:10], COMMAND_RANGE, src,
                       vbat=vbat, notes=tuple(notes))


def motor_signal_missing(motors: tuple[str, ...] | None, values: dict[str, Array]) -> bool:
    """Whether a log lacks a usable motor signal: no complete set of motor columns, or
    every command of the set is 0 or missing throughout."""
    if motors is None:
        return True
    stacked = np.column_stack([values[c] for c in motors])
    return not bool(np.any(np.isfinite(stacked) & (stacked > 0)))

