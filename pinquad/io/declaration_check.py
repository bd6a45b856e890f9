"""Physical tests of what a log's sidecar and vehicle file declare, run before any EM by
``pinquad.io.sanity.findings`` after the tests of what they leave out
(``pinquad.io.conventions_check``).

A declaration is read as true (``pinquad.io.declared``): a false one turns a valid log
into another flight. Each test below reads the log as declared, asks physics, and when
physics disagrees names the declaration, the sidecar or vehicle file, the evidence and
the reading that fits, never another key:

1. **attitude declaration** (sidecar ``"quaternion"`` or ``"euler"``): read as declared,
   the attitude must follow the integrated gyro (``conventions_check.agreement``, 0.2 s
   windows, ratio 1/2 to 2, R^2 >= 0.5) and keep the specific force up (below); every
   reading of the same columns is tried, the declared one included, and the one that
   fits both is named.
2. **frame declaration** (sidecar ``"frame"``): read in the frame declared, the
   accelerometer's specific force of a hovering or flying vehicle points along +z, in the
   body (median acc_z) and once rotated by the attitude (median (R acc)_z); both below
   -``DOWN_SHARE`` of the median |acc| say the log was written in the other frame.
   Whatever is declared, a specific force up in the body and down in the world is an
   attitude that turns the body over; with rotor speeds or thrust, the model-free mass
   m_bal = sum(F c33) / sum(g + z'') [kg] (F the thrust or the rotor model's sum kf
   omega^2, c33 the body z axis' vertical component, z'' the vertical acceleration of
   the positions on a ``BALANCE_S`` grid, over rows with every rotor at flight speed;
   undecided unless sum(g + z'') is within a factor 2 of the weight, as the accelerations
   of a flight telescope to its end and start velocities) must be positive.
3. **rotor-speed unit** (sidecar ``"rotor_speed"``): the hover-thrust ratio of
   ``conventions_check.check_rotor_speed`` on the speeds as declared, within a factor
   ``THRUST_FACTOR``; the other unit is named when it fits.
4. **motor order** (sidecar ``"motor_order"``): the roll and pitch torques'
   correlation with the angular acceleration (``conventions_check.torque_correlations``)
   for every renumbering of the columns as declared; a numbering that correlates above
   ``MIN_CORRELATION`` and by ``CORRELATION_MARGIN`` more than the declared one is
   named, in the file's column terms.
5. **the vehicle file** (a ``.toml`` named by ``--vehicle`` or the sidecar, with
   rotor speeds): over rows with every rotor at flight speed (the file's
   ``[faults] flight_rpm``, else half the hover speed of its reference mass), for
   ``AXIS_MIN_S`` s at least,
   the correlation of each torque axis of the file's rotor model (roll sum y_i T_i,
   pitch -sum x_i T_i, yaw yaw_ratio sum spin_i T_i; smoothed and detrended as in test 4)
   with the gyro's derivative; an axis whose correlation is below -``AXIS_CORRELATION``
   and negative in at least ``AXIS_BLOCKS_NEGATIVE`` of ``BLOCKS`` contiguous blocks (a
   sign test: 5.5 % by chance for a torque that says nothing) contradicts the file's
   ``geometry`` (spin for yaw, positions for roll and pitch). Before it, the model-free
   mass m_bal (test 2) against the file's reference mass (else body mass): a ratio beyond
   ``MASS_FILE_FACTOR`` either way is a file of another vehicle (its kf or mass), or a
   load no multirotor of that mass lifts and still flies.

Each test returns ``(check, column, message)`` or None (passed, not declared, not
applicable, or too little motion to decide).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import GRAVITY, rotation_from_euler
from pinquad.core.vehicle_file import VehicleSpec, is_vehicle_file
from pinquad.io.conventions_check import (
    CORRELATION_MARGIN,
    DETREND_S,
    DOWN_SHARE,
    GRID_S,
    MIN_CORRELATION,
    SMOOTH_S,
    THRUST_FACTOR,
    WINDOW_S,
    agreement,
    agrees,
    attitude_readings,
    check_attitude,
    check_gravity_direction,
    check_motor_order,
    check_rotor_speed,
    filled,
    hover_thrust_ratio,
    rotations,
    rotor_model,
    smooth,
    torque_correlations,
)
from pinquad.io.declared import Conventions
from pinquad.io.errors import Problem
from pinquad.io.logs import FlightLog

Array = NDArray[np.float64]

BALANCE_S = 0.1
"""Grid [s] of the model-free mass's vertical accelerations."""
MIN_BALANCE_S = 5.0
"""Fewest seconds at flight speed for the model-free mass to decide."""
AXIS_MIN_S = 5.0
"""Fewest seconds at flight speed for the torque-axis test to decide."""
AXIS_CORRELATION = 0.1
"""A torque axis contradicts the file below -this correlation (the weakest correct axis
on the shared logs is +0.19: jana00's yaw)."""
BLOCKS, AXIS_BLOCKS_NEGATIVE = 10, 8
"""Contiguous blocks of the sign test, and how many must correlate negatively (on the
shared logs with their files every axis correlates positively in 9 or 10 blocks)."""
MASS_FILE_FACTOR = 1.5
"""The model-free mass lies within this factor of the vehicle file's reference mass: a
multirotor carries at most about half its own mass and still flies (the Crazyflie 2.1:
15 g on 27 g); a lighter vehicle than its own file is no load at all."""
QUAT_COLUMNS = "quat_w, quat_x, quat_y, quat_z"


