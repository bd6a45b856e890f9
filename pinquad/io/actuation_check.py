"""Rotor-speed channels that cannot be the rotors' speeds, named with their rows, before
any EM.

A quadcopter flying on four rotors needs all four turning, and a real speed reading
varies from row to row (the sensor's noise alone moves it every few milliseconds; on the
24 shared IMRC logs no turning channel repeats one value for longer than 41 ms). Each
test below names the column, the rows and what to do:

1. **a channel at zero**: column rpm_i below ``ZERO_SHARE`` of the median of the other
   channels while they turn, in more than ``MAX_SHARE`` of the rows where they turn.
   Skipped for a log that carries the motor commands (PWM): those rows are rebuilt from
   them (``realdata.faults``: the IMRC jana20-29 logs' motor 1).
2. **a channel stuck**: one value, not zero, repeated without change for more than
   ``STUCK_S`` while the other channels turn (a logger holding its last reading; at the
   hover value it looks plausible to every other test).
3. **a false rotor-speed unit**, tested first (a false unit puts every channel out of
   range): ``declaration_check.check_declared_rotor_speed``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.io.declaration_check import check_declared_rotor_speed
from pinquad.io.errors import Problem
from pinquad.io.logs import FlightLog

Array = NDArray[np.float64]

ZERO_SHARE = 0.05
"""A reading below this share of the other channels' median is a rotor at rest."""
MAX_SHARE = 0.05
"""Largest share of the turning rows a channel may read zero in (the share beyond
which ``realdata.faults`` distrusts the whole channel)."""
STUCK_S = 0.5
"""Longest time [s] a turning channel may repeat one value (12 times the longest on the
shared logs' turning channels, 41 ms)."""


def _turning(rpm: Array, i: int) -> tuple[Array, Array]:
    """(rows where the channels other than i turn (N,) bool, their median (N,))."""
    others = np.delete(rpm, i, axis=1)
    with np.errstate(invalid="ignore"):
        med = np.nanmedian(np.where(np.isfinite(others), others, np.nan), axis=1) \
            if np.isfinite(others).any() else np.full(rpm.shape[0], np.nan)
    top = float(np.nanpercentile(med, 90)) if np.isfinite(med).any() else 0.0
    return np.isfinite(med) & (med > 0.3 * top) & (top > 0), med


def _spans(rows: Array, t: Array, limit: int = 3) -> str:
    """'rows a-b (t = x-y s), ...' of the runs of consecutive row indices (0-based in,
    1-based out)."""
    if rows.size == 0:
        return "no rows"
    cuts = np.flatnonzero(np.diff(rows) > 1) + 1
    runs = np.split(rows, cuts)
    text = [f"rows {r[0] + 1}-{r[-1] + 1} (t = {t[r[0]]:.2f}-{t[r[-1]]:.2f} s)" for r in runs[:limit]]
    more = f" and {len(runs) - limit} more stretch(es)" if len(runs) > limit else ""
    return ", ".join(text) + more


def zero_channels(log: FlightLog, max_share: float = MAX_SHARE) -> list[tuple[int, Array, int]]:
    """[(channel i (0-based), rows reading zero, turning rows)] of the channels at zero
    in more than ``max_share`` of the turning rows (test 1; not skipped for PWM: the
    caller decides; max_share -1 lists every channel)."""
    rpm = np.asarray(log.rpm, dtype=float)
    out = []
    for i in range(rpm.shape[1]):
        turning, med = _turning(rpm, i)
        with np.errstate(invalid="ignore"):
            zero = turning & np.isfinite(rpm[:, i]) & (rpm[:, i] < ZERO_SHARE * med)
        if turning.sum() and zero.sum() > max_share * turning.sum():
            out.append((i, np.flatnonzero(zero), int(turning.sum())))
    return out


