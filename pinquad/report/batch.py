"""The batch table (``python -m pinquad.offline --log A B C``): one line per log with the
headline mass and inertia, their verdicts, the effects discovery selected, or the error
of a log that failed; and the batch's batch.json."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict

from pinquad.experiments.batch import BatchRow

SHORT = {"trusted": "ok", "not identifiable": "n/i", "implausible": "impl",
         "model not adequate": "model"}


def _pm(value: float, se: float, scale: float, fmt: str) -> str:
    if not math.isfinite(value):
        return "-"
    if not math.isfinite(se):
        return f"{value * scale:{fmt}}"
    return f"{value * scale:{fmt}} +- {se * scale:{fmt}}"


def batch_table(rows: Sequence[BatchRow]) -> str:
    """A markdown table: log, status, mass [g], I_xx/I_yy/I_zz [1e-6 kg m^2], the
    per-parameter verdicts, effects, seconds, and a failed log's error message."""
    lines = ["| log | status | mass [g] | I_xx [1e-6 kg m^2] | I_yy | I_zz | verdicts "
             "(m, Ixx, Iyy, Izz) | effects | s | error |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        verdicts = ", ".join(SHORT.get(r.verdicts.get(k, ""), r.verdicts.get(k, "") or "-")
                             for k in ("mass", "I_xx", "I_yy", "I_zz")) if r.verdicts else "-"
        inertia = [_pm(v, s, 1e6, ".2f") for v, s in zip(r.inertia_diag, r.inertia_se,
                                                          strict=True)]
        error = r.error.replace("|", "/").replace("\n", " ")
        lines.append(f"| {r.name} | {r.status} | {_pm(r.mass, r.mass_se, 1e3, '.3f')} | "
                     f"{' | '.join(inertia)} | {verdicts} | "
                     f"{', '.join(r.effects) or '-'} | {r.seconds:.0f} | {error} |")
    return "\n".join(lines)


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
               seconds: float) -> dict:
    """batch.json: schema, the command's options, exit code, wall time [s] and one entry
    per log (every BatchRow field; ``report`` the log's report.json inside the batch)."""
    def entry(r: BatchRow) -> dict:
        d = asdict(r)
        d["report"] = None if r.status == "failed" else f"logs/{r.name}/report.json"
        return {k: _finite_or_none(v) for k, v in d.items()}

    return {"schema": "pinquad.batch/1", "argv": list(argv), "exit_code": exit_code,
            "seconds": seconds, "logs": [entry(r) for r in rows]}