@dataclass(frozen=True)
class Upright:
    """The specific force in the log as read: body (median acc_z) and world (median (R
    acc)_z) [m/s^2], the median |acc| [m/s^2]; world None without an attitude."""

    body: float
    world: float | None
    scale: float

    @property
    def down(self) -> float:
        return -DOWN_SHARE * self.scale


def upright(log: FlightLog, rot: Array | None = None) -> Upright | None:
    """The specific force's direction (``Upright``) with the attitude as read (or ``rot``
    (N, 3, 3)); None with too few accelerometer rows."""
    ok = np.isfinite(log.accel).all(axis=1)
    if ok.sum() < 5:
        return None
    scale = float(np.median(np.linalg.norm(log.accel[ok], axis=1)))
    body = float(np.median(log.accel[ok, 2]))
    if rot is None:
        euler = filled(log.euler, log.t)
        rot = None if euler is None else rotation_from_euler(euler)
    world = None
    if rot is not None:
        good = ok & np.isfinite(rot).all(axis=(1, 2))
        if good.sum() >= 5:
            world = float(np.median(np.einsum("nij,nj->ni", rot[good], log.accel[good])[:, 2]))
    return Upright(body, world, scale)


def flight_speed(spec: VehicleSpec) -> float:
    """[rev/min] the file's flight speed, else half the hover speed of its reference (else
    body) mass, sqrt(m g / (n kf)) (``realdata.observation_options.options_for_vehicle``)."""
    if spec.faults.flight_rpm is not None:
        return float(spec.faults.flight_rpm)
    mass = spec.reference.mass if spec.reference.mass is not None else spec.mass
    hover = math.sqrt(mass * GRAVITY / (spec.n_rotors * spec.actuators.kf))  # type: ignore[union-attr]
    return 0.5 * hover * 60.0 / (2.0 * math.pi)


def _airborne(log: FlightLog, spec: VehicleSpec, t: Array) -> Array:
    """(len(t),) bool: every rotor at the file's flight speed at times t."""
    rpm = filled(log.rpm, log.t)  # type: ignore[arg-type]
    if rpm is None:
        return np.zeros(t.size, bool)
    speeds = np.column_stack([np.interp(t, log.t, rpm[:, i]) for i in range(rpm.shape[1])])
    return np.all(speeds >= flight_speed(spec), axis=1)


