"""Physical sanity checks of a flight log, run at the boundary before any EM.

A log is the record of a rigid vehicle flying in Earth's gravity, so its columns must
agree with each other and with the sidecar; a column in the wrong units (positions in
mm, gyro in deg/s, time in ms, accelerometer in g, thrust in grams-force or negated)
reads as a valid file yet makes EM return a confident wrong answer. Each check below
compares two things physics ties together and names the column, what it looks like and
what was expected. Thresholds (module constants) come from physics, with margins wide
enough that no shipped real log and no simulated flight of the paper's experiment trips
them (``tests/test_bad_input.py`` checks both); a factor-of-two error in one column
passes (it cannot be told from a different vehicle), a unit confusion (x 57.3, x 100,
x 1000, x 9.81, x 102) does not.

Checks, in order (the first failure is reported):

1. rows: at least ``MIN_ROWS`` samples;
2. sample spacing: median dt within [``MIN_DT``, ``MAX_DT``] s (ms or us time stamps
   give a dt 1e3 or 1e6 times too large);
3. sidecar gravity within [``MIN_GRAVITY``, ``MAX_GRAVITY``] m/s^2 (a positive magnitude:
   gravity points along -z by convention);
4. impossible values: inf in a measurement column, or any value beyond ``IMPOSSIBLE``
   (e.g. gyro beyond 1e4 rad/s): a located error (column, rows, value);
   then the conventions the sidecar does not declare (``pinquad.io.conventions_check``:
   attitude vs gyro under each quaternion or Euler reading, gravity along -z, rotor
   speeds vs a hover's thrust, motor order vs angular acceleration) and what the
   sidecar and vehicle file declare (``pinquad.io.declaration_check``: each declared
   convention against the same physics, a positive model-free mass, the vehicle file's
   reference mass and torque-axis signs); when one fails, it is reported and the checks
   below are not run;
5. gyro vs attitude: over windows of ``ATTITUDE_WINDOW_S`` (or ``ATTITUDE_WINDOW_RAD``),
   the body rotation vector of R_a^T R_b from the pose against the integrated gyro,
   fitted as rotvec = beta * integral(omega dt); 1 / beta within [1 / ``RATIO_TOLERANCE``,
   ``RATIO_TOLERANCE``] (deg/s gives 57.3, a flipped sign a negative ratio);
6. positions vs velocities: p_b - p_a = beta * integral(v dt) the same way (mm
   positions give 1000, cm 100; mm/s velocities 1/1000);
7. kinematic acceleration: the 99th percentile of |d^2 p / dt^2| (positions on a
   ``WINDOW_S`` grid) and of |dv/dt| at most ``MAX_KINEMATIC_ACCEL`` (no quadcopter
   pinquad knows accelerates at 6 g; positions and velocities both in mm give 1000x);
8. accelerometer: median |acc| within [``MIN_SPECIFIC_FORCE``, ``MAX_SPECIFIC_FORCE``]
   (a flying or resting vehicle reads about g; units of g read about 1);
9. thrust: positive on average, and the mass it implies, m_hat = sum(F c33 (zdd + g)) /
   sum((zdd + g)^2) (vertical Newton's law, c33 the body z axis' vertical component),
   within a factor ``MASS_FACTOR`` of the named vehicle's nominal mass (grams-force
   thrust gives 102x, kilogram-force 1/9.81); a sidecar ``mass_guess`` more than
   ``MASS_GUESS_FACTOR`` times m_hat looks like grams.

Checks that a log lacks the columns for (no attitude, no velocity, rotor speeds instead
of thrust), or that see too little motion to decide (the fitted scale within ``MIN_T_RATIO`` standard
errors of zero), are skipped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.core.params import VEHICLES
from pinquad.io.actuation_check import actuation_problems
from pinquad.io.declaration_check import convention_problems
from pinquad.io.logs import FlightLog, LogFormatError
from pinquad.io.units_check import check_gyro_axes, unit_problems

Array = NDArray[np.float64]

MIN_ROWS = 50
"""Fewest samples identification accepts: 0.5 s at 100 Hz, about two time constants of
the attitude loop; fewer carry no information on the inertia."""
MIN_DT, MAX_DT = 1e-4, 0.25
"""Median sample spacing [s]: 10 kHz to 4 Hz (the dynamics pinquad fits are 1-10 Hz)."""
MIN_GRAVITY, MAX_GRAVITY = 9.7, 9.9
"""Earth's surface gravity is 9.78-9.83 m/s^2."""
IMPOSSIBLE = {"pos": 1e4, "vel": 1e4, "euler": 1e4, "gyro": 1e4, "acc": 1e4, "thrust": 1e5,
              "torque": 1e4, "rpm": 1e6}
