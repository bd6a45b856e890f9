"""``python -m pinquad.offline --log A B C`` (several paths after one ``--log``, or a glob
pattern): batch identification. Each log goes through the one pipeline
(``pinquad.identify_many``, the same options as a single ``--log``) as a task of
its own and writes its run directory under ``logs/<name>/`` of one batch run directory,
with what it printed in ``logs/<name>.txt``; a log that fails (bad file, numerical
failure) is a row with its error message and does not stop the others. A task run again
(a Dask worker lost mid-task) replaces its own output. The batch directory holds
``table.md`` (one row per log: mass, inertia, verdicts, effects, error) and
``batch.json``.

Exit codes: 0 every log's headline trusted; 3 every log identified, some headline not
trusted; 4 at least one log failed (its row says why); 2 bad arguments (no log matches a
pattern, --out unusable: nothing written).
"""

from __future__ import annotations

import argparse
import glob
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from pinquad.core.execution import Backend, open_executor
from pinquad.io.runs import RunWriter, new_run_dir
from pinquad.pipeline import PipelineOptions
from pinquad.report.batch import batch_counts, batch_json, batch_table
from pinquad.results.batch import identify_many

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


def run_batch(args: argparse.Namespace, options: PipelineOptions, backend: Backend,
              argv: Sequence[str] = ()) -> int:
    """Identify every log of ``args.log`` (module docstring) through
    ``pinquad.identify_many`` on ``backend`` (the process pool or a Dask
    cluster: the same tasks, the same rows) and write the batch run directory; returns
    the batch exit code. Raises ValueError / OutputError on bad arguments, BackendError
    when the backend cannot be had, before any work."""
    logs = expand_logs(args.log)
    writer = RunWriter(args.out or new_run_dir("batch"))  # --out checked before any work
    t0 = time.perf_counter()
    print(f"pinquad offline batch: {len(logs)} logs, {backend.describe()}, E-step "
          f"{args.estep}, M-step(s) {args.mstep}{', no discovery' if args.no_discover else ''}")
    with open_executor(backend, len(logs)) as pool, writer:
        # the rows only: each log's run is on disk, its Result need not travel back
        batch = identify_many(logs, pool, options, writer.path("logs"), keep_results=False)
        rows = batch.rows
        for row in rows:
            print(f"  {row.name}: {row.status}" + (f" ({row.error})" if row.error else ""))
        table = batch_table(rows, batch.scatters)
        code = batch.exit_code
        writer.path("table.md").write_text(
            f"# pinquad offline batch\n\n{batch_counts(rows)}; exit code {code}\n\n{table}\n")
        writer.path("batch.json").write_text(json.dumps(
            batch_json(rows, argv, code, time.perf_counter() - t0, batch.scatters), indent=2))
        final = writer.publish()
    print()
    print(table)
    print()
    print(f"{batch_counts(rows)}; {time.perf_counter() - t0:.0f} s")
    print(f"batch written to {final} (each log's run in logs/<name>/)")
    if code:
        print(f"exit code {code}: {BATCH_EXIT_CODES}", file=sys.stderr)
    return code
