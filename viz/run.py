"""Read a finished run directory into typed records the viewer draws.

The viewer only reads what a run wrote (``report.json``, ``logs/``, ``figures/``); it
never recomputes an estimate. Everything the scene needs is loaded here once, so the
GUI callbacks only index arrays.

A run directory holds ``report.json`` with schema ``pinquad.report.offline/1``;
``run_logs`` maps a name (the sensor set, or the log's name for a recorded flight) to
``{"log": <parquet/csv>, "smoothed": <npy (N, 12)>}`` relative to the run directory.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pinquad.io.logs import LogFormatError, read_table
from pinquad.io.runs import REPORT_SCHEMA
from viz.recorded import (
    Headline,
    Iterates,
    ResidualTrack,
    load_headline,
    load_iterates,
    load_mocap,
    load_residuals,
)

Array = NDArray[np.float64]



class RunError(ValueError):
    """The directory is not a readable pinquad run; the message names it and says why."""


@dataclass(frozen=True)
class Flight:
    """One logged flight, ready to draw.

    name: key in ``run_logs`` (the sensor set for simulations); cycle: Monte Carlo cycle
    the log belongs to, if known; t (N,) [s]; true_pos / est_pos (N, 3) [m, world] and
    true_euler / est_euler (N, 3) roll, pitch, yaw [rad], each None when the run has no
    such data; est_source: what the estimate is ("smoothed" E-step posterior mean, or
    "measured" when only the raw log exists); residuals: the residual size per step of a
    recorded log's run (None otherwise); mocap (P, 4) [t [s], x, y, z [m]]: its raw
    motion-capture samples, or None.
    """

    name: str
    cycle: int | None
    t: Array
    true_pos: Array | None
    true_euler: Array | None
    est_pos: Array | None
    est_euler: Array | None
    est_source: str
    residuals: ResidualTrack | None = None
    mocap: Array | None = None

    @property
    def duration(self) -> float:
        """Logged time span [s]."""
        return float(self.t[-1] - self.t[0])

    def index_at(self, time: float) -> int:
        """Row of the last sample at or before ``time`` [s] (clamped to the log)."""
        i = int(np.searchsorted(self.t, time, side="right")) - 1
        return min(max(i, 0), self.t.shape[0] - 1)


@dataclass(frozen=True)
class CycleRecord:
    """Parameter history of one (sensor, cycle, M-step) identification.

    x (K,): EM iteration index, or time [s] of each online update when the run logged
    it (x_label says which); mass (K,) [kg]; inertia_diag (K, 3) [kg m^2]. est_* are the
    final estimates; true_* the simulator's values, or None for a recorded flight;
    loglik (K,) [nats] per iterate (NaN where not recorded) or None; e_steps: the
    E-steps EM used, when the run recorded it.
    """

    sensor: str
    mstep: str
    cycle: int
    seed: int | None
    x: Array
    x_label: str
    mass: Array
    inertia_diag: Array
    est_mass: float
    est_inertia_diag: Array
    true_mass: float | None
    true_inertia_diag: Array | None
    loglik: Array | None = None
    e_steps: int | None = None


@dataclass(frozen=True)
class Discovery:
    """Effect discovery outcome: selected effect names with their coefficients (as
    printable text), residual RMS before/after per channel, how that was validated,
    and figure files (absolute paths that exist)."""

    selected: tuple[tuple[str, str], ...]
    rms_before: tuple[tuple[str, float], ...]
    rms_after: tuple[tuple[str, float], ...]
    validation: str
    figures: tuple[Path, ...]


@dataclass(frozen=True)
class Run:
    """Everything the viewer shows of one run directory.

    waypoints (W, 3) [m] and start (3,) [m] come from the scenario (None for recorded
    flights). warnings: problems that did not stop loading (e.g. a missing log file).
    vehicle_named: whether the run's log named its vehicle (False: ``vehicle`` is a
    default and vehicle_note says so); headline: a recorded log's final and base
    estimates with verdicts and reference values, or None.
    """

    path: Path
    kind: str
    vehicle: str
    flights: tuple[Flight, ...]
    cycles: tuple[CycleRecord, ...]
    waypoints: Array | None
    start: Array | None
    discovery: Discovery | None
    figures: tuple[Path, ...]
    warnings: tuple[str, ...]
    vehicle_named: bool = True
    vehicle_note: str = ""
    headline: Headline | None = None

    @property
    def sensors(self) -> tuple[str, ...]:
        """Names offered in the sensor control: logged flights first, then any sensor
        that only has parameter histories."""
        names = [f.name for f in self.flights]
        names += [c.sensor for c in self.cycles if c.sensor not in names]
        return tuple(dict.fromkeys(names))

    def flight(self, name: str) -> Flight | None:
        """The logged flight called ``name``, if the run kept one."""
        return next((f for f in self.flights if f.name == name), None)


# ------------------------------------------------------------------------------ helpers

def decimate_indices(n: int, max_points: int) -> NDArray[np.intp]:
    """At most ``max_points`` evenly spaced row indices of ``n`` rows, first and last
    included, so long logs draw as cheaply as short ones."""
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max(max_points, 2)).round().astype(np.intp))


def _ffill(values: Array) -> Array | None:
    """Carry the last valid row forward (and the first valid one backward): the raw
    log of a sparse sensor still gives a pose at every row. None if nothing is valid."""
    ok = np.isfinite(values).all(axis=1)
    if not ok.any():
        return None
    idx = np.where(ok, np.arange(values.shape[0]), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: int(np.argmax(ok))] = int(np.argmax(ok))
    return values[idx]


def _float_or_none(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if np.isfinite(out) else None


def _diag_or_none(inertia: Any) -> Array | None:
    try:
        arr = np.asarray(inertia, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.shape == (3, 3):
        return np.diag(arr).copy()
    if arr.shape == (3,):
        return arr
    return None


def _cycle_from_name(path: str) -> int | None:
    m = re.search(r"cycle(\d+)", path)
    return int(m.group(1)) if m else None


# ------------------------------------------------------------------------------ loading

def _read_report(run_dir: Path) -> dict[str, Any]:
    if not run_dir.exists():
        raise RunError(f"{run_dir}: no such directory")
    if not run_dir.is_dir():
        raise RunError(f"{run_dir}: not a directory; expected a pinquad run directory")
    report_path = run_dir / "report.json"
    if not report_path.is_file():
        raise RunError(f"{run_dir}: not a pinquad run (no report.json); expected a directory "
                       "written by python -m pinquad.offline or pinquad.online")
    try:
        report = json.loads(report_path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise RunError(f"{report_path}: cannot be read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise RunError(f"{report_path}: not valid JSON ({exc.msg} at byte {exc.pos})") from None
    if not isinstance(report, dict):
        raise RunError(f"{report_path}: expected a JSON object at the top level")
    if report.get("schema") != REPORT_SCHEMA:
        raise RunError(f"{report_path}: schema is {report.get('schema')!r}; expected {REPORT_SCHEMA!r}")
    return report


def _load_flight(run_dir: Path, name: str, entry: Any, warnings: list[str]) -> Flight | None:
    if isinstance(entry, str):
        entry = {"log": entry}
    if not isinstance(entry, dict) or not isinstance(entry.get("log"), str):
        warnings.append(f"run_logs[{name!r}]: expected {{'log': path}}; skipped")
        return None
    log_path = run_dir / entry["log"]
    try:
        log = read_table(log_path)
    except LogFormatError as exc:
        warnings.append(f"flight {name!r} skipped: {exc}")
        return None
    true_pos = true_euler = None
    if log.truth is not None and np.isfinite(log.truth[:, :3]).any():
        true_pos, true_euler = _ffill(log.truth[:, 0:3]), _ffill(log.truth[:, 6:9])
    est_pos = est_euler = None
    est_source = "measured"
    smoothed_name = entry.get("smoothed")
    if isinstance(smoothed_name, str):
        sm_path = run_dir / smoothed_name
        try:
            sm = np.load(sm_path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            warnings.append(f"{sm_path}: unreadable smoothed state ({exc}); showing the "
                            "measured pose as the estimate")
        else:
            if sm.ndim == 2 and sm.shape[0] == log.n and sm.shape[1] >= 9:
                est_pos = _ffill(np.asarray(sm[:, 0:3], dtype=float))
                est_euler = _ffill(np.asarray(sm[:, 6:9], dtype=float))
                est_source = "smoothed"
            else:
                warnings.append(f"{sm_path}: shape {sm.shape}; expected ({log.n}, 12) rows "
                                "matching the log; showing the measured pose as the estimate")
    if est_pos is None or est_euler is None:
        est_pos, est_euler = _ffill(log.position), _ffill(log.euler)
        est_source = "measured"
    if est_pos is None or est_euler is None:
        est_pos = est_euler = None
    if (true_pos is None or true_euler is None) and est_pos is None:
        warnings.append(f"flight {name!r} skipped: {log_path} has neither a true nor an "
                        "estimated pose")
        return None
    if true_pos is None or true_euler is None:
        true_pos = true_euler = None
    cycle = entry.get("cycle")
    residuals = mocap = None
    if isinstance(entry.get("step_residuals"), str):
        residuals = load_residuals(run_dir / entry["step_residuals"],
                                   str(entry.get("step_residuals_note") or ""), warnings)
    if isinstance(entry.get("mocap"), str):
        mocap = load_mocap(run_dir / entry["mocap"], warnings)
    return Flight(
        name=name,
        cycle=int(cycle) if isinstance(cycle, int) else _cycle_from_name(entry["log"]),
        t=log.t, true_pos=true_pos, true_euler=true_euler, est_pos=est_pos,
        est_euler=est_euler, est_source=est_source, residuals=residuals, mocap=mocap,
    )


def _load_cycle(entry: Any, index: int) -> CycleRecord | None:
    if not isinstance(entry, dict):
        return None
    hist = entry.get("history") or {}
    est = entry.get("estimates") or {}
    truth = entry.get("truth") or {}
    try:
        mass = np.asarray(hist.get("mass", []), dtype=float).reshape(-1)
        inertia = np.asarray(hist.get("inertia_diag", []), dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        return None
    est_mass = _float_or_none(est.get("mass"))
    est_inertia = _diag_or_none(est.get("inertia"))
    if est_mass is None or est_inertia is None:
        return None
    if mass.size == 0 or mass.shape[0] != inertia.shape[0]:
        # No usable history: the final estimate alone still plots as one point.
        mass, inertia = np.array([est_mass]), est_inertia[None, :]
    x, x_label = np.arange(mass.shape[0], dtype=float), "EM iteration"
    times = hist.get("t")
    if times is not None:
        try:
            t_arr = np.asarray(times, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            t_arr = np.empty(0)
        if t_arr.shape[0] == mass.shape[0]:
            x, x_label = t_arr, "time [s]"
        else:
            x_label = "online update"
    cycle = entry.get("cycle", index)
    seed = entry.get("seed")
    return CycleRecord(
        sensor=str(entry.get("sensor", "?")), mstep=str(entry.get("mstep", "?")),
        cycle=int(cycle) if isinstance(cycle, int) else index,
        seed=int(seed) if isinstance(seed, int) else None,
        x=x, x_label=x_label, mass=mass, inertia_diag=inertia,
        est_mass=est_mass, est_inertia_diag=est_inertia,
        true_mass=_float_or_none(truth.get("mass")),
        true_inertia_diag=_diag_or_none(truth.get("inertia")),
    )


def _top_level_cycle(report: dict[str, Any]) -> CycleRecord | None:
    """A run without ``cycles`` (e.g. one recorded log) still has final estimates."""
    est = report.get("estimates") or {}
    truth = report.get("truth") or {}
    source = report.get("source") or {}
    entry = {"sensor": str(source.get("sensor") or "log"),
             "mstep": str(source.get("mstep") or "regressor"), "cycle": 0,
             "estimates": est, "truth": truth, "history": report.get("history") or {}}
    return _load_cycle(entry, 0)


def _iterate_cycles(its: tuple[Iterates, ...], report: dict[str, Any], flight: str
                    ) -> list[CycleRecord]:
    """One record per run of a recorded log's EM history, tied to its one flight; the
    M-step dropdown tells the runs apart (with the sensor when there are several)."""
    runs = report.get("runs") if isinstance(report.get("runs"), list) else []
    several = len({it.sensor for it in its}) > 1
    out = []
    for it in its:
        entry = runs[it.run] if it.run < len(runs) and isinstance(runs[it.run], dict) else {}
        est = entry.get("estimates") or {}
        est_mass = _float_or_none(est.get("mass"))
        est_inertia = _diag_or_none(est.get("inertia"))
        if est_mass is None or est_inertia is None:
            est_mass, est_inertia = float(it.params[-1, 0]), it.params[-1, 1:].copy()
        out.append(CycleRecord(
            sensor=flight, mstep=f"{it.mstep} ({it.sensor})" if several else it.mstep,
            cycle=0, seed=None, x=np.arange(it.params.shape[0], dtype=float),
            x_label="EM iterate", mass=it.params[:, 0], inertia_diag=it.params[:, 1:],
            est_mass=est_mass, est_inertia_diag=est_inertia, true_mass=None,
            true_inertia_diag=None, loglik=it.loglik, e_steps=it.e_steps))
    return out


def _pairs(obj: Any) -> tuple[tuple[str, float], ...]:
    if not isinstance(obj, dict):
        return ()
    out = []
    for key, value in obj.items():
        num = _float_or_none(value)
        if num is not None:
            out.append((str(key), num))
    return tuple(out)


def _load_discovery(run_dir: Path, report: dict[str, Any], warnings: list[str]
                    ) -> Discovery | None:
    disc = report.get("discovery")
    if not isinstance(disc, dict):
        return None
    selected = []
    for item in disc.get("selected") or []:
        if isinstance(item, dict):
            coeffs = item.get("coefficients") or {}
            text = ", ".join(f"{k} = {v:.4g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                             for k, v in coeffs.items()) if isinstance(coeffs, dict) else ""
            selected.append((str(item.get("effect", "?")), text))
        else:
            selected.append((str(item), ""))
    figures = []
    for name in disc.get("figures") or []:
        path = run_dir / str(name)
        if path.is_file():
            figures.append(path)
        else:
            warnings.append(f"discovery figure {path} is missing")
    return Discovery(
        selected=tuple(selected), rms_before=_pairs(disc.get("residual_rms_before")),
        rms_after=_pairs(disc.get("residual_rms_after")),
        validation=str(disc.get("validation") or ""), figures=tuple(figures),
    )


def load_run(run_dir: str | Path) -> Run:
    """Read a run directory. Raises RunError (naming the directory or file) when it is
    not a run; problems with individual logs become ``Run.warnings`` instead."""
    run_dir = Path(run_dir)
    report = _read_report(run_dir)
    warnings: list[str] = []
    source = report.get("source") if isinstance(report.get("source"), dict) else {}
    vehicle = str(source.get("vehicle") or "paper")

    run_logs = report.get("run_logs") or {}
    if not isinstance(run_logs, dict):
        raise RunError(f"{run_dir / 'report.json'}: 'run_logs' must be an object mapping a "
                       "name to {'log': path, 'smoothed': path}")
    flights = []
    for name, entry in run_logs.items():
        flight = _load_flight(run_dir, str(name), entry, warnings)
        if flight is not None:
            flights.append(flight)

    raw_cycles = report.get("cycles") or []
    if not isinstance(raw_cycles, list):
        raise RunError(f"{run_dir / 'report.json'}: 'cycles' must be a list")
    cycles = [rec for i, entry in enumerate(raw_cycles)
              if (rec := _load_cycle(entry, i)) is not None]
    history = next((e.get("em_history") for e in run_logs.values()
                    if isinstance(e, dict) and isinstance(e.get("em_history"), str)), None)
    if not cycles and history is not None:
        its = load_iterates(run_dir / history, warnings)
        cycles = _iterate_cycles(its, report, flights[0].name if flights else "log")
    if not cycles:
        top = _top_level_cycle(report)
        if top is not None:
            if flights and top.sensor not in {f.name for f in flights}:
                # Tie the lone estimate to the lone flight so one sensor choice shows both.
                top = replace(top, sensor=flights[0].name)
            cycles = [top]

    waypoints = start = None
    scenario = report.get("scenario")
    if isinstance(scenario, dict):
        try:
            wp = np.asarray(scenario.get("waypoints") or [], dtype=float).reshape(-1, 3)
            waypoints = wp if wp.size else None
            st = scenario.get("start")
            start = None if st is None else np.asarray(st, dtype=float).reshape(3)
        except (TypeError, ValueError):
            warnings.append("scenario waypoints unreadable; not drawn")
            waypoints = start = None

    fig_dir = run_dir / "figures"
    figures = tuple(sorted(fig_dir.glob("*.png"))) if fig_dir.is_dir() else ()
    return Run(
        path=run_dir, kind=str(source.get("kind") or "unknown"), vehicle=vehicle,
        flights=tuple(flights), cycles=tuple(cycles), waypoints=waypoints, start=start,
        discovery=_load_discovery(run_dir, report, warnings), figures=figures,
        warnings=tuple(warnings), vehicle_named=source.get("vehicle_named") is not False,
        vehicle_note=str(source.get("vehicle_note") or ""), headline=load_headline(report),
    )
