"""The rotors' own angular acceleration sum_i spin_i d(omega_i)/dt [rad/s^2], the regressor
of the rotor-inertia yaw torque J_r sum_i spin_i omega_i' [N m]: per row of a log, and per
bin of the uniform grid the E-step runs on."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pinquad.io.timebase import find_gaps, gap_steps, gap_transitions

Array = NDArray[np.float64]

RAD_S_PER_RPM = 2.0 * math.pi / 60.0


def rotor_acceleration(t: Array, rpm: Array, spin: Sequence[float], held: bool = False
                       ) -> Array:
    """(N,) sum_i spin_i d(omega_i)/dt [rad/s^2] from rotor speeds rpm (N, n) [rev/min] at
    times t (N,) [s]: central differences of sampled readings, NaN where a neighbouring
    interval is a log gap (``pinquad.io.timebase.gap_steps``) or a speed is not finite.

    ``held``: each row's speed holds until the next row (a zero-order hold, the
    simulator's rotor log), so the speed steps at t_i from omega_{i-1} to omega_i and the
    acceleration of the interval from t_i is the backward difference
    (omega_i - omega_{i-1}) / (t_i - t_{i-1}); its mean over a grid bin is then exactly
    the bin's change of speed over dt. A central difference would put half of the next
    row's step, which the closed loop commands in answer to this interval's disturbance,
    into this interval (a simulated quad's I_zz +3.7 % with J_r fitted, +2.2 % without).

    Times J_r [kg m^2] it is the reaction torque of the rotors' own angular acceleration on
    the body about z, tau_z = sum_i spin_i J_r d(omega_i)/dt [N m], with the sign of the
    rotor's drag torque (the motor supplies J_r omega_i' + Q_i to the rotor along its spin
    axis and the body takes the opposite).
    """
    omega = np.asarray(rpm, dtype=float) * RAD_S_PER_RPM
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return np.full(t.size, np.nan)
    step = np.diff(t)
    gap = gap_steps(t)
    if held:
        acc = np.full(t.size, np.nan)
        acc[1:] = (np.diff(omega, axis=0) / step[:, None]) @ np.asarray(spin, dtype=float)
        acc[1:][gap] = np.nan
        return acc
    acc = np.gradient(omega, t, axis=0) @ np.asarray(spin, dtype=float)
    acc[np.concatenate([gap, [False]]) | np.concatenate([[False], gap])] = np.nan
    return acc


def grid_rotor_acceleration(rpm_bins: Array, spin: Sequence[float], dt: float) -> Array:
    """(K,) mean of sum_i spin_i d(omega_i)/dt [rad/s^2] over each bin [t_k, t_k + dt) of a
    uniform grid, from the bins' mean rotor speeds rpm_bins (K, n) [rev/min].

    The mean over the bin is (omega(t_k + dt) - omega(t_k)) / dt; the speed at a bin's edge
    is the average of the means on either side, omega(t_k) ~ (w_{k-1} + w_k) / 2, so

        a_k = sum_i spin_i (w_{k+1,i} - w_{k-1,i}) / (2 dt)

    (one-sided at the ends; NaN next to a bin without speed). Taken from the bin means
    rather than from per-row differences, it is the same number whether the flight is read
    at its logger's rate or from its resampled export, and a logger's clock jitter and its
    rotor readings' sample-to-sample noise (differentiated at ~500 Hz, then averaged over
    a varying count of rows per bin) do not alias into the 3-8 Hz band the yaw M-step fits.
    """
    omega = np.asarray(rpm_bins, dtype=float) * RAD_S_PER_RPM
    if omega.shape[0] < 2:
        return np.full(omega.shape[0], np.nan)
    return np.gradient(omega, dt, axis=0) @ np.asarray(spin, dtype=float)


def held_grid_rotor_acceleration(t: Array, rpm: Array, spin: Sequence[float], grid: Array,
                                 dt: float) -> Array:
    """(K,) mean of sum_i spin_i d(omega_i)/dt [rad/s^2] over each bin [g_k, g_k + dt) of a
    uniform grid (K,) [s], for rotor speeds rpm (N, n) [rev/min] held from each row at
    times t (N,) [s] until the next (a zero-order hold): exactly

        a_k = sum_i spin_i (omega_i(g_k + dt) - omega_i(g_k)) / dt,

    omega(s) the speed of the last row at or before s (the first row's before it). Only
    which row holds at a bin's edge depends on the stamps, so a clock's jitter moves a_k by
    one row's change of speed at most, where per-row differences divide by the jittered
    steps themselves (two rows 30 ns apart: a rotor acceleration 1e5 times too large). NaN
    for bins that overlap a log gap (``pinquad.io.timebase``) or meet a non-finite speed.
    """
    omega = np.asarray(rpm, dtype=float) * RAD_S_PER_RPM
    t = np.asarray(t, dtype=float)
    grid = np.asarray(grid, dtype=float)
    start = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 1)
    end = np.clip(np.searchsorted(t, grid + dt, side="right") - 1, 0, t.size - 1)
    acc = (omega[end] - omega[start]) @ np.asarray(spin, dtype=float) / dt
    acc[gap_transitions(find_gaps(t), grid, dt)] = np.nan
    return acc
