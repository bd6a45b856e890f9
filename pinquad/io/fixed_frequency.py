"""Reader for Crazyflie micro-SD deck *fixed-frequency* logs (the older, block-based
layout: one record of every configured variable per logger tick, e.g. 100 Hz).

File layout (integers little-endian, no padding):

* byte 0: uint8 number of variables V;
* V declarations ``name(T),``: ASCII name, a Python ``struct`` type character T in
  parentheses, a comma;
* 4 bytes of CRC over the header: ``zlib.crc32`` over the header bytes *and* these 4
  bytes is 0xFFFFFFFF;
* blocks to the end of the file: uint8 number of records K, K packed records (the V
  variables in declared order), 4 bytes of CRC (again: crc32 over count, records and
  CRC is 0xFFFFFFFF).

A block whose CRC fails is excluded: the reader looks for the next offset where a block
with a valid CRC starts (a false match has probability 2^-32) and goes on from there;
the count of excluded blocks and bytes goes into the log's notes. A damaged header, a
file that ends inside a block, or a file with no intact block is a LogFormatError
naming the byte offset and what was expected.

Two layers:

* :func:`parse_fixed_frequency` / :func:`read_fixed_frequency_raw` ->
  :class:`FixedFrequencyLog`: every variable as float64 in the log's own units;
* :func:`to_flight_log` (and :func:`read_fixed_frequency`) -> :class:`FlightLog` in SI
  units, pinquad's frames.

Signals of the Crazyswarm-style compressed state (``stateEstimateZ.*``) and the
controller's output (``motor.*``), converted at this boundary:

* time: variable ``tick`` [us] (the median step of 1e4 at 100 Hz; a median step below 50
  is read as ms) -> t [s] from the first kept row;
* position [mm] / 1000 -> [m, world]; velocity [mm/s] / 1000 -> [m/s, world];
* ``quat``: uint32 compressed quaternion (firmware ``quatcompress.h``): bits 31-30 give
  the index i of the largest component of (x, y, z, w); the other three in x, y, z, w
  order occupy ten bits each from bit 29 down, a sign bit over a 9-bit magnitude m, value
  +-m / 511 / sqrt(2); the largest is sqrt(1 - sum of their squares), >= 0. Read as the
  body-to-world rotation (checked on the flights: the attitude change over 0.2 s agrees
  with the integrated gyro to 0.002 rad RMS; the conjugate misses by 0.03 rad);
* body rates ``rateRoll, ratePitch, rateYaw`` [mrad/s] / 1000 -> gyro [rad/s, body x
  forward, y left, z up], all three with their logged sign (the flights' attitude
  change and commanded torques both say ``ratePitch`` is +omega_y here);
* ``ax, ay, az`` [mm/s^2]: the *world*-frame specific force with gravity added back on
  z (about +9.81 m/s^2 on az in hover; ax, ay follow dv/dt, correlation 0.96-0.99) ->
  body specific force acc = R^T (ax, ay, az) / 1000, the accelerometer convention of
  FlightLog;
* ``motor.thrust`` [N], ``motor.torquex/y/z`` [N m, body]: the controller's commanded
  collective thrust and torques, sampled at each row (``LogMeta.actuation`` ``sampled``,
  declared: the logger copies the 500 Hz controller's output at its tick);
* ``pm.vbatMV`` [mV] / 1000 -> vbat [V].

Records whose time stamp does not increase, or whose thrust or torques are not finite,
are dropped (counted in the notes). The rest are placed on a uniform grid at the median
interval (``place_on_grid``): a missed record (up to ``MAX_FILL`` in a row) leaves a row
of NaN measurements with interpolated commands; a longer gap splits the flight and the
longest stretch is kept, the rest noted as excluded.

The file name's ``cfNN`` part, when it is one of the Neural-Swarm data set's vehicles
(``BUILDS``), gives EM's starting guess (``LogMeta.mass_guess``, ``inertia_guess``) and
a note with the floor plane the data set states. It never names the vehicle
(``LogMeta.vehicle`` stays the default, ``vehicle_named`` False): a file name is weak
evidence, so the report compares with no vehicle's reference values unless the user
names one (``--vehicle``, or ``"vehicle"`` in the sidecar ``<log>.json``). LogMeta has no
floor-height field: the floor level is found from the data (``models.contact``).
"""

from __future__ import annotations