"""Values no flight record can hold whatever its units (|x| beyond these: m, m/s, rad,
rad/s, m/s^2, N, N m, rev/min): corrupt cells, not unit confusions."""
WINDOW_S = 0.1
"""Window over which a velocity is integrated and compared with the position change it
explains, and grid step of the kinematic accelerations [s]."""
ATTITUDE_WINDOW_S, ATTITUDE_WINDOW_RAD = 1.0, 0.5
"""Window over which the gyro is integrated and compared with the attitude change: 1 s,
or less once the pose has turned 0.5 rad (the paper's gentle flights turn about 0.02
rad in 1 s against 0.01 rad of attitude noise per sample; the Crazyflie's yaw sweeps
turn 6 rad/s)."""
MIN_WINDOWS = 5
"""Fewest windows for a ratio check to decide."""
MIN_T_RATIO = 10.0
"""A ratio check decides only when the log's motion fixes the scale to this many
standard errors (a hovering vehicle's noise does not)."""
RATIO_TOLERANCE = 2.0
"""A rate and the change it explains agree within this factor (unit errors are 57, 100,
1000)."""
MAX_KINEMATIC_ACCEL = 6.0 * 9.81
"""Largest acceleration [m/s^2] (99th percentile): the Crazyflie's thrust-to-weight is
about 2, the paper's vehicle is capped at 2.5; 6 g leaves a margin."""
MIN_SPECIFIC_FORCE, MAX_SPECIFIC_FORCE = 0.5 * 9.81, 2.0 * 9.81
"""Median accelerometer magnitude [m/s^2]: g at rest and in hover, within a factor 2."""
MASS_FACTOR = 8.0
"""The mass the thrust implies lies within this factor of the named vehicle's nominal
mass (the paper's 0.18 kg and the Crazyflie's 0.035 kg differ by 5.2; grams-force is 102,
kilogram-force 1/9.81)."""
MASS_GUESS_FACTOR = 30.0
"""A mass_guess this many times heavier than the thrust implies is in grams (guesses err
low: the paper starts at 1 g for 180 g)."""


class ImplausibleLogError(LogFormatError):
    """A readable log whose columns contradict physics (wrong units, impossible values)."""


@dataclass(frozen=True)
class Finding:
    """One failed check: check name, column(s) concerned, message."""

    check: str
    column: str
    message: str


def _filled(values: Array, t: Array) -> Array | None:
    """Columns (N, k) with NaN rows interpolated in time, or None with < 2 samples."""
    ok = np.isfinite(values).all(axis=1)
    if ok.sum() < 2:
        return None
    return np.column_stack([np.interp(t, t[ok], values[ok, i]) for i in range(values.shape[1])])


def _windows(t: Array, ok: NDArray[np.bool_]) -> tuple[Array, Array]:
    """Window bounds (row a, row b): rows with a sample, about WINDOW_S apart."""
    rows = np.flatnonzero(ok)
    starts, stops, last = [], [], None
    for r in rows:
        if last is None:
            last = r
        elif t[r] - t[last] >= WINDOW_S:
            starts.append(last)
            stops.append(r)
            last = r
    return np.array(starts, dtype=int), np.array(stops, dtype=int)


