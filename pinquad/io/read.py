"""Read any flight log pinquad knows: a Crazyflie micro-SD binary log, or a CSV or
Parquet table (the columns of ``pinquad.io.logs``) with its JSON sidecar."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.core.vehicle_file import SHIPPED, is_vehicle_file
from pinquad.io import ddd_csv, fixed_frequency, imu_log, logs, sdlog, ulog
from pinquad.io.command_log import CommandLog
from pinquad.io.logs import FlightLog, LogFormatError, vehicle_file_named


def read_log(path: str | Path, vehicle: str | None = None) -> FlightLog:
    """The flight in ``path``, whatever its format: a Crazyflie micro-SD binary log
    (recognised by its content), a CSV or Parquet table (by its suffix; the log columns of
    ``pinquad.io.logs``) with its optional JSON sidecar, or a file that starts like a
    fixed-frequency header. vehicle: a shipped vehicle name or a ``.toml`` vehicle file
    (relative to the working directory) that overrides the log's sidecar (``offline --log
    PATH --vehicle``; None: the log's own). Raises LogFormatError naming the file, and the
    column, row or byte offset, when it is not a readable log, or the vehicle when it is
    not one."""
    log = _read_any(Path(path))
    return log if vehicle is None else with_vehicle(log, vehicle, Path.cwd(), "--vehicle")


def _read_any(path: Path) -> FlightLog:
    """The flight in ``path`` as its sidecar describes it (:func:`read_log`)."""
    if not path.exists():
        raise LogFormatError(f"{path}: no such file; expected a CSV, Parquet or Crazyflie "
                             "micro-SD log")
    if path.is_dir():
        raise LogFormatError(f"{path}: is a directory; expected a log file")
    if sdlog.is_sdlog(path):
        log = sdlog.read_sdlog(path)
        if log.rpm is None and not (np.isfinite(log.position).any()
                                    or np.isfinite(log.velocity).any()):
            raise LogFormatError(f"{path}: onboard IMU and motor commands only (no pose, "
                                 "velocity or rotor speed): identify it with python -m "
                                 "pinquad.offline --log FILE --mass KG --vehicle FILE "
                                 "(known-mass mode, docs/imu_only.md)")
        return with_sidecar_vehicle(log)
    if is_command_log(path):
        read_command_log(path)  # its own errors first (e.g. no armed flight segment)
        raise LogFormatError(f"{path}: a PX4 log: its actuation is motor commands, not thrust "
                             "or rotor speeds; identify it with python -m pinquad.offline "
                             "--log FILE --mass KG --vehicle FILE (known-mass mode, "
                             "docs/px4.md)")
    if _is_fixed_frequency(path):
        return with_sidecar_vehicle(fixed_frequency.read_fixed_frequency(path))
    return logs.read_table(path)


def is_command_log(path: Path) -> bool:
    """Whether a file is a PX4 log: a ULog by its magic bytes, or a CSV with the
    data-driven-dynamics columns (``pinquad.io.ddd_csv``)."""
    return ulog.is_ulog(path) or ddd_csv.is_ddd_csv(path)


def read_command_log(path: str | Path) -> CommandLog:
    """The flight in a PX4 log (ULog or data-driven-dynamics CSV) or a Crazyflie micro-SD
    log read as IMU-only (``pinquad.io.imu_log``), motor commands as its actuation.
    Raises LogFormatError naming the file and what was expected."""
    path = Path(path)
    if not path.is_file():
        raise LogFormatError(f"{path}: no such file; expected a PX4 ULog (.ulg), a "
                             "data-driven-dynamics CSV or a Crazyflie micro-SD log")
    if ulog.is_ulog(path):
        return ulog.read_ulog(path)
    if sdlog.is_sdlog(path):
        return imu_log.read_imu_log(path)
    if path.suffix.lower() == ".csv":
        return ddd_csv.read_ddd_csv(path)  # names the columns it lacks
    raise LogFormatError(f"{path}: neither a ULog (magic bytes 'ULog') nor a CSV with the "
                         f"data-driven-dynamics columns ({', '.join(ddd_csv.REQUIRED)})")


def _is_fixed_frequency(path: Path) -> bool:
    """Not a table or sidecar by its suffix, and a fixed-frequency header by its content."""
    return (path.suffix.lower() not in (".csv", ".parquet", ".json")
            and fixed_frequency.is_fixed_frequency(path))


def is_flight_log(path: Path) -> bool:
    """Whether a file is a log :func:`read_log` reads: a CSV or Parquet table by its
    suffix, a Crazyflie micro-SD log by its content (a sidecar ``.json`` is not)."""
    if path.suffix.lower() in (".csv", ".parquet"):
        return True
    return path.suffix.lower() != ".json" and sdlog.is_sdlog(path)


def with_sidecar_vehicle(log: FlightLog) -> FlightLog:
    """A micro-SD log with the vehicle its sidecar ``<log>.json`` names (``"vehicle"``: a
    shipped name or a vehicle file, relative to the sidecar), if it has one. Raises
    LogFormatError for an unreadable sidecar or vehicle file."""
    side = Path(str(log.meta.source) + ".json")
    if not side.exists():
        return log
    try:
        raw = json.loads(side.read_text(encoding="utf-8-sig", errors="replace"))
    except json.JSONDecodeError as exc:
        raise LogFormatError(f"{side}: not valid JSON ({exc.msg} at byte {exc.pos})") from None
    vehicle = raw.get("vehicle") if isinstance(raw, dict) else None
    if vehicle is None:
        return log
    return with_vehicle(log, vehicle, side.parent, side)


def with_vehicle(log: FlightLog, vehicle: str, base: Path, where: Path | str) -> FlightLog:
    """The log with its vehicle set: a shipped name (``paper``, ``crazyflie21``) or a
    ``.toml`` vehicle file (relative to ``base``; read to check it). Raises
    LogFormatError naming ``where`` otherwise."""
    if not isinstance(vehicle, str) or not (vehicle in SHIPPED or is_vehicle_file(vehicle)):
        raise LogFormatError(f"{where}: vehicle {vehicle!r}: expected one of "
                             f"{', '.join(SHIPPED)} or a path to a .toml vehicle file")
    if is_vehicle_file(vehicle):
        vehicle = vehicle_file_named(vehicle, base, where)
    return replace(log, meta=replace(log.meta, vehicle=vehicle, vehicle_named=True))
