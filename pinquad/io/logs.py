"""FlightLog: the typed record of one flight, and its CSV / Parquet readers and writers.

Columns (SI units, NaN where a sensor has no sample in that row):
``t``; ``pos_*``, ``vel_*`` [world]; ``quat_w..z`` (body to world) or ``roll, pitch,
yaw``; ``gyro_*`` [rad/s, body]; ``acc_*`` [m/s^2, body specific force]; actuation
``thrust`` + ``torque_*`` or ``rpm_1..4``; optional ``vbat``, ``contact``; truth in
``true_*`` columns, never read by estimators. A JSON sidecar ``<log>.json`` carries
``vehicle``, ``mass_guess``, ``inertia_guess`` (3x3, or its diagonal as three numbers),
``gravity``, and may declare conventions other than pinquad's (``frame``, ``quaternion``,
``euler``, ``rotor_speed``, ``motor_order``: ``pinquad.io.declared``), converted once on
reading.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from pinquad.core.conventions import (
    GRAVITY,
    STATE_NAMES,
    euler_from_quat_wxyz,
    quat_wxyz_from_euler,
)
from pinquad.core.params import VEHICLES
from pinquad.core.vehicle_file import VehicleFileError, is_vehicle_file, load_vehicle
from pinquad.io.csv_table import duplicated_names, read_csv_table
from pinquad.io.declared import (
    CALIBRATION_KEYS,
    WRENCH_FROM_RPM,
    Conventions,
    calibration,
    read_conventions,
    to_pinquad,
    wrench_from_rpm,
)
from pinquad.io.errors import LogFormatError
from pinquad.io.runs import atomic_write_bytes
from pinquad.io.timebase import irregular_note, relative_time, stored_resolution_problem

Array = NDArray[np.float64]


@dataclass(frozen=True)
class LogMeta:
    """What the sidecar says about a log.

    vehicle: vehicle name (``paper``, ``crazyflie21``); mass_guess [kg] and
    inertia_guess (3, 3) [kg m^2]: initial values for identification (None if unknown);
    gravity [m/s^2]; source: where the log came from (a path or "simulation");
    notes: human-readable remarks (e.g. detected sensor faults); actuation: how the
    logged thrust and torques relate to what acted between rows (``ACTUATION``):
    ``held``, each row's value acted over the interval that follows it (a zero-order
    hold: pinquad's simulator), or ``sampled``, each row holds the command of a faster
    controller at that instant, so it moves within the interval (a recorded log; what a
    sidecar that does not say is taken to mean); actuation_declared: the log's sidecar
    says which (False: ``sampled`` is an assumption, and the verdict checks what rests on
    it); vehicle_named: whether the log
    itself names the vehicle (False: no sidecar or no ``vehicle`` in it, and ``vehicle``
    is the default ``paper``, not the log's); t_origin [s]: the file's time of its first
    row (the log's ``t`` counts from it: ``pinquad.io.timebase.relative_time``);
    calibration: the relative standard uncertainties [-] of the logged thrust, yaw torque
    and the arm length behind the roll and pitch torques, as the sidecar's
    ``calibration`` declares them (0, 0, 0: the applied wrench exactly, as a simulator
    logs it), or None (not declared: the vehicle file's or pinquad's defaults,
    ``identification.budget``); wrench_from_rpm: the thrust and torque columns were
    computed from the rotor speeds (pinquad's export of a measured flight; sidecar
    ``"wrench": "from rpm"``): the log is identified from its rotor speeds, as the
    flight it was exported from. payload_mass [kg] >= 0: a load the vehicle carried
    that its vehicle file does not hold (sidecar ``payload_mass``), added to the file's
    reference mass (``identification.reference``).
    """

    vehicle: str = "paper"
    mass_guess: float | None = None
    inertia_guess: Array | None = None
    gravity: float = GRAVITY
    source: str = "simulation"
    notes: tuple[str, ...] = ()
    actuation: str = "held"
    actuation_declared: bool = True
    vehicle_named: bool = True
    calibration: tuple[float, float, float] | None = None
    wrench_from_rpm: bool = False
    t_origin: float = 0.0
    conventions: Conventions = field(default_factory=Conventions)
    payload_mass: float = 0.0


ACTUATION = ("held", "sampled")
"""The sidecar's ``actuation`` values (``LogMeta.actuation``)."""

SAMPLED_NOTE = ("actuation taken as sampled at each row (the sidecar does not say "
                "\"actuation\": \"held\" or \"sampled\"): each transition uses the mean of "
                "its two rows' thrust and torques, and the verdict checks what rests on that")


@dataclass(frozen=True)
class MeasuredSamples:
    """What a measured log carries beyond its rows (a Crazyflie micro-SD log).

    pose_t (P,) [s, log clock], pose_position (P, 3) [m, world], pose_euler (P, 3) roll,
    pitch, yaw [rad]: motion-capture poses at their own times (None: no pose stream;
    euler NaN where the quaternion was missing or not unit); pwm (N, 4) [0..65535]:
    motor commands per row, or None; onboard_position (N, 3) [m]: the vehicle's own
    position estimate per row, or None.
    """

    pose_t: Array | None = None
    pose_position: Array | None = None
    pose_euler: Array | None = None
    pwm: Array | None = None
    onboard_position: Array | None = None

    def rows(self, start: int, stop: int, t_first: float, t_last: float) -> MeasuredSamples:
        """Rows start..stop-1, and the poses with t_first <= t <= t_last."""
        def cut(a: Array | None) -> Array | None:
            return None if a is None else a[start:stop]
        if self.pose_t is None:
            return replace(self, pwm=cut(self.pwm), onboard_position=cut(self.onboard_position))
        keep = (self.pose_t >= t_first) & (self.pose_t <= t_last)
        return MeasuredSamples(self.pose_t[keep], self.pose_position[keep],
                               self.pose_euler[keep], cut(self.pwm), cut(self.onboard_position))


@dataclass(frozen=True)
class FlightLog:
    """One flight, one row per time sample (N rows).

    t (N,) [s] strictly increasing.
    position (N, 3) [m, world]; velocity (N, 3) [m/s, world]; euler (N, 3) roll, pitch,
    yaw [rad]; gyro (N, 3) [rad/s, body]; accel (N, 3) [m/s^2, body specific force].
    Any of these may be NaN in rows without a sample, or entirely NaN.
    thrust (N,) [N] and torque (N, 3) [N m, body]: the applied actuation (NaN-free when
    present); rpm (N, 4) [rev/min]: measured rotor speeds, the alternative actuation.
    vbat (N,) [V]; contact (N,) bool: the vehicle touches the floor (simulator flag).
    truth (N, 12) or None: simulator state [p, v, Theta, omega], for scoring only.
    onboard (N, 12) or None: the vehicle's own state estimate (columns ``est_*``), the
    one its controller used.
    measured: what a measured log carries beyond its rows (raw motion-capture poses,
    motor commands), or None.
    """

    t: Array
    position: Array
    velocity: Array
    euler: Array
    gyro: Array
    accel: Array
    thrust: Array | None = None
    torque: Array | None = None
    rpm: Array | None = None
    vbat: Array | None = None
    contact: NDArray[np.bool_] | None = None
    truth: Array | None = None
    onboard: Array | None = None
    meta: LogMeta = field(default_factory=LogMeta)
    measured: MeasuredSamples | None = None

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    @property
    def dt(self) -> float:
        """Median sample interval [s]."""
        return float(np.median(np.diff(self.t))) if self.n > 1 else float("nan")

    def slice(self, start: int, stop: int) -> FlightLog:
        """Rows start..stop-1 as a new log."""
        def cut(a):
            return None if a is None else a[start:stop]
        return replace(
            self, t=self.t[start:stop], position=self.position[start:stop],
            velocity=self.velocity[start:stop], euler=self.euler[start:stop],
            gyro=self.gyro[start:stop], accel=self.accel[start:stop],
            thrust=cut(self.thrust), torque=cut(self.torque), rpm=cut(self.rpm),
            vbat=cut(self.vbat), contact=cut(self.contact), truth=cut(self.truth),
            onboard=cut(self.onboard),
            measured=None if self.measured is None else self.measured.rows(
                start, stop, float(self.t[start]), float(self.t[stop - 1])),
        )


def _nan3(n: int) -> Array:
    return np.full((n, 3), np.nan)


# ----------------------------------------------------------------------------- writing

def log_columns(log: FlightLog) -> dict[str, Array]:
    """The log as named columns (those above); attitude written as a quaternion and
    as Euler angles."""
    cols: dict[str, Array] = {"t": log.t}
    for name, arr in (("pos", log.position), ("vel", log.velocity)):
        for i, ax in enumerate("xyz"):
            cols[f"{name}_{ax}"] = arr[:, i]
    quat = np.full((log.n, 4), np.nan)
    ok = ~np.isnan(log.euler).any(axis=1)
    if ok.any():
        quat[ok] = quat_wxyz_from_euler(log.euler[ok])
    for i, ax in enumerate("wxyz"):
        cols[f"quat_{ax}"] = quat[:, i]
    for i, ax in enumerate(("roll", "pitch", "yaw")):
        cols[ax] = log.euler[:, i]
    for name, arr in (("gyro", log.gyro), ("acc", log.accel)):
        for i, ax in enumerate("xyz"):
            cols[f"{name}_{ax}"] = arr[:, i]
    if log.thrust is not None:
        cols["thrust"] = log.thrust
    if log.torque is not None:
        for i, ax in enumerate("xyz"):
            cols[f"torque_{ax}"] = log.torque[:, i]
    if log.rpm is not None:
        for i in range(log.rpm.shape[1]):
            cols[f"rpm_{i + 1}"] = log.rpm[:, i]
    if log.vbat is not None:
        cols["vbat"] = log.vbat
    if log.contact is not None:
        cols["contact"] = log.contact.astype(float)
    if log.truth is not None:
        for i, name in enumerate(STATE_NAMES):
            cols[f"true_{name}"] = log.truth[:, i]
    if log.onboard is not None:
        for i, name in enumerate(STATE_NAMES):
            cols[f"est_{name}"] = log.onboard[:, i]
    return cols


def sidecar(meta: LogMeta) -> dict:
    """The JSON sidecar of a log (``vehicle`` only when the log names one: a default
    written out would name it on reading)."""
    return {
        **({"vehicle": meta.vehicle} if meta.vehicle_named else {}),
        "mass_guess": meta.mass_guess,
        "inertia_guess": None if meta.inertia_guess is None else np.asarray(meta.inertia_guess).tolist(),
        "gravity": meta.gravity,
        **({"payload_mass": meta.payload_mass} if meta.payload_mass else {}),
        "actuation": meta.actuation,
        **({} if meta.calibration is None else {"calibration": dict(zip(
            CALIBRATION_KEYS, meta.calibration, strict=True))}),
        **({"wrench": WRENCH_FROM_RPM} if meta.wrench_from_rpm else {}),
    }


def write_log(log: FlightLog, path: str | Path) -> Path:
    """Write the log as CSV or Parquet (by suffix) plus its JSON sidecar, atomically."""
    path = Path(path)
    cols = log_columns(log)
    suffix = path.suffix.lower()
    if suffix == ".parquet":
        buf = io.BytesIO()
        pq.write_table(pa.table({k: np.asarray(v, dtype=float) for k, v in cols.items()}), buf)
        atomic_write_bytes(path, buf.getvalue())
    elif suffix == ".csv":
        names = list(cols)
        mat = np.column_stack([np.asarray(cols[k], dtype=float) for k in names])
        lines = [",".join(names)]
        for row in mat:
            lines.append(",".join("" if math.isnan(v) else repr(float(v)) for v in row))
        atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())
    else:
        raise LogFormatError(f"{path}: unknown log format {suffix!r}; expected .csv or .parquet")
    atomic_write_bytes(Path(str(path) + ".json"), json.dumps(sidecar(log.meta), indent=2).encode())
    return path


# ----------------------------------------------------------------------------- reading

def _read_table(path: Path) -> tuple[dict[str, Array], tuple[str, ...]]:
    """The file's columns and notes on how they were read (a CSV's dialect)."""
    suffix = path.suffix.lower()
    if suffix == ".parquet":
        try:
            table = pq.read_table(path)
        except Exception as exc:  # pyarrow raises several types for corrupt files
            raise LogFormatError(f"{path}: not a readable Parquet file ({exc})") from None
        duplicated_names(path, table.column_names)
        out = {}
        t_type = table.schema.field("t").type if "t" in table.column_names else None
        bits = t_type.bit_width if t_type is not None and pa.types.is_floating(t_type) else 64
        for name in table.column_names:
            try:
                out[name] = np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=float)
            except (TypeError, ValueError):
                raise LogFormatError(
                    f"{path}: column {name!r} is not numeric; expected numbers") from None
        if "t" in out and (problem := stored_resolution_problem(out["t"], bits)):
            raise LogFormatError(f"{path}: column 't' {problem}")
        return out, ()
    if suffix == ".csv":
        table = read_csv_table(path)
        return table.columns, table.notes
    raise LogFormatError(f"{path}: unknown log format {suffix!r}; expected .csv, .parquet or a "
                         "Crazyflie micro-SD binary log")


