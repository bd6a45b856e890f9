"""``pinquad.identify_many``: one ``Result`` per log, the same as ``pinquad.identify`` on
that log alone, and rows holding the numbers each log's report.json says. A batch
survives a Dask worker killed mid-task: on a local cluster of two single-threaded worker
processes, one of them SIGKILLed while it runs a task and holds a finished one, the
scheduler runs the lost tasks again elsewhere, each replaces its own partial output, and
every row, Result and written report equals the undisturbed batch's."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from dataclasses import asdict
from pathlib import Path

import distributed
import numpy as np
import pytest
from conftest import row_from_written_report, write_with_paper_guess
from threadpoolctl import threadpool_limits

import pinquad
from pinquad.experiments.batch import compare_flights
from pinquad.io.runs import without_wall_times
from pinquad.pipeline import PipelineOptions
from pinquad.pipeline.identify import LogOptions
from pinquad.results.batch import Batch, identify_many
from pinquad.sim.simulator import SimConfig, flight_log, simulate

# short EM runs: the point is the batch's mechanics under a worker's death, not accuracy
FAST = PipelineOptions(LogOptions(sensors=("B",), msteps=("regressor",), max_iterations=6,
                                  information=False), discover=False)


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Four windows of one seeded sensor-B flight, as CSV with the paper's guess: the
    first 18 s (while it runs on one worker, the other finishes the second log and starts
    the third), then three of 6 s."""
    directory = tmp_path_factory.mktemp("windows")
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(23)))
    paths = []
    for i, (start, stop) in enumerate(((0, 1800), (1800, 2400), (2400, 3000), (3000, 3600))):
        written = write_with_paper_guess(log.slice(start, stop), directory / f"w{i}.csv")
        paths.append(written)
    return paths


@pytest.fixture(scope="module")
def undisturbed(logs: list[Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Batch, Path]:
    """The four logs' batch in this process, and the directory of its runs."""
    out = tmp_path_factory.mktemp("undisturbed")
    return identify_many(logs, None, FAST, out), out


def _comparable(row) -> str:
    """A row without its wall time (the only field that differs between two runs), as
    JSON text (NaN, where there is no standard error, equals NaN there)."""
    d = asdict(row)
    d.pop("seconds")
    return json.dumps(d)


def _reports(logs_dir: Path) -> dict[str, object]:
    """Every report.json under ``logs_dir``, without its wall times."""
    return {path.parent.name: without_wall_times(json.loads(path.read_text()))
            for path in sorted(logs_dir.glob("*/report.json"))}


def test_identify_many_returns_the_results_of_identify_and_the_rows_of_their_reports(
        logs: list[Path], undisturbed: tuple[Batch, Path], tmp_path: Path):
    batch, out = undisturbed
    assert len(batch.results) == len(logs) == len(batch.rows)
    for path, result, row in zip(logs, batch.results, batch.rows, strict=True):
        assert isinstance(result, pinquad.Result)
        with threadpool_limits(limits=1):  # as every batch task runs: the same bits
            alone = pinquad.identify(pinquad.read_log(path), sensor="B", mstep="regressor",
                                     max_iterations=6, information=False)
        assert result.mass == alone.mass and row.mass == alone.mass
        np.testing.assert_array_equal(result.inertia, alone.inertia)
        np.testing.assert_array_equal(result.stderr, alone.stderr)
        assert result.verdict.overall == alone.verdict.overall
        assert [(p.name, p.verdict) for p in result.verdict.parameters] == \
            [(p.name, p.verdict) for p in alone.verdict.parameters]
        # what it prints, but the first line's wall time
        assert result.summary().splitlines()[1:] == alone.summary().splitlines()[1:]
    # the rows hold what each log's report.json says: those the batch built from the
    # written reports, compared between flights the same way
    from_reports, _ = compare_flights([
        row_from_written_report(r.name, r.path,
                                 json.loads((out / r.name / "report.json").read_text()),
                                 r.seconds) for r in batch.rows])
    assert [_comparable(r) for r in batch.rows] == [_comparable(r) for r in from_reports]
    # a Result saves the run directory its task wrote
    again = batch.results[1].save(tmp_path / "again")
    assert without_wall_times(json.loads((again / "report.json").read_text())) == \
        _reports(out)["w1.csv"]
    # a log that fails is its row's error and no Result; rows only when asked
    broken = tmp_path / "broken.csv"
    broken.write_text("t,pos_x\n0.0,1.0\n0.0,2.0\n")
    failed = identify_many([broken, logs[1]], None, FAST)
    assert [r.status for r in failed.rows][0] == "failed" and str(broken) in failed.rows[0].error
    assert failed.results[0] is None and failed.results[1].mass == batch.results[1].mass
    assert identify_many([broken], None, FAST, keep_results=False).results == ()


def test_a_worker_killed_mid_task_loses_no_row(logs: list[Path],
                                                undisturbed: tuple[Batch, Path], tmp_path: Path):
    paths = logs
    undisturbed, undisturbed_dir = undisturbed
    assert [r.status for r in undisturbed.rows].count("failed") == 0

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        outcome: dict = {}
        batch = threading.Thread(target=lambda: outcome.setdefault(
            "batch", identify_many(paths, client, FAST, tmp_path / "killed")))
        batch.start()
        victim, deadline = None, time.monotonic() + 60
        while victim is None and time.monotonic() < deadline:
            # a worker that is running a task and holds a finished one the batch still
            # waits to read (the first log is still running): both are lost and run again
            busy = {w for w, keys in client.processing().items() if keys}
            holding = {w for ws in client.who_has().values() for w in ws}
            victim = next(iter(busy & holding), None)
            time.sleep(0.05)
        assert victim is not None, "no worker was running a task beside a finished one"
        os.kill(pids[victim], signal.SIGKILL)
        batch.join(timeout=120)
        assert not batch.is_alive(), "the batch did not finish after the worker was killed"
        killed = outcome["batch"]
        assert pids[victim] not in client.run(os.getpid).values()  # a new worker took over

    assert [_comparable(r) for r in killed.rows] == [_comparable(r) for r in undisturbed.rows]
    assert killed.exit_code == undisturbed.exit_code
    # the Results came back from the workers whole: the same numbers, and one saves the
    # run its task wrote
    assert [r.mass for r in killed.results] == [r.mass for r in undisturbed.results]
    assert [r.verdict.overall for r in killed.results] == \
        [r.verdict.overall for r in undisturbed.results]
    shipped = killed.results[2].save(tmp_path / "shipped")
    assert without_wall_times(json.loads((shipped / "report.json").read_text())) == \
        _reports(undisturbed_dir)["w2.csv"]
    assert _reports(tmp_path / "killed") == _reports(undisturbed_dir)
    # nothing an interrupted attempt left half written: the same files, no staging
    listing = sorted(p.name for p in (tmp_path / "killed").iterdir())
    assert listing == sorted(p.name for p in undisturbed_dir.iterdir())
    assert listing == ["w0.csv", "w0.csv.txt", "w1.csv", "w1.csv.txt", "w2.csv",
                       "w2.csv.txt", "w3.csv", "w3.csv.txt"]
    # a rerun that failed after the batch had read the first attempt's row would show
    # only in what the log printed
    for console in sorted((tmp_path / "killed").glob("*.txt")):
        assert "error:" not in console.read_text(), console.read_text()[-300:]
