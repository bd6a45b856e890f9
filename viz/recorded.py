"""What a recorded log's run directory (``python -m pinquad.offline --log``) adds for the
viewer, read from the files ``pinquad.report.run_tables`` writes: every run's EM
iterates (``em_history.csv``), the residual size per step before and after discovery's
refit (``step-residuals.csv``), the raw motion capture (``mocap.csv``), and report.json's
headline (``estimates`` with its verdict, ``base``, ``reference``).

Nothing here is computed from the flight: the viewer runs no estimation.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

RESIDUAL_CHOICES = (("force residual, base fit", "force_before"),
                    ("force residual, final model", "force_after"),
                    ("torque residual, base fit", "torque_before"),
                    ("torque residual, final model", "torque_after"))
"""The path-colour selector's entries and the ``step-residuals.csv`` column each shows."""
PARAMS = ("mass", "I_xx", "I_yy", "I_zz")


@dataclass(frozen=True)
class Iterates:
    """One run's EM history from ``em_history.csv``: run (index in report.json ``runs``),
    sensor, mstep; params (R, 4) [m [kg], I_xx, I_yy, I_zz [kg m^2]] per iterate (row 0:
    the initial guess; NaN where not recorded); loglik (R,) [nats] (NaN where not
    recorded); e_steps: the E-steps the run used."""

    run: int
    sensor: str
    mstep: str
    params: Array
    loglik: Array
    e_steps: int | None


@dataclass(frozen=True)
class ResidualTrack:
    """Residual size per step: t (N,) [s]; columns: ``RESIDUAL_CHOICES`` column -> (N,)
    [N or N m] (NaN: no used transition); note: how they were computed, in words."""

    t: Array
    columns: dict[str, Array]
    note: str

    def at(self, column: str, times: Array) -> Array:
        """Values of ``column`` at ``times`` [s] (the nearest earlier step's)."""
        i = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, self.t.shape[0] - 1)
        return self.columns[column][i]


@dataclass(frozen=True)
class EstimateRow:
    """One estimate of report.json: mass [kg], inertia_diag (3,) [kg m^2], stderr (4,)
    (NaN: not computed), verdicts: parameter name -> (verdict, first reason or "");
    overall verdict and its reasons; model: what it was fitted under, in words."""

    mass: float
    inertia_diag: Array
    stderr: Array
    verdicts: dict[str, tuple[str, str]]
    overall: str
    reasons: tuple[str, ...]
    model: str

    @property
    def values(self) -> Array:
        """(4,) [m, I_xx, I_yy, I_zz]."""
        return np.r_[self.mass, self.inertia_diag]


@dataclass(frozen=True)
class Headline:
    """The parameter panel's numbers: final (the final model's estimate), base (the base
    fit, None when discovery did not change it), reference (4,) [kg, kg m^2] and its
    source, or None."""

    final: EstimateRow
    base: EstimateRow | None
    reference: Array | None
    reference_source: str


def _num(value: Any) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return float("nan")
    return out


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def load_iterates(path: Path, warnings: list[str]) -> tuple[Iterates, ...]:
    """Every run's history in ``em_history.csv`` (empty, with a warning, if unreadable)."""
    try:
        rows = _read_csv(path)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        warnings.append(f"{path}: unreadable EM history ({exc}); showing final estimates only")
        return ()
    runs: dict[int, list[dict[str, str]]] = {}
    for row in rows:
        try:
            runs.setdefault(int(row["run"]), []).append(row)
        except (KeyError, TypeError, ValueError):
            warnings.append(f"{path}: a row without a run number; skipped")
    out = []
    for run, items in sorted(runs.items()):
        items.sort(key=lambda r: _num(r.get("iterate")))
        params = np.array([[_num(r.get(p)) for p in PARAMS] for r in items])
        e_steps = _num(items[0].get("e_steps"))
        out.append(Iterates(run, items[0].get("sensor") or "?", items[0].get("mstep") or "?",
                            params, np.array([_num(r.get("loglik")) for r in items]),
                            int(e_steps) if np.isfinite(e_steps) else None))
    return tuple(out)


def load_residuals(path: Path, note: str, warnings: list[str]) -> ResidualTrack | None:
    """``step-residuals.csv`` (None, with a warning, if unreadable)."""
    try:
        rows = _read_csv(path)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        warnings.append(f"{path}: unreadable residual table ({exc}); path not coloured")
        return None
    if not rows:
        warnings.append(f"{path}: empty residual table; path not coloured")
        return None
    t = np.array([_num(r.get("t")) for r in rows])
    cols = {c: np.array([_num(r.get(c)) for r in rows]) for _, c in RESIDUAL_CHOICES}
    if not np.all(np.diff(t) > 0):
        warnings.append(f"{path}: times not increasing; path not coloured")
        return None
    return ResidualTrack(t, cols, note)


def load_mocap(path: Path, warnings: list[str]) -> Array | None:
    """(P, 4) [t [s], x, y, z [m]] of ``mocap.csv`` (None, with a warning, if unreadable)."""
    try:
        rows = _read_csv(path)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        warnings.append(f"{path}: unreadable motion-capture samples ({exc}); not drawn")
        return None
    arr = np.array([[_num(r.get(c)) for c in ("t", "x", "y", "z")] for r in rows]).reshape(-1, 4)
    arr = arr[np.isfinite(arr).all(axis=1)]
    return arr if arr.size else None


def _estimate_row(est: Any) -> EstimateRow | None:
    if not isinstance(est, dict):
        return None
    try:
        inertia = np.asarray(est.get("inertia"), dtype=float)
    except (TypeError, ValueError):
        return None
    if inertia.shape == (3, 3):
        inertia = np.diag(inertia).copy()
    if inertia.shape != (3,):
        return None
    se = est.get("stderr") if isinstance(est.get("stderr"), dict) else {}
    se_diag = se.get("inertia_diag") if isinstance(se.get("inertia_diag"), list) else []
    stderr = np.array([_num(se.get("mass"))] + [_num(v) for v in se_diag[:3]]
                      + [float("nan")] * (3 - len(se_diag[:3])))
    verdict = est.get("verdict") if isinstance(est.get("verdict"), dict) else {}
    params = verdict.get("parameters") if isinstance(verdict.get("parameters"), dict) else {}
    verdicts = {}
    for name in PARAMS:
        v = params.get(name)
        if isinstance(v, dict):
            reasons = v.get("reasons") or [""]
            verdicts[name] = (str(v.get("verdict", "")), str(reasons[0]))
    return EstimateRow(_num(est.get("mass")), inertia, stderr, verdicts,
                       str(verdict.get("overall", "")),
                       tuple(str(r) for r in verdict.get("reasons") or ()),
                       str(est.get("model") or ""))


def load_headline(report: dict[str, Any]) -> Headline | None:
    """The headline of a recorded log's report.json, or None (no verdict: not such a run)."""
    final = _estimate_row(report.get("estimates"))
    if final is None or not final.overall:
        return None
    base = _estimate_row(report.get("base"))
    if base is not None and np.allclose(base.values, final.values, rtol=1e-12, atol=0.0):
        base = None
    ref = report.get("reference")
    reference, source = None, ""
    if isinstance(ref, dict):
        vals = np.r_[_num(ref.get("mass")), [_num(v) for v in (ref.get("inertia_diag") or [])]]
        if vals.shape == (4,) and np.isfinite(vals).all():
            reference, source = vals, str(ref.get("source") or "reference")
    return Headline(final, base, reference, source)