def _cols3(cols: dict[str, Array], prefix: str, n: int) -> Array:
    names = [f"{prefix}_{ax}" for ax in "xyz"]
    if all(nm in cols for nm in names):
        return np.column_stack([cols[nm] for nm in names])
    return _nan3(n)


MEASUREMENT_GROUPS = (("pos_x", "pos_y", "pos_z"), ("vel_x", "vel_y", "vel_z"),
                      ("quat_w", "quat_x", "quat_y", "quat_z"), ("roll", "pitch", "yaw"),
                      ("gyro_x", "gyro_y", "gyro_z"), ("acc_x", "acc_y", "acc_z"))
"""Measurement columns that only make sense together."""


def _check_groups(path: Path, cols: dict[str, Array]) -> None:
    """A sensor group present in part is an error naming what is missing (dropping it
    silently made EM identify from the rest); no measurement group at all is one too."""
    complete = 0
    for group in MEASUREMENT_GROUPS:
        have = [c for c in group if c in cols]
        if have and len(have) < len(group):
            missing = [c for c in group if c not in cols]
            raise LogFormatError(
                f"{path}: has {', '.join(have)} but lacks {', '.join(missing)}; a sensor's "
                f"columns come together ({', '.join(group)})")
        complete += len(have) == len(group)
    if complete == 0:
        raise LogFormatError(
            f"{path}: no measurement columns; expected at least one complete group of "
            + "; ".join(", ".join(g) for g in MEASUREMENT_GROUPS))