def _attitude_windows(t: Array, euler: Array) -> tuple[Array, Array]:
    """Window bounds (row a, row b) over rows with an attitude: a window closes after
    ATTITUDE_WINDOW_S or once the pose has turned ATTITUDE_WINDOW_RAD from its start (a
    rotation vector is unambiguous below pi)."""
    rows = np.flatnonzero(np.isfinite(euler).all(axis=1))
    rot = rotation_from_euler(euler[rows])
    starts, stops, first = [], [], 0
    for k in range(1, rows.size):
        rel = rot[first].T @ rot[k]
        angle = math.acos(min(1.0, max(-1.0, 0.5 * (float(np.trace(rel)) - 1.0))))
        if t[rows[k]] - t[rows[first]] >= ATTITUDE_WINDOW_S or angle >= ATTITUDE_WINDOW_RAD:
            starts.append(rows[first])
            stops.append(rows[k])
            first = k
    return np.array(starts, dtype=int), np.array(stops, dtype=int)


def _integral(rate: Array, t: Array, a: Array, b: Array) -> Array:
    """(W, 3) integral of ``rate`` (N, 3) from row a to row b (trapezoid)."""
    steps = np.diff(t)[:, None] * 0.5 * (rate[1:] + rate[:-1])
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
    return cum[b] - cum[a]


def _scale(response: Array, regressor: Array) -> float | None:
    """Least-squares scale beta of response ~ beta * regressor over windows (W, 3), or
    None when the windows do not determine it to MIN_T_RATIO standard errors (too little
    motion). The regressor is the integrated rate (low noise), the response the noisier
    change it explains, so the noise of the response averages out without bias."""
    with np.errstate(all="ignore"):
        keep = np.isfinite(response).all(axis=1) & np.isfinite(regressor).all(axis=1)
        x, y = regressor[keep], response[keep]
        sxx = float(np.sum(x * x))
        if keep.sum() < MIN_WINDOWS or not sxx > 0.0:
            return None
        beta = float(np.sum(x * y)) / sxx
        resid = float(np.sum((y - beta * x) ** 2)) / max(y.size - 1, 1)
        se = math.sqrt(resid / sxx)
    if not math.isfinite(beta) or abs(beta) < MIN_T_RATIO * se:
        return None
    return beta


def _unit_words(ratio: float, named: dict[float, str]) -> str:
    for factor, words in named.items():
        if factor / 3.0 < ratio < factor * 3.0:
            return f"; looks like {words}"
    return ""


def _attitude(log: FlightLog) -> tuple[Array, str] | None:
    if np.isfinite(log.euler).all(axis=1).sum() >= 2:
        return log.euler, "the attitude (quat_* or roll/pitch/yaw)"
    if log.onboard is not None and np.isfinite(log.onboard[:, 6:9]).all(axis=1).sum() >= 2:
        return log.onboard[:, 6:9], "the onboard attitude estimate (est_roll/pitch/yaw)"
    return None


def _rotation_vectors(euler: Array, a: Array, b: Array) -> Array:
    """(W, 3) body-frame rotation vector of R_a^T R_b [rad]."""
    rot = rotation_from_euler(euler)
    rel = np.einsum("wji,wjk->wik", rot[a], rot[b])
    vee = 0.5 * np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0],
                          rel[:, 1, 0] - rel[:, 0, 1]], axis=1)
    angle = np.arccos(np.clip(0.5 * (np.trace(rel, axis1=1, axis2=2) - 1.0), -1.0, 1.0))
    sin = np.linalg.norm(vee, axis=1)
    with np.errstate(all="ignore"):
        scale = np.where(sin > 1e-12, angle / sin, 1.0)
    return vee * scale[:, None]


def gyro_ratio(log: FlightLog) -> float | None:
    """How many times as far the gyro turns as the attitude (1 / beta of check 5), or
    None when the log lacks gyro or attitude, or turns too little to tell."""
    att = _attitude(log)
    gyro = _filled(log.gyro, log.t)
    if att is None or gyro is None:
        return None
    euler = att[0]
    a, b = _attitude_windows(log.t, euler)
    if a.size < MIN_WINDOWS:
        return None
    beta = _scale(_rotation_vectors(euler, a, b), _integral(gyro, log.t, a, b))
    return None if beta is None else 1.0 / beta


