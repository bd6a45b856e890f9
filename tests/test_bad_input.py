"""Issue 21's table, rerunnable: every bad input a new user tried, with its outcome now.

Each case of ``CASES`` is one row of ``docs/bad_input.md``: a short simulated sensor-B
flight (5.3 s, the paper's vehicle; ``short_log``) written as CSV with the paper's
initial guess in its sidecar, damaged as the row says, and given to ``python -m
pinquad.offline --log`` in-process; the row holds when the command exits 2 with a
message that names the column / file / key and says what it looks like. Rows that
concern other commands (``--out``, the benchmark, the viewer, SIGTERM) have their own
tests below. The table in docs/bad_input.md is printed by

    PYTHONPATH=$PWD python -m pytest tests/test_bad_input.py -q -s -k table

(``test_print_table``), and the correct-log side (no check fires on the shipped real
logs or the paper's simulated flights) is ``test_no_check_fires_on_*``.
"""

from __future__ import annotations

import importlib
import json
import math
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

import pinquad
from pinquad.cli import offline as offline_cli
from pinquad.cli import online as online_cli
from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_SCENARIO
from pinquad.identification.identify import unmoved_note
from pinquad.io import sanity
from pinquad.io.logs import log_columns, sidecar
from pinquad.io.read import read_log
from pinquad.io.runs import OutputError, RunWriter
from pinquad.sim.simulator import SimConfig
from viz.__main__ import main as viz_main

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "crazyflie"
SHORT_SCENARIO = replace(PAPER_SCENARIO, start=np.array([0.0, 0.0, 0.0]),
                         waypoints=np.array([[0.0, 0.0, 1.0], [0.6, 0.4, 1.3]]),
                         hover_time=1.0)
"""Take off to 1 m, move 0.8 m, hover: 534 samples at 100 Hz."""


def short_log(sensor: str = "B", seed: int = 1) -> pinquad.FlightLog:
    log = pinquad.simulate(config=SimConfig(sensor=sensor, scenario=SHORT_SCENARIO), seed=seed)
    return replace(log, meta=replace(log.meta, mass_guess=PAPER_INITIAL_MASS,
                                     inertia_guess=np.asarray(PAPER_INITIAL_INERTIA)))


@pytest.fixture(scope="module")
def flight_b() -> pinquad.FlightLog:
    return short_log("B")


@pytest.fixture(scope="module")
def flight_a() -> pinquad.FlightLog:
    return short_log("A")


def write_table(path: Path, cols: dict[str, np.ndarray], side: object | None,
                bom: bool = False) -> Path:
    """A CSV of ``cols`` (NaN as an empty cell) and, unless None, the JSON ``side``."""
    names = list(cols)
    mat = np.column_stack([np.asarray(cols[k], dtype=float) for k in names])
    lines = [",".join(names)] + [",".join("" if math.isnan(v) else repr(float(v)) for v in row)
                                 for row in mat]
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + ("\n".join(lines) + "\n").encode())
    if side is not None:
        Path(f"{path}.json").write_text(json.dumps(side))
    return path


def base_columns(log: pinquad.FlightLog) -> dict[str, np.ndarray]:
    """The log's columns without the simulator's truth and onboard estimate (what a user
    with a recorded flight has)."""
    return {k: v.copy() for k, v in log_columns(log).items()
            if not k.startswith(("true_", "est_"))}


def base_sidecar(log: pinquad.FlightLog) -> dict:
    return sidecar(log.meta)


@dataclass(frozen=True)
class Case:
    """One row of the issue's table: what was done, what happened before the fix, the
    damage (columns, sidecar -> columns, sidecar), extra command-line options, the
    sensor set of the flight, and the words the error message must contain."""

    row: str
    before: str
    damage: Callable[[dict, dict], tuple[dict, object]]
    expect: tuple[str, ...]
    options: tuple[str, ...] = ()
    sensor: str = "B"


def scaled(names: tuple[str, ...], factor: float):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        for name in names:
            cols[name] = cols[name] * factor
        return cols, side
    return damage


def cell(name: str, row: int, value: float):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        cols[name][row] = value
        return cols, side
    return damage


def dropped(*names: str):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        return {k: v for k, v in cols.items() if k not in names}, side
    return damage


def kept(*names: str):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        return {k: v for k, v in cols.items() if k in names}, side
    return damage


def rows(n: int):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        return {k: v[:n] for k, v in cols.items()}, side
    return damage


def side_set(key: str, value: object):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        return cols, {**side, key: value}
    return damage


def side_replaced(value: object):
    def damage(cols: dict, side: dict) -> tuple[dict, object]:
        return cols, value
    return damage