import math
import re
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import euler_from_rotation, rotation_from_quat_wxyz
from pinquad.io.logs import FlightLog, LogFormatError, LogMeta
from pinquad.io.sdlog import STRUCT_TYPES as _TYPES

Array = NDArray[np.float64]

CRC_SIZE = 4
CRC_RESIDUE = 0xFFFFFFFF
"""``zlib.crc32`` over a header or block together with its stored CRC."""
TIME_VARIABLE = "tick"
"""The logger's time stamp variable (uint32, us on the Neural-Swarm flights)."""
MS_BELOW = 50.0
"""A median tick step below this is read as milliseconds (1 kHz ticks), else as us."""
_DECL_RE = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_.\[\]]*)\((?P<type>.)\)$")
_SIGNATURE = re.compile(rb"\([bBhHiIlLqQefd?]\),")
_MAX_NAME = 128
MAX_FILL = 5
"""Most missed records in a row a grid row is filled for (50 ms at 100 Hz, about a
motor time constant: the commanded thrust and torques are interpolated across it);
across a longer gap the flight is split and its longest stretch kept."""
_PREFIX = "stateEstimateZ."
_THRUST, _TORQUES = "motor.thrust", ("motor.torquex", "motor.torquey", "motor.torquez")


@dataclass(frozen=True)
class Build:
    """A vehicle of the Neural-Swarm data set known by its file-name prefix.

    name: in words; floor [m]: the floor plane's height in the log's frame, as the data
    set states it; mass_guess [kg] and inertia_guess (3,) [kg m^2]: where EM starts
    (deliberately not the answer, as a vehicle file's ``[guess]``).
    """

    name: str
    floor: float
    mass_guess: float
    inertia_guess: tuple[float, float, float]


# crazyflie21's [guess]: 25 g and half the published Crazyflie 2.0 inertia
_STOCK = Build("Crazyflie 2.1, unmodified", 0.05, 0.025, (8.3e-6, 8.3e-6, 14.6e-6))
# the [guess] of docs/vehicles/cf21_parrot_frame.toml (50 g, two thirds of the geometric
# inertia estimate), so that a run without --vehicle starts where one with it does
_PARROT = Build("Crazyflie 2.1 on a Parrot frame (67 g)", 0.06, 0.050, (3.0e-5, 3.0e-5, 5.5e-5))
BUILDS: dict[str, Build] = {"cf50": _STOCK, "cf51": _STOCK, "cf52": _STOCK,
                            "cf100": _PARROT, "cf101": _PARROT, "cf102": _PARROT}
"""Neural-Swarm file-name prefix -> build (the data set's notes: cf50-52 unmodified,
floor plane 0.05 m; cf100-102 on the Parrot frame, 67 g, floor plane 0.06 m)."""


@dataclass(frozen=True)
class DamagedBlock:
    """A stretch of the file excluded for a failed CRC.

    offset: byte offset where the damaged block starts; length: bytes skipped up to the
    next intact block (or the end of the file); declared_records: the record count its
    first byte claims (itself possibly damaged).
    """

    offset: int
    length: int
    declared_records: int


@dataclass(frozen=True)
class FixedFrequencyLog:
    """A decoded fixed-frequency log, in the units of the device.

    path: where it was read from; variables: (V,) names without the type suffix;
    types: (V,) struct characters; values: name -> (R,) float64 per record, in file
    order; offsets: (R,) byte offset of each record; header_size: bytes of header and its
    CRC; blocks: intact blocks read; damaged: the blocks excluded for a failed CRC.
    """

    path: str
    variables: tuple[str, ...]
    types: tuple[str, ...]
    values: dict[str, Array]
    offsets: NDArray[np.int64]
    header_size: int
    blocks: int
    damaged: tuple[DamagedBlock, ...]

    @property
    def count(self) -> int:
        """Records decoded (R)."""
        return int(self.offsets.shape[0])

    def has(self, variable: str) -> bool:
        return variable in self.values

    def get(self, variable: str) -> Array:
        """(R,) values of ``variable``, all NaN when the log does not carry it."""
        out = self.values.get(variable)
        return np.full(self.count, np.nan) if out is None else out


def looks_like_fixed_frequency(head: bytes) -> bool:
    """Whether the first bytes of a file look like a fixed-frequency header: a non-zero
    variable count, then ``name(T),`` declarations (the signature ``(T),`` within the
    first 512 bytes). Loose on purpose: a header with a damaged byte is still recognised,
    and :func:`parse_fixed_frequency` names the offset of the damage."""
    return len(head) > 1 and head[0] > 0 and _SIGNATURE.search(head[:512]) is not None


