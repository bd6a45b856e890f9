"""Unit checks of single columns a whole-sensor check cannot see, run before any EM.

``pinquad.io.sanity`` tests each sensor as a whole (the gyro's three axes together,
the accelerometer's magnitude, the thrust against a factor-8 band). A unit error in
one column, or a scale a vehicle of another size could explain, passes those; each
test here compares the column with what physics ties it to on this log, names the
column, what it measured and the fix:

1. **each gyro axis against the attitude**: over windows of ``WINDOW_S`` (0.2 s) the
   body rotation vector of R_a^T R_b from the pose against the integral of the gyro,
   fitted as rotvec = M integral(omega dt) with a full 3 x 3 M (least squares over the
   windows); the length beta_k of M's column k is how far the pose turns per radian of
   gyro axis k, in whatever direction (a motion-capture body frame turned against the
   IMU's makes M a rotation, columns of length 1: on the shared IMRC logs a per-axis
   fit read 0.66 on jana05's roll for that reason). An axis whose motion fixes beta_k to
   ``MIN_T_RATIO`` standard errors must turn 1 / beta_k within [1 /
   ``RATIO_TOLERANCE``, ``RATIO_TOLERANCE``] as far as the pose (one axis in deg/s gives
   57.3 there and about 1 on the others; the sign is that of M's diagonal entry). It
   speaks only when another axis agrees: every axis off is the whole sensor's unit,
   which ``sanity``'s gyro-vs-attitude test names;
2. **the torques against the angular acceleration** (logs with thrust and torque
   columns whose vehicle is named, so its inertia J is the vehicle's, not a guess): per
   axis, the rms of d omega / dt against the rms of J^-1 (tau - omega x J omega), both
   smoothed over ``SMOOTH_S`` and detrended over ``DETREND_S`` on a ``GRID_S`` grid,
   decided where the two correlate at least ``MIN_CORRELATION``. Where they correlate
   at least ``STRONG_CORRELATION`` (the torques explain the motion) the ratio must lie
   within [1 / ``TORQUE_FACTOR``, ``TORQUE_FACTOR``] (torques x10 give 0.1; a real
   inertia within a factor 4 of the named vehicle's, the range the verdict allows,
   passes); below it, within [1 / ``WEAK_TORQUE_FACTOR``, ``WEAK_TORQUE_FACTOR``] (N mm
   gives 0.001): a fast controller's commanded torques answer disturbances the log does
   not hold, and the Neural-Swarm flights' commands, read with their vehicle files,
   have 11 to 16 times the rms their angular acceleration needs (correlation at most
   0.47), which no test can tell from torques x10;
3. **a normalised thrust command**: a thrust column that never exceeds 1 and implies,
   by the hover balance of ``sanity.implied_mass``, more than ``NORMALISED_FACTOR``
   times the named vehicle's reference mass (PX4 logs the collective thrust as a 0..1
   command; on a 35 g Crazyflie that reads as +70 % of mass).

A test the log lacks the columns or the motion for is skipped.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from pinquad.core.conventions import rotation_from_euler
from pinquad.core.params import VEHICLES
from pinquad.core.vehicle_file import VehicleFileError, VehicleSpec, is_vehicle_file, load_vehicle
from pinquad.io.conventions_check import smooth
from pinquad.io.errors import Problem
from pinquad.io.logs import FlightLog

Array = NDArray[np.float64]
"""(check, column(s), message) of one failed test."""

WINDOW_S = 0.2
"""Window of the per-axis gyro test [s]: short enough that the rotation vector of a
window is its integrated rate to a few per cent at 6 rad/s."""
MIN_WINDOWS = 5
MIN_T_RATIO = 10.0
"""An axis is judged only when its motion fixes its scale to this many standard errors."""
RATIO_TOLERANCE = 2.0
"""A gyro axis and the pose agree within this factor (deg/s is 57.3)."""
GRID_S, SMOOTH_S, DETREND_S = 0.01, 0.05, 1.0
"""Torque test: grid step, smoothing window (the gyro's noise differentiated) and
detrending window (offsets and slow disturbances) [s]."""
MIN_CORRELATION, STRONG_CORRELATION = 0.3, 0.6
"""The torque test decides an axis only where the torques correlate with the angular
acceleration this much; from the second on it holds them to ``TORQUE_FACTOR``."""
TORQUE_FACTOR = 5.0
"""Torques and the angular acceleration through the named vehicle's inertia agree in
rms within this factor where they explain the motion (x10 lies beyond; the correct
logs lie within 1.7)."""
WEAK_TORQUE_FACTOR = 50.0
"""... and within this factor where they correlate less (N mm and N cm lie beyond, the
Neural-Swarm commands' 16 within)."""
NORMALISED_FACTOR = 1.5
"""A thrust column at most 1 that implies this many times the named vehicle's mass is
a normalised command (0..1), not newtons."""


def _filled(values: Array, t: Array) -> Array | None:
    ok = np.isfinite(values).all(axis=1)
    if ok.sum() < 2:
        return None
    return np.column_stack([np.interp(t, t[ok], values[ok, i]) for i in range(values.shape[1])])


# ------------------------------------------------------------------ 1. gyro per axis

def gyro_axis_ratios(log: FlightLog) -> tuple[float | None, float | None, float | None]:
    """Per body axis, how many times as far the gyro turns as the pose (1 / beta_a of
    test 1), or None where the log lacks gyro or attitude or the axis turns too little
    to tell."""
    none = (None, None, None)
    gyro = _filled(log.gyro, log.t)
    rows = np.flatnonzero(np.isfinite(log.euler).all(axis=1))
    if gyro is None or rows.size < 2:
        return none
    marks = np.arange(log.t[rows[0]], log.t[rows[-1]], WINDOW_S)
    anchors = np.unique(rows[np.minimum(np.searchsorted(log.t[rows], marks), rows.size - 1)])
    a, b = anchors[:-1], anchors[1:]
    if a.size < MIN_WINDOWS:
        return none
    rot = rotation_from_euler(log.euler[anchors])
    rel = np.einsum("wji,wjk->wik", rot[:-1], rot[1:])
    y = Rotation.from_matrix(rel).as_rotvec()
    steps = np.diff(log.t)[:, None] * 0.5 * (gyro[1:] + gyro[:-1])
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
    x = cum[b] - cum[a]
    gram = x.T @ x
    if a.size < MIN_WINDOWS + 3 or not np.linalg.cond(gram) < 1e12:
        return none
    inv = np.linalg.inv(gram)
    fit = np.linalg.solve(gram, x.T @ y).T  # rotvec(pose) = fit @ integral(gyro)
    resid = y - x @ fit.T
    var = np.sum(resid ** 2, axis=0) / max(a.size - 3, 1)  # per pose axis
    out: list[float | None] = []
    for k in range(3):
        norm = float(np.linalg.norm(fit[:, k]))
        se = math.sqrt(float(np.sum(var)) * inv[k, k])
        sign = 1.0 if fit[k, k] >= 0 else -1.0
        out.append(sign / norm if norm > 0 and norm >= MIN_T_RATIO * se else None)
    return out[0], out[1], out[2]


def check_gyro_axes(log: FlightLog) -> Problem | None:
    """Test 1 of the module docstring."""
    ratios = gyro_axis_ratios(log)
    names = ("gyro_x", "gyro_y", "gyro_z")
    bad = [k for k, r in enumerate(ratios)
           if r is not None and not 1 / RATIO_TOLERANCE <= r <= RATIO_TOLERANCE]
    # one column wrong shows against an axis that agrees; all of them wrong is the
    # whole sensor's unit, which sanity's gyro-vs-attitude test names
    if not bad or len(bad) == sum(r is not None for r in ratios):
        return None
    k = bad[0]
    ratio = ratios[k]
    assert ratio is not None
    others = ", ".join(f"{names[j]} {ratios[j]:.3g}" if ratios[j] is not None
                       else f"{names[j]} not decided" for j in range(3) if j != k)
    if 180 / math.pi / 1.5 < ratio < 180 / math.pi * 1.5:
        fix = f"looks like deg/s in {names[k]} (expected rad/s): multiply it by pi/180"
    elif ratio < 0:
        fix = f"{names[k]}'s sign looks flipped: negate it, or check the body axes"
    else:
        fix = f"expected about 1 (rad/s, body axis {'xyz'[k]})"
    return ("gyro-axis", names[k],
            f"column {names[k]!r} turns {ratio:.3g} times as far as the attitude does about "
            f"body {'xyz'[k]} over {WINDOW_S} s windows ({others}); {fix}")


# ------------------------------------------------------------------ 2. torque scale

def _named_file(log: FlightLog) -> VehicleSpec | None:
    """The vehicle file (``.toml``) the log names, or None (none named, a shipped
    vehicle's name, or a file that does not read: its own check names that)."""
    if not log.meta.vehicle_named or not is_vehicle_file(log.meta.vehicle):
        return None
    try:
        return load_vehicle(log.meta.vehicle)
    except VehicleFileError:
        return None


def named_inertia(log: FlightLog) -> Array | None:
    """(3, 3) [kg m^2] inertia of the vehicle the log names (a shipped vehicle, or a
    vehicle file's [reference] inertia, else its body's); None when the log names none
    (a sidecar's guess is not a reference)."""
    if log.meta.vehicle_named and log.meta.vehicle in VEHICLES:
        return np.asarray(VEHICLES[log.meta.vehicle].inertia, dtype=float)
    spec = _named_file(log)
    if spec is None:
        return None
    ref = spec.reference.inertia
    if ref is None:
        return np.asarray(spec.inertia, dtype=float)
    return np.diag(np.asarray(ref, dtype=float))  # [reference] gives the diagonal


def named_mass(log: FlightLog) -> float | None:
    """Mass [kg] of the vehicle the log names (its [reference] mass, else its body's),
    or None."""
    if log.meta.vehicle_named and log.meta.vehicle in VEHICLES:
        return float(VEHICLES[log.meta.vehicle].mass)
    spec = _named_file(log)
    if spec is None:
        return None
    return float(spec.reference.mass if spec.reference.mass is not None else spec.mass)


def torque_scales(log: FlightLog, inertia: Array
                  ) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]] | None:
    """Per body axis (rms ratio, correlation) of the angular acceleration against
    J^-1 (tau - omega x J omega) (test 2), or None without gyro, torques or 3 s of log."""
    gyro = _filled(log.gyro, log.t)
    if gyro is None or log.torque is None or log.t[-1] - log.t[0] < 3 * DETREND_S:
        return None
    grid = np.arange(log.t[0], log.t[-1], GRID_S)
    width = max(int(round(SMOOTH_S / GRID_S)), 1)
    wide = max(int(round(DETREND_S / GRID_S)), 1)
    rate = smooth(np.column_stack([np.interp(grid, log.t, gyro[:, i]) for i in range(3)]), width)
    tau = smooth(np.column_stack([np.interp(grid, log.t, log.torque[:, i]) for i in range(3)]),
                  width)
    accel = np.gradient(rate, GRID_S, axis=0)
    pred = np.linalg.solve(inertia, (tau - np.cross(rate, rate @ inertia.T)).T).T
    accel = (accel - smooth(accel, wide))[wide:-wide]
    pred = (pred - smooth(pred, wide))[wide:-wide]
    out = []
    for k in range(3):
        x, y = pred[:, k], accel[:, k]
        sxx, syy = float(x @ x), float(y @ y)
        if not (sxx > 0 and syy > 0):
            out.append((math.nan, 0.0))
            continue
        out.append((math.sqrt(syy / sxx), float(x @ y) / math.sqrt(sxx * syy)))
    return out[0], out[1], out[2]