def _sidecar_number(side: Path, raw: dict, key: str) -> float | None:
    value = raw.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(float(value)):
        raise LogFormatError(f"{side}: key {key!r} is {value!r}; expected a finite number")
    return float(value)


def _inertia_guess(side: Path, value: object) -> Array | None:
    """The sidecar's ``inertia_guess`` as (3, 3) [kg m^2]: a 3x3 list, or a list of three
    numbers (the diagonal, I_xx, I_yy, I_zz); None when absent or null."""
    if value is None:
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (ValueError, TypeError):
        arr = np.zeros(0)
    if arr.shape == (3,):
        return np.diag(arr)
    if arr.shape == (3, 3):
        return arr
    raise LogFormatError(f"{side}: key 'inertia_guess' is {value!r}; expected a 3x3 list of "
                         "numbers or a list of three (the diagonal I_xx, I_yy, I_zz) [kg m^2]")


def vehicle_file_named(vehicle: str, base: Path, where: Path | str) -> str:
    """The absolute path of a vehicle file named by a sidecar or an option (relative to
    ``base``), checked by reading it. Raises LogFormatError naming ``where``."""
    p = Path(vehicle).expanduser()
    p = (p if p.is_absolute() else base / p).resolve()
    try:
        load_vehicle(str(p))
    except VehicleFileError as exc:
        raise LogFormatError(f"{where}: vehicle file: {exc}") from None
    return str(p)