def unchanged(cols: dict, side: dict) -> tuple[dict, object]:
    return cols, side


POS = ("pos_x", "pos_y", "pos_z")
VEL = ("vel_x", "vel_y", "vel_z")
GYRO = ("gyro_x", "gyro_y", "gyro_z")
ACC = ("acc_x", "acc_y", "acc_z")

CASES = (
    Case("positions in mm (x1000)", "exit 0, mass 78.6 g (truth 180), `converged: true`",
         scaled(POS, 1e3), ("pos_x/y/z", "millimetres")),
    Case("positions and velocities in mm", "exit 0, 79.1 g / 140.8 g",
         scaled(POS + VEL, 1e3), ("pos_x, pos_y, pos_z", "centimetres or millimetres")),
    Case("`t` in ms", 'exit 0, "10000 ms" steps, paper M-step I_xx 7.5e21',
         scaled(("t",), 1e3), ("column 't'", "milliseconds")),
    Case("gyro in deg/s", "exit 0, I_xx 7.6 (truth 2.5e-4)",
         scaled(GYRO, 180 / math.pi), ("gyro_x, gyro_y, gyro_z", "deg/s")),
    Case("one gyro column dropped", "exit 0, all gyro silently ignored, I_xx 0.29",
         dropped("gyro_y"), ("lacks gyro_y",)),
    Case("only t, thrust, torques", "exit 0, I_xx 4.6e3",
         kept("t", "thrust", "torque_x", "torque_y", "torque_z"), ("no measurement columns",)),
    Case("one gyro cell 1e300", "exit 0 after 126 s, returns the initial guess 1.000 g",
         cell("gyro_x", 200, 1e300), ("'gyro_x'", "row(s) 201")),
    Case("one thrust cell 1e300", "exit 0, mass inf (null in JSON)",
         cell("thrust", 200, 1e300), ("'thrust'", "row(s) 201")),
    Case("one position cell 1e300", "exit 0, 0.000 g",
         cell("pos_z", 200, 1e300), ("'pos_z'", "row(s) 201")),
    Case("thrust negated", "exit 0, 1.000 g (the initial guess)",
         scaled(("thrust",), -1.0), ("thrust has mean", "sign flipped")),
    Case("sidecar gravity -9.81", "exit 0, 1.000 g (the initial guess)",
         side_set("gravity", -9.81), ("sidecar's key 'gravity' is -9.81", "positive magnitude")),
    Case("1 row", 'exit 0, the initial guess, "1 steps of nan ms"', rows(1), ("1 row(s)",)),
    Case("5 rows", "exit 0, the initial guess", rows(5), ("5 row(s)",)),
    Case("`--max-iterations 0`", "exit 0, the initial guess", unchanged,
         ("--max-iterations",), options=("--max-iterations", "0")),
    Case("`--max-iterations -5`", "exit 0, the initial guess", unchanged,
         ("--max-iterations",), options=("--max-iterations", "-5")),
    Case('sidecar `"vehicle": "boeing747"` (no guesses)', "accepted without a word",
         lambda cols, side: (cols, {**side, "vehicle": "boeing747", "mass_guess": None}),
         ("'vehicle'", "boeing747", "paper, crazyflie21", "give 'mass_guess' and "
          "'inertia_guess'")),
    Case("sidecar is a JSON list `[1, 2, 3]`", "traceback `AttributeError`",
         side_replaced([1, 2, 3]), (".json", "JSON list", "expected an object")),
    Case('sidecar `"mass_guess": "heavy"`', "`could not convert string to float: 'heavy'`",
         side_set("mass_guess", "heavy"), (".json", "'mass_guess'", "'heavy'", "number")),
    Case("`inf` in gyro_x", "`math domain error` (names nothing)",
         cell("gyro_x", 100, math.inf), ("'gyro_x'", "row(s) 101", "inf")),
    # beyond the issue's table: the other unit checks of pinquad.io.sanity
    Case("accelerometer in g (sensor A)", "(not in the issue)", scaled(ACC, 1 / 9.81),
         ("acc_x/y/z", "units of g"), sensor="A"),
    Case("thrust in grams-force", "(not in the issue)", scaled(("thrust",), 1e3 / 9.81),
         ("thrust implies", "grams-force")),
    Case("velocities in mm/s", "(not in the issue)", scaled(VEL, 1e3),
         ("vel_x", "mm/s")),
    Case("mass_guess in grams (180)", "(not in the issue)", side_set("mass_guess", 180.0),
         ("mass_guess", "grams")),
    Case("quaternion missing quat_z", "(not in the issue)", dropped("quat_z"),
         ("lacks quat_z",)),
)