def position_velocity_ratio(log: FlightLog) -> float | None:
    """How many times as far the positions move as the velocities integrate to (beta of
    check 6), or None without both or with too little motion."""
    vel = _filled(log.velocity, log.t)
    ok = np.isfinite(log.position).all(axis=1)
    if vel is None or ok.sum() < 2:
        return None
    a, b = _windows(log.t, ok)
    if a.size < MIN_WINDOWS:
        return None
    return _scale(log.position[b] - log.position[a], _integral(vel, log.t, a, b))


def _check_gyro(log: FlightLog) -> Finding | None:
    ratio = gyro_ratio(log)
    if ratio is None or 1 / RATIO_TOLERANCE <= ratio <= RATIO_TOLERANCE:
        return None
    att = _attitude(log)
    where = att[1] if att is not None else "the attitude"
    words = _unit_words(ratio, {180 / math.pi: "deg/s (expected rad/s)",
                                math.pi / 180: "rad/s scaled as deg"})
    if ratio < 0:
        words = "; the gyro's sign looks flipped"
    return Finding("gyro-vs-attitude", "gyro_x, gyro_y, gyro_z",
                   f"gyro_x, gyro_y, gyro_z turn {ratio:.3g} times as far as {where} over the "
                   f"same windows of up to {ATTITUDE_WINDOW_S} s{words}; expected about 1 "
                   "(gyro in rad/s, body frame)")


def _check_position_velocity(log: FlightLog) -> Finding | None:
    ratio = position_velocity_ratio(log)
    if ratio is None or 1 / RATIO_TOLERANCE <= ratio <= RATIO_TOLERANCE:
        return None
    words = _unit_words(ratio, {1000.0: "positions in millimetres", 100.0: "positions in "
                                "centimetres", 1e-3: "velocities in mm/s",
                                1e-2: "velocities in cm/s"})
    if ratio < 0:
        words = "; one of them has its sign flipped"
    return Finding("position-vs-velocity", "pos_*, vel_*",
                   f"pos_x/y/z move {ratio:.3g} times as far as vel_x/y/z integrate to over "
                   f"the same {WINDOW_S} s windows{words}; expected about 1 (m and m/s)")


def _kinematic_accel(values: Array, t: Array, order: int) -> float | None:
    """99th percentile of |d^order values / dt^order| [units / s^order] on a WINDOW_S grid."""
    filled = _filled(values, t)
    if filled is None or t[-1] - t[0] < 3 * WINDOW_S:
        return None
    grid = np.arange(t[0], t[-1], WINDOW_S)
    pts = np.column_stack([np.interp(grid, t, filled[:, i]) for i in range(3)])
    deriv = np.diff(pts, n=order, axis=0) / WINDOW_S ** order
    return float(np.percentile(np.linalg.norm(deriv, axis=1), 99))


def _check_kinematics(log: FlightLog) -> Finding | None:
    for values, order, column in ((log.position, 2, "pos_x, pos_y, pos_z"),
                                  (log.velocity, 1, "vel_x, vel_y, vel_z")):
        accel = _kinematic_accel(values, log.t, order)
        if accel is not None and accel > MAX_KINEMATIC_ACCEL:
            # the kinematics alone cannot tell cm from mm on a gentle flight
            words = ("; looks like centimetres or millimetres (expected metres)"
                     if accel / 1000.0 <= MAX_KINEMATIC_ACCEL else "")
            return Finding("kinematic-acceleration", column,
                           f"{column} imply an acceleration of {accel:.3g} m/s^2 (99th "
                           f"percentile), beyond the {MAX_KINEMATIC_ACCEL:.0f} m/s^2 (6 g) a "
                           f"quadcopter can reach{words}")
    return None


def specific_force(log: FlightLog) -> float | None:
    """Median accelerometer magnitude [m/s^2 if SI] (check 8), None without samples."""
    ok = np.isfinite(log.accel).all(axis=1)
    if ok.sum() < MIN_WINDOWS:
        return None
    return float(np.median(np.linalg.norm(log.accel[ok], axis=1)))


def _check_accelerometer(log: FlightLog) -> Finding | None:
    median = specific_force(log)
    if median is None or MIN_SPECIFIC_FORCE <= median <= MAX_SPECIFIC_FORCE:
        return None
    words = _unit_words(median, {1.0: "units of g (expected m/s^2)"})
    return Finding("accelerometer-magnitude", "acc_x, acc_y, acc_z",
                   f"acc_x/y/z have median magnitude {median:.3g}{words}; a vehicle at rest "
                   f"or in flight reads about g = 9.81 m/s^2 (body specific force)")


