"""A batch on a Dask cluster with one worker process killed mid-run, against the same
batch undisturbed: are all rows there, and equal?

    PINQUAD_CRAZYFLIE_DATA=../shared/data/crazyflie python scripts/dask_worker_kill.py \\
        OUT_DIR ../shared/data/crazyflie/imrc_brushed/jana0{0,2,3} \\
        ../shared/data/crazyflie/imrc_brushed/jana10

starts ``dask scheduler`` and ``dask worker --nworkers 2 --nthreads 1`` (this checkout on
their PYTHONPATH), runs ``python -m pinquad.offline --log LOGS --scheduler ADDRESS`` into
OUT_DIR/undisturbed, then again into OUT_DIR/killed while one worker process is
SIGKILLed ``KILL_AFTER_S`` (default 15) seconds in (set the environment variable to
change it; with ``KILL_WHEN=held``, after that the first worker seen running a log while
it holds another log's finished result that the batch has not read yet), and prints
each run's exit code, every row of both batch.json files, whether the rows (without
their wall times) and the reports (without theirs) are equal, and the error lines in
what each log printed (``logs/<name>.txt``).
The cluster is stopped at the end.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pinquad.io.runs import without_wall_times

ROOT = Path(__file__).resolve().parents[1]


def _rows(batch_dir: Path) -> list[dict]:
    return [without_wall_times(r) for r in json.loads((batch_dir / "batch.json").read_text())["logs"]]


def _reports(batch_dir: Path) -> dict:
    return {p.parent.name: without_wall_times(json.loads(p.read_text()))
            for p in sorted((batch_dir / "logs").glob("*/report.json"))}


def _console_errors(batch_dir: Path) -> dict[str, list[str]]:
    """Each log's error lines in what it printed (``logs/<name>.txt``): a rerun that
    failed after the batch had read the first attempt's row shows only there."""
    return {p.name: [line for line in p.read_text().splitlines() if line.startswith("error:")]
            for p in sorted((batch_dir / "logs").glob("*.txt"))}


def _victim(client, held: bool) -> str | None:
    """The first worker seen running a log while it holds another's finished result that
    the batch has not read yet (both are lost with it), waiting up to 10 minutes."""
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline:
        busy = {w for w, keys in client.processing().items() if keys}
        holding = {w for w, keys in client.has_what().items() if keys}
        if busy & holding:
            return sorted(busy & holding)[0]
        time.sleep(0.2)
    return None


def _batch(logs: list[str], address: str, out: Path, env: dict) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "pinquad.offline", "--log", *logs,
                             "--scheduler", address, "--out", str(out)], env=env,
                            stdout=open(f"{out}.txt", "w"), stderr=subprocess.STDOUT)


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    out, logs = Path(argv[0]), [str(Path(p).absolute()) for p in argv[1:]]
    kill_after = float(os.environ.get("KILL_AFTER_S", "15"))
    held = os.environ.get("KILL_WHEN") == "held"
    out.mkdir(parents=True, exist_ok=False)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    scheduler_file = out / "scheduler.json"
    cluster = [subprocess.Popen(["dask", "scheduler", "--port", "0", "--no-dashboard",
                                 "--scheduler-file", str(scheduler_file)], env=env,
                                stdout=open(out / "scheduler.log", "w"), stderr=subprocess.STDOUT)]
    try:
        while not scheduler_file.exists():
            time.sleep(0.2)
        time.sleep(0.5)
        address = json.loads(scheduler_file.read_text())["address"]
        cluster.append(subprocess.Popen(
            ["dask", "worker", "--scheduler-file", str(scheduler_file), "--nworkers", "2",
             "--nthreads", "1", "--no-dashboard"], env=env,
            stdout=open(out / "workers.log", "w"), stderr=subprocess.STDOUT))
        from distributed import Client  # optional dependency, only for this script

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=120)
            t0 = time.perf_counter()
            code_undisturbed = _batch(logs, address, out / "undisturbed", env).wait()
            print(f"undisturbed: exit {code_undisturbed}, {time.perf_counter() - t0:.0f} s")
            t0 = time.perf_counter()
            killed_run = _batch(logs, address, out / "killed", env)
            time.sleep(kill_after)
            victim = _victim(client, held) if held else None
            pids = client.run(os.getpid)
            victim = victim or sorted(pids)[0]
            os.kill(pids[victim], signal.SIGKILL)
            print(f"killed worker {victim} (process {pids[victim]}) "
                  f"{time.perf_counter() - t0:.0f} s in")
            code_killed = killed_run.wait()
            print(f"killed: exit {code_killed}, {time.perf_counter() - t0:.0f} s")
    finally:
        for process in reversed(cluster):
            process.terminate()
            process.wait(timeout=30)
    undisturbed, killed = _rows(out / "undisturbed"), _rows(out / "killed")
    for label, rows in (("undisturbed", undisturbed), ("killed", killed)):
        for r in rows:
            inertia = ", ".join(f"{v * 1e6:.4f}" for v in r["inertia_diag"] if v is not None)
            print(f"{label:11s} {r['name']}: {r['status']}, mass "
                  f"{(r['mass'] or float('nan')) * 1e3:.4f} g, I diag [{inertia}] e-6 kg m^2, "
                  f"effects {r['effects']}{', error ' + r['error'] if r['error'] else ''}")
    same_rows = undisturbed == killed
    same_reports = _reports(out / "undisturbed") == _reports(out / "killed")
    errors = {label: {k: v for k, v in _console_errors(out / label).items() if v}
              for label in ("undisturbed", "killed")}
    print(f"rows equal (without wall times): {same_rows}; reports equal (without wall "
          f"times): {same_reports}; exit codes {code_undisturbed} / {code_killed}; errors "
          f"in the logs' printed text: {errors}")
    same = same_rows and same_reports and errors["undisturbed"] == errors["killed"]
    return 0 if same and code_undisturbed == code_killed else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