def is_fixed_frequency(path: str | Path) -> bool:
    """True when the file starts like a fixed-frequency micro-SD log (by content, not
    name; see :func:`looks_like_fixed_frequency`)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError:
        return False
    return looks_like_fixed_frequency(head)


def _parse_header(buf: bytes, source: str) -> tuple[list[str], list[str], int]:
    n = buf[0]
    if n == 0:
        raise LogFormatError(f"{source}: byte offset 0: the header declares 0 variables; "
                             "expected a uint8 count of at least 1")
    names: list[str] = []
    types: list[str] = []
    off = 1
    for k in range(n):
        end = buf.find(b",", off, off + _MAX_NAME + 1)
        if end < 0:
            raise LogFormatError(
                f"{source}: byte offset {off}: declaration {k + 1} of {n} has no ',' within "
                f"{_MAX_NAME} bytes (truncated or damaged header); expected 'name(T),'")
        try:
            text = buf[off:end].decode("ascii")
        except UnicodeDecodeError:
            bad = off + next(i for i, c in enumerate(buf[off:end]) if c > 127)
            raise LogFormatError(
                f"{source}: byte offset {bad}: declaration {k + 1} of {n} holds byte "
                f"0x{buf[bad]:02X}; expected ASCII 'name(T),'") from None
        m = _DECL_RE.match(text)
        if m is None or m["type"] not in _TYPES:
            raise LogFormatError(
                f"{source}: byte offset {off}: declaration {k + 1} of {n} is {text!r}; "
                f"expected 'name(T)' with T one of {''.join(_TYPES)}")
        if m["name"] in names:
            raise LogFormatError(f"{source}: byte offset {off}: variable {m['name']!r} is "
                                 "declared twice; expected unique names")
        names.append(m["name"])
        types.append(m["type"])
        off = end + 1
    if off + CRC_SIZE > len(buf):
        raise LogFormatError(f"{source}: byte offset {off}: the file ends before the header's "
                             f"4-byte CRC; expected {CRC_SIZE} bytes, {len(buf) - off} remain")
    crc = zlib.crc32(memoryview(buf)[:off + CRC_SIZE])
    if crc != CRC_RESIDUE:
        raise LogFormatError(
            f"{source}: byte offset {off}: the header's CRC does not check (crc32 over bytes "
            f"0..{off + CRC_SIZE - 1} is 0x{crc:08X}; expected 0xFFFFFFFF): the header is "
            "damaged")
    return names, types, off + CRC_SIZE


def _block_ok(buf: bytes, off: int, record: int) -> int:
    """End offset of an intact block starting at ``off``, or -1."""
    end = off + 1 + buf[off] * record + CRC_SIZE
    if end > len(buf):
        return -1
    return end if zlib.crc32(memoryview(buf)[off:end]) == CRC_RESIDUE else -1


def _resync(buf: bytes, start: int, record: int, max_count: int) -> int:
    """The first offset after ``start`` where an intact block of at most ``max_count``
    records starts, or len(buf). (Bounding the count bounds the CRC work per candidate
    offset to about one block's bytes.)"""
    for off in range(start + 1, len(buf)):
        if buf[off] <= max_count and _block_ok(buf, off, record) >= 0:
            return off
    return len(buf)


def _walk_blocks(buf: bytes, source: str, start: int, record: int
                 ) -> tuple[list[int], int, list[DamagedBlock]]:
    """Record offsets of every intact block from ``start``, the number of intact blocks,
    and the damaged stretches excluded."""
    offsets: list[int] = []
    damaged: list[DamagedBlock] = []
    blocks = most = 0
    off = start
    size = len(buf)
    while off < size:
        count = buf[off]
        end = _block_ok(buf, off, record)
        if end >= 0:
            offsets.extend(range(off + 1, off + 1 + count * record, record))
            blocks += 1
            most = max(most, count)
            off = end
            continue
        # the next intact block holds no more records than the largest seen so far
        nxt = _resync(buf, off, record, most or 255)
        if nxt == size and off + 1 + count * record + CRC_SIZE > size:
            raise LogFormatError(
                f"{source}: byte offset {off}: the file ends inside a data block: its count "
                f"byte says {count} records of {record} bytes, {1 + count * record + CRC_SIZE} "
                f"bytes with the CRC, but {size - off} remain; expected whole blocks "
                "(truncated file)")
        damaged.append(DamagedBlock(off, nxt - off, count))
        off = nxt
    return offsets, blocks, damaged


def parse_fixed_frequency(data: bytes, source: str = "<bytes>") -> FixedFrequencyLog:
    """Decode the bytes of a fixed-frequency log (module docstring). ``source`` names the
    file in error messages. Raises LogFormatError naming the byte offset and what was
    expected."""
    if len(data) < 2:
        raise LogFormatError(f"{source}: byte offset {len(data)}: file is only {len(data)} "
                             "bytes; expected a variable count and declarations")
    names, types, start = _parse_header(data, source)
    dtype = np.dtype([(v, _TYPES[c]) for v, c in zip(names, types, strict=True)])
    offsets, blocks, damaged = _walk_blocks(data, source, start, dtype.itemsize)
    if not offsets:
        what = (f"{len(damaged)} damaged block(s)" if damaged else "no data block")
        raise LogFormatError(f"{source}: byte offset {start}: {what} after the header and no "
                             "intact record; expected at least one block with a valid CRC")
    offs = np.asarray(offsets, dtype=np.int64)
    raw = np.frombuffer(data, dtype=np.uint8)
    rows = np.ascontiguousarray(raw[offs[:, None] + np.arange(dtype.itemsize)])
    rec = rows.view(dtype).reshape(-1)
    values = {v: rec[v].astype(np.float64) for v in names}
    return FixedFrequencyLog(path=source, variables=tuple(names), types=tuple(types),
                             values=values, offsets=offs, header_size=start, blocks=blocks,
                             damaged=tuple(damaged))


def read_fixed_frequency_raw(path: str | Path) -> FixedFrequencyLog:
    """Read and decode a fixed-frequency log file (see :func:`parse_fixed_frequency`)."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if path.is_dir():
        raise LogFormatError(f"{path}: is a directory; expected a micro-SD log file")
    return parse_fixed_frequency(path.read_bytes(), str(path))


def decompress_quaternion(comp: Array) -> Array:
    """(R, 4) unit quaternions (w, x, y, z) of (R,) compressed uint32 values (module
    docstring; the firmware's order is x, y, z, w). NaN rows where the three small
    components' squares sum above 1 (a value no compression produces)."""
    c = np.asarray(comp, dtype=np.float64).astype(np.uint64)
    largest = (c >> np.uint64(30)).astype(np.int64)
    xyzw = np.zeros((c.shape[0], 4))
    rest = c.copy()
    for i in range(3, -1, -1):
        take = largest != i
        mag = (rest & np.uint64(511)).astype(np.float64)
        neg = ((rest >> np.uint64(9)) & np.uint64(1)).astype(bool)
        value = np.where(neg, -mag, mag) / 511.0 / math.sqrt(2.0)
        xyzw[take, i] = value[take]
        rest = np.where(take, rest >> np.uint64(10), rest)
    small = np.sum(xyzw ** 2, axis=1)
    with np.errstate(invalid="ignore"):
        big = np.sqrt(1.0 - small)
    xyzw[np.arange(c.shape[0]), largest] = big
    return np.column_stack([xyzw[:, 3], xyzw[:, :3]])


def build_of(path: str | Path) -> tuple[str, Build] | None:
    """(prefix, build) when the file name starts with a Neural-Swarm vehicle's ``cfNN``
    (after an experiment name: ``randomwalk_l_cf102_01`` -> cf102), else None."""
    for part in Path(path).name.lower().split("_"):
        if part in BUILDS:
            return part, BUILDS[part]
    return None


def _time_seconds(tick: Array, notes: list[str]) -> Array:
    """Seconds from the time stamps (uint32 wrap-around undone; us or ms by the median
    step, ``MS_BELOW``)."""
    steps = np.diff(tick)
    wraps = np.concatenate([[0.0], np.cumsum(np.where(steps < -2.0 ** 31, 2.0 ** 32, 0.0))])
    tick = tick + wraps
    positive = np.diff(tick)
    positive = positive[positive > 0]
    median = float(np.median(positive)) if positive.size else 1.0
    scale = 1e-3 if median < MS_BELOW else 1e-6
    notes.append(f"time: '{TIME_VARIABLE}' read in {'ms' if scale == 1e-3 else 'us'} (median "
                 f"step {median:.0f})")
    return tick * scale


def _keep_rows(t: Array, act: Array) -> NDArray[np.bool_]:
    """Rows later than every row before them, with finite actuation."""
    later = np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])
    return later & np.isfinite(act).all(axis=1)


