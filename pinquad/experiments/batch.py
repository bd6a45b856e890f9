"""Batch identification of many recorded logs (``python -m pinquad.offline --log A B C``):
one row per log, read from the log's own report.json (DESIGN 4.3) or, when the log could
not be identified, its error message; and the batch's exit code.

Each log goes through exactly the single ``--log`` pipeline (pinquad.cli.offline.run_log)
in its own subdirectory; this module only summarises what those runs wrote.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

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
    effects: names of the effects discovery selected, in order (DESIGN 4.4).
    seconds: the run's wall time [s].
    error: the error message of a failed log, else "".
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


NAN3 = (float("nan"),) * 3


def _number(value: object) -> float:
    """A report's number, nan where it has none (null: e.g. no standard errors asked for)."""
    return float("nan") if value is None else float(value)


def row_from_report(name: str, path: str, report: dict, seconds: float) -> BatchRow:
    """The row of a log identified by the single-log pipeline, from its report.json."""
    est = report["estimates"]
    verdict = est.get("verdict") or report.get("verdict") or {}
    overall = verdict.get("overall", "")
    inertia = np.asarray(est["inertia"], dtype=float)
    se = est.get("stderr") or {}
    discovery = report.get("discovery") or {}
    return BatchRow(
        name=name, path=path, status="trusted" if overall == "trusted" else "not trusted",
        mass=float(est["mass"]), mass_se=_number(se.get("mass")),
        inertia_diag=tuple(float(v) for v in np.diag(inertia)),
        inertia_se=tuple(_number(v) for v in (se.get("inertia_diag") or NAN3)),
        overall=overall,
        verdicts={k: v.get("verdict", "") for k, v in verdict.get("parameters", {}).items()},
        effects=tuple(s["effect"] for s in discovery.get("selected", [])),
        seconds=seconds, error="")


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