def model_free_mass(log: FlightLog, rot: Array | None = None,
                    spec: VehicleSpec | None = None) -> float | None:
    """m_bal [kg] of test 2 with the attitude as read (or ``rot`` (N, 3, 3)), the force
    from the rotor speeds through ``spec``'s rotor model when given, else the thrust
    column, else the rotor speeds through the log's rotor model (``rotor_model``); None
    without them, positions or ``MIN_BALANCE_S`` s to use."""
    if spec is None and log.thrust is not None:
        force = np.asarray(log.thrust, float)
    elif log.rpm is not None and (spec := spec or rotor_model(log)) is not None \
            and spec.actuators is not None and spec.positions.shape[0] == log.rpm.shape[1]:
        omega = filled(log.rpm, log.t)
        if omega is None:
            return None
        force = spec.actuators.kf * np.sum((omega * 2.0 * math.pi / 60.0) ** 2, axis=1)  # type: ignore[union-attr]
    else:
        return None
    pos = filled(log.position, log.t)
    if rot is None:
        euler = filled(log.euler, log.t)
        rot = None if euler is None else rotation_from_euler(euler)
    if pos is None or rot is None or log.t[-1] - log.t[0] < MIN_BALANCE_S:
        return None
    c33 = filled(rot[:, 2, 2][:, None], log.t)
    if c33 is None:
        return None
    grid = np.arange(log.t[0], log.t[-1], BALANCE_S)
    lift = np.interp(grid, log.t, force * c33[:, 0])[1:-1]
    zdd = np.diff(np.interp(grid, log.t, pos[:, 2]), n=2) / BALANCE_S ** 2
    use = np.ones(lift.size, bool) if spec is None else _airborne(log, spec, grid)[1:-1]
    support = float(np.sum(zdd[use] + log.meta.gravity))
    weight = float(use.sum() * log.meta.gravity)
    # over a flight the accelerations telescope to (end - start) velocity: far from the
    # weight they are positions in other units, whose own test speaks
    if use.sum() * BALANCE_S < MIN_BALANCE_S or not 0.5 * weight <= support <= 2.0 * weight:
        return None
    return float(np.sum(lift[use]) / support)


def _mass_words(mass: float | None) -> str:
    """The model-free mass as evidence of an attitude upside down (said when not positive)."""
    return "" if mass is None or mass > 0 else f"; the model-free mass (mean vertical " \
        f"force over g) is {mass * 1e3:.4g} g, where a vehicle's is positive"


# ------------------------------------------------------------------ 1. attitude

def _attitude_declaration(conv: Conventions) -> dict:
    key = "quaternion" if conv.attitude_columns == "quat" else "euler"
    return {key: conv.sidecar()[key]} if key in conv.sidecar() else {}


def _fits(log: FlightLog, rot: Array) -> tuple[tuple[float, float] | None, Upright | None, bool]:
    """(gyro agreement, specific force, whether both fit) of one reading."""
    fit = agreement(log.t, rot, log.gyro)
    up = upright(log, rot)
    upside_down = up is not None and up.world is not None and up.body > -up.down \
        and up.world < up.down
    return fit, up, agrees(fit) and not upside_down


def check_declared_attitude(log: FlightLog) -> Problem | None:
    """Test 1 of the module docstring."""
    conv = log.meta.conventions
    declared = _attitude_declaration(conv)
    if not declared:
        return None
    rot = rotations(log.euler, rotation_from_euler)
    fit, up, ok = _fits(log, rot)
    if ok or (fit is None and (up is None or up.world is None)):
        return None
    readings = attitude_readings(log.euler, conv, every=True)
    good = {}
    for name, (alt, side) in readings.items():
        alt_fit, alt_up, alt_ok = _fits(log, alt)
        if alt_ok:
            good[name] = (alt_fit, alt_up, side)
    column = QUAT_COLUMNS if conv.attitude_columns == "quat" else "roll, pitch, yaw"
    said = json.dumps(declared)[1:-1]
    flipped = up is not None and up.world is not None and up.world < up.down \
        and up.body > -up.down
    if not good and not flipped:
        return None  # no reading fits: the gyro's units or frame, whose tests speak
    how = ("its turn does not follow the gyro's" if fit is None else
           f"it turns {fit[0]:.3g} times as far as the integrated gyro over {WINDOW_S} s "
           f"windows (R^2 {fit[1]:.2f})")
    if flipped:
        how += (f" and turns the body upside down (the accelerometer's {up.body:.3g} m/s^2 "  # type: ignore[union-attr]
                f"along body z reads {up.world:.3g} along world z)")  # type: ignore[union-attr]
    how += _mass_words(model_free_mass(log, rot))
    if not good:
        return ("attitude-declaration", column,
                f"the sidecar says {said}, and the log contradicts it: read so, the attitude "
                f"({column}): {how}; no other reading of these columns fits either: check the "
                f"sidecar's {next(iter(declared))!r} key and the gyro's units and frame")
    best = max(good, key=lambda n: good[n][0][1])
    best_fit, best_up, side = good[best]
    keys = json.loads(side)
    pinquads = keys in ({"quaternion": {"order": "wxyz", "rotation": "body_to_world"}},
                        {"euler": {"order": "ZYX", "unit": "rad"}})
    fix = (f"remove the sidecar's {next(iter(declared))!r} key (or declare {side[1:-1]})"
           if pinquads else f"declare {side[1:-1]} in the sidecar instead")
    return ("attitude-declaration", column,
            f"the sidecar says {said}, and the log contradicts it: read so, the attitude "
            f"({column}): {how}; with {best} it turns {best_fit[0]:.3g} times as far (R^2 "
            f"{best_fit[1]:.2f}) and keeps the specific force up: {fix}")


