"""Run directories and all-or-nothing file writes (write to a temporary name, rename)."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import tempfile
import threading
import time
import weakref
from pathlib import Path
from typing import Any

import numpy as np

REPORT_SCHEMA = "pinquad.report/1"
"""The ``schema`` of every report.json. Its keys keep their meaning; keys
are only ever added (``LOG_REPORT_KEYS``)."""

LOG_REPORT_KEYS: dict[str, str] = {
    "estimates": "the estimate under the final model: discovery's refit when effects were "
                 "selected, else the base fit (every report.json's estimate keys plus the keys below)",
    "estimates.verdict": "{'overall', 'reasons', 'parameters': {name: {'verdict', "
                         "'reasons'}}}; verdicts: trusted, not judged, not identifiable, "
                         "model not adequate, implausible (pinquad.identification.verdict)",
    "estimates.stderr_parts": "the error budget: {part: {'mass' [kg], 'inertia_diag' [kg m^2] "
                              "(3)}} for statistical, thrust_calibration, "
                              "yaw_torque_coefficient, arm_length, input_reading, "
                              "between_flights (and rotor_speed_repair); 'assumed': the "
                              "relative uncertainties and where each came from; "
                              "estimates.stderr is their root sum of squares "
                              "(pinquad.identification.budget)",
    "search_range": "where EM searched mass and inertia: {'mass': [lo, hi] [kg], "
                    "'inertia_lo', 'inertia_hi' (3) [kg m^2], 'source'}; null: unbounded "
                    "(pinquad.identification.search_range)",
    "discovery.not_run": "why discovery did not run on this base fit (unconverged, or outside "
                         "the physical set and no effect brings it inside), else null",
    "discovery.note": "what discovery looked for when the base fit's inertia is undetermined",
    "discovery.unphysical": "effects whose best fit is outside their physical domain, not "
                            "kept: [{'effect', 'reason', 'closest_unphysical_fit', 'stderr', "
                            "'unexplained_rows': {axis: {'rms_before', 'rms_after', 'share'}}}]",
    "discovery.ground_effect_floor": "where the ground-effect law puts the floor: {'height' [m], "
                                     "'source' (flags, contact or none: z = 0), 'note'}; null "
                                     "when discovery did not reach the log",
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
"""Keys a recorded log's report.json (``offline --log``) adds to that layout, by dotted
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


def without_wall_times(value: Any) -> Any:
    """A report's JSON value (report.json, batch.json) with every wall time (the keys
    ``seconds``, at any depth) left out: what two runs of the same task must agree on."""
    if isinstance(value, dict):
        return {k: without_wall_times(v) for k, v in value.items() if k != "seconds"}
    if isinstance(value, list):
        return [without_wall_times(v) for v in value]
    return value


def new_run_dir(kind: str, root: str | Path = "runs") -> Path:
    """A fresh directory name ``runs/<kind>-YYYYmmdd-HHMMSS[-n]`` (not yet created)."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = Path(root) / f"{kind}-{stamp}"
    candidate, i = base, 1
    while candidate.exists():
        candidate = Path(f"{base}-{i}")
        i += 1
    return candidate


class OutputError(ValueError):
    """An output path that cannot take a run: the message names the path and why."""


def _writable_dir(directory: Path, what: Path) -> None:
    """Raise OutputError unless ``directory`` (created later if missing) can be written:
    its nearest existing ancestor is a writable directory."""
    probe = directory
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise OutputError(f"{what}: {probe} is a file, not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"{what}: cannot write in {probe} (permission denied)")


def check_output_file(path: str | Path) -> Path:
    """Check before any work that a result file can be written at ``path``: not a
    directory, in a writable directory. Raises OutputError."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path}: is a directory; expected a file name for the result")
    _writable_dir(path.parent, path)
    return path