def _read_sidecar(path: Path) -> LogMeta:
    side = Path(str(path) + ".json")
    if not side.exists():
        return LogMeta(source=str(path), actuation="sampled", notes=(SAMPLED_NOTE,),
                       actuation_declared=False, vehicle_named=False)
    try:
        raw = json.loads(side.read_text(encoding="utf-8-sig", errors="replace"))
    except json.JSONDecodeError as exc:
        raise LogFormatError(f"{side}: not valid JSON ({exc.msg} at byte {exc.pos})") from None
    if not isinstance(raw, dict):
        raise LogFormatError(f"{side}: is a JSON {type(raw).__name__}; expected an object "
                             '{"vehicle": ..., "mass_guess": ..., "inertia_guess": ..., '
                             '"gravity": ...}')
    inertia_arr = _inertia_guess(side, raw.get("inertia_guess"))
    if inertia_arr is not None and not np.isfinite(inertia_arr).all():
        raise LogFormatError(f"{side}: 'inertia_guess' must hold finite numbers")
    vehicle = raw.get("vehicle", "paper")
    mass_guess = _sidecar_number(side, raw, "mass_guess")
    if not isinstance(vehicle, str):
        raise LogFormatError(f"{side}: key 'vehicle' is {vehicle!r}; expected a name")
    if is_vehicle_file(vehicle):
        vehicle = vehicle_file_named(vehicle, side.parent, side)
    elif vehicle not in VEHICLES and (mass_guess is None or inertia_arr is None):
        # an unknown name would silently start EM from the paper vehicle's guess
        raise LogFormatError(
            f"{side}: key 'vehicle' is {vehicle!r}; expected one of {', '.join(VEHICLES)}, "
            "or give 'mass_guess' and 'inertia_guess' for another vehicle")
    gravity = _sidecar_number(side, raw, "gravity")
    payload = _sidecar_number(side, raw, "payload_mass")
    if payload is not None and payload < 0:
        raise LogFormatError(f"{side}: key 'payload_mass' is {payload!r}; expected the mass "
                             "[kg] of a load the vehicle carried, 0 or more")
    notes = () if vehicle in VEHICLES or is_vehicle_file(vehicle) else (
        f"vehicle {vehicle!r} is not one pinquad knows ({', '.join(VEHICLES)}): EM starts "
        "from the sidecar's guesses and the thrust is not compared with a nominal mass",)
    actuation = raw.get("actuation", "sampled")
    if actuation not in ACTUATION:
        raise LogFormatError(f"{side}: key 'actuation' is {actuation!r}; expected one of "
                             f"{', '.join(ACTUATION)} (held: each row's thrust and torques "
                             "acted until the next row; sampled: a faster controller's command "
                             "at the row's instant)")
    if actuation == "sampled":
        notes = (*notes, SAMPLED_NOTE if "actuation" not in raw else (
            "actuation sampled at each row (the sidecar says so): each transition uses the "
            "mean of its two rows' thrust and torques"))
    return LogMeta(
        vehicle=vehicle,
        mass_guess=mass_guess,
        inertia_guess=inertia_arr,
        gravity=GRAVITY if gravity is None else gravity,
        source=str(path),
        notes=notes,
        actuation=actuation,
        actuation_declared="actuation" in raw,
        vehicle_named="vehicle" in raw,
        calibration=calibration(side, raw.get("calibration")),
        wrench_from_rpm=wrench_from_rpm(side, raw.get("wrench")),
        conventions=read_conventions(side, raw),
        payload_mass=payload or 0.0,
    )