# ------------------------------------------------------------------ 2. frame

def check_declared_frame(log: FlightLog) -> Problem | None:
    """Test 2 of the module docstring: a frame declaration the gravity contradicts, and
    (whatever is declared) a model-free mass that is not positive."""
    conv = log.meta.conventions
    up = upright(log)
    if conv.frame is not None and up is not None and up.body < up.down \
            and (up.world is None or up.world < up.down):
        other = "ENU/FLU" if conv.frame == "NED/FRD" else "NED/FRD"
        # in the file's own columns: the two frames' z axes are each other's negatives
        world = "" if up.world is None else f" and its attitude turns that to {-up.world:.3g} " \
            "along world z"
        sense, expected = ("up", "-z (z down)") if conv.frame == "NED/FRD" else ("down", "+z")
        fix = ("remove the key (ENU/FLU is pinquad's own) or declare \"frame\": \"ENU/FLU\""
               if other == "ENU/FLU" else "declare \"frame\": \"NED/FRD\" in the sidecar")
        return ("frame-declaration", "acc_x, acc_y, acc_z",
                f"the sidecar says \"frame\": \"{conv.frame}\"; the log's gravity and "
                f"attitude say {other}: acc_z reads {-up.body:.3g} m/s^2 (median){world}, the "
                f"specific force pointing {sense}, while in {conv.frame} that of a hovering or "
                f"flying vehicle points along {expected}{_mass_words(model_free_mass(log))}: "
                f"{fix}")
    mass = model_free_mass(log)
    if mass is None or mass > 0 or (log.thrust is not None and not np.mean(log.thrust) > 0):
        return None  # a negative thrust is the thrust's sign, whose own test speaks
    said = conv.sidecar()
    keys = {k: v for k, v in said.items() if k in ("frame", "quaternion", "euler")}
    words = (f"the sidecar's {json.dumps(keys)[1:-1]}" if keys else
             "the attitude columns read in pinquad's conventions (nothing declared)")
    return ("model-free-mass", "thrust" if log.thrust is not None else "rpm_*",
            f"the model-free mass (mean vertical force over g) is {mass * 1e3:.4g} g, not "
            f"positive: with {words} the thrust points down on average; the attitude or the "
            "frame is read upside down")


# ------------------------------------------------------------------ 3. rotor speeds

def check_declared_rotor_speed(log: FlightLog) -> Problem | None:
    """Test 3 of the module docstring."""
    declared = log.meta.conventions.rotor_speed
    if log.rpm is None or declared is None:
        return None
    spec = rotor_model(log)
    if spec is None:
        return None
    ratio = hover_thrust_ratio(log, spec)
    if 1 / THRUST_FACTOR <= ratio <= THRUST_FACTOR:
        return None
    # read as the other unit: rad/s columns were multiplied by 60 / (2 pi) on reading
    factor = 2.0 * math.pi / 60.0 if declared == "rad/s" else 60.0 / (2.0 * math.pi)
    other = "rev/min" if declared == "rad/s" else "rad/s"
    alt = hover_thrust_ratio(log, spec, factor)
    if not 1 / THRUST_FACTOR <= alt <= THRUST_FACTOR:
        return None  # neither unit: not the declaration's doing (another vehicle?)
    fix = ("remove the key (rev/min is pinquad's own)" if other == "rev/min"
           else "declare \"rotor_speed\": \"rad/s\"")
    return ("rotor-speed-declaration", "rpm_*",
            f"the sidecar says \"rotor_speed\": \"{declared}\", and the log contradicts it: "
            f"read so, rpm_* give {ratio:.3g} times the thrust a hover of vehicle "
            f"'{spec.name}' ({spec.mass * 1e3:.4g} g) needs through its rotor model "
            f"(90th-percentile row); read as {other} they give {alt:.3g} times (expected "
            f"within a factor {THRUST_FACTOR:g}): {fix}")


