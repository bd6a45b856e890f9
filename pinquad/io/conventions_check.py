"""Physical tests of the conventions a log's sidecar does not declare
(``pinquad.io.declared``), run before any EM by ``pinquad.io.sanity.findings``.

A log written in another logger's conventions reads as a valid file: an NED/FRD world,
a quaternion in scalar-last order or of the inverse rotation, Euler angles in degrees or
another order, rotor speeds in rad/s, motors numbered from another corner. Each test
below compares two things physics ties together, tries the declarable alternatives on
the same data, and names only what it tried:

1. **attitude vs gyro** (attitude not declared): over windows of ``WINDOW_S`` the body
   rotation vector of R_a^T R_b is fitted as beta * integral(gyro dt) (R^2: the share of
   its variance the fit explains). When the attitude as read does not agree (beta outside
   [1 / ``RATIO_TOLERANCE``, ``RATIO_TOLERANCE``], R^2 below ``MIN_R2``, or beta not
   decided to ``MIN_T_RATIO`` standard errors), the alternatives are fitted: for
   quaternion columns the scalar-last order, the inverse rotation and both (and, to tell
   an inverse rotation from a negated gyro, the gyro negated); for roll/pitch/yaw columns
   every Tait-Bryan order in rad and deg. An alternative that agrees is named with the
   sidecar key that declares it. Roll beyond pi or pitch beyond pi/2 (plus
   ``RANGE_MARGIN``) are not radians of any Tait-Bryan order: degrees are named when the
   angles / 57.3 are in range.
2. **gravity along -z** (frame not declared): the accelerometer's specific force reads
   +g along body z in hover and along world z once rotated by the attitude (ENU/FLU).
   Both medians below -``DOWN_SHARE`` of the median |acc| is a z-down frame (NED/FRD);
   body up and world down is an attitude that turns z over.
3. **rotor speeds vs the thrust a hover needs** (rotor_speed not declared): through the
   rotor model the rpm columns are read with (the named vehicle file's, else
   crazyflie21's), the 90th-percentile row's thrust sum k_f omega^2 against the model
   vehicle's weight m g, within [1 / ``THRUST_FACTOR``, ``THRUST_FACTOR``]; rad/s is named
   when the same speeds read as rad/s are within it.
4. **motor order vs angular acceleration** (motor_order not declared): the roll and
   pitch torques of the rotor model, tau_x = sum y_i T_i, tau_y = -sum x_i T_i, against the
   gyro's derivative (both on a ``GRID_S`` grid, smoothed over ``SMOOTH_S``, their
   ``DETREND_S`` moving average removed); the mean of
   the two correlations is compared for every numbering of the rpm columns. Another
   numbering that correlates above ``MIN_CORRELATION`` and by ``CORRELATION_MARGIN`` more
   than the columns as read is named.

Each test returns ``(check, column, message)`` or None (passed, not applicable, or too
little motion to decide: nothing is said then). The motor test runs only when the
others pass (it leans on the gyro's frame and the rotor speeds' unit); the order, with
the tests of what the sidecar and vehicle file do declare, is
``pinquad.io.declaration_check.convention_problems``'s.
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from pinquad.core.conventions import GRAVITY, rotation_from_euler
from pinquad.core.vehicle_file import VehicleFileError, VehicleSpec, is_vehicle_file, load_vehicle
from pinquad.io.declared import (
    BODY_SWAP,
    EULER_ORDERS,
    EULER_UNITS,
    QUATERNION_ORDERS,
    QUATERNION_ROTATIONS,
    WORLD_SWAP,
    Conventions,
    euler_of_rotation,
    quat_of_rotation,
    rotation_of_euler,
    rotation_of_quat,
)
from pinquad.io.errors import Problem
from pinquad.io.logs import FlightLog

Array = NDArray[np.float64]

WINDOW_S = 0.2
"""Window [s] over which the gyro is integrated and compared with the attitude change
(a Crazyflie's 6 rad/s yaw sweep turns 1.2 rad in it, below pi)."""
MIN_WINDOWS = 5
MIN_T_RATIO = 10.0
"""The attitude test decides only when beta is fixed to this many standard errors."""
RATIO_TOLERANCE = 2.0
MIN_R2 = 0.5
"""The attitude agrees with the gyro when the fit explains at least half the rotation."""
RANGE_MARGIN = 0.1
"""[rad] beyond pi (roll) or pi/2 (pitch) before angles are not radians."""
DOWN_SHARE = 0.5
THRUST_FACTOR = 5.0
"""Hover thrust from the rotor speeds within this factor of the model vehicle's weight
(rad/s for rev/min gives (2 pi / 60)^2 = 1/91)."""
GRID_S, SMOOTH_S, DETREND_S = 0.01, 0.03, 1.0
"""Grid [s], smoothing window [s] and the window [s] of the moving average removed from
torques and angular accelerations (the rotors' steady imbalance and trim)."""
MIN_CORRELATION, CORRELATION_MARGIN = 0.3, 0.2
MAX_ROTORS = 6
"""Numberings tried: n! (720 for a hexacopter)."""


# ------------------------------------------------------------------ attitude vs gyro

def filled(values: Array, t: Array) -> Array | None:
    """Columns (N, k) with NaN rows interpolated in time, or None with < 2 samples."""
    ok = np.isfinite(values).all(axis=1)
    if ok.sum() < 2:
        return None
    return np.column_stack([np.interp(t, t[ok], values[ok, i]) for i in range(values.shape[1])])


def _windows(t: Array, rows: Array) -> tuple[Array, Array]:
    """(a, b) attitude rows about WINDOW_S apart."""
    marks = np.arange(t[rows[0]], t[rows[-1]], WINDOW_S)
    anchors = np.unique(rows[np.minimum(np.searchsorted(t[rows], marks), rows.size - 1)])
    return anchors[:-1], anchors[1:]


def agreement(t: Array, rot: Array, gyro: Array) -> tuple[float, float] | None:
    """(beta, R^2) of rotvec(R_a^T R_b) = beta * integral(gyro dt) over windows, for
    rotations rot (N, 3, 3) (NaN rows: no attitude) and gyro (N, 3) [rad/s]; None when
    too few windows or beta is not decided (module docstring, test 1)."""
    rows = np.flatnonzero(np.isfinite(rot).all(axis=(1, 2)))
    rates = filled(gyro, t)
    if rows.size < 2 or rates is None:
        return None
    a, b = _windows(t, rows)
    if a.size < MIN_WINDOWS:
        return None
    rel = np.einsum("wji,wjk->wik", rot[a], rot[b])
    y = Rotation.from_matrix(rel).as_rotvec()
    steps = np.diff(t)[:, None] * 0.5 * (rates[1:] + rates[:-1])
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
    x = cum[b] - cum[a]
    sxx, syy = float(np.sum(x * x)), float(np.sum(y * y))
    if not (sxx > 0 and syy > 0):
        return None
    beta = float(np.sum(x * y)) / sxx
    resid = float(np.sum((y - beta * x) ** 2))
    se = math.sqrt(resid / max(y.size - 1, 1) / sxx)
    if abs(beta) < MIN_T_RATIO * se:
        return None
    return beta, 1.0 - resid / syy


def agrees(fit: tuple[float, float] | None) -> bool:
    """Whether an ``agreement`` fit says the attitude follows the gyro (test 1's bounds)."""
    return fit is not None and 1 / RATIO_TOLERANCE <= fit[0] <= RATIO_TOLERANCE \
        and fit[1] >= MIN_R2


def rotations(euler: Array, make) -> Array:
    """(N, 3, 3) rotations ``make`` builds from the finite rows of euler (N, 3); NaN
    elsewhere."""
    ok = np.isfinite(euler).all(axis=1)
    out = np.full((euler.shape[0], 3, 3), np.nan)
    if ok.any():
        out[ok] = make(euler[ok])
    return out


def _declared_rotations(euler: Array, conv: Conventions) -> Array:
    """(N, 3, 3) the attitude as read, back in the declared frame (NaN rows kept)."""
    rot = rotations(euler, rotation_from_euler)
    return WORLD_SWAP @ rot @ BODY_SWAP if conv.frame == "NED/FRD" else rot


def _in_pinquads_frame(rot: Array, conv: Conventions) -> Array:
    return WORLD_SWAP @ rot @ BODY_SWAP if conv.frame == "NED/FRD" else rot


def attitude_readings(euler: Array, conv: Conventions, every: bool = False
                      ) -> dict[str, tuple[Array, str]]:
    """Readings of the attitude columns other than the one read: words -> (rotations
    (N, 3, 3) in pinquad's frames, the sidecar declaration that reads them so). The
    columns are rebuilt from the attitude as read with the reader's own conversion
    (``pinquad.io.declared``), then read each other way: every undeclared reading, or
    with ``every`` also those that contradict the sidecar's quaternion or Euler keys (the
    frame stays as declared)."""
    rot = _declared_rotations(euler, conv)
    ok = np.isfinite(rot).all(axis=(1, 2))
    out: dict[str, tuple[Array, str]] = {}
    if not ok.any():
        return out
    if conv.attitude_columns == "quat":
        order0, turn0 = conv.quaternion_order or "wxyz", conv.quaternion_rotation or "body_to_world"
        cols = quat_of_rotation(rot[ok], order0, turn0)
        orders = QUATERNION_ORDERS if every or conv.quaternion_order is None else (order0,)
        turns = QUATERNION_ROTATIONS if every or conv.quaternion_rotation is None \
            else (turn0,)
        for order, turn in itertools.product(orders, turns):
            if (order, turn) == (order0, turn0):
                continue
            words = " and ".join(w for w in (
                "the quaternion columns in x, y, z, w order" if order == "xyzw" else "",
                "the quaternion of the inverse rotation (world to body)"
                if turn == "world_to_body" else "") if w) or "the quaternion columns as w, x, y, z"
            new = np.full_like(rot, np.nan)
            new[ok] = _in_pinquads_frame(rotation_of_quat(cols, order, turn), conv)
            out[words] = (new, json.dumps({"quaternion": {"order": order, "rotation": turn}}))
    else:
        order0, unit0 = conv.euler_order or "ZYX", conv.euler_unit or "rad"
        if conv.frame != "NED/FRD" and order0 == "ZYX":
            # the reader scaled a unit alone exactly (unwrapped): undo it the same way
            cols = euler[ok] * (180.0 / math.pi if unit0 == "deg" else 1.0)
        else:
            cols = euler_of_rotation(rot[ok], order0, unit0)
        orders = [o for o in EULER_ORDERS if o.isupper()] \
            if every or conv.euler_order is None else [order0]
        units = EULER_UNITS if every or conv.euler_unit is None else (unit0,)
        for order, unit in itertools.product(orders, units):
            if (order, unit) == (order0, unit0):
                continue
            new = np.full_like(rot, np.nan)
            new[ok] = _in_pinquads_frame(rotation_of_euler(cols, order, unit), conv)
            out[f"roll, pitch, yaw as {order} angles in {unit}"] = (new, json.dumps(
                {"euler": {"order": order, "unit": unit}}))
    return out


def _degrees_by_range(log: FlightLog) -> Problem | None:
    e = log.euler[np.isfinite(log.euler).all(axis=1)]
    if e.size == 0 or log.meta.conventions.euler_unit is not None:
        return None
    roll, pitch = float(np.max(np.abs(e[:, 0]))), float(np.max(np.abs(e[:, 1])))
    if roll <= math.pi + RANGE_MARGIN and pitch <= math.pi / 2 + RANGE_MARGIN:
        return None
    fits = (math.radians(roll) <= math.pi + RANGE_MARGIN
            and math.radians(pitch) <= math.pi / 2 + RANGE_MARGIN)
    words = ("; in degrees they are in range: declare \"euler\": {\"unit\": \"deg\"} in the "
             "sidecar" if fits else "; read as degrees they are out of range too")
    return ("euler-range", "roll, pitch",
            f"roll reaches {roll:.4g} and pitch {pitch:.4g}, beyond the pi and pi/2 rad any "
            f"Tait-Bryan angles stay within{words}")


def check_attitude(log: FlightLog) -> Problem | None:
    """Test 1 of the module docstring."""
    conv = log.meta.conventions
    if conv.attitude_columns == "euler" and (found := _degrees_by_range(log)):
        return found
    if conv.attitude_columns not in ("quat", "euler"):
        return None
    as_read = agreement(log.t, rotations(log.euler, rotation_from_euler), log.gyro)
    if agrees(as_read):
        return None
    alternatives = attitude_readings(log.euler, conv)
    fits = {name: agreement(log.t, rot, log.gyro) for name, (rot, _) in alternatives.items()}
    good = [name for name, fit in fits.items() if agrees(fit)]
    if not good:
        return None  # no declarable alternative: the units and sign checks speak
    best = max(good, key=lambda name: fits[name][1])  # type: ignore[index]
    beta, r2 = fits[best]  # type: ignore[misc]
    column = "quat_w, quat_x, quat_y, quat_z" if conv.attitude_columns == "quat" \
        else "roll, pitch, yaw"
    fit = ("its turn does not follow the gyro's at all" if as_read is None else
           f"it turns {as_read[0]:.3g} times as far as the integrated gyro (R^2 "
           f"{as_read[1]:.2f})")
    msg = (f"the gyro does not agree with the attitude ({column}) as read: over "
           f"{WINDOW_S} s windows {fit}; with {best} it turns {beta:.3g} times "
           f"as far (R^2 {r2:.2f}): declare {alternatives[best][1]} in the sidecar")
    if conv.attitude_columns == "quat" and "inverse" in best:
        flipped = agreement(log.t, rotations(log.euler, rotation_from_euler), -log.gyro)
        if agrees(flipped):
            msg += (f"; the gyro negated fits as well (R^2 {flipped[1]:.2f}: the flight turns "
                    "too little about the vertical to tell them apart), so either may be the "
                    "cause")
    return ("attitude-convention", column, msg)


# ------------------------------------------------------------------ gravity along -z

def check_gravity_direction(log: FlightLog) -> Problem | None:
    """Test 2 of the module docstring."""
    if log.meta.conventions.frame is not None:
        return None
    acc_ok = np.isfinite(log.accel).all(axis=1)
    if acc_ok.sum() < MIN_WINDOWS:
        return None
    scale = float(np.median(np.linalg.norm(log.accel[acc_ok], axis=1)))
    body = float(np.median(log.accel[acc_ok, 2]))
    euler = filled(log.euler, log.t)
    world = None
    if euler is not None:
        rot = rotation_from_euler(euler[acc_ok])
        world = float(np.median(np.einsum("nij,nj->ni", rot, log.accel[acc_ok])[:, 2]))
    down = -DOWN_SHARE * scale
    if body < down and (world is None or world < down):
        where = "" if world is None else f" and {world:.3g} along world z once rotated by the " \
            "attitude"
        return ("gravity-direction", "acc_x, acc_y, acc_z",
                f"the accelerometer reads {body:.3g} m/s^2 along body z (median){where}; in "
                "pinquad's frames (world east-north-up, body forward-left-up) the specific "
                "force of a hovering or flying vehicle points along +z: z points down, as in "
                "PX4's and ArduPilot's NED/FRD frames: declare \"frame\": \"NED/FRD\" in the "
                "sidecar")
    if world is not None and body > -down and world < down:
        return ("gravity-direction", "acc_x, acc_y, acc_z",
                f"the accelerometer reads {body:.3g} m/s^2 along body z (median), up as "
                f"expected, but {world:.3g} along world z once rotated by the attitude: the "
                "attitude turns the body upside down; check the sidecar's \"quaternion\" or "
                "\"euler\" declaration")
    return None


# ------------------------------------------------------------------ rotor speeds

def rotor_model(log: FlightLog) -> VehicleSpec | None:
    """The vehicle whose rotor model reads the log's rpm columns: the named vehicle file,
    else crazyflie21 (as the rotor-speed path does); None when it has no actuators."""
    name = log.meta.vehicle if is_vehicle_file(log.meta.vehicle) else "crazyflie21"
    try:
        spec = load_vehicle(name)
    except VehicleFileError:
        return None
    return spec if spec.actuators is not None else None


def hover_thrust_ratio(log: FlightLog, spec: VehicleSpec, factor: float = 1.0) -> float:
    """The 90th-percentile row's thrust sum k_f (factor * omega)^2 over the model
    vehicle's weight m g [-] (omega from the rpm columns in rev/min)."""
    omega = log.rpm * factor * 2.0 * math.pi / 60.0
    thrust = spec.actuators.kf * np.sum(omega ** 2, axis=1)  # type: ignore[union-attr]
    return float(np.percentile(thrust, 90)) / (spec.mass * GRAVITY)


def check_rotor_speed(log: FlightLog) -> Problem | None:
    """Test 3 of the module docstring."""
    if log.rpm is None or log.meta.conventions.rotor_speed is not None:
        return None
    spec = rotor_model(log)
    if spec is None:
        return None
    ratio = hover_thrust_ratio(log, spec)
    if 1 / THRUST_FACTOR <= ratio <= THRUST_FACTOR:
        return None
    as_rad = hover_thrust_ratio(log, spec, 60.0 / (2.0 * math.pi))
    words = (f"; read as rad/s they give {as_rad:.3g} times: declare \"rotor_speed\": "
             "\"rad/s\" in the sidecar" if 1 / THRUST_FACTOR <= as_rad <= THRUST_FACTOR
             else "")
    return ("rotor-speed", "rpm_*",
            f"rpm_* (rev/min) give {ratio:.3g} times the thrust a hover of vehicle "
            f"'{spec.name}' ({spec.mass * 1e3:.4g} g) needs through its rotor model "
            f"(90th-percentile row){words}; expected within a factor {THRUST_FACTOR:g} (or "
            "name the vehicle whose rotors these are: sidecar \"vehicle\")")


# ------------------------------------------------------------------ motor order

def smooth(x: Array, width: int) -> Array:
    """Moving average of each column of x (N, k) over ``width`` samples (same length)."""
    kernel = np.ones(width) / width
    return np.column_stack([np.convolve(x[:, i], kernel, mode="same") for i in range(x.shape[1])])


def torque_correlations(log: FlightLog, spec: VehicleSpec) -> dict[tuple[int, ...], float]:
    """For every numbering p of the rpm columns (column i is motor p[i]), the mean
    correlation of the rotor model's roll and pitch torques with the gyro's derivative
    (module docstring, test 4)."""
    gyro = filled(log.gyro, log.t)
    n = log.rpm.shape[1]  # type: ignore[union-attr]
    if gyro is None or n > MAX_ROTORS or spec.positions.shape[0] != n \
            or log.t[-1] - log.t[0] < 20 * SMOOTH_S:
        return {}
    grid = np.arange(log.t[0], log.t[-1], GRID_S)
    width = max(int(round(SMOOTH_S / GRID_S)), 1)
    rate = smooth(np.column_stack([np.interp(grid, log.t, gyro[:, i]) for i in range(3)]), width)
    accel = np.gradient(rate, GRID_S, axis=0)[width:-width, :2]
    omega = log.rpm * 2.0 * math.pi / 60.0  # type: ignore[operator]
    thrust = smooth(np.column_stack([np.interp(grid, log.t, spec.actuators.kf * omega[:, i] ** 2)
                                      for i in range(n)]), width)[width:-width]
    arms = np.column_stack([spec.positions[:, 1], -spec.positions[:, 0]])  # (n, 2)
    wide = max(int(round(DETREND_S / GRID_S)), 1)
    thrust, accel = thrust - smooth(thrust, wide), accel - smooth(accel, wide)
    out = {}
    for perm in itertools.permutations(range(1, n + 1)):
        torque = thrust @ arms[np.asarray(perm) - 1]
        corr = [np.corrcoef(torque[:, k], accel[:, k])[0, 1] for k in range(2)]
        out[perm] = float(np.mean(np.nan_to_num(corr)))
    return out


def check_motor_order(log: FlightLog) -> Problem | None:
    """Test 4 of the module docstring."""
    if log.rpm is None or log.meta.conventions.motor_order is not None:
        return None
    spec = rotor_model(log)
    scores = {} if spec is None else torque_correlations(log, spec)
    if not scores:
        return None
    identity = tuple(range(1, log.rpm.shape[1] + 1))
    best = max(scores, key=scores.__getitem__)
    if best == identity or scores[best] < MIN_CORRELATION \
            or scores[best] - scores[identity] < CORRELATION_MARGIN:
        return None
    return ("motor-order", "rpm_*",
            f"the roll and pitch torques of rpm_* through vehicle '{spec.name}''s rotor layout "  # type: ignore[union-attr]
            f"correlate {scores[identity]:.2f} with the gyro's angular acceleration as "
            f"numbered; numbered {list(best)} they correlate {scores[best]:.2f}: declare "
            f"\"motor_order\": {list(best)} in the sidecar (column rpm_i holds motor k_i)")