def read_table(path: str | Path) -> FlightLog:
    """Read a CSV or Parquet flight log (and its sidecar): the table part of
    ``pinquad.io.read.read_log``, which reads every format. Raises LogFormatError."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if path.is_dir():
        raise LogFormatError(f"{path}: is a directory; expected a log file")
    cols, read_notes = _read_table(path)
    meta = _read_sidecar(path)
    meta = replace(meta, notes=(*meta.notes, *read_notes))
    if "t" not in cols:
        raise LogFormatError(f"{path}: missing required column 't' (time in seconds)")
    _check_groups(path, cols)
    t = cols["t"]
    n = t.shape[0]
    if n == 0:
        raise LogFormatError(f"{path}: no data rows")
    if not np.isfinite(t).all():
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise LogFormatError(f"{path}: column 't', row {bad + 1}: not a finite number")
    steps = np.diff(t)
    if (steps <= 0).any():
        bad = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise LogFormatError(
            f"{path}: column 't' is not strictly increasing at row {bad + 1} "
            f"(t = {t[bad - 1]!r} then {t[bad]!r})")
    t, t_origin = relative_time(t)  # float64, before anything differences or bins t
    cols = to_pinquad(cols, meta.conventions, path)  # once, here: the rest is pinquad's
    source = "quat" if all(f"quat_{a}" in cols for a in "wxyz") else (
        "euler" if all(a in cols for a in ("roll", "pitch", "yaw")) else None)
    meta = replace(meta, conventions=replace(meta.conventions, attitude_columns=source))
    if source == "quat":
        quat = np.column_stack([cols[f"quat_{a}"] for a in "wxyz"])
        euler = np.full((n, 3), np.nan)
        ok = np.isfinite(quat).all(axis=1) & (np.linalg.norm(np.nan_to_num(quat), axis=1) > 0)
        if ok.any():
            euler[ok] = euler_from_quat_wxyz(quat[ok])
    elif source == "euler":
        euler = np.column_stack([cols["roll"], cols["pitch"], cols["yaw"]])
    else:
        euler = _nan3(n)

    thrust = torque = rpm = None
    # an export's thrust and torques were computed from its rotor speeds: read those
    from_rpm = meta.wrench_from_rpm and "rpm_1" in cols
    if "thrust" in cols and not from_rpm:
        missing = [f"torque_{a}" for a in "xyz" if f"torque_{a}" not in cols]
        if missing:
            raise LogFormatError(f"{path}: has 'thrust' but lacks {', '.join(missing)}")
        thrust = cols["thrust"]
        torque = np.column_stack([cols[f"torque_{a}"] for a in "xyz"])
        act = np.column_stack([thrust, torque])
        names = ["thrust", "torque_x", "torque_y", "torque_z"]
    elif all(f"rpm_{i}" in cols for i in range(1, 5)):
        # rpm_1..rpm_k, however many rotors: the vehicle file says whether k is right
        k = 4
        while f"rpm_{k + 1}" in cols:
            k += 1
        rpm = np.column_stack([cols[f"rpm_{i}"] for i in range(1, k + 1)])
        act = rpm
        names = [f"rpm_{i}" for i in range(1, k + 1)]
    else:
        raise LogFormatError(
            f"{path}: no actuation columns; expected 'thrust' with 'torque_x/y/z', or "
            "'rpm_1'..'rpm_4'")
    bad_rows, bad_cols = np.nonzero(~np.isfinite(act))
    if bad_rows.size:
        raise LogFormatError(
            f"{path}: column {names[bad_cols[0]]!r}, row {bad_rows[0] + 1}: actuation must be "
            "a finite number in every row")

    truth = None
    true_names = [f"true_{nm}" for nm in STATE_NAMES]
    if all(nm in cols for nm in true_names):
        truth = np.column_stack([cols[nm] for nm in true_names])
    onboard = None
    est_names = [f"est_{nm}" for nm in STATE_NAMES]
    if all(nm in cols for nm in est_names):
        onboard = np.column_stack([cols[nm] for nm in est_names])
    contact = cols["contact"] > 0.5 if "contact" in cols else None
    return FlightLog(
        t=t, position=_cols3(cols, "pos", n), velocity=_cols3(cols, "vel", n), euler=euler,
        gyro=_cols3(cols, "gyro", n), accel=_cols3(cols, "acc", n), thrust=thrust,
        torque=torque, rpm=rpm, vbat=cols.get("vbat"), contact=contact, truth=truth,
        onboard=onboard, meta=_with_time_notes(replace(meta, t_origin=t_origin), t),
    )


def _with_time_notes(meta: LogMeta, t: Array) -> LogMeta:
    """meta with a note on irregular time stamps (``timebase.irregular_note``) if any."""
    note = irregular_note(t)
    return meta if note is None else replace(meta, notes=(*meta.notes, note))


def log_contents(log: FlightLog) -> str:
    """What a log carries, in words: its actuation (thrust/torque commands, rotor speeds,
    motor commands) and, when it has ``true_*`` columns, simulator truth."""
    if log.thrust is not None:
        parts = ["thrust/torque commands"]
    elif log.rpm is not None:
        parts = ["rotor speeds"]
    else:
        parts = ["motor commands"]
    if log.measured is not None:
        parts[0] += " (Crazyflie micro-SD log)"
    if log.truth is not None:
        parts.append("simulator truth")
    return ", ".join(parts)
