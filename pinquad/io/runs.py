"""Run directories and all-or-nothing file writes (write to a temporary name, rename)."""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPORT_SCHEMA = "pinquad.report/1"
"""The ``schema`` of every report.json (DESIGN 4.3). Its keys keep their meaning; keys
are only ever added (``LOG_REPORT_KEYS``)."""

LOG_REPORT_KEYS: dict[str, str] = {
    "estimates": "the estimate under the final model: discovery's refit when effects were "
                 "selected, else the base fit (DESIGN 4.3 layout plus the keys below)",
    "estimates.verdict": "{'overall', 'reasons', 'parameters': {name: {'verdict', "
                         "'reasons'}}}; verdicts: trusted, not identifiable, model not "
                         "adequate, implausible (pinquad.identification.verdict)",
    "estimates.model": "the model the estimate was fitted under, in words",
    "estimates.stderr_note": "how its standard errors were computed",
    "base": "the base fit (the first run), the same layout as estimates",
    "verdict": "the headline's verdict, estimates.verdict repeated at the top",
    "runs[].estimates.verdict": "each run's own verdict",
    "source.log_type": "what the log carries, in words (thrust/torque commands, rotor "
                       "speeds, simulator truth)",
    "source.log_kind": "the internal kind (simulated: thrust/torque columns; sdlog; "
                       "measured-table)",
    "source.vehicle_named": "whether the log names its vehicle (sidecar 'vehicle', or a "
                            "micro-SD log); False: source.vehicle is the default, not the log's",
    "source.vehicle_note": "when the log names no vehicle, a sentence saying so and that the "
                           "viewer draws a quad of the identified mass; else null",
    "run_logs.log.em_history": "CSV of every run's EM iterates: run, sensor, mstep, iterate, "
                               "mass [kg], I_xx, I_yy, I_zz [kg m^2], loglik [nats], e_steps "
                               "(pinquad.report.run_tables)",
    "run_logs.log.step_residuals": "CSV per step: t [s], force_before, torque_before, "
                                   "force_after, torque_after: norms [N, N m] of the window-"
                                   "mean body-wrench residual before and after discovery's refit "
                                   "(null for the ten-parameter fit)",
    "run_logs.log.step_residuals_note": "how the residual sizes were computed, in words",
    "reference": "values of the vehicle known without the flight, when there are any: "
                 "{'mass' [kg], 'inertia_diag' [kg m^2], 'source'} (the Crazyflie 2.1's "
                 "scale mass and published inertia); null when none are known",
    "run_logs.log.mocap": "CSV of the raw motion-capture samples: t [s], x, y, z [m]",
}
"""Keys a recorded log's report.json (``offline --log``) adds to DESIGN 4.3, by dotted
path, with their meaning."""


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` whole or not at all, with the permissions an ordinary
    new file gets (mkstemp's temporary file is private to its owner)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_json(path: str | Path, obj: Any) -> Path:
    """Write a JSON document atomically (NaN written as null)."""
    return atomic_write_bytes(path, json.dumps(_clean(obj), indent=2).encode())


def _clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return None if math.isnan(f) or math.isinf(f) else f
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def new_run_dir(kind: str, root: str | Path = "runs") -> Path:
    """A fresh directory name ``runs/<kind>-YYYYmmdd-HHMMSS[-n]`` (not yet created)."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = Path(root) / f"{kind}-{stamp}"
    candidate, i = base, 1
    while candidate.exists():
        candidate = Path(f"{base}-{i}")
        i += 1
    return candidate


class RunWriter:
    """Collect a run's files in a hidden staging directory, then publish them at once.

    ``publish()`` renames the staging directory to the target, so a reader never sees a
    partly written run; if the run fails, the staging directory is removed. Used as a
    context manager (``with writer:``), an exception leaving the block aborts the run.
    """

    def __init__(self, target: str | Path):
        self.target = Path(target)
        if self.target.exists() and any(self.target.iterdir()):
            raise FileExistsError(f"{self.target}: output directory exists and is not empty")
        self.target.parent.mkdir(parents=True, exist_ok=True)
        self.staging = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.", dir=self.target.parent))

    def path(self, name: str) -> Path:
        """Where to write file ``name`` while staging."""
        p = self.staging / name
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def publish(self) -> Path:
        if self.target.exists():
            self.target.rmdir()
        os.replace(self.staging, self.target)
        return self.target

    def abort(self) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: object) -> None:
        if exc_type is not None:
            self.abort()
