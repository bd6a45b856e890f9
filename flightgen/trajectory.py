"""Smooth reference trajectories: sums of sines or minimum-snap splines through random
waypoints, with an optional take-off from and landing on the floor and dips that make
the vehicle strike it.

A reference is a derivative stack: ``pos`` (5, M, 3) holds position [m], velocity
[m/s], acceleration [m/s^2], jerk [m/s^3] and snap [m/s^4] at M times; ``yaw`` (3, M)
yaw [rad] and its first two derivatives. The peak acceleration of the excursion is
scaled to ``accel_cap`` [m/s^2] (gentle 1.5, aggressive 6).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np
from numpy.polynomial import polynomial as P
from numpy.typing import NDArray

Array = NDArray[np.float64]

KINDS = ("sines", "minsnap")
ORDERS = 5  # position .. snap


@dataclass(frozen=True)
class Reference:
    """pos (5, M, 3) [m, m/s, .., m/s^4], yaw (3, M) [rad, rad/s, rad/s^2] at times t (M,)."""

    t: Array
    pos: Array
    yaw: Array


def _sines(t: Array, n: int, f_lo: float, f_hi: float, rng: np.random.Generator) -> Array:
    """Derivative stack (5, M) of sum_k a_k sin(w_k t + phi_k), a_k = 1 / w_k^2."""
    w = 2 * np.pi * rng.uniform(f_lo, f_hi, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    out = np.zeros((ORDERS, t.size))
    for wk, pk in zip(w, phi, strict=True):
        for d in range(ORDERS):
            out[d] += wk ** (d - 2) * np.sin(wk * t + pk + d * np.pi / 2)
    return out


def _minsnap_1d(waypoints: Array, times: Array) -> list[Array]:
    """Per-segment polynomial coefficients (degree 7, in the segment's local time) of the
    minimum-snap spline through ``waypoints`` at the knots ``times``, at rest (velocity,
    acceleration, jerk zero) at both ends. For fixed knots the optimum is the degree-7
    spline with derivatives 1..6 continuous at interior knots: one square system."""
    s = len(waypoints) - 1
    n = 8 * s
    a = np.zeros((n, n))
    b = np.zeros(n)
    row = 0

    def deriv_row(tau: float, d: int) -> Array:
        r = np.zeros(8)
        for i in range(d, 8):
            r[i] = factorial(i) / factorial(i - d) * tau ** (i - d)
        return r

    for k in range(s):
        h = times[k + 1] - times[k]
        a[row, 8 * k:8 * k + 8] = deriv_row(0.0, 0)
        b[row] = waypoints[k]
        row += 1
        a[row, 8 * k:8 * k + 8] = deriv_row(h, 0)
        b[row] = waypoints[k + 1]
        row += 1
    for d in (1, 2, 3):
        a[row, 0:8] = deriv_row(0.0, d)
        row += 1
        a[row, 8 * (s - 1):8 * s] = deriv_row(times[-1] - times[-2], d)
        row += 1
    for k in range(s - 1):
        h = times[k + 1] - times[k]
        for d in range(1, 7):
            a[row, 8 * k:8 * k + 8] = deriv_row(h, d)
            a[row, 8 * (k + 1):8 * (k + 1) + 8] = -deriv_row(0.0, d)
            row += 1
    coef = np.linalg.solve(a, b)
    return [coef[8 * k:8 * k + 8] for k in range(s)]


def _minsnap(t: Array, waypoints: Array, times: Array) -> Array:
    """Derivative stack (5, M) of the 1-D minimum-snap spline (constant outside)."""
    out = np.zeros((ORDERS, t.size))
    segs = _minsnap_1d(waypoints, times)
    idx = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(segs) - 1)
    for k, c in enumerate(segs):
        sel = idx == k
        tau = np.clip(t[sel] - times[k], 0.0, times[k + 1] - times[k])
        poly = c
        for d in range(ORDERS):
            out[d, sel] = P.polyval(tau, poly)
            poly = P.polyder(poly)
    return out


def _smoothstep(t: Array, t0: float, t1: float) -> Array:
    """Derivative stack (5, M) of the degree-9 step from 0 (t <= t0) to 1 (t >= t1),
    derivatives 1..4 zero at both ends."""
    c = np.array([0, 0, 0, 0, 0, 126, -420, 540, -315, 70], dtype=float)
    h = t1 - t0
    u = np.clip((t - t0) / h, 0.0, 1.0)
    inside = (t > t0) & (t < t1)
    out = np.zeros((ORDERS, t.size))
    out[0] = P.polyval(u, c)
    for d in range(1, ORDERS):
        c = P.polyder(c)
        out[d] = np.where(inside, P.polyval(u, c) / h**d, 0.0)
    return out


def _bump(t: Array, center: float, half_width: float) -> Array:
    """Derivative stack (5, M) of (1 - u^2)^5, u = (t - center) / half_width, 0 for |u| > 1."""
    c = P.polypow([1.0, 0.0, -1.0], 5)
    u = (t - center) / half_width
    inside = np.abs(u) < 1
    out = np.zeros((ORDERS, t.size))
    for d in range(ORDERS):
        out[d] = np.where(inside, P.polyval(u, c) / half_width**d, 0.0)
        c = P.polyder(c)
    return out


def _product(a: Array, b: Array) -> Array:
    """Leibniz: derivative stack of a * b from those of a (5, M) and b (5, M, ...)."""
    out = np.zeros(np.broadcast_shapes(a.shape, b.shape) if a.ndim == b.ndim else b.shape)
    for n in range(ORDERS):
        for k in range(n + 1):
            binom = factorial(n) / (factorial(k) * factorial(n - k))
            ak = a[k] if a.ndim == b.ndim else a[k][:, None]
            out[n] += binom * ak * b[n - k]
    return out


def excursion(t: Array, kind: str, aggressive: bool, rng: np.random.Generator) -> Array:
    """The flight's excursion about its hover point (5, M, 3), zero mean position, peak
    horizontal acceleration scaled to the cap."""
    if kind not in KINDS:
        raise ValueError(f"unknown trajectory kind {kind!r}; expected one of {KINDS}")
    duration = float(t[-1] - t[0])
    out = np.zeros((ORDERS, t.size, 3))
    if kind == "sines":
        f_hi = 0.8 if aggressive else 0.35
        for ax in range(3):
            out[:, :, ax] = _sines(t, 4, 0.08, f_hi, rng)
    else:
        seg = 1.2 if aggressive else 2.5
        s = max(2, int(duration // seg))
        knots = np.linspace(t[0], t[-1], s + 1)
        for ax in range(3):
            wp = rng.uniform(-1.0, 1.0, s + 1)
            out[:, :, ax] = _minsnap(t, wp, knots)
    out[0] -= out[0].mean(axis=0)
    cap = 6.0 if aggressive else 1.5
    horiz = np.abs(out[2, :, :2]).max()
    out[:, :, :2] *= cap / max(horiz, 1e-12)
    vert = np.abs(out[2, :, 2]).max()
    out[:, :, 2] *= 0.4 * cap / max(vert, 1e-12)
    z_span = np.abs(out[0, :, 2]).max()
    if z_span > 0.4:  # keep the vehicle between 0.6 and 1.4 m of a 1 m hover
        out[:, :, 2] *= 0.4 / z_span
    return out


def reference(t: Array, kind: str, aggressive: bool, hover_height: float,
              rng: np.random.Generator, start_on_floor: bool = False, land: bool = False,
              floor_strikes: int = 0) -> Reference:
    """The reference flown at times t (M,) [s]: hover point (0, 0, hover_height) plus the
    excursion, blended from a point below the floor (take-off) and back to it (landing);
    each floor strike is a 1.2 s wide dip that takes the reference 5 cm below the floor."""
    exc = excursion(t, kind, aggressive, rng)
    pos = exc.copy()
    pos[0, :, 2] += hover_height
    t0, t1 = float(t[0]), float(t[-1])
    if floor_strikes:
        centers = np.linspace(t0, t1, floor_strikes + 2)[1:-1]
        for c in centers:
            depth = np.interp(c, t, pos[0, :, 2]) + 0.05
            pos[:, :, 2] -= depth * _bump(t, float(c), 0.6)
    if start_on_floor or land:
        ground = np.zeros((ORDERS, t.size, 3))
        ground[0, :, 2] = -0.03
        ground[0, :, :2] = pos[0, 0, :2]
        env = np.ones((ORDERS, t.size))
        env[1:] = 0.0
        if start_on_floor:
            env = _product(env, _smoothstep(t, t0 + 1.0, t0 + 4.0))
        if land:
            down = _smoothstep(t, t1 - 5.0, t1 - 2.0)
            down[0] = 1.0 - down[0]
            down[1:] *= -1.0
            env = _product(env, down)
        pos = ground + _product(env, pos - ground)
    amp = 0.8 if aggressive else 0.3
    yaw = _sines(t, 2, 0.05, 0.2, rng)[:3] * (amp * (2 * np.pi * 0.1) ** 2)
    return Reference(t=t, pos=pos, yaw=yaw)