def stuck_runs(log: FlightLog, min_s: float = STUCK_S) -> list[tuple[int, int, int, float]]:
    """[(channel i, first row, last row (0-based), value)] of each channel's longest run
    of one repeated non-zero reading while the others turn, where it lasts more than
    ``min_s`` [s] (test 2; min_s -1 lists every channel's longest)."""
    rpm = np.asarray(log.rpm, dtype=float)
    out = []
    for i in range(rpm.shape[1]):
        turning, med = _turning(rpm, i)
        rows = np.flatnonzero(np.isfinite(rpm[:, i]) & turning)
        if rows.size < 2:
            continue
        v = rpm[rows, i]
        # a new run starts where the value changes or the turning rows break
        new = np.r_[True, (np.diff(v) != 0) | (np.diff(rows) > 1)]
        starts = np.flatnonzero(new)
        ends = np.r_[starts[1:] - 1, rows.size - 1]
        length = log.t[rows[ends]] - log.t[rows[starts]]
        # a run at zero is test 1's (a rotor read as stopped), not a held reading
        length[v[starts] < ZERO_SHARE * med[rows[starts]]] = -np.inf
        k = int(np.argmax(length))
        if length[k] > min_s:
            out.append((i, int(rows[starts[k]]), int(rows[ends[k]]), float(v[starts[k]])))
    return out


def _has_pwm(log: FlightLog) -> bool:
    pwm = None if log.measured is None else log.measured.pwm
    return pwm is not None and bool(np.isfinite(pwm).all())


def check_zero_channel(log: FlightLog) -> Problem | None:
    """Test 1 of the module docstring."""
    if log.rpm is None or _has_pwm(log):
        return None
    found = zero_channels(log)
    if not found:
        return None
    i, rows, turning = found[0]
    rpm = np.asarray(log.rpm, dtype=float)
    good = np.isfinite(rpm).all(axis=1)
    for _, bad, _ in found:
        good[bad] = False
    return ("rotor-at-zero", f"rpm_{i + 1}",
            f"column 'rpm_{i + 1}' reads 0 rev/min (below {100 * ZERO_SHARE:g} % of the other "
            f"rotors' median) in {rows.size} of the {turning} rows where the other rotors turn "
            f"({100 * rows.size / turning:.0f} %): {_spans(rows, log.t)}; a rotor at rest would "
            "bring the vehicle down, so the channel lost its reading there. The log carries "
            "no motor commands (PWM) to rebuild it from: cut the log to the rows where every "
            f"rotor reads ({int(good.sum())} of {log.n} rows), or give the micro-SD log with "
            "its PWM commands (offline --faults repair rebuilds the channel from them)")


def check_stuck_channel(log: FlightLog) -> Problem | None:
    """Test 2 of the module docstring."""
    if log.rpm is None:
        return None
    found = stuck_runs(log)
    if not found:
        return None
    i, a, b, value = found[0]
    span = log.t[b] - log.t[a]
    return ("rotor-stuck", f"rpm_{i + 1}",
            f"column 'rpm_{i + 1}' holds {value:.6g} rev/min without change in rows {a + 1}-"
            f"{b + 1} (t = {log.t[a]:.2f}-{log.t[b]:.2f} s, {span:.2f} s, "
            f"{100 * span / max(log.t[-1] - log.t[0], 1e-9):.0f} % of the log) while the other "
            f"rotors' speeds vary; a turning rotor's reading changes within {STUCK_S:g} s "
            "(sensor noise alone moves it every few ms): the logger repeated its last value. "
            "Cut the log to the rows outside that stretch, or rebuild the channel from the "
            "motor commands (offline --faults repair, on a micro-SD log with PWM)")


def actuation_problems(log: FlightLog) -> tuple[Problem, ...]:
    """Every failed test of the module docstring: the rotor-speed declaration first (a
    false unit puts every channel out of range)."""
    declared = check_declared_rotor_speed(log)
    if declared is not None:
        return (declared,)
    found = (check_zero_channel(log), check_stuck_channel(log))
    return tuple(p for p in found if p is not None)