def torque_band(corr: float) -> float:
    """The factor the torque test allows at a correlation ``corr`` (module docstring)."""
    return TORQUE_FACTOR if corr >= STRONG_CORRELATION else WEAK_TORQUE_FACTOR


def check_torque_scale(log: FlightLog) -> Problem | None:
    """Test 2 of the module docstring."""
    inertia = named_inertia(log)
    if inertia is None or log.torque is None:
        return None
    scales = torque_scales(log, inertia)
    if scales is None:
        return None
    names = ("torque_x", "torque_y", "torque_z")
    bad = [k for k, (ratio, corr) in enumerate(scales)
           if corr >= MIN_CORRELATION and not 1 / torque_band(corr) <= ratio <= torque_band(corr)]
    if not bad:
        return None
    cols = ", ".join(names[k] for k in bad)
    ratio = scales[bad[0]][0]
    factor = 1.0 / ratio
    words = ""
    strong = scales[bad[0]][1] >= STRONG_CORRELATION
    for unit, scale in (("N mm (expected N m): divide by 1000", 1000.0),
                        ("N cm (expected N m): divide by 100", 100.0),
                        ("10 times N m: divide by 10", 10.0)):
        if strong and scale / 2.0 < factor < scale * 2.0:
            words = f"; looks like {unit}"
            break
    if not strong:  # loosely tied torques: the factor is not a unit's to the digit
        words = ("; the torques explain the motion too loosely to name the unit: check "
                 "that they are in N m")
    diag = ", ".join(f"{v * 1e6:.3g}" for v in np.diag(inertia))
    axes = ", ".join("xyz"[k] for k in bad)
    return ("torque-scale", cols,
            f"{cols} say{'' if len(bad) > 1 else 's'} {factor:.3g} times the torque the gyro's "
            f"angular acceleration about body {axes} needs through vehicle "
            f"{log.meta.vehicle!r}'s inertia ({diag} e-6 kg m^2): rms of d omega/dt over "
            f"rms of J^-1 tau {', '.join(f'{scales[k][0]:.3g}' for k in bad)}, correlation "
            f"{', '.join(f'{scales[k][1]:.2f}' for k in bad)}{words}; expected within a "
            f"factor {torque_band(scales[bad[0]][1]):g} (or name the vehicle these torques "
            "move: sidecar \"vehicle\")")


