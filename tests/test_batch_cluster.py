"""A batch survives a Dask worker killed mid-task: ``pinquad.identify_many`` on a local
cluster of two single-threaded worker processes, one of them SIGKILLed while it runs a
task and holds a finished one; the scheduler runs the lost tasks again elsewhere, each
replaces its own partial output, and every row and every written report equals the
undisturbed batch's."""

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
from conftest import write_with_paper_guess

from pinquad.io.runs import without_wall_times
from pinquad.pipeline import PipelineOptions
from pinquad.pipeline.identify import LogOptions
from pinquad.results.batch import identify_many
from pinquad.sim.simulator import SimConfig, flight_log, simulate

# short EM runs: the point is the batch's mechanics under a worker's death, not accuracy
FAST = PipelineOptions(LogOptions(sensors=("B",), msteps=("regressor",), max_iterations=6,
                                  information=False), discover=False)


def _logs(directory: Path) -> list[Path]:
    """Four windows of one seeded sensor-B flight, as CSV with the paper's guess: the
    first 18 s (while it runs on one worker, the other finishes the second log and starts
    the third), then three of 6 s."""
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(23)))
    paths = []
    for i, (start, stop) in enumerate(((0, 1800), (1800, 2400), (2400, 3000), (3000, 3600))):
        written = write_with_paper_guess(log.slice(start, stop), directory / f"w{i}.csv")
        paths.append(written)
    return paths


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


def test_a_worker_killed_mid_task_loses_no_row(tmp_path: Path):
    paths = _logs(tmp_path)
    undisturbed = identify_many(paths, None, FAST, tmp_path / "undisturbed")
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
    assert _reports(tmp_path / "killed") == _reports(tmp_path / "undisturbed")
    # nothing an interrupted attempt left half written: the same files, no staging
    listing = sorted(p.name for p in (tmp_path / "killed").iterdir())
    assert listing == sorted(p.name for p in (tmp_path / "undisturbed").iterdir())
    assert listing == ["w0.csv", "w0.csv.txt", "w1.csv", "w1.csv.txt", "w2.csv",
                       "w2.csv.txt", "w3.csv", "w3.csv.txt"]
    # a rerun that failed after the batch had read the first attempt's row would show
    # only in what the log printed
    for console in sorted((tmp_path / "killed").glob("*.txt")):
        assert "error:" not in console.read_text(), console.read_text()[-300:]
