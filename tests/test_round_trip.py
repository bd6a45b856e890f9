"""One flight, one answer: a measured micro-SD flight, pinquad's own export of it
(``logs/flight.parquet``, whose sidecar says its thrust and torques were computed from
the rotor speeds) and a CSV copy of that export, as a spreadsheet or pyarrow writes it
(quoted names), are identified from the same rotor speeds."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq
import pytest

from pinquad.experiments.recorded import LogOptions, identify_log
from pinquad.io.logs import write_log
from pinquad.io.read import read_log

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed"
OPTIONS = LogOptions(msteps=("regressor",), information=False)


def _values(result) -> np.ndarray:
    run = result.runs[0]
    return np.r_[run.mass, np.diag(run.inertia)]


@pytest.mark.parametrize("name", ["jana00", "jana02"])
def test_micro_sd_export_and_csv_copy_give_one_answer(name, tmp_path):
    path = DATA / name
    assert path.is_file(), f"the Crazyflie data are missing: expected {path}"
    first = identify_log(read_log(path), OPTIONS)
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
    # against the micro-SD reading: the mass to 1e-4, roll and pitch inertia within 1 %
    a, b = _values(first), _values(again)
    assert abs(b[0] / a[0] - 1) < 1e-4
    np.testing.assert_allclose(b[1:3], a[1:3], rtol=0.01)


@pytest.mark.xfail(strict=True, reason="I_zz of the export differs from the micro-SD "
                   "reading's (jana05: +84 %, 10 statistical errors; jana10 +28 %): the yaw "
                   "torque's rotor-inertia term takes the rotor acceleration from the "
                   "export's 100 Hz speeds instead of the raw 500 Hz ones")
def test_the_exports_yaw_inertia_is_the_micro_sd_ones(tmp_path):
    path = DATA / "jana05"
    assert path.is_file(), f"the Crazyflie data are missing: expected {path}"
    first = identify_log(read_log(path), OPTIONS)
    again = identify_log(read_log(write_log(first.log, tmp_path / "f.parquet")), OPTIONS)
    assert abs(_values(again)[3] / _values(first)[3] - 1) < 0.10


def test_a_simulated_log_is_not_read_from_rpm(tmp_path):
    """Without the export's sidecar key, a log with thrust and rotor-speed columns is
    identified from its thrust and torques, as before."""
    path = DATA / "jana00"
    assert path.is_file(), f"the Crazyflie data are missing: expected {path}"
    first = identify_log(read_log(path), OPTIONS)
    log = replace(first.log, meta=replace(first.log.meta, wrench_from_rpm=False))
    back = read_log(write_log(log, tmp_path / "plain.parquet"))
    assert back.thrust is not None and back.rpm is None and not back.meta.wrench_from_rpm
