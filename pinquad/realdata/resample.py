"""Samples at their own times onto the uniform grid t_k = t_0 + k dt: bin means, the
nearest sample, motion-capture glitches, and gaps filled by interpolation."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.io.timebase import frame_clock

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

BIN_TOLERANCE = 1e-4
"""A sample this fraction of a bin (1 us of a 10 ms bin) before a bin's edge is on it."""


def bin_mean(t: Array, values: Array, start: Array, dt: float, k: int) -> Array:
    """(k, C) mean of the finite values with start[j] <= t < start[j] + dt; NaN if none.

    start is a uniform grid (start[j] = start[0] + j dt), so each sample's bin is
    floor((t - start[0]) / dt + ``BIN_TOLERANCE``): a sample stamped on a bin's edge
    belongs to the bin it starts even when its stamp's rounding (a float64 Unix time
    resolves 2.4e-7 s) puts it a hair before.
    """
    values = np.asarray(values, dtype=float).reshape(t.size, -1)
    idx = np.floor((t - start[0]) / dt + BIN_TOLERANCE).astype(np.int64)
    inside = (idx >= 0) & (idx < k)
    out = np.full((k, values.shape[1]), np.nan)
    for c in range(values.shape[1]):
        ok = inside & np.isfinite(values[:, c])
        total = np.bincount(idx[ok], weights=values[ok, c], minlength=k)
        count = np.bincount(idx[ok], minlength=k)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, c] = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return out


def sample_average(t: Array, values: Array, start: Array, dt: float, k: int,
                   row_step: float, phase: float) -> Array:
    """(k, C) each bin's mean of the straight line through the finite samples,

        y_j = (1/S) sum_{s=0}^{S-1} x(start[j] + (s + phase) dt / S),   S = round(dt / row_step),

    x the samples (t (N,) [s], values (N, C)) joined linearly; NaN where the row
    nearest the point has no finite value in a channel finite on most rows (a row
    flagged implausible; a channel only some rows carry is joined across the others),
    or where no finite sample lies within a row step plus a bin of the point
    on both sides (a dropout). ``phase`` puts the points where rows
    on the grid's lattice would be: 1/2 for bins centred on the grid times, 0 for bins
    that start at them. At one row per bin the value is that row's own; at five rows per
    bin it averages five points as the bin's five rows would. Unlike the rows' plain mean it moves
    continuously with the rows' times: a row crossing a bin's edge changes the bin by a
    fraction of a row, not by a whole one."""
    values = np.asarray(values, dtype=float).reshape(t.size, -1)
    sub = max(1, int(round(dt / row_step))) if row_step > 0 else 1
    points = (start[:k, None] + (np.arange(sub) + phase) * dt / sub).ravel()
    reach = row_step + dt
    # the row nearest each point: a point whose nearest row has no finite value is NaN
    upper = np.clip(np.searchsorted(t, points), 1, max(t.size - 1, 1))
    nearest = np.where(np.abs(t[upper] - points) < np.abs(points - t[upper - 1]), upper,
                       upper - 1) if t.size > 1 else np.zeros(points.size, dtype=np.int64)
    out = np.full((k, values.shape[1]), np.nan)
    for c in range(values.shape[1]):
        ok = np.isfinite(values[:, c])
        if ok.sum() < 2:
            continue
        ts, xs = t[ok], values[ok, c]
        right = np.clip(np.searchsorted(ts, points, side="right"), 1, ts.size - 1)
        after, before = ts[right] - points, points - ts[right - 1]
        on_sample = np.minimum(np.abs(after), np.abs(before)) <= 1e-9 * dt
        near = on_sample | ((after <= reach) & (before <= reach))
        if ok.mean() >= 0.5:  # a channel of every row: its NaN rows are holes
            near &= ok[nearest]
        x = np.where(near, np.interp(points, ts, xs), 0.0).reshape(k, sub)
        count = near.reshape(k, sub).sum(axis=1)
        out[:, c] = np.where(count > 0, x.sum(axis=1) / np.maximum(count, 1), np.nan)
    return out


