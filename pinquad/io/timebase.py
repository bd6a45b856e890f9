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

import math
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



CLOCK_HALF_WINDOW = 250
"""Rows on either side of a row in the straight-line fit that gives its time on the log's
clock (:func:`clock_times`)."""


CLOCK_JUMP_Z = 6.0
"""A jump of the stamps' mean departure from a steady clock is a clock break only when it
is this many of its standard errors (the rows' own jitter over the rows averaged on
either side): near an end, where only a few rows lie on one side, jitter of a few ms
must not pass for a jump of half a step, while rows dropped there still show. Under
normal jitter the chance of a false break at one place is 2e-9, below 1e-4 over the
~30 000 places of a long log."""


CLOCK_RATE_Z = 3.0
"""A piece too short to measure its own rate takes that of the rows around it, unless
its own straight line's slope differs from it by more than this many of its standard
errors, s sqrt(12 / (n (n^2 - 1))) for n rows of jitter s: rows dropped inside the piece,
one by one, where no single step could show them (a logger's burst of drops)."""


def _line_residual(t: Array) -> Array:
    """(N,) t minus its least-squares straight line against row number."""
    j = np.arange(t.size, dtype=np.float64)
    slope, icpt = np.polyfit(j, t - t[0], 1)
    return t - (t[0] + icpt + slope * j)


def _local_line(r: Array, half: int, x: Array | None = None) -> Array:
    """(N,) the least-squares straight line of r (N,) against x (N,) (row number when
    None) over the 2 half + 1 samples around each sample (the window shifted to stay
    inside), evaluated at that sample's x."""
    n = r.size
    width = min(2 * half + 1, n)
    if width < 3:
        return r.copy()
    x = np.arange(n, dtype=np.float64) if x is None else x - np.mean(x)
    lo = np.clip(np.arange(n) - half, 0, n - width)

    def window_sum(v: Array) -> Array:
        c = np.concatenate([[0.0], np.cumsum(v)])
        return c[lo + width] - c[lo]

    mean_x, mean_r = window_sum(x) / width, window_sum(r) / width
    spread = window_sum(x * x) - width * mean_x**2  # sum of (x - mean_x)^2 over the window
    slope = np.where(spread > 0, (window_sum(x * r) - width * mean_x * mean_r)
                     / np.where(spread > 0, spread, 1.0), 0.0)
    return mean_r + slope * (x - mean_x)


def _jitter_sd(t: Array, cuts: NDArray[np.int64], half: int) -> float:
    """The rows' jitter [s], a property of the logger: the robust standard deviation
    (1.4826 x the median absolute deviation) of the stamps t (N,) about their local
    straight line (:func:`_local_line`) on each stretch between cuts (N + 1 bounds, log
    gaps and unexplained steps), pooled; a jump moves the departure on only the few rows
    next to it. 0 when no stretch has three rows."""
    departures = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        if b - a >= 3:
            r = _line_residual(t[a:b])
            departures.append(r - _local_line(r, half))
    if not departures:
        return 0.0
    d = np.concatenate(departures)
    return 1.4826 * float(np.median(np.abs(d - np.median(d))))


