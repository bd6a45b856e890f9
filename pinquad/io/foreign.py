"""A flight written as another logger would write it: pinquad's columns converted to
declared conventions (``pinquad.io.declared.to_declared``), with or without the sidecar
keys that declare them. Reading such a file back with its declaration gives the flight
it came from; without it, ``pinquad.io.conventions_check`` names what is wrong."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pinquad.io.declared import Conventions, to_declared
from pinquad.io.logs import FlightLog, log_columns, sidecar
from pinquad.io.runs import atomic_write_bytes


def write_foreign(log: FlightLog, path: str | Path, conv: Conventions, declare: bool,
                  drop: tuple[str, ...] = ()) -> Path:
    """Write ``log`` as a Parquet file whose columns follow ``conv`` (minus the columns
    named in ``drop``, e.g. the quaternion to leave roll/pitch/yaw), and its sidecar,
    with ``conv``'s keys when ``declare``. Returns the path."""
    path = Path(path)
    cols = {k: v for k, v in to_declared(log_columns(log), conv).items() if k not in drop}
    buf = io.BytesIO()
    pq.write_table(pa.table({k: np.asarray(v, dtype=float) for k, v in cols.items()}), buf)
    atomic_write_bytes(path, buf.getvalue())
    side = {**sidecar(log.meta), **(conv.sidecar() if declare else {})}
    atomic_write_bytes(Path(str(path) + ".json"), json.dumps(side, indent=2).encode())
    return path
