"""Reader for Crazyflie micro-SD deck event-based binary logs.

File layout (all integers little-endian, no padding anywhere):

* byte 0: magic ``0xBC``; bytes 1-2: uint16 version (1 or 2); bytes 3-4: uint16 number
  of event types;
* per event type: uint16 event id, NUL-terminated event name, uint16 number of
  variables, then per variable a NUL-terminated ``name(T)`` where ``T`` is a Python
  ``struct`` format character (the stored type);
* records until the last 4 bytes: uint16 event id, a timestamp (version 1: uint32 [ms];
  version 2: uint64 [us]) and the event's variables packed in declared order;
* the last 4 bytes: CRC-32 (``zlib.crc32``) of every byte before them, stored
  little-endian (checked on all the IMRC Lab files).

Two layers:

* :func:`read_sdlog_raw` -> :class:`SdLog`: every event type decoded into float arrays
  in the log's own units (deg/s, g, mV, ...) on the device clock [s];
* :func:`read_sdflight` -> :class:`SdFlight` (and :func:`read_sdlog` -> its
  :class:`~pinquad.io.logs.FlightLog`): the flight on the ``fixedFrequency`` grid in SI
  units, with the motion-capture pose of ``estPose`` placed at the nearest grid row and
  the motor commands (PWM) and the raw poses at their own times in its ``measured``
  samples.

Unit conversions at this boundary: gyro [deg/s] * pi/180 -> [rad/s]; accelerometer
[g] * 9.81 -> [m/s^2]; battery [mV] / 1000 -> [V]; rotor speed stays [rev/min].
"""

from __future__ import annotations

import math
import re
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import GRAVITY, euler_from_quat_wxyz
from pinquad.io.logs import FlightLog, LogFormatError, LogMeta, MeasuredSamples

Array = NDArray[np.float64]

MAGIC = 0xBC
"""First byte of every micro-SD event log."""
CRC_SIZE = 4
GRID_EVENT = "fixedFrequency"
"""The event whose samples define the FlightLog rows (about 500 Hz)."""
POSE_EVENT = "estPose"
"""The event carrying the motion-capture pose sent to the vehicle (about 100 Hz)."""

STRUCT_TYPES: dict[str, str] = {
    "b": "<i1", "B": "<u1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4",
    "l": "<i4", "L": "<u4", "q": "<i8", "Q": "<u8", "e": "<f2", "f": "<f4", "d": "<f8",
    "?": "<u1",
}
"""struct format character -> little-endian numpy dtype of the stored value (both
micro-SD layouts declare their variables as ``name(T)``)."""
_TYPES = STRUCT_TYPES
_TIMESTAMP = {1: ("<u4", 1e-3), 2: ("<u8", 1e-6)}  # version -> (dtype, seconds per tick)
_VAR_RE = re.compile(r"^(?P<name>[^()]+)\((?P<type>.)\)$")

_POSE_VARS = ("locSrv.x", "locSrv.y", "locSrv.z", "locSrv.qw", "locSrv.qx", "locSrv.qy",
              "locSrv.qz")
_PWM_VARS = ("pwm.m1_pwm", "pwm.m2_pwm", "pwm.m3_pwm", "pwm.m4_pwm")
_RPM_VARS = ("rpm.m1", "rpm.m2", "rpm.m3", "rpm.m4")


# ----------------------------------------------------------------------------- raw layer

@dataclass(frozen=True)
class SdEventType:
    """One event type declared in the header.

    event_id: the uint16 id records carry; name: e.g. ``fixedFrequency``;
    variables: (V,) variable names without the type suffix; types: (V,) struct
    characters; header_offset: byte offset of the declaration in the file.
    """

    event_id: int
    name: str
    variables: tuple[str, ...]
    types: tuple[str, ...]
    header_offset: int

    @property
    def payload_size(self) -> int:
        """Bytes of packed variables per record."""
        return sum(np.dtype(_TYPES[t]).itemsize for t in self.types)


