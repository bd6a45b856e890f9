"""Batch identification (issue 23 part 2): ``python -m pinquad.offline --log A B C`` runs
each log through the single --log pipeline into one batch directory with a per-log
table; a broken file is its row's error and does not stop the others; exit codes."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, row_from_written_report, write_with_paper_guess

from pinquad.cli.batch import expand_logs, is_batch
from pinquad.cli.offline import main as offline_main
from pinquad.experiments.batch import (
    ALL_TRUSTED,
    SOME_FAILED,
    SOME_UNTRUSTED,
    BatchRow,
    batch_exit_code,
    compare_flights,
    failed_row,
    flight_group,
    unique_names,
)
from pinquad.pipeline import PipelineOptions
from pinquad.pipeline.identify import LogOptions
from pinquad.report.batch import batch_json, batch_table
from pinquad.results.batch import identify_many
from pinquad.sim.simulator import SimConfig, flight_log, simulate

# a cheap run: the point is the batch's mechanics and that each log goes through the
# single --log pipeline unchanged, not the accuracy of a short EM (tests/test_offline_log.py)
FAST = ["--sensor", "B", "--mstep", "regressor", "--no-information", "--no-discover",
        "--jobs", "1", "--max-iterations", "8"]


@pytest.fixture(scope="module")
def good_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 10 s simulated sensor-B flight as CSV with the paper's initial guess."""
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(23))).slice(0, 1000)
    return write_with_paper_guess(log, tmp_path_factory.mktemp("logs") / "flight.csv")


def test_batch_rows_equal_single_runs_and_a_broken_file_does_not_stop_it(
        good_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    broken = tmp_path / "broken.csv"
    broken.write_text("t,pos_x\n0.0,1.0\n0.0,2.0\n")  # no actuation, t not increasing
    single = tmp_path / "single"
    single_code = offline_main(["--log", str(good_csv), *FAST, "--out", str(single)])
    assert single_code in (0, 3)
    assert (single / "report.json").is_file() and not (single / "table.md").exists()

    out = tmp_path / "batch"
    code = offline_main(["--log", str(good_csv), str(broken), *FAST, "--out", str(out)])
    assert code == SOME_FAILED
    table = (out / "table.md").read_text()
    batch = json.loads((out / "batch.json").read_text())
    rows = {r["name"]: r for r in batch["logs"]}
    assert list(rows) == ["flight.csv", "broken.csv"] and batch["exit_code"] == SOME_FAILED
    assert rows["broken.csv"]["status"] == "failed"
    assert str(broken) in rows["broken.csv"]["error"] and rows["broken.csv"]["mass"] is None
    assert rows["broken.csv"]["error"].replace("|", "/") in table
    assert (out / "logs" / "broken.csv.txt").read_text().splitlines()[-1].startswith("error: ")
    # the good log went through exactly the single --log pipeline
    alone = json.loads((single / "report.json").read_text())["estimates"]
    in_batch = json.loads((out / "logs" / "flight.csv" / "report.json").read_text())["estimates"]
    assert in_batch["mass"] == alone["mass"] and in_batch["inertia"] == alone["inertia"]
    assert rows["flight.csv"]["mass"] == alone["mass"]
    assert rows["flight.csv"]["status"] == ("trusted" if single_code == 0 else "not trusted")
    assert f"{alone['mass'] * 1e3:.3f}" in table
    assert "1 failed" in capsys.readouterr().out


def test_rows_of_measured_flights_hold_what_their_reports_say(tmp_path: Path):
    """A row is built from its log's Result, not read back from the report.json the run
    wrote, and holds the same: on a repaired IMRC flight (its statistical errors, motor 1
    rebuilt from PWM, hence a group of its own) and a Neural-Swarm flight that names no
    vehicle (compared with no other), three EM iterations each."""
    logs = [DATA / "crazyflie" / "imrc_brushed" / "jana20",
            DATA / "neural_swarm" / "flights" / "takeoff_s_cf50_00"]
    options = PipelineOptions(LogOptions(msteps=("regressor",), max_iterations=3),
                              discover=False)
    batch = identify_many(logs, None, options, tmp_path)
    assert [r.status for r in batch.rows] == ["not trusted", "not trusted"], batch.summary()
    measured, unnamed = batch.rows
    assert measured.group == "crazyflie21, motor(s) M1 rebuilt from PWM"
    assert np.all(np.isfinite(measured.stat_se)) and np.all(np.isnan(unnamed.stat_se))
    assert unnamed.group == "takeoff_s_cf50_00 (no vehicle named)"
    for row, result in zip(batch.rows, batch.results, strict=True):
        written = row_from_written_report(
            row.name, row.path, json.loads((tmp_path / row.name / "report.json").read_text()),
            row.seconds)
        assert json.dumps(asdict(row)) == json.dumps(asdict(written))
        assert row.mass == result.mass and row.overall == result.verdict.overall


def test_a_pattern_that_matches_nothing_is_bad_input(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]):
    out = tmp_path / "batch"
    assert offline_main(["--log", str(tmp_path / "*.csv"), "--out", str(out)]) == 2
    assert "matches no file" in capsys.readouterr().err and not out.exists()


def test_which_arguments_make_a_batch(tmp_path: Path):
    for name in ("b.csv", "a.csv", "c.parquet"):
        (tmp_path / name).write_text("")
    assert not is_batch([tmp_path / "a.csv"])
    assert is_batch([tmp_path / "a.csv", tmp_path / "b.csv"])
    assert is_batch([tmp_path / "*.csv"])
    assert expand_logs([tmp_path / "*.csv", tmp_path / "a.csv", tmp_path / "x.csv"]) == \
        [tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "x.csv"]
    assert unique_names(["d1/jana00", "d2/jana00", "jana01"]) == ["jana00", "jana00-2", "jana01"]


