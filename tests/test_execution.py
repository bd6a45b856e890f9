"""The execution backend (issue 23, ``pinquad.core.execution``): the same tasks and seeds
give the same numbers on the local process pool and on a Dask cluster (a seeded slice of
the paper's Monte Carlo, a batch of logs through ``offline --log A B``), and a backend that
cannot be had is a clear exit-2 message, never a traceback."""

from __future__ import annotations

import json
import logging
import socket
import sys
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import write_with_paper_guess
from distributed import LocalCluster
from threadpoolctl import threadpool_info

from pinquad.cli.discovery import main as discovery_main
from pinquad.cli.offline import main as offline_main
from pinquad.core.execution import (
    Backend,
    BackendError,
    OneThreadExecutor,
    open_executor,
    parse_cluster_spec,
)
from pinquad.core.params import PAPER_SCENARIO
from pinquad.experiments.offline_mc import CycleJob, CycleResult, run_cycles
from pinquad.sim.simulator import SimConfig, flight_log, simulate

# a seeded slice, cheap: two cycles of sensor B, 3 EM iterations (accuracy is elsewhere)
MC_JOBS = [CycleJob(sensor="B", cycle=i, seed=23, msteps=("regressor",), max_iterations=3,
                    information=False) for i in range(2)]
BATCH = ["--sensor", "B", "--mstep", "regressor", "--no-information", "--no-discover",
         "--max-iterations", "6"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two 6 s simulated sensor-B flights (seeds 5 and 6) to the paper's first waypoint,
    as CSV with the paper's initial guess."""
    out = tmp_path_factory.mktemp("logs")
    paths = []
    short = replace(PAPER_SCENARIO, waypoints=PAPER_SCENARIO.waypoints[:1])
    for seed in (5, 6):
        log = flight_log(simulate(SimConfig(sensor="B", scenario=short),
                                  np.random.default_rng(seed)))
        written = write_with_paper_guess(log.slice(0, 600), out / f"flight{seed}.csv")
        paths.append(written)
    return paths


def blas_threads(info: list[dict]) -> set[int]:
    """The thread counts of the BLAS libraries a process has loaded (threadpoolctl)."""
    return {lib["num_threads"] for lib in info if lib["user_api"] == "blas"}


def batch_numbers(out: Path) -> list[dict]:
    """Each log's row of a batch without its wall time, and its report's estimates."""
    rows = json.loads((out / "batch.json").read_text())["logs"]
    return [{**{k: v for k, v in r.items() if k != "seconds"},
             "estimates": json.loads((out / "logs" / r["name"] / "report.json").read_text())
             ["estimates"]} for r in rows]


@pytest.fixture(scope="module")
def on_pool(logs: list[Path], tmp_path_factory: pytest.TempPathFactory
            ) -> tuple[list[CycleResult], list[dict]]:
    """The Monte Carlo slice and the batch on the process pool of 2 workers (run before
    the cluster starts: the pool forks, and a fork should not copy the cluster's threads)."""
    with open_executor(Backend(jobs=2), len(MC_JOBS)) as pool:
        assert isinstance(pool, OneThreadExecutor) and isinstance(pool.inner, ProcessPoolExecutor)
        cycles = run_cycles(MC_JOBS, pool, progress=False)
        assert blas_threads(pool.submit(threadpool_info).result()) == {1}
    out = tmp_path_factory.mktemp("pool") / "batch"
    assert offline_main(["--log", *map(str, logs), *BATCH, "--jobs", "2", "--out", str(out)]) \
        in (0, 3)
    return cycles, batch_numbers(out)


@pytest.fixture(scope="module")
def scheduler(on_pool) -> Iterator[str]:
    """A local Dask cluster of 2 single-threaded worker processes (after the pool's work);
    its scheduler's address."""
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


def test_monte_carlo_slice_has_the_same_numbers_on_dask(on_pool, scheduler: str):
    with open_executor(Backend(scheduler=scheduler)) as dask:
        on_dask = run_cycles(MC_JOBS, dask, progress=False)
        # every backend runs a task on one BLAS thread: the thread count moves BLAS sums'
        # last digits (discovery's refit by ~1e-7), so the backends agree bit for bit
        assert blas_threads(dask.submit(threadpool_info).result()) == {1}
    pooled = on_pool[0]
    # flight seed = base*100000 + sensor*1000 + cycle, sensor B = 1
    assert [c.seed for c in on_dask] == [c.seed for c in pooled] == [2301000, 2301001]
    for a, b in zip(pooled, on_dask, strict=True):
        ra, rb = a.runs[0], b.runs[0]
        assert ra.mass == rb.mass
        np.testing.assert_array_equal(ra.inertia, rb.inertia)
        np.testing.assert_array_equal(ra.loglik, rb.loglik)
        np.testing.assert_array_equal(ra.history_mass, rb.history_mass)
        assert a.flight == b.flight
    # two seeds, two flights: the equality above compares numbers that could differ
    assert pooled[0].runs[0].mass != pooled[1].runs[0].mass


def test_batch_of_logs_has_the_same_rows_on_dask(on_pool, scheduler: str, logs: list[Path],
                                                 tmp_path: Path):
    out = tmp_path / "batch"
    assert offline_main(["--log", *map(str, logs), *BATCH, "--scheduler", scheduler,
                         "--out", str(out)]) in (0, 3)
    on_dask = batch_numbers(out)
    assert [r["name"] for r in on_dask] == ["flight5.csv", "flight6.csv"]
    assert on_dask == on_pool[1]
    assert on_dask[0]["mass"] != on_dask[1]["mass"] and on_dask[0]["mass"] is not None


def test_bad_backend_options_are_exit_2_with_a_message(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str]):
    for spec in ("local", "local:0", "remote:2", "local:two"):
        with pytest.raises(SystemExit) as exc:
            offline_main(["--cluster", spec])
        assert exc.value.code == 2
        assert "expected local:N" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        offline_main(["--cluster", "local:2", "--scheduler", "tcp://127.0.0.1:8786"])
    assert exc.value.code == 2 and "not allowed with" in capsys.readouterr().err
    assert parse_cluster_spec(" local:3 ") == 3

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "run"
    assert offline_main(["--cycles", "1", "--scheduler", f"tcp://127.0.0.1:{port}",
                         "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--scheduler tcp://127.0.0.1:{port}: no Dask scheduler reached" in err
    assert "Traceback" not in err and not out.exists()
    with pytest.raises(BackendError, match="unknown address scheme"):
        with open_executor(Backend(scheduler="foo://127.0.0.1:1")):
            pass

    monkeypatch.setitem(sys.modules, "distributed", None)  # as if it were not installed
    assert discovery_main(["--seeds", "1", "--conditions", "none", "--cluster", "local:2",
                           "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "pip install 'pinquad[cluster]'" in err and not out.exists()