@dataclass(frozen=True)
class SdEvent:
    """All records of one event type, in file order.

    time: (K,) device clock [s] (timestamp ticks times 1 ms or 1 us);
    values: variable name -> (K,) float64 in the log's own units (deg/s, g, mV, ...);
    offsets: (K,) byte offset of each record in the file.
    """

    name: str
    time: Array
    values: dict[str, Array]
    offsets: NDArray[np.int64]

    @property
    def count(self) -> int:
        return int(self.time.shape[0])

    def get(self, variable: str) -> Array:
        """(K,) values of ``variable``, all NaN when the event does not log it."""
        out = self.values.get(variable)
        return np.full(self.count, np.nan) if out is None else out

    def has(self, variable: str) -> bool:
        return variable in self.values


@dataclass(frozen=True)
class SdLog:
    """A decoded micro-SD log, in the units and on the clock of the device.

    path: where it was read from; version: 1 or 2; event_types: the header's
    declarations; events: event name -> :class:`SdEvent` (every declared type, possibly
    with zero records); data_offset: byte offset of the first record;
    crc_stored / crc_computed: the file's trailing CRC-32 and the one of its contents.
    """

    path: str
    version: int
    event_types: tuple[SdEventType, ...]
    events: dict[str, SdEvent]
    data_offset: int
    crc_stored: int
    crc_computed: int

    @property
    def crc_ok(self) -> bool:
        return self.crc_stored == self.crc_computed


def is_sdlog(path: str | Path) -> bool:
    """True when the file starts with the micro-SD magic byte 0xBC (CSV and Parquet
    files never do: they start with text or ``PAR1``)."""
    try:
        with open(path, "rb") as fh:
            first = fh.read(1)
    except OSError:
        return False
    return first == bytes([MAGIC])


def _cstring(buf: bytes, off: int, limit: int, path: str, what: str) -> tuple[str, int]:
    end = buf.find(b"\0", off, limit)
    if end < 0:
        raise LogFormatError(
            f"{path}: byte offset {off}: {what} has no NUL terminator before byte {limit} "
            "(truncated or corrupt header); expected a NUL-terminated string")
    try:
        text = buf[off:end].decode("ascii")
    except UnicodeDecodeError:
        raise LogFormatError(
            f"{path}: byte offset {off}: {what} is not ASCII text; expected a "
            "NUL-terminated name") from None
    return text, end + 1


def _u16(buf: bytes, off: int, limit: int, path: str, what: str) -> int:
    if off + 2 > limit:
        raise LogFormatError(
            f"{path}: byte offset {off}: file ends inside the header while reading {what}; "
            "expected a uint16")
    return buf[off] | (buf[off + 1] << 8)


def _parse_header(buf: bytes, path: str, limit: int) -> tuple[int, list[SdEventType], int]:
    if buf[0] != MAGIC:
        raise LogFormatError(
            f"{path}: byte offset 0: magic byte is 0x{buf[0]:02X}; expected 0xBC (a Crazyflie "
            "micro-SD event log)")
    version = _u16(buf, 1, limit, path, "the version")
    if version not in _TIMESTAMP:
        raise LogFormatError(
            f"{path}: byte offset 1: log version {version}; expected 1 or 2")
    n_types = _u16(buf, 3, limit, path, "the number of event types")
    off = 5
    types: list[SdEventType] = []
    seen_ids: set[int] = set()
    seen_names: set[str] = set()
    for k in range(n_types):
        start = off
        eid = _u16(buf, off, limit, path, f"the id of event type {k + 1}")
        off += 2
        name, off = _cstring(buf, off, limit, path, f"the name of event type {k + 1}")
        if eid in seen_ids or name in seen_names:
            raise LogFormatError(
                f"{path}: byte offset {start}: event type {name!r} (id {eid}) is declared "
                "twice; expected unique event ids and names")
        nvars = _u16(buf, off, limit, path, f"the variable count of event {name!r}")
        off += 2
        names: list[str] = []
        chars: list[str] = []
        for _ in range(nvars):
            var_off = off
            text, off = _cstring(buf, off, limit, path, f"a variable name of event {name!r}")
            m = _VAR_RE.match(text)
            if m is None or m["type"] not in _TYPES:
                raise LogFormatError(
                    f"{path}: byte offset {var_off}: variable {text!r} of event {name!r}; "
                    f"expected 'name(T)' with T one of {''.join(_TYPES)}")
            if m["name"] in names:
                raise LogFormatError(
                    f"{path}: byte offset {var_off}: variable {m['name']!r} appears twice in "
                    f"event {name!r}; expected unique variable names")
            names.append(m["name"])
            chars.append(m["type"])
        types.append(SdEventType(eid, name, tuple(names), tuple(chars), start))
        seen_ids.add(eid)
        seen_names.add(name)
    return version, types, off