def _require(raw: FixedFrequencyLog, names: tuple[str, ...], what: str) -> None:
    missing = [v for v in names if not raw.has(v)]
    if missing:
        raise LogFormatError(
            f"{raw.path}: byte offset 1: the header declares no {', '.join(missing)}; expected "
            f"{what} (declared: {', '.join(raw.variables)})")


@dataclass(frozen=True)
class Grid:
    """Where the kept records sit on the uniform grid t_k = k dt (k = 0 .. N-1).

    dt [s]: the median interval of the records; records (M,): index into the raw
    records of each kept one; slots (M,): its grid row (nearest slot; the logger writes
    one record per tick, its time stamps jitter by under 7 % of a step); n: grid rows
    N; filled: grid rows without a record (a missed record within ``MAX_FILL`` slots).
    """

    dt: float
    records: NDArray[np.int64]
    slots: NDArray[np.int64]
    n: int

    @property
    def filled(self) -> int:
        return self.n - int(self.records.shape[0])


def place_on_grid(t: Array, keep: NDArray[np.bool_], notes: list[str]) -> Grid:
    """The kept records (``keep``, times ``t`` [s]) on a uniform grid: each at its nearest
    slot after the previous one; of the stretches between gaps of more than ``MAX_FILL``
    missing records, the longest is kept (the others noted as excluded)."""
    rows = np.flatnonzero(keep)
    tk = t[rows]
    dt = float(np.median(np.diff(tk)))
    step = np.maximum(np.round(np.diff(tk) / dt), 1).astype(np.int64)
    slot = np.concatenate([[0], np.cumsum(step)])
    cuts = np.flatnonzero(step - 1 > MAX_FILL)
    pieces = np.split(np.arange(rows.size), cuts + 1)
    best = max(pieces, key=lambda b: slot[b[-1]] - slot[b[0]])
    if len(pieces) > 1:
        t0 = tk[0]
        dropped = [f"{tk[b[0]] - t0:.2f}-{tk[b[-1]] - t0:.2f} s" for b in pieces if b is not best]
        gaps = ", ".join(f"{(step[c] - 1) * dt * 1e3:.0f} ms at {tk[c] - t0:.2f} s" for c in cuts)
        notes.append(f"gaps of more than {MAX_FILL} missed records ({gaps}): kept the longest "
                     f"stretch, {tk[best[0]] - t0:.2f}-{tk[best[-1]] - t0:.2f} s of the file; "
                     f"excluded {', '.join(dropped)}")
    return Grid(dt=dt, records=rows[best], slots=slot[best] - slot[best[0]],
                n=int(slot[best[-1]] - slot[best[0]] + 1))