PARAMETER_NAMES = ("mass", "I_xx", "I_yy", "I_zz")


def _row(name: str, overall: str = "trusted", params=(0.03, 1e-5, 1e-5, 2e-5),
         total=(1e-4, 1e-7, 1e-7, 1e-7), stat=(np.nan,) * 4, vehicle: str = "crazyflie21",
         named: bool = True, rebuilt: tuple[int, ...] = ()) -> BatchRow:
    """The row of an identified log, as ``row_from_result`` builds it: every parameter
    judged ``overall``."""
    return BatchRow(
        name=name, path=name, status="trusted" if overall == "trusted" else "not trusted",
        mass=float(params[0]), mass_se=float(total[0]),
        inertia_diag=tuple(float(v) for v in params[1:]),
        inertia_se=tuple(float(v) for v in total[1:]), overall=overall,
        verdicts=dict.fromkeys(PARAMETER_NAMES, overall), effects=(), seconds=1.0, error="",
        vehicle=vehicle, group=flight_group(name, vehicle, named, rebuilt),
        stat_se=tuple(float(v) for v in stat))


def test_batch_exit_code_orders_failed_over_untrusted():
    ok = _row("a")
    weak = _row("b", overall="not identifiable")
    bad = failed_row("c", "c", "c: no such file", 0.0)
    assert (ok.status, weak.status) == ("trusted", "not trusted")
    assert batch_exit_code([ok]) == ALL_TRUSTED
    assert batch_exit_code([ok, weak]) == SOME_UNTRUSTED
    assert batch_exit_code([ok, weak, bad]) == SOME_FAILED


def test_the_flights_compared_are_one_named_vehicle_with_the_same_rebuilt_motors():
    assert flight_group("a", "crazyflie21", True, ()) == "crazyflie21"
    assert flight_group("a", "crazyflie21", True, (0, 2)) == \
        "crazyflie21, motor(s) M1, M3 rebuilt from PWM"
    assert flight_group("a", "crazyflie21", False, ()) == "a (no vehicle named)"


def _measured_row(name: str, izz: float, izz_stat: float, vehicle: str = "crazyflie21",
                  rebuilt: tuple[int, ...] = (), named: bool = True) -> BatchRow:
    """The row of a measured Crazyflie flight: every parameter trusted, mass and
    roll/pitch alike on every flight, I_zz ``izz`` +- ``izz_stat`` (statistical) inside a
    total with kf's 4.8 % and the yaw ratio's 8.3 %."""
    params = np.array([0.0347, 16.6e-6, 16.7e-6, izz])
    stat = np.array([5e-5, 0.5e-6, 0.5e-6, izz_stat])
    total = np.hypot(stat, params * np.array([0.048, 0.048, 0.048, np.hypot(0.048, 0.083)]))
    return _row(name, "trusted", params, total, stat, vehicle, named, rebuilt)


def test_batch_compares_the_flights_of_one_vehicle():
    """Four flights of one Crazyflie whose I_zz (26.9, 15.8, 13.2, 17.7 e-6, each +-0.6-2.0
    statistical) scatter 6x beyond their errors: the batch scales the errors, lowers
    the two whose scaled error covers too much of the range to not identifiable (the
    batch's exit code with them), leaves mass and roll/pitch (which agree) as they were,
    and does not mix in a flight with a rebuilt motor or one that failed."""
    values = {"a": (26.9e-6, 0.8e-6), "b": (15.8e-6, 2.0e-6), "c": (13.2e-6, 1.3e-6),
              "d": (17.7e-6, 0.6e-6)}
    rows = [_measured_row(n, *v) for n, v in values.items()]
    rows.append(_measured_row("e", 40e-6, 0.5e-6, rebuilt=(0,)))
    rows.append(failed_row("f", "f", "f: no such file", 0.0))
    assert batch_exit_code(rows) == SOME_FAILED
    assert all(r.status == "trusted" for r in rows[:5])
    judged, scatters = compare_flights(rows)
    izz = [s for s in scatters if s.parameter == "I_zz"]
    assert len(izz) == 1 and izz[0].logs == ("a", "b", "c", "d")
    assert izz[0].scale == pytest.approx(6.34, abs=0.02)
    by = {r.name: r for r in judged}
    assert {n: by[n].verdicts["I_zz"] for n in "abcd"} == {
        "a": "trusted", "b": "not identifiable", "c": "not identifiable", "d": "trusted"}
    assert [by[n].status for n in "abcd"] == ["trusted", "not trusted", "not trusted", "trusted"]
    assert by["a"].inertia_se[2] == pytest.approx(
        np.sqrt(rows[0].inertia_se[2] ** 2 + (izz[0].scale ** 2 - 1.0) * (0.8e-6) ** 2))
    for n in "abcd":
        assert by[n].mass_se == rows["abcd".index(n)].mass_se
        assert by[n].scatter_scale[0] == 1.0 and by[n].scatter_scale[3] > 6.0
    assert by["e"] == rows[4] and by["f"] == rows[5]
    text = batch_table(judged, scatters)
    assert "[x6.3]" in text and "I_zz, crazyflie21 (a 26.9" in text
    data = batch_json(judged, ["--log"], 4, 1.0, scatters)
    assert [d["parameter"] for d in data["between_flights"]] == ["mass", "I_xx", "I_yy", "I_zz"]
    # on their own (no scatter to compare with) the flights keep their verdicts
    alone, none = compare_flights(rows[:1])
    assert alone == rows[:1] and none == []
    # logs that name no vehicle are not taken for one vehicle
    unnamed = [_measured_row(n, *v, named=False) for n, v in values.items()]
    same, nothing = compare_flights(unnamed)
    assert same == unnamed and nothing == []