def _walk_records(buf: bytes, path: str, start: int, end: int, sizes: dict[int, int],
                  names: dict[int, str]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Offsets and ids of all records between ``start`` and ``end`` (the CRC).

    Events interleave, so record boundaries are only known by walking the headers one
    by one; this loop touches two bytes per record and leaves decoding to numpy.
    """
    offs: list[int] = []
    ids: list[int] = []
    add_off, add_id = offs.append, ids.append
    off = start
    while off < end:
        if off + 2 > end:
            raise LogFormatError(
                f"{path}: byte offset {off}: truncated record: {end - off} byte(s) left before "
                "the 4-byte CRC; expected a uint16 event id")
        eid = buf[off] | (buf[off + 1] << 8)
        size = sizes.get(eid)
        if size is None:
            known = ", ".join(f"{i} ({names[i]})" for i in sorted(names))
            raise LogFormatError(
                f"{path}: byte offset {off}: unknown event id {eid}; expected one of the ids "
                f"declared in the header: {known}")
        if off + size > end:
            raise LogFormatError(
                f"{path}: byte offset {off}: truncated record: event {names[eid]!r} needs "
                f"{size} bytes but only {end - off} remain before the 4-byte CRC")
        add_off(off)
        add_id(eid)
        off += size
    return np.asarray(offs, dtype=np.int64), np.asarray(ids, dtype=np.int64)


def parse_sdlog(data: bytes, source: str = "<bytes>", verify_crc: bool = True) -> SdLog:
    """Decode the bytes of a micro-SD log. ``source`` names the file in error messages.

    Raises LogFormatError on anything that does not follow the format (see the module
    docstring), naming the byte offset and what was expected; a CRC mismatch is an error
    unless ``verify_crc`` is False.
    """
    minimum = 1 + 2 + 2 + CRC_SIZE
    if len(data) < minimum:
        raise LogFormatError(
            f"{source}: byte offset {len(data)}: file is only {len(data)} bytes; expected at "
            f"least {minimum} (magic, version, event count, CRC-32)")
    end = len(data) - CRC_SIZE
    version, types, data_offset = _parse_header(data, source, end)
    ts_dtype, ts_scale = _TIMESTAMP[version]
    ts_size = np.dtype(ts_dtype).itemsize
    sizes = {et.event_id: 2 + ts_size + et.payload_size for et in types}
    names = {et.event_id: et.name for et in types}
    offsets, ids = _walk_records(data, source, data_offset, end, sizes, names)

    crc_stored = int.from_bytes(data[end:], "little")
    crc_computed = zlib.crc32(memoryview(data)[:end])
    if verify_crc and crc_stored != crc_computed:
        raise LogFormatError(
            f"{source}: byte offset {end}: CRC-32 mismatch: the last 4 bytes hold "
            f"0x{crc_stored:08X} but bytes 0..{end - 1} give 0x{crc_computed:08X}; the file "
            "is corrupt or was cut short")

    raw = np.frombuffer(data, dtype=np.uint8)
    events: dict[str, SdEvent] = {}
    for et in types:
        rec_dtype = np.dtype(
            [("__id", "<u2"), ("__ts", ts_dtype)]
            + [(v, _TYPES[c]) for v, c in zip(et.variables, et.types, strict=True)])
        offs = offsets[ids == et.event_id]
        # Gather each record's bytes into one contiguous row, then view the rows through
        # the packed structured dtype: one vectorised decode per event type.
        rows = raw[offs[:, None] + np.arange(rec_dtype.itemsize)]
        rec = np.ascontiguousarray(rows).view(rec_dtype).reshape(-1)
        values = {v: rec[v].astype(np.float64) for v in et.variables}
        events[et.name] = SdEvent(
            name=et.name, time=rec["__ts"].astype(np.float64) * ts_scale, values=values,
            offsets=offs)
    return SdLog(path=source, version=version, event_types=tuple(types), events=events,
                 data_offset=data_offset, crc_stored=crc_stored, crc_computed=crc_computed)


def read_sdlog_raw(path: str | Path, verify_crc: bool = True) -> SdLog:
    """Read and decode a micro-SD log file (see :func:`parse_sdlog`)."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if path.is_dir():
        raise LogFormatError(f"{path}: is a directory; expected a micro-SD log file")
    return parse_sdlog(path.read_bytes(), str(path), verify_crc=verify_crc)


# ----------------------------------------------------------------------------- flight layer

@dataclass(frozen=True)
class SdFlight:
    """A micro-SD log on the ``fixedFrequency`` grid (N rows), in SI units.

    log: the FlightLog (t starts at 0 at the first kept grid sample).
    pwm: (N, 4) motor commands M1..M4 [0..65535], NaN where not logged.
    rows: (N,) index into ``raw.events["fixedFrequency"]`` of each kept row (rows with a
        duplicate or backwards timestamp are dropped).
    pose_rows: (P,) grid row of each placed ``estPose`` sample.
    t0: device clock of row 0 [s].
    raw: the decoded file.
    """

    log: FlightLog
    pwm: Array
    rows: NDArray[np.int64]
    pose_rows: NDArray[np.int64]
    t0: float
    raw: SdLog


def _increasing_mask(t: Array) -> NDArray[np.bool_]:
    """Keep a sample only if it is later than every sample before it."""
    if t.size == 0:
        return np.zeros(0, dtype=bool)
    prev_max = np.maximum.accumulate(t)
    return np.concatenate([[True], t[1:] > prev_max[:-1]])


def _place_nearest(grid: Array, times: Array, tol: float) -> tuple[NDArray[np.int64],
                                                                   NDArray[np.int64]]:
    """Match sample times to their nearest grid time within ``tol`` [s].

    Returns (rows, which): ``grid[rows[k]]`` is matched to ``times[which[k]]``; a grid
    row receives at most one sample (the closest one).
    """
    j = np.searchsorted(grid, times)
    lo = np.clip(j - 1, 0, grid.size - 1)
    hi = np.clip(j, 0, grid.size - 1)
    pick_hi = np.abs(grid[hi] - times) < np.abs(grid[lo] - times)
    rows = np.where(pick_hi, hi, lo)
    dist = np.abs(grid[rows] - times)
    ok = np.flatnonzero(dist <= tol)
    order = ok[np.argsort(dist[ok], kind="stable")]
    _, first = np.unique(rows[order], return_index=True)
    which = np.sort(order[first])
    return rows[which].astype(np.int64), which.astype(np.int64)


def to_flight(raw: SdLog) -> SdFlight:
    """Map a decoded log onto the ``fixedFrequency`` grid (see the module docstring).

    Position and Euler angles come from the ``estPose`` motion-capture pose placed at
    the nearest grid row within half the median grid interval (NaN in all other rows);
    velocity from the onboard estimate ``stateEstimate.v{x,y,z}`` [m/s, world]; gyro
    [rad/s] = gyro.* [deg/s] * pi/180; accel [m/s^2] = acc.* [g] * 9.81; rpm [rev/min];
    vbat [V] = pm.vbatMV / 1000.
    """
    path = raw.path
    if GRID_EVENT not in raw.events:
        declared = ", ".join(repr(et.name) for et in raw.event_types) or "none"
        raise LogFormatError(
            f"{path}: byte offset 5: the header declares {declared}; expected an event type "
            f"named {GRID_EVENT!r} (the time grid of the flight)")
    grid = raw.events[GRID_EVENT]
    if grid.count == 0:
        raise LogFormatError(
            f"{path}: byte offset {raw.data_offset}: no {GRID_EVENT!r} record in the file; "
            "expected at least one")
    notes: list[str] = []
    if not raw.crc_ok:
        notes.append(f"CRC-32 mismatch (stored 0x{raw.crc_stored:08X}, computed "
                     f"0x{raw.crc_computed:08X}); decoded anyway")

    keep = _increasing_mask(grid.time)
    rows = np.flatnonzero(keep).astype(np.int64)
    dropped = grid.count - rows.size
    if dropped:
        notes.append(f"{GRID_EVENT}: dropped {dropped} of {grid.count} samples whose timestamp "
                     "did not increase (duplicate or backwards)")
    t0 = float(grid.time[rows[0]])
    t = grid.time[rows] - t0
    n = t.size
    if n > 1:
        steps = np.diff(t)
        dt_med = float(np.median(steps))
        big = int(np.argmax(steps))
        notes.append(f"{GRID_EVENT}: {n} samples, median interval {dt_med * 1e3:.2f} ms "
                     f"({1.0 / dt_med:.0f} Hz); longest gap {steps[big] * 1e3:.1f} ms "
                     f"at t = {t[big]:.3f} s")
    else:
        dt_med = float("nan")

    missing = sorted(v for v in (*[f"gyro.{a}" for a in "xyz"], *[f"acc.{a}" for a in "xyz"],
                                 *[f"stateEstimate.v{a}" for a in "xyz"], *_RPM_VARS,
                                 "pm.vbatMV", *_PWM_VARS) if not grid.has(v))
    if missing:
        notes.append(f"{GRID_EVENT}: not logged (NaN): {', '.join(missing)}")

    def cols(names: tuple[str, ...] | list[str], scale: float = 1.0) -> Array:
        return np.column_stack([grid.get(v)[rows] * scale for v in names])

    gyro = cols([f"gyro.{a}" for a in "xyz"], math.pi / 180.0)
    accel = cols([f"acc.{a}" for a in "xyz"], GRAVITY)
    velocity = cols([f"stateEstimate.v{a}" for a in "xyz"])
    rpm = cols(_RPM_VARS) if any(grid.has(v) for v in _RPM_VARS) else None
    vbat = grid.get("pm.vbatMV")[rows] / 1000.0 if grid.has("pm.vbatMV") else None
    pwm = cols(_PWM_VARS)

    position = np.full((n, 3), np.nan)
    euler = np.full((n, 3), np.nan)
    pose_rows = np.zeros(0, dtype=np.int64)
    pose = raw.events.get(POSE_EVENT)
    if pose is None or pose.count == 0:
        notes.append(f"no {POSE_EVENT!r} samples: position and attitude are NaN")
    elif n < 2:
        notes.append(f"only one {GRID_EVENT} sample: {POSE_EVENT} samples not placed")
    else:
        pkeep = np.flatnonzero(_increasing_mask(pose.time))
        if pkeep.size < pose.count:
            notes.append(f"{POSE_EVENT}: dropped {pose.count - pkeep.size} samples whose "
                         "timestamp did not increase")
        tp = pose.time[pkeep] - t0
        pose_rows, which = _place_nearest(t, tp, 0.5 * dt_med)
        src = pkeep[which]
        if pose_rows.size < pkeep.size:
            notes.append(f"{POSE_EVENT}: {pkeep.size - pose_rows.size} of {pkeep.size} samples "
                         f"had no {GRID_EVENT} row within half an interval "
                         f"({0.5 * dt_med * 1e3:.2f} ms) and were left out")
        p = np.column_stack([pose.get(v)[src] for v in _POSE_VARS])
        position[pose_rows] = p[:, :3]
        quat = p[:, 3:]
        norm = np.linalg.norm(quat, axis=1)
        # A zero or far-from-unit quaternion is a placeholder, not an attitude.
        good = np.isfinite(quat).all(axis=1) & (np.abs(norm - 1.0) < 0.1)
        if (~good).any():
            notes.append(f"{POSE_EVENT}: {int((~good).sum())} samples with a missing or "
                         "non-unit quaternion: attitude left NaN there")
        if good.any():
            euler[pose_rows[good]] = euler_from_quat_wxyz(quat[good] / norm[good, None])
        poses_hz = (pose_rows.size - 1) / (t[-1] - t[0]) if n > 1 else float("nan")
        notes.append(f"{POSE_EVENT}: {pose_rows.size} motion-capture poses placed "
                     f"({poses_hz:.0f} Hz on average)")

    meta = LogMeta(vehicle="crazyflie21", mass_guess=None, source=path, notes=tuple(notes),
                   actuation="sampled")  # rotor-speed readings, not held commands
    log = FlightLog(t=t, position=position, velocity=velocity, euler=euler, gyro=gyro,
                    accel=accel, rpm=rpm, vbat=vbat, meta=meta)
    return SdFlight(log=log, pwm=pwm, rows=rows, pose_rows=pose_rows, t0=t0, raw=raw)


def read_sdflight(path: str | Path, verify_crc: bool = True) -> SdFlight:
    """Read a micro-SD log and map it onto the ``fixedFrequency`` grid."""
    return to_flight(read_sdlog_raw(path, verify_crc=verify_crc))


def measured_samples(flight: SdFlight) -> MeasuredSamples:
    """What the flight carries beyond its grid rows: the motion-capture poses from the raw
    ``estPose`` records at their own times (not the copies snapped to the grid rows; a
    record no later than every earlier one is dropped; Euler angles NaN where the
    quaternion is missing or its norm is off 1 by 0.1 or more), the motor commands, and
    the onboard position estimate ``stateEstimate.x/y/z`` on the grid rows."""
    raw = flight.raw
    pose_t = pose_pos = pose_euler = None
    ev = raw.events.get(POSE_EVENT)
    if ev is not None and ev.count:
        t = ev.time - flight.t0
        keep = np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])
        pose_pos = np.column_stack([ev.get(f"locSrv.{a}") for a in "xyz"])[keep]
        quat = np.column_stack([ev.get(f"locSrv.q{a}") for a in "wxyz"])[keep]
        norm = np.linalg.norm(quat, axis=1)
        good = np.isfinite(quat).all(axis=1) & (np.abs(norm - 1.0) < 0.1)
        pose_euler = np.full((quat.shape[0], 3), np.nan)
        if good.any():
            pose_euler[good] = euler_from_quat_wxyz(quat[good] / norm[good, None])
        pose_t = t[keep]
    grid = raw.events[GRID_EVENT]
    onboard = None
    if all(grid.has(f"stateEstimate.{a}") for a in "xyz"):
        onboard = np.column_stack([grid.get(f"stateEstimate.{a}")[flight.rows] for a in "xyz"])
    return MeasuredSamples(pose_t=pose_t, pose_position=pose_pos, pose_euler=pose_euler,
                           pwm=flight.pwm, onboard_position=onboard)


def read_sdlog(path: str | Path) -> FlightLog:
    """Read a Crazyflie micro-SD log as a FlightLog (see :func:`to_flight`) with its
    :func:`measured_samples`.

    meta: vehicle ``crazyflie21``, no mass guess, source = the path, notes on dropped
    samples, gaps and pose placement. Raises LogFormatError.
    """
    flight = read_sdflight(path)
    return replace(flight.log, measured=measured_samples(flight))
