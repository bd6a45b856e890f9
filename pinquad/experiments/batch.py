"""Batch identification of many recorded logs (``python -m pinquad.offline --log A B C``):
one row per log, built from the log's pipeline result (``pipeline.single.PipelineResult``:
its judged headline, its reported run, discovery's selection) or, when the log could not
be identified, its error message; and the batch's exit code.

Each log goes through exactly the single ``--log`` pipeline (``pinquad.pipeline``); this
module only summarises what those runs found. A row holds the numbers of that log's
report.json, taken from the values the report is written from, never read back from it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from pinquad.identification.verdict import (
    TRUSTED,
    VehicleRange,
    scaled_error_verdicts,
    vehicle_range,
)
from pinquad.pipeline.single import PipelineResult
from pinquad.realdata.consistency import (
    PARAMETERS,
    FlightEstimate,
    FlightScatter,
    comparable_error,
    scaled_totals,
)

ALL_TRUSTED, SOME_UNTRUSTED, SOME_FAILED = 0, 3, 4
"""Batch exit codes: every headline trusted; every log identified but some headline not
trusted; at least one log failed (bad file, numerical failure: its row says why). Bad
arguments (no log matches, --out unusable) exit 2 with nothing written, as a single log."""


@dataclass(frozen=True)
class BatchRow:
    """One log of a batch.

    name: the log's subdirectory name in the batch's ``logs/`` (unique in the batch).
    path: the log's path as given.
    status: "trusted", "not trusted" (identified, headline verdict not trusted) or
        "failed" (no report: ``error`` says why).
    mass: headline mass [kg] (nan when failed); mass_se its standard error [kg].
    inertia_diag: (3,) headline I_xx, I_yy, I_zz [kg m^2]; inertia_se (3,) their errors.
    verdicts: per-parameter verdicts, e.g. {"mass": "trusted", "I_xx": ...} (empty when
        failed); overall the headline's overall verdict ("" when failed).
    effects: names of the effects discovery selected, in order (``pinquad.core.effect_vocabulary``).
    seconds: the run's wall time [s].
    error: the error message of a failed log, else "".
    vehicle: the vehicle the log was read as ("" when failed); group: the flights it is
        compared with (``compare_flights``: same named vehicle, same rebuilt motors; a
        log naming no vehicle is a group of its own).
    stat_se: (4,) statistical standard errors of [m, I_xx, I_yy, I_zz] (the run's, NaN
        where the report has none: then the total's); scatter_scale: (4,) the between-
        flight scale factors S inside mass_se / inertia_se (1: not scaled).
    """

    name: str
    path: str
    status: str
    mass: float
    mass_se: float
    inertia_diag: tuple[float, float, float]
    inertia_se: tuple[float, float, float]
    overall: str
    verdicts: dict[str, str]
    effects: tuple[str, ...]
    seconds: float
    error: str
    vehicle: str = ""
    group: str = ""
    stat_se: tuple[float, float, float, float] = (float("nan"),) * 4
    scatter_scale: tuple[float, float, float, float] = (1.0,) * 4


NAN3 = (float("nan"),) * 3


def _finite(value: object) -> float:
    """A number of the row, NaN where there is none (not computed, not finite: report.json
    writes it as null)."""
    f = float(value)
    return f if np.isfinite(f) else float("nan")


def flight_group(name: str, vehicle: str, named: bool, rebuilt: Sequence[int]) -> str:
    """The flights a log is compared with (``compare_flights``): its vehicle, and the
    motors (0-based ``rebuilt``) whose speeds were rebuilt from PWM; a log that names no
    vehicle is a group of its own (``name``): the default it was read as says nothing
    about which vehicle flew it."""
    group = vehicle if named else f"{name} (no vehicle named)"
    if rebuilt:
        group += ", motor(s) " + ", ".join(f"M{int(i) + 1}" for i in rebuilt) + \
            " rebuilt from PWM"
    return group


def row_from_result(name: str, path: str, result: PipelineResult, seconds: float) -> BatchRow:
    """The row of a log identified by the single-log pipeline, from its result: the
    headline (``result.estimate``: mass, inertia, total standard errors, verdicts under
    the final model), discovery's selected effects, the vehicle the log was read as, and
    of a measured flight's reported run its statistical standard errors and the motors
    rebuilt from PWM (report.json's ``runs[0].stderr_statistical`` and ``motor_split``)."""
    final = result.estimate
    verdict = final.verdict
    run = result.run
    measured = run.measured
    stat = (np.full(4, np.nan) if measured is None
            else np.asarray(measured.se_stat, dtype=float))
    split = None if measured is None else measured.motor_split
    meta = result.identified.log.meta
    vehicle = str(meta.vehicle or "")
    stderr = np.asarray(final.stderr, dtype=float)
    return BatchRow(
        name=name, path=path, status="trusted" if verdict.trusted else "not trusted",
        mass=float(final.mass), mass_se=_finite(stderr[0]),
        inertia_diag=tuple(float(v) for v in np.diag(np.asarray(final.inertia, dtype=float))),
        inertia_se=tuple(_finite(v) for v in stderr[1:4]),
        overall=verdict.overall,
        verdicts={p.name: p.verdict for p in verdict.parameters},
        effects=tuple(result.selected),
        seconds=seconds, error="", vehicle=vehicle,
        group=flight_group(name, vehicle, bool(meta.vehicle_named),
                           () if split is None else tuple(split.rebuilt)),
        stat_se=tuple(_finite(v) for v in stat[:4]))


def failed_row(name: str, path: str, error: str, seconds: float) -> BatchRow:
    """The row of a log that could not be identified: its error message."""
    return BatchRow(name=name, path=path, status="failed", mass=float("nan"),
                    mass_se=float("nan"), inertia_diag=NAN3, inertia_se=NAN3, overall="",
                    verdicts={}, effects=(), seconds=seconds, error=error)


def batch_exit_code(rows: Sequence[BatchRow]) -> int:
    """SOME_FAILED if any row failed, else SOME_UNTRUSTED if any headline is not
    trusted, else ALL_TRUSTED."""
    if any(r.status == "failed" for r in rows):
        return SOME_FAILED
    if any(r.status != "trusted" for r in rows):
        return SOME_UNTRUSTED
    return ALL_TRUSTED


def unique_names(paths: Sequence[str]) -> list[str]:
    """Subdirectory names for ``paths``: each file's name, with ``-2``, ``-3``... when two
    logs from different directories share one."""
    seen: dict[str, int] = {}
    names = []
    for p in paths:
        base = p.replace("\\", "/").rstrip("/").rsplit("/", 1)[-1] or "log"
        seen[base] = seen.get(base, 0) + 1
        names.append(base if seen[base] == 1 else f"{base}-{seen[base]}")
    return names


def compare_flights(rows: Sequence[BatchRow]) -> tuple[list[BatchRow], list[FlightScatter]]:
    """The batch's flights of one vehicle against each other (``realdata.consistency``):
    per group (same vehicle, same motors rebuilt from PWM) and parameter, the scatter of
    the trusted estimates against their statistical errors (the total's where a report
    has none or a degenerate one, ``comparable_error``: a weaker test, never a stronger);
    where it exceeds them every
    row of the group gets its statistical error scaled by S inside its total, and a
    trusted parameter whose scaled error then covers too much of the vehicle's range is
    "not identifiable" (``verdict.scaled_error_verdicts``; the row not trusted). Only that check
    depends on the error's size, so a verdict can only be lowered here. Returns the rows
    and the scatters compared."""
    done = [r for r in rows if r.status != "failed" and r.verdicts]
    flights = [FlightEstimate(
        r.name, r.group, np.array([_value(r, j) for j in range(4)]),
        np.array([_stat(r, j) for j in range(4)]), np.array([_total(r, j) for j in range(4)]),
        np.array([r.verdicts.get(name) == TRUSTED for name in PARAMETERS])) for r in done]
    scale, totals, scatters = scaled_totals(flights)
    new = {r.name: (s, t) for r, s, t in zip(done, scale, totals, strict=True)
           if np.any(s != 1.0)}
    out = []
    for r in rows:
        if r.name not in new:
            out.append(r)
            continue
        s, total = new[r.name]
        verdicts, overall = scaled_error_verdicts(r.verdicts, r.overall, total, s,
                                                  _vehicle_range(r.vehicle))
        lowered = verdicts != r.verdicts
        out.append(replace(r, mass_se=float(total[0]),
                           inertia_se=tuple(float(v) for v in total[1:4]),
                           verdicts=verdicts, scatter_scale=tuple(float(v) for v in s),
                           status="not trusted" if lowered else r.status, overall=overall))
    return out, scatters


def _vehicle_range(vehicle: str) -> VehicleRange | None:
    """The vehicle's range, None when there is none to judge against (no vehicle, or a
    vehicle file that no longer reads: the batch's rows are written regardless)."""
    if not vehicle:
        return None
    try:
        return vehicle_range(vehicle)
    except (OSError, ValueError):
        return None


def _value(r: BatchRow, j: int) -> float:
    return r.mass if j == 0 else r.inertia_diag[j - 1]


def _total(r: BatchRow, j: int) -> float:
    return r.mass_se if j == 0 else r.inertia_se[j - 1]


def _stat(r: BatchRow, j: int) -> float:
    return comparable_error(_value(r, j), r.stat_se[j], _total(r, j))
