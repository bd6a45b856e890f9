"""The CSV layout of PX4's data-driven-dynamics pipeline (a ULog resampled to one row per
time step), read into a :class:`pinquad.io.command_log.CommandLog`.

Columns: ``timestamp`` [us from boot]; ``u0..u{k-1}`` motor outputs (PWM [us], or
normalized 0..1 when every value lies in [0, 1]); ``vx, vy, vz`` [m/s, NED];
``q0..q3`` (w, x, y, z, FRD body to NED); ``ang_vel_x/y/z`` [rad/s, FRD];
``acc_b_x/y/z`` [m/s^2, FRD body specific force, -9.81 on z at hover]; optional
``x, y, z`` [m, NED] and ``landed`` (rows with landed = 1 are dropped). Other columns
(``ang_acc_b_*``, the pipeline's numerical derivative, aux channels) are not read:
pinquad differentiates the gyro itself.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from pinquad.core.conventions import quat_wxyz_from_ned_frd, vector_from_ned_frd
from pinquad.io.command_log import CommandLog, command_log
from pinquad.io.errors import LogFormatError

REQUIRED = ("timestamp", "u0", "vx", "vy", "vz", "q0", "q1", "q2", "q3", "ang_vel_x",
            "ang_vel_y", "ang_vel_z", "acc_b_x", "acc_b_y", "acc_b_z")
"""The columns that make a CSV a data-driven-dynamics log."""

PWM_RANGE = (1000.0, 2000.0)
"""PX4's default PWM output range [us] (PWM_MAIN_MIN, PWM_MAIN_MAX): 0 and 1 of the
normalized command, unless the caller says otherwise."""


def csv_header(path: Path) -> list[str]:
    """The first row of a CSV file, stripped (empty when unreadable)."""
    try:
        with path.open(encoding="utf-8-sig", errors="replace", newline="") as fh:
            return [h.strip() for h in next(csv.reader(fh), [])]
    except (OSError, csv.Error):
        return []


def is_ddd_csv(path: Path) -> bool:
    """Whether ``path`` is a CSV whose header holds every data-driven-dynamics column
    (``REQUIRED``)."""
    return path.suffix.lower() == ".csv" and set(REQUIRED) <= set(csv_header(path))


def _columns(path: Path) -> dict[str, np.ndarray]:
    with path.open(encoding="utf-8-sig", errors="replace", newline="") as fh:
        rows = [r for r in csv.reader(fh) if any(c.strip() for c in r)]
    header = [h.strip() for h in rows[0]]
    if len(rows) < 3:
        raise LogFormatError(f"{path}: {len(rows) - 1} data rows; expected a flight")
    wanted = {name: header.index(name) for name in header if name}
    out = {name: np.empty(len(rows) - 1) for name in wanted}
    for r, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise LogFormatError(f"{path}: data row {r + 1} has {len(row)} fields; expected "
                                 f"{len(header)} (one per header column)")
        for name, c in wanted.items():
            try:
                out[name][r] = float(row[c])
            except ValueError:
                raise LogFormatError(f"{path}: data row {r + 1}, column {name!r}: {row[c]!r} is "
                                     "not a number") from None
    return out


def read_ddd_csv(path: str | Path, command_range: tuple[float, float] | None = None
                 ) -> CommandLog:
    """The flight in a data-driven-dynamics CSV (module docstring). command_range: the
    raw motor outputs of 0 and 1 (default ``PWM_RANGE`` for PWM, (0, 1) for normalized
    outputs). Raises LogFormatError naming the file, row and column."""
    path = Path(path)
    missing = [c for c in REQUIRED if c not in csv_header(path)]
    if missing:
        raise LogFormatError(f"{path}: lacks column(s) {', '.join(missing)}; expected the "
                             f"data-driven-dynamics layout ({', '.join(REQUIRED)})")
    cols = _columns(path)
    if "landed" in cols:
        keep = cols["landed"] < 0.5
        if not keep.any():
            raise LogFormatError(f"{path}: column 'landed' is 1 in every row; no airborne "
                                 "flight segment")
        cols = {k: v[keep] for k, v in cols.items()}
    k = 1
    while f"u{k}" in cols:
        k += 1
    raw = np.column_stack([cols[f"u{i}"] for i in range(k)])
    for name, values in cols.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size and name in (*REQUIRED, *(f"u{i}" for i in range(k))):
            raise LogFormatError(f"{path}: column {name!r}, data row {bad[0] + 1}: not a "
                                 "finite number")
    t_us = cols["timestamp"]
    steps = np.diff(t_us)
    if (steps <= 0).any():
        bad = int(np.flatnonzero(steps <= 0)[0]) + 2
        raise LogFormatError(f"{path}: column 'timestamp' is not strictly increasing at data "
                             f"row {bad}; expected microseconds from boot")
    normalized = bool(((raw >= 0.0) & (raw <= 1.0)).all())
    notes: tuple[str, ...] = ()
    if command_range is None:
        command_range = (0.0, 1.0) if normalized else PWM_RANGE
        if not normalized:
            notes = (f"motor outputs read as PWM, {PWM_RANGE[0]:.0f}-{PWM_RANGE[1]:.0f} us = "
                     "0-1 (PX4's default range; the CSV does not say)",)

    def vec(prefix: str, axes: str = "xyz") -> np.ndarray:
        return vector_from_ned_frd(np.column_stack([cols[f"{prefix}{a}"] for a in axes]))

    position = vec("", "xyz") if all(a in cols for a in "xyz") else None
    quat = quat_wxyz_from_ned_frd(np.column_stack([cols[f"q{i}"] for i in range(4)]))
    return command_log(t_us, vec("v", "xyz"), quat, vec("ang_vel_"), vec("acc_b_"), raw,
                       command_range, str(path), position=position, notes=notes)