def _clock_break(t: Array, step: float, jitter: float, half: int) -> int | None:
    """The row where the clock jumps (rows dropped, or a late burst), or None: the row i
    where |D_i| stands furthest above its bound, D_i = mean(u[i:hi]) - mean(u[lo:i]) over
    up to W = ``half`` rows on either side (lo = max(i - W, 0), hi = min(i + W, N)), u
    the stamps' departure from a steady clock (its rate the median over spans of rows),
    when |D_i| exceeds both half a step and ``CLOCK_JUMP_Z`` standard errors,
    s sqrt(1 / (i - lo) + 1 / (hi - i)), s = ``jitter`` (:func:`_jitter_sd`). In the
    middle of a log jitter moves D by about s sqrt(2 / W), far below half a step; next to
    an end, with a few rows on one side, the standard error is what rules."""
    n = t.size
    if n < 4:
        return None
    # the clock's rate from many spans of rows: their median is not moved by a jump,
    # where a least-squares line through the rows would take part of it as a slope
    span = min(half, n // 4)
    rate = float(np.median((t[span:] - t[:-span]) / span))
    u = t - t[0] - rate * np.arange(n)
    c = np.concatenate([[0.0], np.cumsum(u)])
    i = np.arange(1, n)
    lo, hi = np.maximum(i - half, 0), np.minimum(i + half, n)
    jump = (c[hi] - c[i]) / (hi - i) - (c[i] - c[lo]) / (i - lo)
    stderr = jitter * np.sqrt(1.0 / (i - lo) + 1.0 / (hi - i))
    score = np.abs(jump) / np.maximum(0.5 * step, CLOCK_JUMP_Z * stderr)
    best = int(np.argmax(score))
    return int(i[best]) if score[best] > 1.0 else None


def _pooled_rate(t: Array, piece: NDArray[np.int64]) -> float:
    """The clock's rate [s per row] shared by the pieces of consecutive rows at stamps t
    (M,), piece (M,) the piece of each row, each piece with its own offset (rows dropped
    between them): the pooled within-piece slope against row number j,

        b = sum_p sum_{j in p} (j - jbar_p) (t_j - tbar_p) / sum_p sum_{j in p} (j - jbar_p)^2,

    or the mean step when no piece has two rows."""
    j = np.arange(t.size, dtype=np.float64)
    u = t - t[0]
    _, group = np.unique(piece, return_inverse=True)
    count = np.bincount(group)
    dj = j - (np.bincount(group, weights=j) / count)[group]
    du = u - (np.bincount(group, weights=u) / count)[group]
    spread = float(np.sum(dj * dj))
    return float(np.sum(dj * du)) / spread if spread > 0 else uniform_step(t)


def _unexplained_steps(t: Array) -> BoolArray:
    """(N-1,) steps longer than 1.5 median steps and than the median plus 6 robust
    standard deviations of the steps (1.4826 x their median absolute deviation): rows
    dropped where no jitter of this log explains it, found wherever they are, from a
    single step."""
    steps = np.diff(t)
    med = float(np.median(steps))
    spread = 1.4826 * float(np.median(np.abs(steps - med)))
    return steps > max(1.5 * med, med + 6.0 * spread)


def _clock_pieces(t: Array, step: float, jitter: float, half: int
                  ) -> list[tuple[int, int]]:
    """[(start, end)] row ranges of t on which the clock runs without a jump
    (:func:`_clock_break`)."""
    pieces, todo = [], [(0, t.size)]
    while todo:
        a, b = todo.pop()
        cut = _clock_break(t[a:b], step, jitter, half)
        if cut is None:
            pieces.append((a, b))
        else:
            todo += [(a, a + cut), (a + cut, b)]
    return sorted(pieces)


def clock_times(t: Array, half_window: int = CLOCK_HALF_WINDOW) -> Array:
    """(N,) each row's time [s] on the log's own clock.

    A logger samples on a steady clock and stamps each row with a few ms of jitter. The
    rows are split where the clock stops (log gaps, :func:`gap_steps`) or jumps (rows
    dropped: a step no jitter of the log explains, or the stamps' mean departure from a
    steady clock jumping, between up to ``half_window`` rows before and after, by more
    than half a step and than ``CLOCK_JUMP_Z`` standard errors of the jitter, so rows
    dropped a few rows from an end are found too). On each piece a row's
    time is the straight-line fit of the stamps against row number over the 2 W + 1
    rows around it (W = ``half_window``, the window shifted to stay inside the piece),

        t_clock[i] = a_i + b_i i,   (a_i, b_i) = argmin sum_{|j - i| <= W} (t_j - a - b j)^2;

    a piece of fewer than 2 W + 1 rows (a few rows before a drop at the log's start) has
    too few to measure its own rate: it takes the rate b shared with the pieces around it
    over the 2 W + 1 rows around it (:func:`_pooled_rate`; its own line's slope instead
    when that differs by more than ``CLOCK_RATE_Z`` standard errors) and its own mean
    offset, t_clock[i] = mean_j (t_j - b j) + b i.

    The fit follows a rate that drifts over seconds and leaves of jitter of standard
    deviation s about s / sqrt(2 W + 1), so a row's grid bin does not depend on its
    stamp's jitter. Evenly stamped rows come back as they are (to rounding). The fit is
    done on the stamps' departure from the piece's straight line, so Unix times (1.7e9 s)
    lose nothing."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 3:
        return t.copy()
    out = t.copy()
    # the step of the rows' clock: the median step of sorted jittered stamps is short by
    # a fair fraction of the jitter (500 Hz, +-4 ms: 1.59 ms for 1.97 ms)
    step = uniform_step(t)
    cuts = np.concatenate([[0], np.flatnonzero(gap_steps(t) | _unexplained_steps(t)) + 1,
                           [t.size]])
    jitter = _jitter_sd(t, cuts, half_window)
    pieces = [(a + lo, a + hi) for a, b in zip(cuts[:-1], cuts[1:], strict=True)
              for lo, hi in _clock_pieces(t[a:b], step, jitter, half_window)]
    piece = np.repeat(np.arange(len(pieces)), [hi - lo for lo, hi in pieces])
    width = 2 * half_window + 1
    for lo, hi in pieces:
        seg = t[lo:hi]
        if seg.size >= width:
            residual = _line_residual(seg)
            out[lo:hi] = seg - residual + _local_line(residual, half_window)
        else:  # short: the rate of the rows around it unless its own stamps refute it
            w0 = max(0, min((lo + hi) // 2 - half_window, t.size - width))
            rate = _pooled_rate(t[w0:w0 + width], piece[w0:w0 + width])
            j = np.arange(seg.size, dtype=np.float64)
            if seg.size >= 3:
                own = float(np.polyfit(j, seg - seg[0], 1)[0])
                own_se = jitter * math.sqrt(12.0 / (seg.size * (seg.size**2 - 1.0)))
                if abs(own - rate) > CLOCK_RATE_Z * own_se:  # rows dropped inside it
                    rate = own
            out[lo:hi] = seg[0] + np.mean(seg - seg[0] - rate * j) + rate * j
    return out


def grid_times(t: Array, dt: float) -> Array:
    """(K,) the uniform grid t_k = t_a - n dt + k dt [s] that covers rows at times t (N,)
    [s, on the log's clock, :func:`clock_times`]: anchored on the middle row t_a, whose
    clock time carries the least jitter (the first row's, at a piece's end, carries the
    most), n the number of steps that puts the first grid time at or before the first
    row, K the number that reaches the last. Rows evenly stamped dt apart lie on it."""
    t = np.asarray(t, dtype=np.float64)
    anchor = float(t[t.size // 2])
    start = anchor - dt * math.ceil((anchor - t[0]) / dt - 1e-6)
    return start + dt * np.arange(int(math.floor((t[-1] - start) / dt + 1e-6)) + 1)


FRAME_MIN_SAMPLES = 50
"""A stream of fewer samples is not fitted to a frame clock (:func:`frame_clock`)."""

FRAME_HALF_WINDOW = 100
"""Samples on either side of a sample in the straight-line fit of stamps against frame
number (:func:`frame_clock`)."""

FRAME_EVIDENCE = 4.5
"""A stream lies on a frame lattice when the lattice's periodogram peak, |sum_k
exp(-2 pi i f t_k)| / P, is this many times its level for stamps at random (1 / sqrt P)."""


def _lattice_frequency(t: Array) -> tuple[float, float]:
    """(f [Hz], evidence): the frame rate of stamps t (P,) [s, from 0] taken at a fixed
    rate with frames lost, and how far its periodogram peak |S(f)| / P, S(f) = sum_k
    exp(-2 pi i f t_k), stands above the 1 / sqrt(P) of stamps at random. The peak is
    sought between 0.5 / q and 1.5 / q, q the lower quartile of the steps (a quarter of
    the frames arrive one after the other), on the FFT of the stamps binned at q / 40,
    then refined on a fine grid of frequencies around it."""
    steps = np.diff(t)
    q = float(np.percentile(steps, 25.0))
    span = float(t[-1] - t[0])
    if q <= 0.0 or span <= 0.0:
        return float("nan"), 0.0
    width = q / 40.0
    counts = np.bincount(np.floor((t - t[0]) / width).astype(np.int64))
    size = 1 << int(math.ceil(math.log2(max(counts.size, 2) * 2)))
    power = np.abs(np.fft.rfft(counts, size))
    freq = np.fft.rfftfreq(size, width)
    band = (freq >= 0.5 / q) & (freq <= 1.5 / q)
    if not band.any():
        return float("nan"), 0.0
    coarse = float(freq[band][np.argmax(power[band])])
    fine = coarse + np.linspace(-2.0, 2.0, 161) / (size * width)
    # one frequency at a time: the (frequencies x stamps) table of a long log would
    # hold 160 complex numbers per stamp
    spectrum = np.array([abs(np.exp(-2j * np.pi * f * (t - t[0])).sum()) for f in fine])
    best = int(np.argmax(spectrum))
    return float(fine[best]), float(spectrum[best] / math.sqrt(t.size))


def frame_numbers(t: Array) -> NDArray[np.int64] | None:
    """(P,) the frame number of each stamp t (P,) [s] of a stream sampled at a fixed rate
    whose frames are lost on the way (a motion-capture stream over radio), or None when
    the stamps lie on no such lattice (:data:`FRAME_EVIDENCE`) or are too few.

    With f the frame rate (:func:`_lattice_frequency`) and phi the phase of S(f), a stamp
    is frame n_k = round(f (t_k - d_k) + phi / (2 pi)), d_k the running median over 51
    stamps of the departure from the global lattice (a slow drift of the two clocks);
    numbers strictly increase, the collisions resolved at least squared departure
    (:func:`_increasing_frames`). Jitter of less than half a frame period leaves every number right."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < FRAME_MIN_SAMPLES or not np.all(np.diff(t) > 0):
        return None
    rel = t - t[0]
    f, evidence = _lattice_frequency(rel)
    if not math.isfinite(f) or evidence < FRAME_EVIDENCE:
        return None
    phase = float(np.angle(np.exp(-2j * np.pi * f * rel).sum()))
    cycles = f * rel + phase / (2.0 * np.pi)
    departure = cycles - np.round(cycles)
    # the running median of the departure, which wraps at +-half a frame: a drift of the
    # two clocks is followed while it stays inside that (the global rate takes out their
    # mean difference); taking the median about each window's circular mean would follow
    # any drift but, measured on the shared logs at 4 ms of jitter, numbers twice as many
    # stamps wrong
    pad = 25
    padded = np.pad(departure, pad, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * pad + 1)
    drift = np.median(windows, axis=1)
    return _increasing_frames(cycles - drift)


def _increasing_frames(cycles: Array) -> NDArray[np.int64]:
    """(P,) strictly increasing whole frame numbers n_k nearest the frame coordinates c_k
    (P,): argmin sum_k (c_k - n_k)^2 over n_k in {round(c_k) - 1, round(c_k),
    round(c_k) + 1} with n_k > n_(k-1), by dynamic programming. Two stamps that round to
    one frame (a late arrival beside an early one) are told apart by whichever move
    costs least, not always by pushing the later one on."""
    shifts = np.array([-1, 0, 1])
    options = np.round(cycles).astype(np.int64)[:, None] + shifts[None, :]
    cost = (cycles[:, None] - options) ** 2
    total = cost[0].copy()
    back = np.zeros((cycles.size, shifts.size), dtype=np.int64)
    for k in range(1, cycles.size):
        allowed = options[k - 1][None, :] < options[k][:, None]  # (now, before)
        step = np.where(allowed, total[None, :], np.inf)
        back[k] = np.argmin(step, axis=1)
        total = cost[k] + step[np.arange(shifts.size), back[k]]
    choice = np.empty(cycles.size, dtype=np.int64)
    choice[-1] = int(np.argmin(total))
    for k in range(cycles.size - 1, 0, -1):
        choice[k - 1] = back[k, choice[k]]
    return options[np.arange(cycles.size), choice]


def frame_clock(t: Array, half_window: int = FRAME_HALF_WINDOW) -> Array | None:
    """(P,) each stamp's time [s] on a clock fitted to frame numbers, or None for stamps
    on no frame lattice (:func:`frame_numbers`): the stamps t (P,)
    of a stream taken at a fixed rate and stamped on arrival (radio latency, logger
    jitter) lie on t_k = a + T n_k + e_k, n_k the frame number (:func:`frame_numbers`);
    each is placed at the straight-line fit of the stamps against frame number over the
    2 W + 1 samples around it (W = ``half_window``),

        t_clock[k] = a_k + T_k n_k,   (a_k, T_k) = argmin sum_{|j - k| <= W} (t_j - a - T n_j)^2,

    which leaves of a jitter of standard deviation s about s / sqrt(2 W + 1)."""
    t = np.asarray(t, dtype=np.float64)
    numbers = frame_numbers(t)
    if numbers is None:
        return None
    x = (numbers - numbers[0]).astype(np.float64)
    slope, icpt = np.polyfit(x, t - t[0], 1)
    residual = t - (t[0] + icpt + slope * x)
    return t - residual + _local_line(residual, half_window, x)
