"""Samples at their own times onto the uniform grid t_k = t_0 + k dt: bin means, the
nearest sample, motion-capture glitches, and gaps filled by interpolation."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

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