def held_average(t: Array, values: Array, start: Array, dt: float, k: int) -> Array:
    """(k, C) each bin's time average of values held from each row to the next,

        y_j = (1/dt) int_{start[j]}^{start[j] + dt} x(tau) dtau,   x(tau) = x_i on [t_i, t_{i+1}),

    the last row held for one median step; a bin the rows cover only in part averages
    over that part; NaN where a held NaN covers part of the bin or no row covers it. The
    integral is a straight line between the rows' cumulative sums, so a bin moves
    continuously with the rows' times."""
    values = np.asarray(values, dtype=float).reshape(t.size, -1)
    step = float(np.median(np.diff(t))) if t.size > 1 else dt
    knots = np.append(t, t[-1] + step)
    widths = np.diff(knots)
    a = np.clip(start[:k], knots[0], knots[-1])
    b = np.clip(start[:k] + dt, knots[0], knots[-1])
    covered = b - a
    out = np.empty((k, values.shape[1]))
    for c in range(values.shape[1]):
        bad = ~np.isfinite(values[:, c])
        area = np.concatenate([[0.0], np.cumsum(np.where(bad, 0.0, values[:, c]) * widths)])
        holes = np.concatenate([[0.0], np.cumsum(bad * widths)])
        inside = np.interp(b, knots, area) - np.interp(a, knots, area)
        hole = np.interp(b, knots, holes) - np.interp(a, knots, holes)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, c] = np.where((hole > 0) | (covered <= 0), np.nan, inside / covered)
    return out


def nearest_samples(grid_t: Array, times: Array, tol: float) -> tuple[NDArray[np.int64],
                                                                 NDArray[np.int64]]:
    """(rows, which): grid row ``rows[i]`` takes sample ``which[i]``, the sample nearest
    that row's time within ``tol`` [s] (one sample per row, the closest)."""
    dt = grid_t[1] - grid_t[0] if grid_t.size > 1 else 1.0
    rows = np.rint((times - grid_t[0]) / dt).astype(np.int64)
    ok = (rows >= 0) & (rows < grid_t.size)
    dist = np.full(times.size, np.inf)
    dist[ok] = np.abs(grid_t[rows[ok]] - times[ok])
    cand = np.flatnonzero(ok & (dist <= tol))
    order = cand[np.lexsort((dist[cand], rows[cand]))]
    first = np.concatenate([[True], rows[order][1:] != rows[order][:-1]]) if order.size else \
        np.zeros(0, dtype=bool)
    which = order[first]
    return rows[which], which


def at_grid_time(grid_t: Array, times: Array, values: Array, rows: NDArray[np.int64],
                 which: NDArray[np.int64], span: float, angle: bool = False) -> Array:
    """(R, C) the samples (times (P,) [s], values (P, C)) at the grid times of ``rows``,
    each row's nearest sample ``which`` (:func:`nearest_samples`) moved to the row's time
    along the straight line to its neighbour on the row's other side,

        y = x_w + (x_o - x_w) (t_row - t_w) / (t_o - t_w),

    when that neighbour is finite and at most ``span`` [s] away, else x_w as it is
    (angles [rad] taken the short way round). A pose sample a few ms from its grid step
    is then read at the step's time, not at its own, and moves with its stamp
    continuously instead of jumping from one step to the next."""
    values = np.asarray(values, dtype=float).reshape(times.size, -1)
    at = grid_t[rows]
    other = np.where(times[which] <= at, which + 1, which - 1)
    inside = (other >= 0) & (other < times.size)
    other = np.clip(other, 0, times.size - 1)
    near = inside & (np.abs(times[other] - times[which]) <= span) & (other != which)
    x_w, x_o = values[which], values[other]
    if angle:
        x_o = x_w + (x_o - x_w + np.pi) % (2 * np.pi) - np.pi
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(near, (at - times[which]) / (times[other] - times[which]), 0.0)
    moved = x_w + frac[:, None] * (x_o - x_w)
    if angle:  # back into (-pi, pi], as every Euler angle pinquad reads
        moved = np.where(np.isfinite(moved), (moved + np.pi) % (2 * np.pi) - np.pi, moved)
    return np.where(near[:, None] & np.isfinite(moved), moved, x_w)