def run_case(case: Case, log: pinquad.FlightLog, tmp: Path,
             capsys: pytest.CaptureFixture) -> tuple[int, str]:
    cols, side = case.damage(base_columns(log), base_sidecar(log))
    path = write_table(tmp / "flight.csv", cols, side)
    try:
        code = offline_cli.main(["--log", str(path), "--out", str(tmp / "run"),
                                 "--no-discover", *case.options])
    except SystemExit as exc:  # argparse
        code = int(exc.code)
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize("case", CASES, ids=[c.row for c in CASES])
def test_issue_row_exits_2_with_a_located_message(case, flight_a, flight_b, tmp_path, capsys):
    code, err = run_case(case, flight_a if case.sensor == "A" else flight_b, tmp_path, capsys)
    assert code == 2, err
    assert "Traceback" not in err
    for words in case.expect:
        assert words in err, (words, err)
    assert not (tmp_path / "run").exists()


def test_print_table(flight_a, flight_b, tmp_path, capsys):
    """docs/bad_input.md's rows from the test's own runs (``-s`` shows them)."""
    lines = []
    for case in CASES:
        code, err = run_case(case, flight_a if case.sensor == "A" else flight_b, tmp_path,
                             capsys)
        message = " ".join(err.strip().splitlines()[-1:]).replace(str(tmp_path) + "/", "")
        lines.append(f"| {case.row} | {case.before} | exit {code}: {message} |")
    lines.insert(next(i for i, c in enumerate(CASES) if "boeing747" in c.row) + 1,
                 '| sidecar `"vehicle": "boeing747"` with mass_guess and inertia_guess | '
                 'accepted without a word | read with a note (printed and in report.json): '
                 f'{unknown_vehicle_note(flight_b, tmp_path)} |')
    with capsys.disabled():
        print("\n" + "\n".join(lines))
    assert len(lines) == len(CASES) + 1


def unknown_vehicle_note(log: pinquad.FlightLog, tmp: Path) -> str:
    side = {**base_sidecar(log), "vehicle": "boeing747"}
    back = read_log(write_table(tmp / "boeing.csv", base_columns(log), side))
    assert sanity.findings(back) == ()
    (note,) = back.meta.notes
    return note


def test_an_unknown_vehicle_with_both_guesses_is_read_with_a_note(flight_b, tmp_path):
    note = unknown_vehicle_note(flight_b, tmp_path)
    assert "'boeing747' is not one pinquad knows" in note and "sidecar's guesses" in note


def test_the_undamaged_short_log_passes_every_check(flight_a, flight_b, tmp_path):
    for name, log in (("a", flight_a), ("b", flight_b)):
        path = write_table(tmp_path / f"{name}.csv", base_columns(log), base_sidecar(log))
        back = read_log(path)
        assert sanity.findings(back) == ()
        ev = sanity.evidence(back)
        assert ev.implied_mass == pytest.approx(0.18, rel=0.05)


def test_a_csv_with_a_byte_order_mark_is_read(flight_b, tmp_path):
    cols = base_columns(flight_b)
    path = write_table(tmp_path / "bom.csv", cols, base_sidecar(flight_b), bom=True)
    back = read_log(path)
    np.testing.assert_allclose(back.t, cols["t"])
    assert sanity.findings(back) == ()


def test_no_check_fires_on_the_shipped_real_logs():
    """Every micro-SD log in ../shared/data/crazyflie (rotor speeds: no thrust checks);
    fails, not skips, when the data is missing."""
    paths = sorted(p for d in ("imrc_brushed", "imrc_brushless") for p in (REAL / d).iterdir()
                   if p.suffix != ".txt")
    assert len(paths) == 24, f"expected the 24 shipped logs in {REAL}"
    for path in paths:
        log = read_log(path)
        assert sanity.findings(log) == (), path.name
        ev = sanity.evidence(log)
        # the checks ran (decided), they were not skipped for want of motion
        assert ev.gyro_ratio == pytest.approx(1.0, abs=0.1), path.name
        assert ev.position_velocity_ratio == pytest.approx(1.0, abs=0.2), path.name
        assert ev.specific_force == pytest.approx(9.81, rel=0.05), path.name


@pytest.mark.parametrize("sensor", ["A", "B", "C"])
def test_no_check_fires_on_the_papers_simulated_flights(sensor):
    """The paper's 37 s scenario, one seeded flight per sensor set (the Monte Carlo's
    first cycle's seed)."""
    log = pinquad.simulate(sensor=sensor, seed=0)
    assert sanity.findings(log) == ()
    ev = sanity.evidence(log)
    assert ev.gyro_ratio == pytest.approx(1.0, abs=0.3)
    assert ev.implied_mass == pytest.approx(0.18, rel=0.05)


