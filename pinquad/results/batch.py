"""Many recorded logs through the one pipeline: ``identify_many(paths, executor=...)``.

Each log is one task, ``run_log_task``: the single-log pipeline (``pipeline.single``)
gives the log's ``Result``, its run directory is saved under ``logs/<name>/`` of the
batch directory and what it would print goes to ``logs/<name>.txt``; the task returns the
log's row, built from the Result's numbers (``experiments.batch.row_from_result``), and
the Result itself. A log that fails (bad file, numerical failure) is a row with its error
message and does not stop the others. The flights of one vehicle are then compared with
each other (``compare_flights``).

Every task is idempotent: it writes only its own ``logs/<name>/`` and ``logs/<name>.txt``,
and a rerun replaces whatever an earlier attempt wrote or left half written
(``RunWriter(replace=True)``, files written whole by rename), and returns the same row and
Result. A Dask worker killed mid-task, whose lost tasks the scheduler runs again elsewhere
(including finished ones whose results lived on it), therefore leaves the batch with every
row, the same as an undisturbed run.

The executor is anything with ``concurrent.futures.Executor``'s ``map`` (a process pool,
``core.execution``'s backends) or a Dask ``distributed.Client`` (its
``get_executor(pure=False)``: every task is run, none taken from an earlier identical
call). Each task runs with one BLAS thread, on every backend the same bits.

A Result travels back from a worker whole, smoothed posteriors included, so that
``save()`` and ``summary()`` on it give what the worker wrote: 4.8 MB pickled for the
Crazyflie flight jana00 with discovery (its two EM runs' posteriors, 919 steps of means
(12,), covariances and lag-one covariances (12, 12), 2.2 MB each; discovery's refit shares
the reported run's), in proportion to the log's length. ``keep_results=False`` returns
the rows only (the command line's batch, whose runs are on disk).
"""

from __future__ import annotations

import contextlib
import io
import time
import traceback
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pinquad.core.execution import InProcessExecutor, OneThreadExecutor
from pinquad.experiments.batch import (
    BatchRow,
    batch_exit_code,
    compare_flights,
    failed_row,
    row_from_result,
    unique_names,
)
from pinquad.io.logs import LogFormatError
from pinquad.io.runs import atomic_write_bytes
from pinquad.pipeline.single import PipelineOptions, run_path
from pinquad.realdata.consistency import FlightScatter
from pinquad.report.batch import batch_counts, batch_table
from pinquad.results.result import Result


@dataclass(frozen=True)
class LogTask:
    """One log of a batch, picklable for a worker process.

    log: the log's path (absolute: a worker need not share the caller's working
    directory); given: the path as the caller gave it (the row's ``path``); name: its
    unique name in the batch; options: the pipeline's; logs_dir: the directory that holds
    the log's ``<name>/`` run and ``<name>.txt`` (None: nothing written); keep_result:
    return the log's Result (False: its row only).
    """

    log: Path
    given: str
    name: str
    options: PipelineOptions
    logs_dir: Path | None
    keep_result: bool = True


@dataclass(frozen=True)
class LogOutcome:
    """What a task returns: the log's row (``BatchRow``: its numbers, verdicts, effects
    and wall time [s], or its error), its Result (None when it failed or was not kept)
    and what it printed."""

    row: BatchRow
    result: Result | None
    console: str


def run_log_task(task: LogTask) -> LogOutcome:
    """The single-log pipeline on one log, its run directory saved (replacing any earlier
    attempt's), what it prints captured; a failure of any kind becomes the row's error
    (one bad log must not stop a batch)."""
    buffer = io.StringIO()
    t0 = time.perf_counter()
    result, error = None, ""
    with contextlib.redirect_stdout(buffer), contextlib.redirect_stderr(buffer):
        print(f"pinquad offline --log {task.log}: E-step {task.options.identification.estep}"
              f", M-step(s) {', '.join(task.options.identification.msteps)}")
        try:
            result = Result.of(run_path(task.log, task.options))
            print(result.explain())
            if task.logs_dir is not None:
                final = result.save(task.logs_dir / task.name, replace=True)
                print(f"run written to {final}")
        except (LogFormatError, FileExistsError, FileNotFoundError, ValueError) as exc:
            result, error = None, str(exc) or type(exc).__name__
        except Exception as exc:  # noqa: BLE001 - reported in the row, the batch goes on
            result, error = None, f"{type(exc).__name__}: {exc}"
            traceback.print_exc(file=buffer)
    seconds = time.perf_counter() - t0
    if error:
        buffer.write(f"error: {error}\n")
    if task.logs_dir is not None:
        atomic_write_bytes(task.logs_dir / f"{task.name}.txt", buffer.getvalue().encode())
    row = (failed_row(task.name, task.given, error, seconds) if result is None
           else row_from_result(task.name, task.given, result, seconds))
    return LogOutcome(row, result if task.keep_result else None, buffer.getvalue())