def to_flight_log(raw: FixedFrequencyLog) -> FlightLog:
    """The flight in SI units and pinquad's frames (module docstring) on a uniform grid
    (:func:`place_on_grid`): rows without a record hold NaN measurements and the
    commanded thrust and torques interpolated linearly between their neighbours. Raises
    LogFormatError when the time stamp or the actuation (thrust and torques) is not
    declared, or fewer than two records are usable."""
    _require(raw, (TIME_VARIABLE,), "the logger's time stamp")
    _require(raw, (_THRUST, *_TORQUES), "the commanded thrust [N] and torques [N m]")
    notes: list[str] = []
    if raw.damaged:
        lost = sum(d.length for d in raw.damaged)
        where = ", ".join(f"byte {d.offset}" for d in raw.damaged[:5])
        notes.append(f"CRC: {len(raw.damaged)} damaged block(s) excluded ({lost} bytes, at "
                     f"{where}{', ...' if len(raw.damaged) > 5 else ''}); {raw.blocks} intact "
                     "blocks read")
    t_all = _time_seconds(raw.get(TIME_VARIABLE), notes)
    act_all = np.column_stack([raw.get(_THRUST), *(raw.get(v) for v in _TORQUES)])
    keep = _keep_rows(t_all, act_all)
    if (~keep).any():
        notes.append(f"dropped {int((~keep).sum())} of {raw.count} records (time stamp not "
                     "increasing, or thrust / torques not finite)")
    if keep.sum() < 2:
        raise LogFormatError(f"{raw.path}: byte offset {raw.header_size}: {int(keep.sum())} "
                             "usable record(s); expected at least two")
    grid = place_on_grid(t_all, keep, notes)
    rows, slots, n = grid.records, grid.slots, grid.n
    notes.append(f"{n} rows of {grid.dt * 1e3:.2f} ms ({1.0 / grid.dt:.0f} Hz); {grid.filled} "
                 f"without a record (missed records, at most {MAX_FILL} in a row): "
                 "measurements NaN, thrust and torques interpolated")

    def cols(names: list[str], scale: float) -> Array:
        out = np.full((n, len(names)), np.nan)
        out[slots] = np.column_stack([raw.get(v)[rows] * scale for v in names])
        return out

    position = cols([f"{_PREFIX}{a}" for a in "xyz"], 1e-3)
    velocity = cols([f"{_PREFIX}v{a}" for a in "xyz"], 1e-3)
    gyro = cols([f"{_PREFIX}rate{a}" for a in ("Roll", "Pitch", "Yaw")], 1e-3)
    accel_world = cols([f"{_PREFIX}a{a}" for a in "xyz"], 1e-3)
    quat = np.full((n, 4), np.nan)
    if raw.has(f"{_PREFIX}quat"):
        quat[slots] = decompress_quaternion(raw.get(f"{_PREFIX}quat")[rows])
        bad = int((~np.isfinite(quat[slots]).all(axis=1)).sum())
        if bad:
            notes.append(f"{bad} records with an invalid compressed quaternion: attitude and "
                         "accelerometer NaN there")
    ok = np.isfinite(quat).all(axis=1)
    euler = np.full((n, 3), np.nan)
    accel = np.full((n, 3), np.nan)
    if ok.any():
        rot = rotation_from_quat_wxyz(quat[ok])
        euler[ok] = euler_from_rotation(rot)
        accel[ok] = np.einsum("nji,nj->ni", rot, accel_world[ok])  # R^T a_world
    absent = [v for v in (*(f"{_PREFIX}{a}" for a in ("x", "y", "z", "vx", "vy", "vz", "ax",
                                                      "ay", "az", "quat", "rateRoll",
                                                      "ratePitch", "rateYaw")), "pm.vbatMV")
              if not raw.has(v)]
    if absent:
        notes.append(f"not logged (NaN): {', '.join(absent)}")
    notes.append("state: the onboard estimate (stateEstimateZ: motion capture fused on "
                 "board); accelerometer: the logged world-frame specific force rotated into "
                 "the body frame")
    notes.append("actuation: the controller's commanded thrust and torques, sampled at "
                 "each row (not measured)")
    k = np.arange(n)
    act = np.column_stack([np.interp(k, slots, act_all[rows, j]) for j in range(4)])
    vbat = (np.interp(k, slots, raw.get("pm.vbatMV")[rows] / 1000.0)
            if raw.has("pm.vbatMV") else None)
    return FlightLog(t=k * grid.dt, position=position, velocity=velocity, euler=euler,
                     gyro=gyro, accel=accel, thrust=act[:, 0], torque=act[:, 1:4], vbat=vbat,
                     meta=_meta(raw.path, notes))


