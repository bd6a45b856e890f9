"""The tables a recorded log's run directory holds for the viewer (``python -m viz``), so
that it draws the EM history, the raw motion capture and where the model fails without
running any estimation:

- ``logs/em_history.csv``: every run's EM iterates (``EM_HISTORY_COLUMNS``);
- ``logs/step-residuals.csv``: the residual size per step before and after discovery's
  refit (``pinquad.experiments.step_residuals``; ``RESIDUAL_COLUMNS``);
- ``logs/mocap.csv``: the raw motion-capture positions at their own times
  (``MOCAP_COLUMNS``).

Their names go into report.json's ``run_logs.log`` beside the log and the smoothed means
(keys ``em_history``, ``step_residuals``: None for the ten-parameter fit, ``mocap``);
``source.vehicle_named`` / ``source.vehicle_note`` say whether the log named its vehicle,
and ``reference`` holds the values of the vehicle known without the flight, if any
(``pinquad.io.runs.LOG_REPORT_KEYS`` documents every key).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import is_vehicle_file, load_vehicle
from pinquad.discovery.calibrated import DiscoveryOutcome
from pinquad.experiments.step_residuals import StepResiduals, step_residuals
from pinquad.identification.identify import Identification
from pinquad.io.logs import FlightLog
from pinquad.io.runs import RunWriter, atomic_write_bytes
from pinquad.pipeline.identify import LogResult

Array = NDArray[np.float64]

EM_HISTORY = "logs/em_history.csv"
STEP_RESIDUALS = "logs/step-residuals.csv"
MOCAP = "logs/mocap.csv"

EM_HISTORY_COLUMNS = ("run", "sensor", "mstep", "iterate", "mass", "I_xx", "I_yy", "I_zz",
                      "loglik", "e_steps")
"""run: index in report.json ``runs``; iterate: 0 = the initial guess; mass [kg]; I_*
[kg m^2]; loglik [nats]: log p(y | iterate) of the E-step at that iterate (empty where
the run did not record one); e_steps: the E-steps the run used in all (each row)."""
RESIDUAL_COLUMNS = ("t", "force_before", "torque_before", "force_after", "torque_after")
"""t [s]; force_* [N], torque_* [N m]: norms of the window-mean body-wrench residual
(``StepResiduals``); empty where no transition was used."""
MOCAP_COLUMNS = ("t", "x", "y", "z")
"""t [s, log clock]; x, y, z [m, world]: each motion-capture sample as recorded."""


def _csv(header: Sequence[str], rows: Sequence[Sequence[object]]) -> bytes:
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    out.writerow(header)
    for row in rows:
        out.writerow(["" if isinstance(v, float) and not np.isfinite(v) else
                      (f"{v:.10g}" if isinstance(v, float) else v) for v in row])
    return buf.getvalue().encode()


def em_iterates(run: Identification) -> tuple[Array, Array]:
    """(R, 4) [m, I_xx, I_yy, I_zz] and (R,) loglik of a run's EM, one row per iterate.

    The paths record them differently: one iterate per log-likelihood (the simulated
    path); the initial guess first, then one per log-likelihood (measured flights); or
    only the start and the end (the ten-parameter fit: its iterates in between are
    NaN, its log-likelihoods kept)."""
    params = np.column_stack([run.history_mass, run.history_inertia])
    ll = np.asarray(run.loglik, dtype=float).reshape(-1)
    n_hist, n_ll = params.shape[0], ll.size
    if n_hist >= n_ll:
        loglik = np.full(n_hist, np.nan)
        loglik[n_hist - n_ll:] = ll
        return params, loglik
    out = np.full((n_ll, 4), np.nan)
    out[0], out[-1] = params[0], params[-1]
    return out, ll


def em_history_rows(runs: Sequence[Identification]) -> list[list[object]]:
    """The rows of ``em_history.csv`` (``EM_HISTORY_COLUMNS``) of ``runs``."""
    rows: list[list[object]] = []
    for i, r in enumerate(runs):
        params, loglik = em_iterates(r)
        e_steps = r.e_steps if r.e_steps is not None else r.iterations
        for k in range(params.shape[0]):
            rows.append([i, r.sensor, r.mstep, k, *(float(v) for v in params[k]),
                         float(loglik[k]), int(e_steps)])
    return rows


def residual_rows(res: StepResiduals) -> list[list[object]]:
    """The rows of ``step-residuals.csv`` (``RESIDUAL_COLUMNS``)."""
    cols = (res.t, res.force_before, res.torque_before, res.force_after, res.torque_after)
    return [[float(c[k]) for c in cols] for k in range(res.t.shape[0])]


def mocap_samples(log: FlightLog) -> tuple[Array, Array]:
    """t (P,) [s] and positions (P, 3) [m] of the raw motion capture: the recorded poses
    at their own times when the log kept them (micro-SD logs), else the log's rows with a
    finite position."""
    m = log.measured
    if m is not None and m.pose_t is not None and m.pose_position is not None:
        ok = np.isfinite(m.pose_position).all(axis=1)
        return m.pose_t[ok], m.pose_position[ok]
    ok = np.isfinite(log.position).all(axis=1)
    return log.t[ok], log.position[ok]


def vehicle_note(result: LogResult, mass: float) -> str | None:
    """What the report says when the log names no vehicle (None when it does)."""
    if result.log.meta.vehicle_named:
        return None
    return (f"vehicle not named by the log: drawn at the size of a {mass * 1e3:.1f} g quad "
            f"(the identified mass); give the vehicle in the log's sidecar "
            f"(<log>.json: {{\"vehicle\": ...}})")


def reference(vehicle: str) -> dict | None:
    """report.json's ``reference``: values of the vehicle known without the flight (the
    vehicle file's [reference]: for the Crazyflie 2.1 its scale mass and published
    inertia), or None."""
    if vehicle != "crazyflie21" and not is_vehicle_file(vehicle):
        return None
    ref = load_vehicle(vehicle).reference
    if ref.mass is None:
        return None
    if vehicle == "crazyflie21":
        source = ("scale / published (mass weighed on a scale; inertia of a Crazyflie "
                  "2.0 without decks, bifilar pendulum)")
    else:
        source = f"vehicle file {vehicle}: mass {ref.mass_note or 'given'}; inertia " + (
            ref.inertia_note or "given" if ref.inertia is not None else "not given")
    return {"mass": ref.mass,
            "inertia_diag": None if ref.inertia is None else np.asarray(ref.inertia).tolist(),
            "source": source}


def write_run_tables(writer: RunWriter, result: LogResult, outcome: DiscoveryOutcome | None,
                     report: dict) -> list[str]:
    """Write the module's tables into ``writer``'s staging directory, name them in
    ``report`` (``run_logs.log``, ``source.vehicle_named`` / ``vehicle_note``, ``reference``)
    and return the lines report.md adds."""
    entry = report.setdefault("run_logs", {}).setdefault("log", {})
    atomic_write_bytes(writer.path(EM_HISTORY),
                       _csv(EM_HISTORY_COLUMNS, em_history_rows(result.runs)))
    entry["em_history"] = EM_HISTORY
    t, pos = mocap_samples(result.log)
    atomic_write_bytes(writer.path(MOCAP), _csv(MOCAP_COLUMNS, [
        [float(t[k]), *(float(v) for v in pos[k])] for k in range(t.shape[0])]))
    entry["mocap"] = MOCAP
    lines = []
    res = step_residuals(result, outcome)
    entry["step_residuals"] = entry["step_residuals_note"] = None
    if res is not None:
        atomic_write_bytes(writer.path(STEP_RESIDUALS), _csv(RESIDUAL_COLUMNS, residual_rows(res)))
        entry["step_residuals"] = STEP_RESIDUALS
        entry["step_residuals_note"] = (
            f"norms of the {res.window_seconds:g}-s window mean of the body-wrench residual "
            f"Y pi - tau (- the selected effects' wrench) per step [N, N m]; before: base fit; "
            f"after: {res.after_model}")
    source = report.setdefault("source", {})
    note = vehicle_note(result, float(report.get("estimates", {}).get("mass", np.nan)))
    source["vehicle_named"] = note is None
    source["vehicle_note"] = note
    report["reference"] = reference(result.log.meta.vehicle) if note is None else None
    if note is not None:
        lines.append(f"- note: {note}")
    return lines