POSE_BRIDGE_S = 0.1
"""Two pose samples at most this far apart [s] are joined by a straight line to read a
pose at its grid step's time; further apart, the nearer sample is taken as it is.
Motion capture over radio arrives in bursts (IMRC: 5 % of its steps over 40 ms)."""


def pose_stream_times(pose_t: Array, row_t: Array, row_clock: Array
                      ) -> tuple[Array, str | None]:
    """((P,) times [s] on the log's clock of a pose stream stamped on its own, a note or
    None): on the stream's frame clock (``io.timebase.frame_clock``: motion capture is
    taken at a fixed rate and frames are lost on the radio, so each pose is placed by its
    frame number, not by its stamp's arrival jitter), else each stamp moved as the rows
    around it are by the rows' clock (row_t (N,) stamps, row_clock (N,) their clock
    times [s])."""
    on_frames = frame_clock(pose_t)
    if on_frames is None:
        return pose_t + np.interp(pose_t, row_t, row_clock - row_t), None
    moved = on_frames - pose_t
    return on_frames, (f"motion capture: poses placed on their frame clock (a fixed-rate "
                       f"stream with frames lost), {np.sqrt(np.mean(moved**2)) * 1e3:.2f} "
                       "ms rms from their stamps")


def poses_on_grid(grid_t: Array, times: Array, position: Array, euler: Array,
                  dt: float) -> tuple[Array, Array]:
    """((K, 3) position [m], (K, 3) Euler angles [rad]) on the grid grid_t (K,) [s]: each
    grid step with a pose sample (times (P,) [s], position and euler (P, 3)) within dt/2
    reads the nearest one at its own time (:func:`at_grid_time`, bridging up to
    ``POSE_BRIDGE_S``); the other steps are NaN (missing samples)."""
    rows, which = nearest_samples(grid_t, times, 0.5 * dt)
    pos = np.full((grid_t.size, 3), np.nan)
    eul = np.full((grid_t.size, 3), np.nan)
    pos[rows] = at_grid_time(grid_t, times, position, rows, which, POSE_BRIDGE_S)
    eul[rows] = at_grid_time(grid_t, times, euler, rows, which, POSE_BRIDGE_S, angle=True)
    return pos, eul


def pose_glitches(x: Array, limit: float, angle: bool = False, half: int = 3) -> BoolArray:
    """(P,) samples further than ``limit`` from the median of their 2*half finite
    neighbours in any component (angles unwrapped first); NaN samples are never
    flagged."""
    p = x.shape[0]
    bad = np.zeros(p, dtype=bool)
    offsets = np.concatenate([np.arange(-half, 0), np.arange(1, half + 1)])
    for c in range(x.shape[1]):
        ok = np.flatnonzero(np.isfinite(x[:, c]))
        if ok.size < 2 * half + 1:
            continue
        col = np.unwrap(x[ok, c]) if angle else x[ok, c]
        idx = np.clip(np.arange(ok.size)[:, None] + offsets[None, :], 0, ok.size - 1)
        bad[ok] |= np.abs(col - np.median(col[idx], axis=1)) > limit
    return bad



def interp_nan(t: Array, x: Array) -> Array:
    """x with NaNs linearly interpolated in t (held at the ends); all-NaN stays NaN."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    if ok.all() or not ok.any():
        return x.copy()
    out = x.copy()
    out[~ok] = np.interp(t[~ok], t[ok], x[ok])
    return out


def fill_rows(t: Array, x: Array) -> Array:
    """(N, C) each column of x (N, C) with NaNs interpolated in t (:func:`interp_nan`)."""
    return np.column_stack([interp_nan(t, x[:, c]) for c in range(x.shape[1])])