def test_em_that_did_not_move_is_not_converged():
    inertia = np.diag([1e-4, 2e-4, 1e-4])
    assert "iteration 0" in unmoved_note(0.001, inertia, 0.001, inertia, 0)
    assert "no information" in unmoved_note(0.001, inertia, 0.001, inertia, 7)
    assert "non-finite" in unmoved_note(0.001, inertia, math.inf, inertia, 7)
    assert unmoved_note(0.001, inertia, 0.18, inertia * 2, 7) is None


# ------------------------------------------------------------------------- --out rows

def read_only_directory(tmp_path: Path) -> Path:
    """A directory this process cannot write in: a chmod 500 one, or /sys (mounted
    read-only in containers) when running as root, whom modes do not stop."""
    if os.geteuid() == 0:
        return Path("/sys")
    locked = tmp_path / "ro"
    locked.mkdir()
    locked.chmod(0o500)
    return locked


def test_out_under_a_read_only_directory_or_naming_a_file_exits_2(flight_b, tmp_path, capsys):
    path = write_table(tmp_path / "f.csv", base_columns(flight_b), base_sidecar(flight_b))
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    for out, words in ((read_only_directory(tmp_path) / "run", "ermission denied"),
                       (a_file, "is a file")):
        code = offline_cli.main(["--log", str(path), "--out", str(out), "--no-discover"])
        out_err = capsys.readouterr()
        assert code == 2 and words in out_err.err, out_err.err
        # found before any work: nothing was identified
        assert "log type" not in out_err.out
    assert not Path("/sys/.run.lock").exists()


def test_a_second_run_to_the_same_out_is_refused_before_any_work(flight_b, tmp_path, capsys):
    path = write_table(tmp_path / "f.csv", base_columns(flight_b), base_sidecar(flight_b))
    first = RunWriter(tmp_path / "run")  # a run in progress holds the directory
    code = offline_cli.main(["--log", str(path), "--out", str(tmp_path / "run"),
                             "--no-discover"])
    out_err = capsys.readouterr()
    assert code == 2 and "in use by another run" in out_err.err
    assert "log type" not in out_err.out
    with first:
        first.path("report.json").write_text("{}")
        final = first.publish()
    assert (final / "report.json").exists() and final == tmp_path / "run"
    assert not first.lock.exists()
    with pytest.raises(OutputError, match="not empty"):
        RunWriter(tmp_path / "run")


def test_a_dead_runs_lock_is_taken_over(tmp_path):
    (tmp_path / ".run.lock").write_text("999999999 0")
    with RunWriter(tmp_path / "run") as writer:
        writer.path("a.txt").write_text("a")
        assert writer.publish() == tmp_path / "run"


def test_online_replay_with_a_list_sidecar_exits_2(flight_b, tmp_path, capsys):
    path = write_table(tmp_path / "f.csv", base_columns(flight_b), [1, 2, 3])
    code = online_cli.main(["--log", str(path)])
    err = capsys.readouterr().err
    assert code == 2 and "JSON list" in err and "f.csv.json" in err


@pytest.mark.parametrize("command, out_is_dir", [
    ("flight", True), ("response", True), ("discovery", False), ("realdiscovery", False),
    ("bench", True)])
def test_every_command_checks_out_before_any_work(command, out_is_dir, tmp_path, capsys):
    """A directory where a file is written, or a file where a directory is, exits 2 at
    once (the benchmark used to fail after its 13-minute run)."""
    module = importlib.import_module(f"pinquad.cli.{command}")
    out = tmp_path
    if not out_is_dir:
        out = tmp_path / "file.txt"
        out.write_text("x")
    assert module.main(["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and ("is a directory" in err or "is a file" in err), err


SIGTERM_SCRIPT = """
import sys, time
from pinquad.io.runs import RunWriter
with RunWriter(sys.argv[1]) as writer:
    writer.path("report.json").write_text("{}")
    print("staged", flush=True)
    time.sleep(60)
"""


def test_sigterm_while_writing_removes_the_staging_directory(tmp_path):
    target = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-c", SIGTERM_SCRIPT, str(target)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(REPO)}, cwd=REPO)
    assert proc.stdout.readline().strip() == "staged"
    assert any(p.name.startswith(".run.") for p in tmp_path.iterdir())
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=30)
    assert proc.returncode != 0
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("host", ["8.8.8.8", "no-such-host.invalid"])
def test_viewer_exits_2_when_it_cannot_bind(host, tmp_path, capsys):
    assert viz_main([str(tmp_path), "--host", host]) == 2
    assert f"--host {host}" in capsys.readouterr().err
