"""A log's own time base: times relative to its first row, its sampling interval, and
the gaps in it, judged on the log's own sampling rather than on a fixed clock.

Every logger's clock jitters (a few ms on a microcontroller or a PC), and many stamp
rows in Unix time (t ~ 1.7e9 s). Both must leave the estimate unchanged:

* **Relative time.** Readers subtract the first row's time, in float64, before anything
  else differences, bins or narrows the times (:func:`relative_time`). At 1.7e9 s a
  float64 resolves 2.4e-7 s, so the subtraction is exact and loses nothing the file
  held; a float32 column there resolves only 128 s, which no subtraction can restore
  (:func:`stored_resolution_problem` says so instead of reading it).
* **Gaps.** A step between consecutive rows is a gap when it is longer than
  ``GAP_FACTOR`` (4) times the median step *and* longer than ``GAP_MIN_S`` (20 ms)
  (:func:`gap_threshold`). A row stamped up to +-5 ms off its place therefore never
  makes a gap at any rate (the step is at most the median + 10 ms, below both bounds),
  a dropped row or two at 100 Hz is not one either (interpolated over), while a pause of
  the logger (a 2 s hole in the rows) always is, at every rate pinquad reads (median
  step at most 0.25 s, so the threshold is at most 1 s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

GAP_FACTOR = 4.0
"""A step longer than this many median steps (and than ``GAP_MIN_S``) is a log gap."""

GAP_MIN_S = 0.02
"""No step of 20 ms or less is a gap, whatever the rate: clock jitter of a few ms on a
fast log (500 Hz: median 2 ms) must not become one."""


def relative_time(t: Array) -> tuple[Array, float]:
    """(t - t[0] (N,) [s] in float64, t[0] [s]): times relative to the first row, computed
    in float64 before any differencing, so an epoch offset (Unix time) costs nothing
    the file held. An empty t gives (t, 0.0)."""
    t = np.asarray(t, dtype=np.float64)
    if t.size == 0:
        return t.copy(), 0.0
    t0 = float(t[0])
    return t - t0, t0


def stored_resolution_problem(t: Array, bits: int) -> str | None:
    """Why times stored as ``bits``-bit floats cannot be read as a log's times, or None:
    their resolution at the log's largest |t| (one unit in the last place) must be below
    1 % of the median step, else jitter-free rows read as equal or jumping times (a
    float32 column of Unix times resolves 128 s)."""
    if bits >= 64 or t.size < 2:
        return None
    dtype = {16: np.float16, 32: np.float32}.get(bits)
    if dtype is None:
        return None
    top = float(np.max(np.abs(t)))
    ulp = float(np.spacing(dtype(top)))
    steps = np.diff(np.asarray(t, dtype=np.float64))
    step = float(np.median(steps[steps > 0])) if (steps > 0).any() else 0.0
    if step > 0 and ulp < 0.01 * step:
        return None
    return (f"is stored as {bits}-bit floats, whose resolution at t = {top:.6g} s is "
            f"{ulp:.3g} s, not below 1 % of the log's step ({step:.3g} s); expected 64-bit "
            "floats, or times relative to the first row")


def sampling_interval(t: Array) -> float:
    """The log's own sampling interval [s]: the median step between rows (NaN for fewer
    than two rows)."""
    t = np.asarray(t, dtype=np.float64)
    return float(np.median(np.diff(t))) if t.size > 1 else float("nan")


def uniform_step(t: Array) -> float:
    """The step [s] of rows taken as evenly spaced: the mean of the steps that are not log
    gaps. Under clock jitter it is exact to (jitter / number of rows), where the median
    step of a jittered log is off by a fair fraction of the jitter (a 1 % error in dt is
    a 1 % error in every inertia)."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2:
        return float("nan")
    steps = np.diff(t)
    ok = ~gap_steps(t)
    return float(np.mean(steps[ok])) if ok.any() else float(np.median(steps))


def gap_threshold(t: Array) -> float:
    """The step [s] beyond which two consecutive rows of this log have a gap between
    them: max(``GAP_FACTOR`` x median step, ``GAP_MIN_S``) (module docstring)."""
    return max(GAP_FACTOR * sampling_interval(t), GAP_MIN_S)


def gap_steps(t: Array) -> BoolArray:
    """(N-1,) whether the step from row i to row i+1 is a log gap (:func:`gap_threshold`)."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2:
        return np.zeros(0, dtype=bool)
    return np.diff(t) > gap_threshold(t)


@dataclass(frozen=True)
class LogGaps:
    """The gaps of a log: starts (G,) and ends (G,) [s, the log's times] of each gap
    (the rows on either side), threshold [s] (:func:`gap_threshold`) and interval [s]
    (the median step)."""

    starts: Array
    ends: Array
    threshold: float
    interval: float

    @property
    def count(self) -> int:
        return int(self.starts.size)

    def describe(self) -> str:
        """The gaps in words: how many, the longest and where, and the rule."""
        if not self.count:
            return "no log gap"
        long = int(np.argmax(self.ends - self.starts))
        return (f"{self.count} log gap(s) (no row for longer than {self.threshold * 1e3:.0f} "
                f"ms: {GAP_FACTOR:g} x the median step of {self.interval * 1e3:.2f} ms, at "
                f"least {GAP_MIN_S * 1e3:.0f} ms), the longest "
                f"{self.ends[long] - self.starts[long]:.3f} s from t = {self.starts[long]:.3f} s")


def find_gaps(t: Array) -> LogGaps:
    """The log gaps of rows at times t (N,) [s] (:func:`gap_steps`)."""
    t = np.asarray(t, dtype=np.float64)
    big = np.flatnonzero(gap_steps(t))
    return LogGaps(t[big], t[big + 1], gap_threshold(t) if t.size > 1 else float("nan"),
                   sampling_interval(t))


def gap_lines(t: Array) -> tuple[str, ...]:
    """The report's exclusion line for the steps over log gaps of rows at times t (N,)
    [s] (excluded, and resets for the E-step), or () when there are none."""
    gaps = find_gaps(t)
    if not gaps.count:
        return ()
    return (f"{gaps.count} transitions: {gaps.describe()} (resets for the E-step)",)


def gap_transitions(gaps: LogGaps, grid: Array, dt: float) -> BoolArray:
    """(K,) whether grid transition k -> k+1 (grid[k] to grid[k] + dt, a uniform grid of
    K rows) overlaps a log gap (open interval between the rows on either side); the
    last entry is always False."""
    grid = np.asarray(grid, dtype=np.float64)
    out = np.zeros(grid.size, dtype=bool)
    for a, b in zip(gaps.starts, gaps.ends, strict=True):
        out |= (grid < b) & (grid + dt > a)
    if out.size:
        out[-1] = False
    return out


def irregular_note(t: Array, spread: float = 0.1) -> str | None:
    """A note when the log's steps (outside gaps) spread by more than ``spread`` of the
    median step (5th to 95th percentile), else None: what the rows' irregularity is and
    that it is not a gap."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 3:
        return None
    steps = np.diff(t)[~gap_steps(t)]
    if steps.size < 2:
        return None
    med = float(np.median(steps))
    lo, hi = (float(v) for v in np.percentile(steps, (5.0, 95.0)))
    if hi - lo <= spread * med:
        return None
    return (f"time stamps irregular: steps {lo * 1e3:.2f}-{hi * 1e3:.2f} ms (5th-95th "
            f"percentile) around the median {med * 1e3:.2f} ms; none is a log gap (longer "
            f"than {gap_threshold(t) * 1e3:.0f} ms)")
