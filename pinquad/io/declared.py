"""What a log's JSON sidecar declares about how its columns were written, read once at
the reading boundary.

pinquad's own conventions (``pinquad.core.conventions``): world ENU (z up), body FLU
(x forward, y left, z up), quaternions ``quat_w, quat_x, quat_y, quat_z`` of the
body-to-world rotation, Euler angles ``roll, pitch, yaw`` [rad] of the intrinsic z-y-x
sequence, rotor speeds ``rpm_1..`` [rev/min] in the vehicle's motor numbering. A sidecar
may declare that its log was written otherwise (:class:`Conventions`):

* ``"frame": "ENU/FLU"`` or ``"NED/FRD"`` (PX4, ArduPilot: world north-east-down, body
  forward-right-down). World vectors v (pos_*, vel_*) become ``P_w v`` with
  ``P_w = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]`` (x_ENU = y_NED = east, y_ENU = x_NED =
  north, z_ENU = -z_NED); body vectors (gyro_*, acc_*, torque_*) become ``P_b v``
  with ``P_b = diag(1, -1, -1)``; the body-to-world rotation R becomes ``P_w R P_b``.
  ``thrust`` is the magnitude along the thrust axis [N] in both frames, unchanged. Both
  P are proper rotations and their own inverses, so the conversion is exact and the
  same map takes pinquad's frames to NED/FRD (:func:`to_declared`).
* ``"quaternion": {"order": "wxyz" | "xyzw", "rotation": "body_to_world" |
  "world_to_body"}``: ``order`` is what the four columns quat_w, quat_x, quat_y,
  quat_z hold, in that column order (``xyzw``: a logger's q[0..3] in scalar-last order,
  ROS and Pinocchio, written under those names); ``world_to_body``: the quaternion of
  the inverse rotation, conjugated on reading.
* ``"euler": {"order": SEQ, "unit": "rad" | "deg"}``: SEQ a Tait-Bryan sequence in
  SciPy's notation (``Rotation.from_euler``: upper case intrinsic, lower case extrinsic;
  pinquad's is ``ZYX``), whose rotations about x, y and z are the columns roll, pitch and
  yaw.
* ``"rotor_speed": "rev/min" | "rad/s"``: rad/s columns are multiplied by 60 / (2 pi).
* ``"motor_order": [k_1, k_2, ...]``: column rpm_i holds the speed of the vehicle's
  motor k_i (a permutation of 1..n, n the number of rpm columns).

A key that is absent is not assumed right: ``pinquad.io.conventions_check`` tests each
undeclared convention with physics before any EM.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from pinquad.core.conventions import STATE_NAMES, euler_from_rotation, rotation_from_euler
from pinquad.io.errors import LogFormatError

Array = NDArray[np.float64]

FRAMES = ("ENU/FLU", "NED/FRD")
QUATERNION_ORDERS = ("wxyz", "xyzw")
QUATERNION_ROTATIONS = ("body_to_world", "world_to_body")
EULER_ORDERS = ("ZYX", "XYZ", "YXZ", "ZXY", "XZY", "YZX", "zyx", "xyz", "yxz", "zxy", "xzy",
                "yzx")
"""Tait-Bryan sequences (SciPy's notation); ``ZYX`` is pinquad's."""
EULER_UNITS = ("rad", "deg")
ROTOR_SPEED_UNITS = ("rev/min", "rad/s")
CONVENTION_KEYS = ("frame", "quaternion", "euler", "rotor_speed", "motor_order")
"""The sidecar keys this module reads."""

WORLD_SWAP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""P_w: NED world vector -> ENU (and back: P_w @ P_w = I)."""
BODY_SWAP = np.diag([1.0, -1.0, -1.0])
"""P_b: FRD body vector -> FLU (and back)."""

QUATERNION_NORM_TOLERANCE = 0.01
"""A unit quaternion's norm is 1 to float32 rounding (1e-7); a median norm more than 1 %
off is not a rotation's quaternion (scaled, or other numbers under those names)."""


@dataclass(frozen=True)
class Conventions:
    """How a log's columns were written, as its sidecar declares them; None: not
    declared (pinquad's own is assumed on reading and tested before any EM).

    frame: ``FRAMES``; quaternion_order: ``QUATERNION_ORDERS``; quaternion_rotation:
    ``QUATERNION_ROTATIONS``; euler_order: ``EULER_ORDERS``; euler_unit: ``EULER_UNITS``;
    rotor_speed: ``ROTOR_SPEED_UNITS``; motor_order: (n,) 1-based motor numbers of the
    columns rpm_1..rpm_n. attitude_columns: where the reader took the log's attitude
    from, ``"quat"``, ``"euler"`` or None (none): not a sidecar key, set by the reader so
    the checks know which convention the attitude rests on.
    """

    frame: str | None = None
    quaternion_order: str | None = None
    quaternion_rotation: str | None = None
    euler_order: str | None = None
    euler_unit: str | None = None
    rotor_speed: str | None = None
    motor_order: tuple[int, ...] | None = None
    attitude_columns: str | None = None

    def sidecar(self) -> dict:
        """The sidecar keys that declare these conventions (only the declared ones)."""
        out: dict = {}
        if self.frame is not None:
            out["frame"] = self.frame
        quat = {k: v for k, v in (("order", self.quaternion_order),
                                  ("rotation", self.quaternion_rotation)) if v is not None}
        if quat:
            out["quaternion"] = quat
        euler = {k: v for k, v in (("order", self.euler_order), ("unit", self.euler_unit))
                 if v is not None}
        if euler:
            out["euler"] = euler
        if self.rotor_speed is not None:
            out["rotor_speed"] = self.rotor_speed
        if self.motor_order is not None:
            out["motor_order"] = list(self.motor_order)
        return out


def _choice(side: Path, key: str, value: object, allowed: tuple[str, ...], what: str) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise LogFormatError(f"{side}: key {key!r} is {value!r}; expected one of "
                            f"{', '.join(allowed)} ({what})")
    return value


def _sub(side: Path, raw: dict, key: str, fields: tuple[str, ...], example: str) -> dict:
    value = raw.get(key)
    if value is None:
        return {}
    if not isinstance(value, dict) or not set(value) <= set(fields):
        raise LogFormatError(f"{side}: key {key!r} is {value!r}; expected an object with "
                            f"keys among {', '.join(fields)}, e.g. {example}")
    return value


def read_conventions(side: Path, raw: dict) -> Conventions:
    """The conventions a sidecar ``raw`` (its JSON object, file ``side``) declares.
    Raises LogFormatError naming the sidecar and the key."""
    frame = raw.get("frame")
    if frame is not None:
        frame = _choice(side, "frame", frame, FRAMES,
                        "world east-north-up and body forward-left-up, or world "
                        "north-east-down and body forward-right-down")
    quat = _sub(side, raw, "quaternion", ("order", "rotation"),
                '{"order": "xyzw", "rotation": "body_to_world"}')
    euler = _sub(side, raw, "euler", ("order", "unit"), '{"order": "ZYX", "unit": "deg"}')
    speed = raw.get("rotor_speed")
    order = raw.get("motor_order")
    if order is not None:
        ok = (isinstance(order, list) and all(isinstance(k, int) and not isinstance(k, bool)
                                              for k in order)
              and sorted(order) == list(range(1, len(order) + 1)) and len(order) >= 3)
        if not ok:
            raise LogFormatError(f"{side}: key 'motor_order' is {order!r}; expected the "
                                "vehicle's motor number of each column rpm_1, rpm_2, ... "
                                "(a permutation of 1..n, e.g. [2, 3, 4, 1])")
        order = tuple(order)
    return Conventions(
        frame=frame,
        quaternion_order=None if "order" not in quat else _choice(
            side, "quaternion.order", quat["order"], QUATERNION_ORDERS,
            "what the columns quat_w, quat_x, quat_y, quat_z hold, in that order"),
        quaternion_rotation=None if "rotation" not in quat else _choice(
            side, "quaternion.rotation", quat["rotation"], QUATERNION_ROTATIONS,
            "the rotation the quaternion turns"),
        euler_order=None if "order" not in euler else _choice(
            side, "euler.order", euler["order"], EULER_ORDERS,
            "SciPy's sequence: upper case intrinsic, lower case extrinsic; pinquad's ZYX"),
        euler_unit=None if "unit" not in euler else _choice(
            side, "euler.unit", euler["unit"], EULER_UNITS, "of roll, pitch, yaw"),
        rotor_speed=None if speed is None else _choice(
            side, "rotor_speed", speed, ROTOR_SPEED_UNITS, "of rpm_1, rpm_2, ..."),
        motor_order=order,
    )


# ------------------------------------------------------------------- column conversion

def _stack(cols: dict[str, Array], names: list[str]) -> Array | None:
    return np.column_stack([cols[n] for n in names]) if all(n in cols for n in names) else None


def _put(cols: dict[str, Array], names: list[str], values: Array) -> None:
    for i, n in enumerate(names):
        cols[n] = values[:, i]


def _vector_groups(prefixes: tuple[str, ...]) -> list[list[str]]:
    return [[f"{p}_{a}" for a in "xyz"] for p in prefixes]


WORLD_VECTORS = _vector_groups(("pos", "vel", "est_pos", "est_vel", "true_pos", "true_vel"))
BODY_VECTORS = _vector_groups(("gyro", "acc", "torque", "est_gyro", "true_gyro"))
QUAT = ["quat_w", "quat_x", "quat_y", "quat_z"]
EULER_SETS = [[f"{p}{n}" for n in STATE_NAMES[6:9]] for p in ("", "est_", "true_")]


def rotation_of_quat(q: Array, order: str, rotation: str) -> Array:
    """(N, 3, 3) body-to-world rotations of the quaternion columns q (N, 4) (finite,
    nonzero rows) as declared."""
    wxyz = q if order == "wxyz" else q[:, [3, 0, 1, 2]]
    rot = Rotation.from_quat(wxyz, scalar_first=True).as_matrix()
    return rot if rotation == "body_to_world" else np.swapaxes(rot, -1, -2)


def quat_of_rotation(rot: Array, order: str, rotation: str) -> Array:
    """Inverse of :func:`rotation_of_quat`: the columns (N, 4) of rotations (N, 3, 3)."""
    rot = rot if rotation == "body_to_world" else np.swapaxes(rot, -1, -2)
    wxyz = Rotation.from_matrix(rot).as_quat(canonical=True, scalar_first=True)
    return wxyz if order == "wxyz" else wxyz[:, [1, 2, 3, 0]]


def rotation_of_euler(e: Array, order: str, unit: str) -> Array:
    """(N, 3, 3) body-to-world rotations of roll, pitch, yaw columns e (N, 3)."""
    e = np.deg2rad(e) if unit == "deg" else e
    if order == "ZYX":
        return rotation_from_euler(e)
    axis = {"x": 0, "y": 1, "z": 2}
    return Rotation.from_euler(order, e[:, [axis[c] for c in order.lower()]]).as_matrix()


def euler_of_rotation(rot: Array, order: str, unit: str) -> Array:
    """Inverse of :func:`rotation_of_euler` (angles wrapped to (-pi, pi])."""
    if order == "ZYX":
        e = euler_from_rotation(rot)
    else:
        seq = Rotation.from_matrix(rot).as_euler(order)
        e = np.empty_like(seq)
        for i, c in enumerate(order.lower()):
            e[:, {"x": 0, "y": 1, "z": 2}[c]] = seq[:, i]
    return np.rad2deg(e) if unit == "deg" else e


def quaternion_norm_problem(q: Array) -> str | None:
    """Why the quaternion columns q (N, 4) are not unit quaternions, or None: their median
    norm over finite rows is more than ``QUATERNION_NORM_TOLERANCE`` from 1."""
    ok = np.isfinite(q).all(axis=1)
    if not ok.any():
        return None
    norm = float(np.median(np.linalg.norm(q[ok], axis=1)))
    if abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE:
        return None
    return (f"columns quat_w, quat_x, quat_y, quat_z have median norm {norm:.4g}; expected "
            "unit quaternions (norm 1): the quaternion of the body-to-world rotation")


def _convert(cols: dict[str, Array], conv: Conventions, forward: bool) -> dict[str, Array]:
    out = dict(cols)
    ned = conv.frame == "NED/FRD"
    if ned:
        for group, swap in ((WORLD_VECTORS, WORLD_SWAP), (BODY_VECTORS, BODY_SWAP)):
            for names in group:
                v = _stack(out, names)
                if v is not None:
                    _put(out, names, v @ swap.T)
    q_order = conv.quaternion_order or "wxyz"
    q_rot = conv.quaternion_rotation or "body_to_world"
    q = _stack(out, QUAT)
    if q is not None and (ned or (q_order, q_rot) != ("wxyz", "body_to_world")):
        ok = np.isfinite(q).all(axis=1) & (np.linalg.norm(np.nan_to_num(q), axis=1) > 0)
        new = np.full_like(q, np.nan)
        if ok.any():
            if forward:
                rot = rotation_of_quat(q[ok], q_order, q_rot)
                new[ok] = quat_of_rotation(WORLD_SWAP @ rot @ BODY_SWAP if ned else rot,
                                            "wxyz", "body_to_world")
            else:
                rot = rotation_of_quat(q[ok], "wxyz", "body_to_world")
                new[ok] = quat_of_rotation(WORLD_SWAP @ rot @ BODY_SWAP if ned else rot,
                                            q_order, q_rot)
        _put(out, QUAT, new)
    e_order = conv.euler_order or "ZYX"
    e_unit = conv.euler_unit or "rad"
    for names in EULER_SETS:
        e = _stack(out, names)
        if e is None:
            continue
        ok = np.isfinite(e).all(axis=1)
        if not ned and e_order == "ZYX":  # a unit alone: exact, and keeps an unwrapped yaw
            scale = math.pi / 180.0 if e_unit == "deg" else 1.0
            _put(out, names, e * scale if forward else e / scale)
            continue
        new = np.full_like(e, np.nan)
        if ok.any():
            if forward:
                rot = rotation_of_euler(e[ok], e_order, e_unit)
                new[ok] = euler_from_rotation(WORLD_SWAP @ rot @ BODY_SWAP if ned else rot)
            else:
                rot = rotation_from_euler(e[ok])
                new[ok] = euler_of_rotation(WORLD_SWAP @ rot @ BODY_SWAP if ned else rot,
                                             e_order, e_unit)
        _put(out, names, new)
    rpm = sorted((n for n in out if n.startswith("rpm_") and n[4:].isdigit()),
                 key=lambda n: int(n[4:]))
    if rpm and conv.rotor_speed == "rad/s":
        scale = 60.0 / (2.0 * math.pi)
        for n in rpm:
            out[n] = out[n] * scale if forward else out[n] / scale
    if rpm and conv.motor_order is not None:
        old = np.column_stack([out[n] for n in rpm])
        new = np.empty_like(old)
        idx = np.asarray(conv.motor_order) - 1
        if forward:
            new[:, idx] = old
        else:
            new = old[:, idx]
        _put(out, rpm, new)
    return out


def to_pinquad(cols: dict[str, Array], conv: Conventions, path: Path) -> dict[str, Array]:
    """The columns of a log in pinquad's conventions, from columns written as ``conv``
    declares (module docstring). Raises LogFormatError naming the file and column when
    the quaternion columns are not unit quaternions, or the motor order does not fit the
    rpm columns."""
    q = _stack(cols, QUAT)
    if q is not None and (problem := quaternion_norm_problem(q)):
        raise LogFormatError(f"{path}: {problem}")
    n_rpm = sum(1 for n in cols if n.startswith("rpm_") and n[4:].isdigit())
    if conv.motor_order is not None and n_rpm and len(conv.motor_order) != n_rpm:
        raise LogFormatError(f"{path}: the sidecar's 'motor_order' {list(conv.motor_order)} "
                            f"names {len(conv.motor_order)} motors; the log has {n_rpm} rpm "
                            "columns")
    return _convert(cols, conv, forward=True)


def to_declared(cols: dict[str, Array], conv: Conventions) -> dict[str, Array]:
    """The inverse of :func:`to_pinquad`: pinquad's columns written as ``conv`` declares
    (how another logger would have written the same flight)."""
    return _convert(cols, conv, forward=False)


# ------------------------------------------------------------------- wrench declarations

WRENCH_FROM_RPM = "from rpm"
"""The sidecar's ``wrench`` value of a log whose thrust and torques were computed from
its rotor speeds (``LogMeta.wrench_from_rpm``)."""


def wrench_from_rpm(side: Path, raw: object) -> bool:
    """Whether the sidecar's ``wrench`` (``raw``) says the thrust and torque columns were
    computed from the rotor speeds; raises LogFormatError for any other value."""
    if raw is None:
        return False
    if raw != WRENCH_FROM_RPM:
        raise LogFormatError(f"{side}: key 'wrench' is {raw!r}; expected {WRENCH_FROM_RPM!r} "
                             "(the thrust and torque columns were computed from rpm_1..) or "
                             "no such key (they are the applied or commanded wrench)")
    return True


CALIBRATION_KEYS = ("thrust", "yaw_torque", "arm")
"""The sidecar's ``calibration`` keys (``LogMeta.calibration``)."""


def calibration(side: Path, raw: object) -> tuple[float, float, float] | None:
    """The sidecar's ``calibration`` object, {"thrust": r, "yaw_torque": r, "arm": r},
    relative standard uncertainties in [0, 1) (None when absent)."""
    if raw is None:
        return None
    ok = isinstance(raw, dict) and set(raw) == set(CALIBRATION_KEYS) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 <= v < 1.0
        for v in raw.values())
    if not ok:
        raise LogFormatError(f"{side}: key 'calibration' is {raw!r}; expected "
                             '{"thrust": r, "yaw_torque": r, "arm": r}, relative standard '
                             "uncertainties in [0, 1) of the logged thrust, yaw torque and "
                             "arm length (0: the applied wrench exactly)")
    return tuple(float(raw[k]) for k in CALIBRATION_KEYS)  # type: ignore[return-value]
