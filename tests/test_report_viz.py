"""pinquad.report.offline on hand-built cycles (numbers worked by hand) and viz.run's
reading of a hand-written run directory."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from pinquad.io.runs import REPORT_SCHEMA
from pinquad.report.offline import offline_tables, summarize
from viz.run import RunError, load_run

TRUTH_I = np.diag([2.0e-4, 3.0e-4, 4.0e-4])


def _cycle(i: int, mass: float, ixx: float):
    run = SimpleNamespace(mstep="regressor", mass=mass,
                          inertia=np.diag([ixx, 3.0e-4, 4.0e-4]), info_truth=None)
    return SimpleNamespace(sensor="B", cycle=i, truth_mass=1.0, truth_inertia=TRUTH_I,
                           runs=(run,))


def test_summarize_and_tables_on_two_cycles_worked_by_hand():
    summary = summarize([_cycle(0, 1.02, 2.2e-4), _cycle(1, 0.98, 2.4e-4)])
    st = summary[("B", "regressor")]
    # mass 1.02, 0.98 vs 1: bias 0, std (ddof 1) = sqrt(2 * 0.02^2) = 0.028284...
    assert st["mass"].bias == pytest.approx(0.0, abs=1e-12)
    assert st["mass"].std == pytest.approx(0.02 * 2 ** 0.5, rel=1e-12)
    assert st["mass"].max_rel_err == pytest.approx(0.02, rel=1e-9)
    # Ixx 2.2e-4, 2.4e-4 vs 2e-4: bias 0.3e-4 (+15 %), std 0.1414e-4 (7.071 %), max 20 %.
    assert st["Ixx"].bias == pytest.approx(0.3e-4, rel=1e-9)
    assert st["Ixx"].std == pytest.approx(0.1e-4 * 2 ** 0.5, rel=1e-9)
    assert (st["Ixx"].low, st["Ixx"].high) == (pytest.approx(2.2e-4), pytest.approx(2.4e-4))
    text = offline_tables(summary)
    assert "| B | regressor | mass | 2.000 % | +0.000 % | 2.828 % |" in text
    assert "| B | regressor | Ixx | 20.000 % | +15.000 % | 7.071 % |" in text
    assert "(0.98000, 1.02000)" in text


def _write_report(run_dir, report) -> None:
    run_dir.mkdir()
    (run_dir / "report.json").write_text(json.dumps(report))


def test_load_run_holds_the_report_numbers(tmp_path):
    entry = {"sensor": "B", "mstep": "paper", "seed": 7, "cycle": 2,
             "estimates": {"mass": 0.5, "inertia": np.diag([1e-3, 2e-3, 3e-3]).tolist()},
             "truth": {"mass": 0.55, "inertia": [1.1e-3, 2.1e-3, 3.1e-3]},
             "history": {"mass": [0.001, 0.3, 0.5], "inertia_diag": [[1, 2, 3]] * 3}}
    _write_report(tmp_path / "run", {"schema": REPORT_SCHEMA, "source": {"kind": "offline"},
                                     "cycles": [entry], "scenario": {
                                         "start": [0, 0, 0], "waypoints": [[1, 2, 3]]}})
    run = load_run(tmp_path / "run")
    assert run.kind == "offline" and run.sensors == ("B",)
    rec = run.cycles[0]
    assert (rec.sensor, rec.mstep, rec.seed, rec.cycle) == ("B", "paper", 7, 2)
    assert rec.est_mass == 0.5 and rec.true_mass == 0.55
    np.testing.assert_array_equal(rec.est_inertia_diag, [1e-3, 2e-3, 3e-3])
    np.testing.assert_array_equal(rec.true_inertia_diag, [1.1e-3, 2.1e-3, 3.1e-3])
    np.testing.assert_array_equal(rec.mass, [0.001, 0.3, 0.5])
    np.testing.assert_array_equal(rec.x, [0, 1, 2])
    np.testing.assert_array_equal(run.waypoints, [[1, 2, 3]])


@pytest.mark.parametrize("text, why", [("{not json", "not valid JSON"),
                                       ('{"schema": "other/1"}', "schema is 'other/1'"),
                                       ("[1, 2]", "JSON object")])
def test_broken_report_names_the_file(tmp_path, text, why):
    (tmp_path / "report.json").write_text(text)
    with pytest.raises(RunError) as exc:
        load_run(tmp_path)
    assert str(tmp_path / "report.json") in str(exc.value) and why in str(exc.value)
    (tmp_path / "empty").mkdir()
    with pytest.raises(RunError, match="no report.json"):
        load_run(tmp_path / "empty")
