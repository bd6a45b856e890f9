"""The `--log` user path: a simulated flight written to CSV and identified by the command
line gives the same estimates as identifying the in-memory log, and the run directory is
complete."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import offline_on_csv

from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_VEHICLE
from pinquad.identification.identify import identify
from pinquad.identification.search_range import search_range
from pinquad.io.read import read_log
from pinquad.models.sources import observations
from pinquad.pipeline.identify import RECORDED_PER_PARAMETER
from pinquad.sim.simulator import SimConfig, flight_log, simulate


@pytest.fixture(scope="module")
def flight_b():
    flight = simulate(SimConfig(sensor="B"), np.random.default_rng(20261122))
    return flight_log(flight)


def test_csv_log_through_the_command_line_equals_in_memory_identification(flight_b, tmp_path):
    out = tmp_path / "run"
    proc = offline_on_csv(flight_b, tmp_path / "flight.csv", out, "--sensor", "B",
                          "--mstep", "regressor", "--no-information", "--no-discover")
    # --no-information: numbers without standard errors are "not judged", never trusted
    assert proc.returncode == 3, proc.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    assert report["estimates"]["verdict"]["overall"] == "not judged"
    assert report["source"]["sensor"] == "B" and report["source"]["mstep"] == "regressor"

    # The CSV holds repr() floats, but the attitude goes through its quaternion columns
    # (DESIGN.md 4.2) and comes back within the last bit (4e-17 rad), which the
    # per-parameter over-relaxation's sign tests can carry to 2e-7 of I_zz: the
    # in-memory identification is of the log as read back, so the same observations
    # go in bit for bit.
    back = read_log(tmp_path / "flight.csv")
    ident, _ = identify(observations(back, "B"), PAPER_INITIAL_MASS,
                        np.asarray(PAPER_INITIAL_INERTIA), PAPER_VEHICLE.gravity, "rts",
                        "regressor", 100, information=False,
                        per_parameter=RECORDED_PER_PARAMETER, bounds=search_range(back))
    assert report["estimates"]["mass"] == pytest.approx(ident.mass, rel=1e-9)
    inertia = np.asarray(report["estimates"]["inertia"])
    assert inertia.shape == (3, 3)  # DESIGN.md 4.3: a 3x3 matrix
    np.testing.assert_allclose(inertia, ident.inertia, rtol=1e-9, atol=1e-15)
    # ... and the answer is the vehicle's (clean-data accuracy of sensor B).
    assert report["estimates"]["mass"] == pytest.approx(PAPER_VEHICLE.mass, rel=2e-3)
    np.testing.assert_allclose(np.diag(inertia), np.diag(PAPER_VEHICLE.inertia), rtol=0.08)
    assert (out / "report.md").exists()