# ------------------------------------------------------------------ 4. motor order

def check_declared_motor_order(log: FlightLog) -> Problem | None:
    """Test 4 of the module docstring."""
    declared = log.meta.conventions.motor_order
    if log.rpm is None or declared is None:
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
    # as read, column j is motor j; the best says as-read column j is motor best[j-1]; the
    # file's column c was placed at declared[c]
    right = [best[k - 1] for k in declared]
    fix = ("remove the key (the columns are in the vehicle's numbering)"
           if right == list(identity) else f"declare \"motor_order\": {right}")
    return ("motor-order-declaration", "rpm_*",
            f"the sidecar says \"motor_order\": {list(declared)}, and the log contradicts it: "
            f"numbered so, the roll and pitch torques of rpm_* through vehicle "
            f"'{spec.name}''s rotor layout correlate {scores[identity]:.2f} with the gyro's "  # type: ignore[union-attr]
            f"angular acceleration; numbered {right} they correlate {scores[best]:.2f}: {fix}")


# ------------------------------------------------------------------ 5. the vehicle file

@dataclass(frozen=True)
class AxisEvidence:
    """Correlations (3,) of the file's roll, pitch and yaw torques with the angular
    acceleration, how many of ``BLOCKS`` contiguous blocks correlate negatively (3,), and
    the seconds used."""

    correlation: Array
    negative_blocks: NDArray[np.int_]
    seconds: float


def axis_correlations(log: FlightLog, spec: VehicleSpec) -> AxisEvidence | None:
    """Test 5's correlations over rows with every rotor at flight speed; None without
    rotor speeds matching the file or ``AXIS_MIN_S`` s to use."""
    gyro = filled(log.gyro, log.t)
    if log.rpm is None or gyro is None or spec.actuators is None \
            or spec.positions.shape[0] != log.rpm.shape[1] or log.t[-1] - log.t[0] < 2 * DETREND_S:
        return None
    rpm = filled(log.rpm, log.t)
    if rpm is None:
        return None
    grid = np.arange(log.t[0], log.t[-1], GRID_S)
    width = max(int(round(SMOOTH_S / GRID_S)), 1)
    core = slice(width, -width)
    rate = smooth(np.column_stack([np.interp(grid, log.t, gyro[:, i]) for i in range(3)]), width)
    accel = np.gradient(rate, GRID_S, axis=0)[core]
    omega = rpm * 2.0 * math.pi / 60.0
    thrust = smooth(np.column_stack([np.interp(grid, log.t, spec.actuators.kf * omega[:, i] ** 2)
                                     for i in range(rpm.shape[1])]), width)[core]
    wide = max(int(round(DETREND_S / GRID_S)), 1)
    thrust, accel = thrust - smooth(thrust, wide), accel - smooth(accel, wide)
    arms = np.column_stack([spec.positions[:, 1], -spec.positions[:, 0],
                            spec.actuators.yaw_ratio * spec.spin])
    torque = thrust @ arms
    use = _airborne(log, spec, grid)[core]
    if use.sum() * GRID_S < AXIS_MIN_S:
        return None
    x, y = torque[use], accel[use]
    corr = np.array([_corr(x[:, k], y[:, k]) for k in range(3)])
    blocks = np.array_split(np.arange(x.shape[0]), BLOCKS)
    each = np.array([[_corr(x[b, k], y[b, k]) for k in range(3)] for b in blocks])
    return AxisEvidence(corr, np.sum(each < 0, axis=0), float(use.sum() * GRID_S))


def _corr(a: Array, b: Array) -> float:
    sa, sb = float(np.std(a)), float(np.std(b))
    return 0.0 if not (sa > 0 and sb > 0) else float(np.mean((a - a.mean()) * (b - b.mean()))
                                                     / (sa * sb))


def _file_spec(log: FlightLog) -> VehicleSpec | None:
    return rotor_model(log) if is_vehicle_file(log.meta.vehicle) and log.rpm is not None \
        else None