def _meta(path: str, notes: list[str]) -> LogMeta:
    """LogMeta of a fixed-frequency log: the build its file name suggests (``BUILDS``)
    gives the starting guess; the vehicle stays unnamed (``paper``, ``vehicle_named``
    False), as the file name is weak evidence."""
    found = build_of(path)
    mass_guess = inertia_guess = None
    if found is not None:
        prefix, build = found
        mass_guess, inertia_guess = build.mass_guess, np.diag(build.inertia_guess)
        notes.append(
            f"file name prefix {prefix}: the Neural-Swarm data set's {build.name}, taken "
            f"as weak evidence: EM starts from {build.mass_guess * 1e3:.0f} g, inertia "
            f"diagonal {', '.join(f'{v:.3g}' for v in build.inertia_guess)} kg m^2, and the "
            "vehicle is not named (give --vehicle to name it); the data set puts the floor "
            f"plane at z = {build.floor:.2f} m in this log's frame (pinquad finds the floor "
            "level from the data)")
    return LogMeta(mass_guess=mass_guess, inertia_guess=inertia_guess, source=path,
                   notes=tuple(notes), actuation="sampled", actuation_declared=True,
                   vehicle_named=False)


def read_fixed_frequency(path: str | Path) -> FlightLog:
    """Read a fixed-frequency micro-SD log as a FlightLog (see :func:`to_flight_log`).
    Raises LogFormatError."""
    return to_flight_log(read_fixed_frequency_raw(path))