# ------------------------------------------------------------------ 3. normalised thrust

def check_normalised_thrust(log: FlightLog, implied: float | None) -> Problem | None:
    """Test 3 of the module docstring; ``implied``: the mass [kg] the thrust implies
    (``sanity.implied_mass``)."""
    mass = named_mass(log)
    if log.thrust is None or implied is None or mass is None:
        return None
    top = float(np.max(log.thrust))
    ratio = implied / mass
    if top > 1.0 or ratio <= NORMALISED_FACTOR:
        return None
    words = (f"column 'thrust' never exceeds {top:.3g} and implies a mass of "
             f"{implied * 1e3:.4g} g by the hover balance F cos(tilt) = m (zdd + g), "
             f"{ratio:.3g} times the {mass * 1e3:.4g} g of vehicle {log.meta.vehicle!r}")
    if mass * log.meta.gravity >= 1.0:  # this vehicle's thrust in N exceeds 1 at hover
        return ("thrust-normalised", "thrust",
                f"{words}; looks like a normalised thrust command (0..1, as PX4 logs it), not "
                "newtons: convert it to N through the vehicle's thrust curve, or name the "
                "vehicle that flew (sidecar \"vehicle\" or --vehicle)")
    # a vehicle this light never needs 1 N either: the column's range cannot tell the two
    return ("thrust-normalised", "thrust",
            f"{words}: either the vehicle named is not the one that flew (a file of another "
            "vehicle: name the vehicle that flew, sidecar \"vehicle\" or --vehicle), or the "
            "column is a normalised thrust command (0..1, as PX4 logs it), not newtons "
            "(convert it to N through the vehicle's thrust curve); a vehicle this light "
            "needs less than 1 N, so the column's range does not tell which")


def unit_problems(log: FlightLog, implied: float | None) -> tuple[Problem, ...]:
    """Every failed test of the module docstring but the first (``sanity`` runs
    :func:`check_gyro_axes` before its whole-gyro test), in its order."""
    found = (check_torque_scale(log), check_normalised_thrust(log, implied))
    return tuple(p for p in found if p is not None)
