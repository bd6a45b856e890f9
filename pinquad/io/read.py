"""Read any flight log pinquad knows: a Crazyflie micro-SD binary log, or a CSV or
Parquet table (DESIGN 4.2) with its JSON sidecar."""

from __future__ import annotations

from pathlib import Path

from pinquad.io import logs, sdlog
from pinquad.io.logs import FlightLog, LogFormatError


def read_log(path: str | Path) -> FlightLog:
    """The flight in ``path``, whatever its format (micro-SD logs are recognised by their
    content, tables by their suffix). Raises LogFormatError naming the file, and the
    column, row or byte offset, when it is not a readable log."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file; expected a CSV, Parquet or Crazyflie "
                             "micro-SD log")
    if path.is_dir():
        raise LogFormatError(f"{path}: is a directory; expected a log file")
    if sdlog.is_sdlog(path):
        return sdlog.read_sdlog(path)
    return logs.read_log(path)