@dataclass(frozen=True)
class Batch:
    """A batch's outcome: one row per log in the order given (``BatchRow``: estimates,
    verdicts, effects, or the error), the flights of one vehicle compared with each other
    (``FlightScatter``), the exit code (0 every headline trusted, 3 some not, 4 some log
    failed) and ``results``: one ``Result`` per log in the same order (None where the log
    failed; its row says why), each what ``pinquad.identify`` / ``pinquad.discover`` and
    ``offline --log`` give for that log alone (``mass``, ``verdict``, ``summary()``,
    ``save()``); empty when ``identify_many`` was asked not to keep them.

    A row can differ from its Result where the flights were compared with each other:
    its errors scaled by the scatter between flights (``scatter_scale``), and a trusted
    parameter whose scaled error covers too much of the vehicle's range lowered to "not
    identifiable". The Result is the log on its own.
    """

    rows: tuple[BatchRow, ...]
    scatters: tuple[FlightScatter, ...]
    exit_code: int
    results: tuple[Result | None, ...] = ()

    def summary(self) -> str:
        """What ``offline --log A B C`` prints at the end: the counts and the table (one
        row per log: mass, inertia, verdicts, effects or the error)."""
        return f"{batch_counts(self.rows)}\n\n{batch_table(self.rows, self.scatters)}"


def as_executor(executor: Any) -> Executor:
    """``executor`` as a ``concurrent.futures.Executor`` whose tasks run with one BLAS
    thread: a Dask ``distributed.Client`` through ``get_executor(pure=False)``, None as
    this process, anything else as it is (it must have ``map``)."""
    if executor is None:
        return OneThreadExecutor(InProcessExecutor())
    if hasattr(executor, "get_executor"):  # a dask.distributed Client
        executor = executor.get_executor(pure=False)
    if isinstance(executor, OneThreadExecutor):
        return executor
    if not callable(getattr(executor, "map", None)):
        raise TypeError(f"executor: expected a concurrent.futures.Executor or a "
                        f"distributed.Client; got {type(executor).__name__}")
    return OneThreadExecutor(executor)


def identify_many(paths: Sequence[str | Path], executor: Any = None,
                  options: PipelineOptions | None = None,
                  logs_dir: str | Path | None = None, *, keep_results: bool = True) -> Batch:
    """Every log of ``paths`` through the one pipeline (module docstring), as tasks on
    ``executor`` (a ``concurrent.futures.Executor``, a Dask ``distributed.Client``, or
    None: one after the other in this process): a ``Batch`` whose ``results`` are one
    ``Result`` per log and whose ``rows`` the batch table, both in the order of
    ``paths``. logs_dir: where each log's run directory ``<name>/`` and printed text
    ``<name>.txt`` go (None: not kept); keep_results: False returns the rows only (no
    Result travels back from the workers). A missing or unreadable file is its row's
    error (its Result None), not the batch's end."""
    options = options or PipelineOptions()
    given = [Path(p) for p in paths]
    names = unique_names([str(p) for p in given])
    out = None if logs_dir is None else Path(logs_dir).absolute()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    tasks = [LogTask(p.absolute(), str(p), n, options, out, keep_results)
             for p, n in zip(given, names, strict=True)]
    outcomes = list(as_executor(executor).map(run_log_task, tasks))
    # flights of one vehicle against each other: errors scaled where they scatter more
    # than they allow, and a verdict lowered where the scaled error is too wide
    compared, scatters = compare_flights([o.row for o in outcomes])
    return Batch(tuple(compared), tuple(scatters), batch_exit_code(compared),
                 tuple(o.result for o in outcomes) if keep_results else ())
