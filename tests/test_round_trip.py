"""One flight, one answer: a measured micro-SD flight, pinquad's own export of it
(``logs/flight.parquet``, whose sidecar says its thrust and torques were computed from
the rotor speeds) and a CSV copy of that export, as a spreadsheet or pyarrow writes it
(quoted names), are identified from the same rotor speeds to the same estimates."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinquad.io.logs import write_log
from pinquad.io.read import read_log
from pinquad.pipeline.identify import LogOptions, identify_log

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed"
OPTIONS = LogOptions(msteps=("regressor",), information=False, max_iterations=30)
"""30 EM iterations: the paths must take the same steps, converged or not (full runs:
``scripts/round_trip.py``)."""
SAME = 1e-4
"""Relative agreement of the micro-SD reading and its export: the export stores the
grid's times relative to the first row and its values in float64, so the E-step sees the
same numbers up to rounding; EM then amplifies rounding by at most ~1e-6 on these logs."""


def _values(result) -> np.ndarray:
    run = result.runs[0]
    return np.r_[run.mass, np.diag(run.inertia)]


def _log(name: str):
    path = DATA / name
    assert path.is_file(), f"the Crazyflie data are missing: expected {path}"
    return read_log(path)


@pytest.mark.parametrize("name", ["jana00", "jana05"])
def test_micro_sd_export_and_csv_copy_give_one_answer(name, tmp_path):
    first = identify_log(_log(name), OPTIONS)
    export = write_log(first.log, tmp_path / "flight.parquet")
    back = read_log(export)
    # the export reads back as written: the same rows, rotor speeds and poses
    assert back.meta.wrench_from_rpm and back.thrust is None
    np.testing.assert_array_equal(back.rpm, first.log.rpm)
    np.testing.assert_allclose(back.position, first.log.position, rtol=0, atol=0)
    np.testing.assert_allclose(back.t, first.log.t - first.log.t[0], rtol=0, atol=1e-12)
    again = identify_log(back, OPTIONS)
    # a CSV copy with quoted column names, its sidecar beside it
    csv = tmp_path / "copy.csv"
    pa_csv.write_csv(pq.read_table(export), csv)
    (tmp_path / "copy.csv.json").write_text((tmp_path / "flight.parquet.json").read_text())
    copy = identify_log(read_log(csv), OPTIONS)
    assert again.kind == copy.kind == "measured-table"
    np.testing.assert_allclose(_values(copy), _values(again), rtol=1e-9)
    # against the micro-SD reading: every estimate, the yaw inertia included (its rotor
    # acceleration comes from the bins' mean speeds on either path)
    np.testing.assert_allclose(_values(again), _values(first), rtol=SAME)


@settings(max_examples=3, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(["jana01", "jana02", "jana03", "jana10", "jana20", "jana24"]),
       start=st.floats(0.15, 0.6))
def test_any_stretch_of_a_real_flight_reads_back_to_its_estimates(name, start, tmp_path):
    """A 15 s stretch of a shared IMRC flight, cut anywhere in its middle: the micro-SD
    reading and the export of what the E-step saw give the same mass and inertia (EM
    stopped after 8 iterations: the two paths must take the same steps, converged or not)."""
    log = _log(name)
    first_row = int(np.searchsorted(log.t, log.t[0] + start * (log.t[-1] - log.t[0])))
    last_row = int(np.searchsorted(log.t, log.t[first_row] + 15.0))
    stretch = log.slice(first_row, last_row)
    first = identify_log(stretch, replace(OPTIONS, max_iterations=8))
    again = identify_log(read_log(write_log(first.log, tmp_path / f"{name}.parquet")),
                         replace(OPTIONS, max_iterations=8))
    np.testing.assert_allclose(_values(again), _values(first), rtol=SAME)


def test_a_simulated_log_is_not_read_from_rpm(tmp_path):
    """Without the export's sidecar key, a log with thrust and rotor-speed columns is
    identified from its thrust and torques, as before."""
    first = identify_log(_log("jana00"), replace(OPTIONS, max_iterations=1))
    log = replace(first.log, meta=replace(first.log.meta, wrench_from_rpm=False))
    back = read_log(write_log(log, tmp_path / "plain.parquet"))
    assert back.thrust is not None and back.rpm is None and not back.meta.wrench_from_rpm
