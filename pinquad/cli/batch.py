"""``python -m pinquad.offline --log A B C`` (several paths after one ``--log``, or a glob
pattern): batch identification. Each log goes through the single ``--log`` pipeline
(``pinquad.cli.offline.run_log``, the same options) in its own worker process and writes
its run directory under ``logs/<name>/`` of one batch run directory, with what it printed
in ``logs/<name>.txt``; a log that fails (bad file, numerical failure) is a row with its
error message and does not stop the others. The batch directory holds ``table.md`` (one
row per log: mass, inertia, verdicts, effects, error) and ``batch.json``.

Exit codes: 0 every log's headline trusted; 3 every log identified, some headline not
trusted; 4 at least one log failed (its row says why); 2 bad arguments (no log matches a
pattern, --out unusable: nothing written).
"""

from __future__ import annotations

import argparse
import contextlib
import glob
import io
import json
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from pinquad.core.execution import Backend, open_executor
from pinquad.experiments.batch import (
    BatchRow,
    batch_exit_code,
    compare_flights,
    failed_row,
    row_from_report,
    unique_names,
)
from pinquad.io.logs import LogFormatError
from pinquad.io.runs import RunWriter, new_run_dir
from pinquad.report.batch import batch_counts, batch_json, batch_table

GLOB_CHARS = frozenset("*?[")

BATCH_EXIT_CODES = (
    "with several --log paths or a pattern (a batch): 0 every log's headline trusted; 3 every "
    "log identified but some headline not trusted; 4 at least one log failed (its row in "
    "table.md says why; the others are identified and written); 2 bad arguments (nothing "
    "written)")


def is_batch(logs: Sequence[Path]) -> bool:
    """Several paths after --log, or one glob pattern (``*``, ``?``, ``[``) that is not an
    existing file's name: a batch. One plain path keeps the single-log command."""
    return len(logs) > 1 or (not logs[0].exists() and bool(GLOB_CHARS & set(str(logs[0]))))


def expand_logs(logs: Sequence[Path]) -> list[Path]:
    """The batch's logs in the order given, each pattern expanded (sorted), duplicates
    dropped. Raises ValueError naming a pattern that matches no file."""
    paths: list[Path] = []
    for given in logs:
        text = str(given)
        if not given.exists() and GLOB_CHARS & set(text):
            matched = sorted(Path(p) for p in glob.glob(text) if Path(p).is_file())
            if not matched:
                raise ValueError(f"--log {text}: the pattern matches no file")
            paths.extend(matched)
        else:
            paths.append(given)  # a missing file is that log's row, not the batch's end
    unique: list[Path] = []
    for p in paths:
        if p not in unique:
            unique.append(p)
    return unique


@dataclass(frozen=True)
class LogTask:
    """One log of a batch, picklable for a worker process.

    run_one: the single-log command (``pinquad.cli.offline.run_log``) taking a Namespace.
    args: the batch's parsed options (``log``, ``out``, ``view`` replaced per log).
    log: the log's path; out: its run directory (inside the batch's staging directory);
    console: where what it prints is written.
    """

    run_one: Callable[[argparse.Namespace], int]
    args: argparse.Namespace
    log: Path
    out: Path
    console: Path


@dataclass(frozen=True)
class LogOutcome:
    """What a worker returns: the single-log exit code (0, 3), or -1 with ``error`` set;
    the run's wall time [s]."""

    code: int
    error: str
    seconds: float


def run_log_task(task: LogTask) -> LogOutcome:
    """Run the single-log command on one log with its output captured; a failure of any
    kind becomes the outcome's error (one bad log must not stop a batch)."""
    args = argparse.Namespace(**{**vars(task.args), "log": task.log, "out": task.out,
                                 "view": False})
    buffer = io.StringIO()
    t0 = time.perf_counter()
    code, error = -1, ""
    with contextlib.redirect_stdout(buffer), contextlib.redirect_stderr(buffer):
        try:
            code = task.run_one(args)
        except (LogFormatError, FileExistsError, FileNotFoundError, ValueError) as exc:
            error = str(exc)
        except Exception as exc:  # noqa: BLE001 - reported in the row, the batch goes on
            error = f"{type(exc).__name__}: {exc}"
            traceback.print_exc(file=buffer)
    seconds = time.perf_counter() - t0
    if error:
        buffer.write(f"error: {error}\n")
    task.console.write_text(buffer.getvalue())
    return LogOutcome(code if not error else -1, error, seconds)


def run_batch(args: argparse.Namespace, run_one: Callable[[argparse.Namespace], int],
              backend: Backend, argv: Sequence[str] = ()) -> int:
    """Identify every log of ``args.log`` (module docstring) on ``backend`` (the process
    pool or a Dask cluster: the same tasks, the same rows) and write the batch run
    directory; returns the batch exit code. Raises ValueError / OutputError on bad
    arguments, BackendError when the backend cannot be had, before any work."""
    logs = expand_logs(args.log)
    writer = RunWriter(args.out or new_run_dir("batch"))  # --out checked before any work
    names = unique_names([str(p) for p in logs])
    t0 = time.perf_counter()
    print(f"pinquad offline batch: {len(logs)} logs, {backend.describe()}, E-step "
          f"{args.estep}, M-step(s) {args.mstep}{', no discovery' if args.no_discover else ''}")
    with open_executor(backend, len(logs)) as pool, writer:
        # absolute paths: a Dask worker need not share this process's working directory
        tasks = [LogTask(run_one, args, p.absolute(), writer.path(f"logs/{n}").absolute(),
                         writer.path(f"logs/{n}.txt").absolute())
                 for p, n in zip(logs, names, strict=True)]
        outcomes = list(pool.map(run_log_task, tasks))
        rows: list[BatchRow] = []
        for task, given, name, outcome in zip(tasks, logs, names, outcomes, strict=True):
            report = task.out / "report.json"
            if outcome.error or not report.is_file():
                rows.append(failed_row(name, str(given), outcome.error or
                                       f"no report written (exit code {outcome.code})",
                                       outcome.seconds))
            else:
                rows.append(row_from_report(name, str(given), json.loads(report.read_text()),
                                            outcome.seconds))
            print(f"  {name}: {rows[-1].status}"
                  + (f" ({rows[-1].error})" if rows[-1].error else ""))
        # flights of one vehicle against each other: errors scaled where they scatter
        # more than they allow, and a verdict lowered where the scaled error is too wide
        rows, scatters = compare_flights(rows)
        code = batch_exit_code(rows)
        table = batch_table(rows, scatters)
        writer.path("table.md").write_text(
            f"# pinquad offline batch\n\n{batch_counts(rows)}; exit code {code}\n\n{table}\n")
        writer.path("batch.json").write_text(json.dumps(
            batch_json(rows, argv, code, time.perf_counter() - t0, scatters), indent=2))
        final = writer.publish()
    print()
    print(table)
    print()
    print(f"{batch_counts(rows)}; {time.perf_counter() - t0:.0f} s")
    print(f"batch written to {final} (each log's run in logs/<name>/)")
    if code:
        print(f"exit code {code}: {BATCH_EXIT_CODES}", file=sys.stderr)
    return code
