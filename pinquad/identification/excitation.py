"""Which rows of a command log are flight, and which of them excite what.

Flight segments (``flight_segments``): the runs of rows in which some motor command is
above ``min_command`` (gaps of all-zero commands shorter than ``max_gap`` [s] are kept
inside the run: a deliberate motor cut, the free fall that shows the motor delay), each
trimmed by ``trim`` [s] at both ends (take-off from a hand or the floor, landing), and
kept when at least ``min_length`` [s] long. What lies outside (on the floor, carried,
the motors off) has no thrust model: the known-mass fits use the segments only.

Useful excitation (``excitation_ranges``): per axis, the one-second windows of a
segment whose band-passed signal (the torque band ``band`` [Hz]; thrust: the body-z
specific force [m/s^2], roll, pitch, yaw: the gyro [rad/s]) has an RMS of at least
``share`` of the axis's 90th-percentile window and at least the floor ``FLOOR`` (so a
still log shows none), merged into ranges (across a single quiet window) of at least
``min_length`` [s]. They are reported for the user to choose --range from; the fits do
not pick them themselves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfiltfilt

from pinquad.io.command_log import CommandLog, between, slice_rows

Array = NDArray[np.float64]

AXES = ("thrust", "roll", "pitch", "yaw")
FLOOR = {"thrust": 0.3, "roll": 0.1, "pitch": 0.1, "yaw": 0.1}
"""Smallest RMS of a band-passed window counted as excitation: 0.3 m/s^2 of body-z
specific force, 0.1 rad/s of rate (a hovering Crazyflie's controller jitter is below
both)."""


@dataclass(frozen=True)
class Excitation:
    """Flight segments and the ranges of useful excitation of one log.

    segments: ((start, stop) row indices, stop exclusive) of the flight segments;
    segment_times: the same on the log's own clock [s] (first and last row);
    ranges: axis (``AXES``) -> ((lo, hi) [s, log clock]) of useful excitation;
    window [s]: the window length; band (lo, hi) [Hz].
    """

    segments: tuple[tuple[int, int], ...]
    segment_times: tuple[tuple[float, float], ...]
    ranges: dict[str, tuple[tuple[float, float], ...]]
    window: float
    band: tuple[float, float]

    def text(self) -> str:
        """One line per axis: its ranges, or none."""
        def fmt(rs: tuple[tuple[float, float], ...]) -> str:
            return ", ".join(f"{a:.1f}-{b:.1f}" for a, b in rs) or "none"
        lines = [f"flight segments (log clock, s): {fmt(self.segment_times)}"]
        lines += [f"useful {axis} excitation ({self.band[0]:g}-{self.band[1]:g} Hz, "
                  f"{self.window:g} s windows): {fmt(self.ranges[axis])}" for axis in AXES]
        return "\n".join(lines)


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def flight_segments(flight: CommandLog, min_command: float = 0.05, max_gap: float = 0.5,
                    trim: float = 0.5, min_length: float = 2.0) -> tuple[tuple[int, int], ...]:
    """Row ranges (start, stop) of the flight segments (module docstring)."""
    dt = float(np.median(np.diff(flight.log.t)))
    on = (flight.command > min_command).any(axis=1)
    off = _runs(~on)
    for a, b in off:  # short motor cuts inside a flight stay in it
        if a > 0 and b < on.size and (b - a) * dt < max_gap:
            on[a:b] = True
    cut = int(round(trim / dt))
    out = []
    for a, b in _runs(on):
        a, b = a + cut, b - cut
        if (b - a) * dt >= min_length:
            out.append((a, b))
    return tuple(out)


def excitation_ranges(flight: CommandLog, segments: tuple[tuple[int, int], ...],
                      band: tuple[float, float], window: float = 1.0, share: float = 0.3,
                      min_length: float = 2.0) -> Excitation:
    """The flight's useful excitation per axis inside ``segments`` (module docstring)."""
    log = flight.log
    dt = float(np.median(np.diff(log.t)))
    clock = log.meta.t_origin + log.t
    sos = butter(4, band, btype="band", fs=1.0 / dt, output="sos")
    w = max(int(round(window / dt)), 1)
    rms: dict[str, list[float]] = {axis: [] for axis in AXES}
    starts: list[int] = []
    for a, b in segments:
        if b - a <= 3 * (2 * sos.shape[0] + 1):  # too short to filter
            continue
        sig = sosfiltfilt(sos, np.column_stack([log.accel[a:b, 2], log.gyro[a:b]]), axis=0)
        for k in range(0, b - a - w + 1, w):
            starts.append(a + k)
            for j, axis in enumerate(AXES):
                rms[axis].append(math.sqrt(float(np.mean(sig[k:k + w, j] ** 2))))
    ranges: dict[str, tuple[tuple[float, float], ...]] = {}
    first = np.asarray(starts, dtype=np.int64)
    for axis in AXES:
        vals = np.asarray(rms[axis])
        if vals.size == 0:
            ranges[axis] = ()
            continue
        good = (vals >= share * np.percentile(vals, 90)) & (vals >= FLOOR[axis])
        # one quiet window between two excited ones does not split a range
        inner = np.flatnonzero(~good[1:-1]) + 1
        good[inner[good[inner - 1] & good[inner + 1] & (first[inner + 1] - first[inner - 1]
                                                       == 2 * w)]] = True
        # consecutive windows (adjacent rows) merge into one range
        out = []
        k = 0
        while k < vals.size:
            if not good[k]:
                k += 1
                continue
            j = k
            while j + 1 < vals.size and good[j + 1] and first[j + 1] == first[j] + w:
                j += 1
            lo, hi = float(clock[first[k]]), float(clock[first[j] + w - 1])
            if hi - lo >= min_length - dt:
                out.append((lo, hi))
            k = j + 1
        ranges[axis] = tuple(out)
    times = tuple((float(clock[a]), float(clock[b - 1])) for a, b in segments)
    return Excitation(segments, times, ranges, window, band)


def segments_of(flight: CommandLog, ranges: list[tuple[float, float]] | None,
                band: tuple[float, float]) -> tuple[list[CommandLog], Excitation | None]:
    """The segments to fit of one log: the --range rows, else (an IMU-only log) its
    flight segments, else the whole log; and, for an IMU-only log, its flight segments'
    excitation report. Raises ValueError when an IMU-only log has no flight segment."""
    excitation = None
    if flight.imu_only:
        found = flight_segments(flight)
        if not found:
            raise ValueError(f"{flight.log.meta.source}: no flight segment (motor commands "
                             "above 5 % of full for 2 s or more); expected a log of a flight")
        excitation = excitation_ranges(flight, found, band)
    if ranges is not None:
        return [between(flight, lo, hi) for lo, hi in ranges], excitation
    if excitation is not None:
        return [slice_rows(flight, a, b) for a, b in excitation.segments], excitation
    return [flight], excitation