def check_vehicle_geometry(log: FlightLog) -> Problem | None:
    """Test 5's torque axes: the file's spins (yaw) and rotor positions (roll, pitch)."""
    spec = _file_spec(log)
    ev = None if spec is None else axis_correlations(log, spec)
    if ev is None:
        return None
    bad = [k for k in (2, 0, 1) if ev.correlation[k] < -AXIS_CORRELATION
           and ev.negative_blocks[k] >= AXIS_BLOCKS_NEGATIVE]
    if not bad:
        return None
    k = bad[0]
    axis = ("roll", "pitch", "yaw")[k]
    key = ("'geometry.spin' (or the [[rotor]] spins)" if k == 2 else
           "'geometry.layout' and its rotor numbering (or the [[rotor]] x, y)")
    what = ("tau_z = yaw_ratio sum_i spin_i T_i" if k == 2 else
            "tau_x = sum_i y_i T_i" if k == 0 else "tau_y = -sum_i x_i T_i")
    fix = (f"the spins are of the other sense: {[-int(s) for s in spec.spin]} fits this log"  # type: ignore[union-attr]
           if k == 2 else "the rotors are not where the file puts them")
    return ("vehicle-geometry", "rpm_*",
            f"the vehicle file {spec.source} contradicts the log: its key {key} gives a {axis} "  # type: ignore[union-attr]
            f"torque ({what}) that correlates {ev.correlation[k]:.2f} with the gyro's {axis} "
            f"acceleration over {ev.seconds:.0f} s at flight speed (negatively in "
            f"{ev.negative_blocks[k]} of {BLOCKS} stretches of it); "
            f"a torque drives its acceleration (positive correlation): {fix}")


def check_vehicle_mass(log: FlightLog) -> Problem | None:
    """Test 5's hover balance against the file's reference mass."""
    spec = _file_spec(log)
    mass = None if spec is None else model_free_mass(log, spec=spec)
    if mass is None or mass <= 0:
        return None
    ref = spec.reference.mass if spec.reference.mass is not None else spec.mass  # type: ignore[union-attr]
    key = "[reference] mass" if spec.reference.mass is not None else "[body] mass"  # type: ignore[union-attr]
    if log.meta.payload_mass > 0:  # a declared load flies with the vehicle
        ref += log.meta.payload_mass
        key += f" plus the declared payload {log.meta.payload_mass * 1e3:.4g} g"
    ratio = mass / ref
    if 1 / MASS_FILE_FACTOR <= ratio <= MASS_FILE_FACTOR:
        return None
    load = (f"or the vehicle carries {(mass - ref) * 1e3:.3g} g, more than a multirotor "
            "lifts and still flies" if ratio > 1 else "a vehicle is not lighter than itself")
    return ("vehicle-mass", "rpm_*",
            f"the vehicle file {spec.source} contradicts the log: through its rotor model "  # type: ignore[union-attr]
            f"(kf {spec.actuators.kf:.4g} N/(rad/s)^2) the rotor speeds hold up "  # type: ignore[union-attr]
            f"{mass * 1e3:.4g} g (model-free mass: mean vertical force over g, rows at flight "
            f"speed), {ratio:.3g} times its {key} {ref * 1e3:.4g} g (expected within a factor "
            f"{MASS_FILE_FACTOR:g}): a file of another vehicle (its kf or its mass), {load}; "
            "give this vehicle's file (--vehicle FILE), its flying mass as [reference] mass, "
            "or the load it carries (--payload-mass KG)")


def convention_problems(log: FlightLog) -> tuple[Problem, ...]:
    """The failed tests of the conventions, declared (this module) and undeclared
    (``pinquad.io.conventions_check``): the first of the attitude and gravity tests
    (declared first: a false declaration is named before what it makes look wrong), the
    first of the rotor-speed tests; when both pass, the first motor-order test, then the
    vehicle file's (each leans on the gyro's frame and the rotor speeds' unit)."""
    out: list[Problem] = []
    for group in ((check_declared_attitude, check_attitude, check_declared_frame,
                   check_gravity_direction),
                  (check_declared_rotor_speed, check_rotor_speed)):
        found = _first(log, group)
        if found is not None:
            out.append(found)
    if not out:
        found = _first(log, (check_declared_motor_order, check_motor_order,
                             check_vehicle_mass, check_vehicle_geometry))
        if found is not None:
            out.append(found)
    return tuple(out)


def _first(log: FlightLog, checks: tuple) -> Problem | None:
    for check in checks:
        found = check(log)
        if found is not None:
            return found
    return None
