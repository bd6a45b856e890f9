"""pinquad.report's tables on hand-built inputs (every printed number worked by hand or
taken from a printed chi-square table), and ``python -m pinquad.realdata``'s table path
on one shared log (missing data is a failure, not a skip)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from pinquad.cli import realdata as realdata_cli
from pinquad.experiments.batch import NAN3, BatchRow
from pinquad.experiments.flight import FlightStats
from pinquad.realdata.dataset import SCALE_MASS
from pinquad.report.batch import batch_counts, batch_json, batch_table
from pinquad.report.flight import flight_tables
from pinquad.report.realdiscovery import realdiscovery_markdown

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "crazyflie"


def _rows() -> list[BatchRow]:
    trusted = BatchRow(
        name="jana00", path="logs/jana00", status="trusted", mass=0.0347, mass_se=0.0005,
        inertia_diag=(16.6e-6, 16.7e-6, 29.3e-6), inertia_se=(0.3e-6, 0.25e-6, math.nan),
        overall="trusted", verdicts={"mass": "trusted", "I_xx": "trusted", "I_yy": "trusted",
                                     "I_zz": "not identifiable"},
        effects=("drag",), seconds=12.4, error="")
    failed = BatchRow(
        name="broken", path="logs/broken.csv", status="failed", mass=math.nan,
        mass_se=math.nan, inertia_diag=NAN3, inertia_se=NAN3, overall="", verdicts={},
        effects=(), seconds=0.6, error="broken.csv: row 3 | column t\nnot increasing")
    return [trusted, failed]


def test_batch_table_counts_and_json_worked_by_hand():
    rows = _rows()
    lines = batch_table(rows).splitlines()
    assert len(lines) == 4 and lines[0].startswith("| log | status | mass [g] |")
    # 0.0347 kg +- 0.0005 kg in g to 3 places; inertia in 1e-6 kg m^2 to 2 places; an
    # entry without a standard error is printed bare; verdicts shortened in m, Ixx, Iyy,
    # Izz order
    assert lines[2] == ("| jana00 | trusted | 34.700 +- 0.500 | 16.60 +- 0.30 | "
                        "16.70 +- 0.25 | 29.30 | ok, ok, ok, n/i | drag | 12 |  |")
    # a failed log: no numbers, its error on one line with no column separator in it
    assert lines[3] == ("| broken | failed | - | - | - | - | - | - | 1 | "
                        "broken.csv: row 3 / column t not increasing |")
    assert batch_counts(rows) == "2 logs: 1 trusted, 0 not trusted, 1 failed"
    doc = batch_json(rows, ["--log", "a", "b"], 4, 13.0)
    assert (doc["schema"], doc["argv"], doc["exit_code"], doc["seconds"]) == (
        "pinquad.batch/1", ["--log", "a", "b"], 4, 13.0)
    good, bad = doc["logs"]
    assert good["report"] == "logs/jana00/report.json" and bad["report"] is None
    assert good["mass"] == 0.0347 and good["inertia_se"] == [0.3e-6, 0.25e-6, None]
    # JSON has no NaN: the failed log's numbers are null
    assert bad["mass"] is None and bad["inertia_diag"] == [None, None, None]
    assert bad["error"] == "broken.csv: row 3 | column t\nnot increasing"


def _stats(vehicle, tuning, miss, pos_err, euler_err, nees, crashed=False) -> FlightStats:
    return FlightStats(vehicle, 0, tuning, np.asarray(miss, float), crashed, True,
                       np.asarray(pos_err, float), np.asarray(euler_err, float), nees,
                       len(pos_err))


def test_flight_tables_worked_by_hand():
    runs = [
        _stats("paper", "tuned", [0.05, 0.08], [0.01, 0.03], [0.001, 0.003], 10.0),
        _stats("paper", "tuned", [0.12, 0.02], [0.02, 0.02], [0.002, 0.002], 30.0,
               crashed=True),
        _stats("paper", "paper", [0.04, 0.04], [0.05, 0.05], [0.01, 0.01], 12.0),
        _stats("crazyflie21", "tuned", [0.01, 0.03], [0.0, 0.0], [0.0, 0.0], 12.0),
    ]
    text, figures = flight_tables(runs, range(3, 5))
    assert text.startswith("seeds 3..4,")
    # paper, tuned: worst 0.12 m, mean (0.05 + 0.08 + 0.12 + 0.02) / 4 = 0.0675 m, one of
    # the two runs all within 0.1 m, one crash
    assert "| paper | 2 | 0.1200 | 0.0675 | 1/2 | 1 | 2/2 |" in text
    assert "| crazyflie21 | 1 | 0.0300 | 0.0200 | 1/1 | 0 | 1/1 |" in text
    assert figures["waypoints"]["paper"] == {"worst_m": 0.12, "mean_m": pytest.approx(0.0675),
                                             "all_within_0.1": 1, "runs": 2, "crashes": 1}
    # Table I, tuned column: position errors 0.01, 0.03, 0.02, 0.02: mean 0.02, std
    # (population) sqrt(2 * 0.01^2 / 4) = 0.00707, max 0.03; the paper's column is its
    # published 0.0102 / 0.0077 / 0.0524
    assert "| Mean position error [m] | 0.0102 | 0.02 | 0.05 |" in text
    assert "| Std of position error [m] | 0.0077 | 0.00707 | 0 |" in text
    assert "| Max position error [m] | 0.0524 | 0.03 | 0.05 |" in text
    # NEES, tuned: runs of 2 steps with 10 and 30, pooled (2 * 10 + 2 * 30) / 4 = 20. The
    # 95 % band of one 2-step run is chi-square(24)'s 2.5 % and 97.5 % points (12.401,
    # 39.364 in the printed tables) over 2; of the pooled 4 steps chi-square(48)'s
    # (30.755, 69.023) over 4. Only the run with 10 is inside its band.
    assert "| tuned | 20.000 | [7.689, 17.256] | 10.00 / 30.00 | [6.20, 19.68] | 1/2 |" in text
    assert figures["ekf"]["tuned"]["runs_inside"] == 1
    assert figures["ekf"]["tuned"]["nees_mean"] == pytest.approx(20.0, rel=1e-12)
    assert figures["ekf"]["paper"]["pos_mean"] == pytest.approx(0.05, rel=1e-12)


def _split() -> dict:
    """One split as ``run_split`` writes it: forces [N] chosen so that every printed
    figure is a round number."""
    rms = {"force_x": 0.010, "force_y": 0.008, "force_z": 0.020}
    after = {"force_x": 0.0075, "force_y": 0.006, "force_z": 0.021}
    return {"drag": {
        "train": ["jana00", "jana02"], "flights": {"jana00": [0.31, 1.04], "jana02": [0.29, 1.5],
                                                   "jana10": [0.45, 0.8]},
        "named_by_flight": {"jana00": ["drag"], "jana02": []},
        "pooled_effects": ["drag"], "coefficients": {"drag": [0.0125, 0.011, 0.0]},
        "stderr_leave_one_flight_out": {"drag": [0.001, 0.002, 0.0]},
        "test_rms": {"jana10": {"before": rms, "after": after}},
        "target": {"effect": "drag", "coefficients": [0.012, 0.01, 0.0],
                   "test_rms": {"jana10": {"before": rms, "after": after}}},
    }}


def test_realdiscovery_markdown_worked_by_hand():
    text = realdiscovery_markdown(_split())
    row = next(line for line in text.splitlines() if line.startswith("| drag |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[:4] == ["drag", "jana00 (0.31 m, 1.0 m/s), jana02 (0.29 m, 1.5 m/s)",
                         "jana00: drag; jana02: -",
                         "drag: D_x 0.0125 ± 0.001, D_y 0.011 ± 0.002, D_z 0 ± 0"]
    # mN, and the change: 7.5 / 10 - 1 = -25 %, 6 / 8 - 1 = -25 %, 21 / 20 - 1 = +5 %
    assert cells[4:] == ["jana10 (0.45 m, 0.8 m/s)", "10.00 -> 7.50 (-25 %)",
                         "8.00 -> 6.00 (-25 %)", "20.00 -> 21.00 (+5 %)"]
    assert ("- drag: drag alone (D_x 0.012, D_y 0.01, D_z 0) on jana10: force_x 10.00 -> "
            "7.50 mN (-25 %), force_y 8.00 -> 6.00 mN (-25 %), force_z 20.00 -> 21.00 mN "
            "(+5 %)") in text


def test_realdata_command_prints_the_table_for_one_log(capsys):
    """``python -m pinquad.realdata --only jana00`` (rotor inertia none, no discovery, no
    information: the table path without its slow options): one row whose mass is within
    the 1.5 % the README states for the clean logs, its relative error printed beside it
    as (mass / 34.7 g - 1), and the closing count line."""
    assert (DATA / "imrc_brushed" / "jana00").is_file(), (
        f"the Crazyflie data are missing: expected {DATA / 'imrc_brushed' / 'jana00'}")
    code = realdata_cli.main(["--data", str(DATA), "--only", "jana00", "--rotor-inertia",
                              "none", "--no-discover", "--no-information", "--jobs", "1"])
    assert code == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| jana00 |")]
    assert len(rows) == 1, out
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    mass_g = float(cells[3].split()[0])
    rel = float(re.fullmatch(r"([+-]\d+\.\d+) %( \(!\))?", cells[4]).group(1))
    assert abs(mass_g / (1e3 * SCALE_MASS) - 1.0) < 0.015, cells[3]
    assert rel == pytest.approx(100 * (mass_g / (1e3 * SCALE_MASS) - 1.0), abs=0.02)
    assert cells[-1] == "not run"  # --no-discover: the effects column says so
    assert re.search(r"^1 logs in \d+ s", out, re.MULTILINE), out
    assert realdata_cli.main(["--data", str(DATA), "--only", "jana99"]) == 2
