"""The batch table (``python -m pinquad.offline --log A B C``): one line per log with the
headline mass and inertia, their verdicts, the effects discovery selected, or the error
of a log that failed; and the batch's batch.json."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict

from pinquad.experiments.batch import BatchRow
from pinquad.realdata.consistency import FlightScatter

SHORT = {"trusted": "ok", "not identifiable": "n/i", "implausible": "impl",
         "model not adequate": "model"}


def _pm(value: float, se: float, scale: float, fmt: str) -> str:
    if not math.isfinite(value):
        return "-"
    if not math.isfinite(se):
        return f"{value * scale:{fmt}}"
    return f"{value * scale:{fmt}} +- {se * scale:{fmt}}"


def batch_table(rows: Sequence[BatchRow], scatters: Sequence[FlightScatter] = ()) -> str:
    """A markdown table: log, status, mass [g], I_xx/I_yy/I_zz [1e-6 kg m^2] (``[xS]``: the
    error scaled for the scatter between flights), the per-parameter verdicts, effects,
    seconds, and a failed log's error message; then the flights compared with each other
    (``experiments.batch.compare_flights``)."""
    lines = ["| log | status | mass [g] | I_xx [1e-6 kg m^2] | I_yy | I_zz | verdicts "
             "(m, Ixx, Iyy, Izz) | effects | s | error |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        verdicts = ", ".join(SHORT.get(r.verdicts.get(k, ""), r.verdicts.get(k, "") or "-")
                             for k in ("mass", "I_xx", "I_yy", "I_zz")) if r.verdicts else "-"
        inertia = [_pm(v, s, 1e6, ".2f") + _scaled(r, j + 1)
                   for j, (v, s) in enumerate(zip(r.inertia_diag, r.inertia_se, strict=True))]
        error = r.error.replace("|", "/").replace("\n", " ")
        mass = _pm(r.mass, r.mass_se, 1e3, ".3f") + _scaled(r, 0)
        lines.append(f"| {r.name} | {r.status} | {mass} | "
                     f"{' | '.join(inertia)} | {verdicts} | "
                     f"{', '.join(r.effects) or '-'} | {r.seconds:.0f} | {error} |")
    if scatters:
        lines += ["", "Flights against each other (trusted estimates of one vehicle with the "
                  "same rebuilt motors; where they scatter beyond their statistical errors, "
                  "those are scaled by S = sqrt(chi2 / dof) inside each total, and a trusted "
                  "parameter whose scaled error covers too much of the vehicle's range is not "
                  "identifiable):"]
        lines += [f"- {sc.describe()}" for sc in scatters]
    return "\n".join(lines)


def _scaled(r: BatchRow, j: int) -> str:
    s = r.scatter_scale[j]
    return f" [x{s:.1f}]" if s > 1.0 else ""


def batch_counts(rows: Sequence[BatchRow]) -> str:
    """One line: how many logs were trusted, not trusted, failed."""
    n = {s: sum(r.status == s for r in rows) for s in ("trusted", "not trusted", "failed")}
    return (f"{len(rows)} logs: {n['trusted']} trusted, {n['not trusted']} not trusted, "
            f"{n['failed']} failed")


def _finite_or_none(v: object) -> object:
    """JSON has no NaN: a failed log's missing numbers are null."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, (tuple, list)):
        return [_finite_or_none(x) for x in v]
    return v


def batch_json(rows: Sequence[BatchRow], argv: Sequence[str], exit_code: int,
               seconds: float, scatters: Sequence[FlightScatter] = ()) -> dict:
    """batch.json: schema, the command's options, exit code, wall time [s], one entry per
    log (every BatchRow field; ``report`` the log's report.json inside the batch) and the
    flights compared with each other (``between_flights``: parameter, group, logs, chi2,
    dof, p, scale)."""
    def entry(r: BatchRow) -> dict:
        d = asdict(r)
        d["report"] = None if r.status == "failed" else f"logs/{r.name}/report.json"
        return {k: _finite_or_none(v) for k, v in d.items()}

    return {"schema": "pinquad.batch/1", "argv": list(argv), "exit_code": exit_code,
            "seconds": seconds, "logs": [entry(r) for r in rows],
            "between_flights": [{"parameter": sc.parameter, "group": sc.group,
                                 "logs": list(sc.logs), "chi2": sc.chi2, "dof": sc.dof,
                                 "p_value": sc.p_value, "scale": sc.scale}
                                for sc in scatters]}