def implied_mass(log: FlightLog) -> float | None:
    """Mass [kg] the thrust implies by vertical Newton's law, F c33 = m (zdd + g), fitted
    by least squares on a WINDOW_S grid; None without thrust, positions or time span."""
    if log.thrust is None:
        return None
    z = _filled(log.position, log.t)
    if z is None or log.t[-1] - log.t[0] < 3 * WINDOW_S:
        return None
    att = _attitude(log)
    c33 = np.ones(log.n) if att is None else rotation_from_euler(
        np.nan_to_num(_filled(att[0], log.t)))[:, 2, 2]
    grid = np.arange(log.t[0], log.t[-1], WINDOW_S)
    zg = np.interp(grid, log.t, z[:, 2])
    zdd = np.diff(zg, n=2) / WINDOW_S ** 2
    lift = np.interp(grid, log.t, log.thrust * c33)[1:-1]
    support = zdd + log.meta.gravity
    return float(np.dot(lift, support) / np.dot(support, support))


def _check_thrust(log: FlightLog) -> Finding | None:
    if log.thrust is None:
        return None
    mean = float(np.mean(log.thrust))
    if mean <= 0.0:
        return Finding("thrust-sign", "thrust",
                       f"thrust has mean {mean:.3g} N; thrust along body +z holds the vehicle "
                       "up and is positive (sign flipped?)")
    mass = implied_mass(log)
    vehicle = VEHICLES.get(log.meta.vehicle)
    if mass is None or vehicle is None:
        return None
    ratio = mass / vehicle.mass
    if not 1 / MASS_FACTOR <= ratio <= MASS_FACTOR:
        words = _unit_words(ratio, {1000 / 9.81: "grams-force (expected N)",
                                    1 / 9.81: "kilogram-force (expected N)"})
        return Finding("thrust-vs-weight", "thrust",
                       f"thrust implies a mass of {mass:.4g} kg by F cos(tilt) = m (zdd + g), "
                       f"{ratio:.3g} times the {vehicle.mass} kg of vehicle "
                       f"'{vehicle.name}'{words}; expected within a factor {MASS_FACTOR:g} (set "
                       "the sidecar's vehicle if it is another one)")
    guess = log.meta.mass_guess
    if guess is not None and guess > MASS_GUESS_FACTOR * mass:
        return Finding("mass-guess", "mass_guess",
                       f"sidecar mass_guess {guess:g} is {guess / mass:.3g} times the "
                       f"{mass:.4g} kg the thrust implies; looks like grams (expected kg)")
    return None


def _check_impossible(log: FlightLog) -> Finding | None:
    xyz = "xyz"
    groups = [("pos", log.position, [f"pos_{a}" for a in xyz]),
              ("vel", log.velocity, [f"vel_{a}" for a in xyz]),
              ("euler", log.euler, ["roll (or quat_*)", "pitch (or quat_*)", "yaw (or quat_*)"]),
              ("gyro", log.gyro, [f"gyro_{a}" for a in xyz]),
              ("acc", log.accel, [f"acc_{a}" for a in xyz])]
    if log.thrust is not None:
        groups.append(("thrust", log.thrust[:, None], ["thrust"]))
    if log.torque is not None:
        groups.append(("torque", log.torque, [f"torque_{a}" for a in xyz]))
    if log.rpm is not None:
        groups.append(("rpm", log.rpm, [f"rpm_{i}" for i in range(1, log.rpm.shape[1] + 1)]))
    for kind, values, names in groups:
        with np.errstate(invalid="ignore"):
            bad = np.isinf(values) | (np.abs(values) > IMPOSSIBLE[kind])
        if not bad.any():
            continue
        rows, cols = np.nonzero(bad)
        column = names[cols[0]]
        listed = ", ".join(str(r + 1) for r in rows[:5]) + (" ..." if rows.size > 5 else "")
        return Finding("impossible-value", column,
                       f"column {column!r}, row(s) {listed} ({rows.size} cell(s)): "
                       f"{float(values[rows[0], cols[0]])!r} is beyond any flight "
                       f"(magnitude at most {IMPOSSIBLE[kind]:g} in SI units); expected a "
                       "finite measurement or an empty cell")
    return None