def check_output_directory(path: str | Path) -> Path:
    """Check before any work that result files can be written into the directory
    ``path`` (created later if missing): not a file, in a writable place. Raises
    OutputError."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{path}: is a file; expected an output directory")
    _writable_dir(path, path)
    return path


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def _release(lock: Path, token: str) -> None:
    try:
        if lock.read_text() == token:
            lock.unlink()
    except OSError:
        pass


class RunWriter:
    """Collect a run's files in a hidden staging directory, then publish them at once.

    The constructor checks the target before any work (a directory that can be written,
    empty or absent, not in use) and takes a lock file ``.NAME.lock`` beside it holding
    this process's id, so a second run to the same directory is refused at its start
    instead of losing its work at the end (a lock whose process has died is taken over;
    the lock goes when the writer publishes, aborts or is dropped). ``publish()`` renames
    the staging directory to the target, so a reader never sees a partly written run; if
    the run fails, the staging directory is removed. Used as a context manager (``with
    writer:``), an exception leaving the block aborts the run, and SIGTERM (``timeout``,
    a service manager) inside the block is turned into KeyboardInterrupt so it cleans up
    like Ctrl-C. Raises OutputError when the target cannot take the run.

    replace=True makes the writer idempotent, for a task that may be run again (a Dask
    worker killed mid-task): a non-empty target is this task's own earlier output and is
    replaced at ``publish()``, and the staging directory has a fixed name
    ``.NAME.partial`` so a rerun removes what a killed attempt left half written.
    """

    def __init__(self, target: str | Path, *, replace: bool = False):
        self.target = Path(target)
        self.replace = replace
        if self.target.exists() and not self.target.is_dir():
            raise OutputError(f"{self.target}: is a file; expected an output directory")
        if not replace and self.target.exists() and any(self.target.iterdir()):
            raise OutputError(f"{self.target}: output directory exists and is not empty")
        _writable_dir(self.target.parent, self.target)
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"{self.target}: cannot create its directory ({exc})") from None
        self.lock = self.target.parent / f".{self.target.name}.lock"
        self._token = f"{os.getpid()} {time.time_ns()}"
        self._take_lock()
        self._finalizer = weakref.finalize(self, _release, self.lock, self._token)
        self._staging: Path | None = None
        self._umask_applied = False
        self._previous_sigterm: object = None

    def _take_lock(self) -> None:
        for _ in range(2):
            try:
                fd = os.open(self.lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid = int(self.lock.read_text().split()[0])
                except (OSError, ValueError, IndexError):
                    pid = -1
                if pid > 0 and _pid_alive(pid):
                    raise OutputError(
                        f"{self.target}: in use by another run (process {pid}; lock file "
                        f"{self.lock}); choose another --out or wait for it") from None
                self.lock.unlink(missing_ok=True)  # its process has died
                continue
            except OSError as exc:
                raise OutputError(f"{self.target}: cannot create the lock file {self.lock} "
                                  f"({exc})") from None
            with os.fdopen(fd, "w") as fh:
                fh.write(self._token)
            return
        raise OutputError(f"{self.target}: could not take the lock file {self.lock}")

    @property
    def staging(self) -> Path:
        """The hidden staging directory (created on first use)."""
        if self._staging is None and self.replace:
            # the lock is held: a .partial left here is a killed attempt's, not a live one's
            partial = self.target.parent / f".{self.target.name}.partial"
            shutil.rmtree(partial, ignore_errors=True)
            shutil.rmtree(self.target.parent / f".{self.target.name}.replaced",
                          ignore_errors=True)
            partial.mkdir(mode=0o700)
            self._staging = partial
        if self._staging is None:
            self._staging = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.",
                                                  dir=self.target.parent))
        if not self._umask_applied:
            # mkdtemp's folder is private to its owner; a run directory gets the
            # permissions any new folder of the user gets
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(self._staging, 0o777 & ~umask)
            self._umask_applied = True
        return self._staging

    def path(self, name: str) -> Path:
        """Where to write file ``name`` while staging."""
        p = self.staging / name
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def publish(self) -> Path:
        """Rename the staging directory to the target and return it. Should the target
        have been filled meanwhile (by a process that ignored the lock), this run goes to
        a fresh ``NAME-n`` beside it instead of overwriting or losing either."""
        staging = self.staging
        final = self.target
        if self.replace and final.exists() and any(final.iterdir()):
            # this task's own earlier output: moved aside, replaced, then removed, so the
            # target is always either the old run or the new one, whole
            old = final.parent / f".{final.name}.replaced"
            shutil.rmtree(old, ignore_errors=True)
            os.replace(final, old)
            os.replace(staging, final)
            shutil.rmtree(old, ignore_errors=True)
            self._finalizer()
            return final
        if final.exists():
            try:
                final.rmdir()
            except OSError:
                final = new_run_dir(final.name, final.parent)
        os.replace(staging, final)
        self._finalizer()
        return final

    def abort(self) -> None:
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
        self._finalizer()

    def __enter__(self) -> RunWriter:
        if threading.current_thread() is threading.main_thread():
            self._previous_sigterm = signal.signal(signal.SIGTERM, _terminate)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: object) -> None:
        if self._previous_sigterm is not None:
            signal.signal(signal.SIGTERM, self._previous_sigterm)
            self._previous_sigterm = None
        if exc_type is not None:
            self.abort()


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt("terminated (SIGTERM)")