@dataclass(frozen=True)
class Evidence:
    """What the checks measured on a log (None: not applicable or not decided).

    gyro_ratio: gyro turn / attitude turn [-]; position_velocity_ratio: position change /
    integrated velocity [-]; position_accel, velocity_accel: 99th percentile of the
    kinematic acceleration [m/s^2]; specific_force: median |acc| [m/s^2]; implied_mass:
    mass the thrust implies [kg]; dt: median sample spacing [s].
    """

    dt: float
    gyro_ratio: float | None
    position_velocity_ratio: float | None
    position_accel: float | None
    velocity_accel: float | None
    specific_force: float | None
    implied_mass: float | None


def evidence(log: FlightLog) -> Evidence:
    """The numbers behind the checks, for reports and the correct-log test."""
    return Evidence(log.dt, gyro_ratio(log), position_velocity_ratio(log),
                    _kinematic_accel(log.position, log.t, 2),
                    _kinematic_accel(log.velocity, log.t, 1), specific_force(log),
                    implied_mass(log))


def findings(log: FlightLog) -> tuple[Finding, ...]:
    """Every failed check of the module docstring, in its order (empty: the log is
    physically plausible). Checks after the first failure of rows, spacing or impossible
    values are not run (their inputs are not trustworthy)."""
    n = log.n
    if n < MIN_ROWS:
        return (Finding("rows", "t", f"{n} row(s); identification needs at least {MIN_ROWS} "
                        "samples (0.5 s at 100 Hz)"),)
    dt = log.dt
    if not MIN_DT <= dt <= MAX_DT:
        words = ""
        if MIN_DT <= dt * 1e-3 <= MAX_DT:
            words = "; looks like milliseconds"
        elif MIN_DT <= dt * 1e-6 <= MAX_DT:
            words = "; looks like microseconds"
        return (Finding("sample-spacing", "t",
                        f"column 't' has a median step of {dt:.6g}{words}; expected seconds "
                        f"with a step between {MIN_DT:g} and {MAX_DT:g} s"),)
    out: list[Finding] = []
    g = log.meta.gravity
    if not MIN_GRAVITY <= g <= MAX_GRAVITY:
        words = " (gravity is a positive magnitude; it points along -z)" if g < 0 else ""
        out.append(Finding("gravity", "gravity",
                           f"the sidecar's key 'gravity' is {g:g}{words}; expected Earth's "
                           f"{MIN_GRAVITY}-{MAX_GRAVITY} m/s^2"))
    impossible = _check_impossible(log)
    if impossible is not None:
        return (*out, impossible)
    # a dead, stuck or falsely declared rotor channel makes the rotor tests below misread
    channels = actuation_problems(log)
    if channels:
        return (*out, *(Finding(*found) for found in channels))
    # an undeclared convention read wrong makes the unit checks below meaningless
    conventions = convention_problems(log)
    if conventions:
        return (*out, *(Finding(*found) for found in conventions))
    axis = check_gyro_axes(log)  # one gyro column wrong: named before the whole sensor
    if axis is not None:
        out.append(Finding(*axis))
    for check in (_check_gyro, _check_position_velocity, _check_kinematics,
                  _check_accelerometer, _check_thrust):
        found = check(log)
        if found is not None:
            out.append(found)
    # single columns the whole-sensor checks above cannot see (pinquad.io.units_check)
    out.extend(Finding(*found) for found in unit_problems(log, implied_mass(log)))
    return tuple(out)


def check_log(log: FlightLog) -> None:
    """Raise ImplausibleLogError (naming the log, the column, what it looks like and what
    was expected) on the first failed check; return silently when all pass."""
    found = findings(log)
    if found:
        first = found[0]
        more = f" ({len(found) - 1} more check(s) failed)" if len(found) > 1 else ""
        raise ImplausibleLogError(f"{log.meta.source}: {first.message}{more}")
