"""Actuation between samples (issue 22 item 2): the sidecar's ``actuation``, the inputs
each transition applies (``models.sources.interval_inputs``) and the verdict on what
rests on a reading of the input the log does not declare."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flightgen import FlightSpec, generate, write_csv
from pinquad.identification.verdict import NOT_IDENTIFIABLE, TRUSTED, VerdictEvidence, judge
from pinquad.io.logs import LogFormatError, LogMeta, read_table, sidecar
from pinquad.models.sources import interval_inputs
from pinquad.pipeline.identify import LogOptions, identify_log

TRUE_INERTIA = np.array([16.6e-6, 16.7e-6, 29.3e-6])


def test_interval_inputs_hold_or_average_the_rows():
    logged = np.arange(12.0).reshape(3, 4) ** 2
    assert interval_inputs(logged, "held") is logged
    mean = interval_inputs(logged, "sampled")
    np.testing.assert_allclose(mean[:2], 0.5 * (logged[:2] + logged[1:]))
    np.testing.assert_allclose(mean[2], logged[2])


def test_sidecar_actuation_is_written_read_and_checked(tmp_path):
    assert sidecar(LogMeta())["actuation"] == "held"
    path = tmp_path / "f.csv"
    rows = "\n".join(f"{0.01 * k},{0.35},0,0,0,{k * 1e-3},0,1" for k in range(60))
    path.write_text("t,thrust,torque_x,torque_y,torque_z,pos_x,pos_y,pos_z\n" + rows + "\n")
    meta = read_table(path).meta
    assert meta.actuation == "sampled" and not meta.actuation_declared   # no sidecar
    for value, declared in (("held", True), ("sampled", True)):
        (tmp_path / "f.csv.json").write_text(json.dumps({"vehicle": "crazyflie21",
                                                         "actuation": value}))
        meta = read_table(path).meta
        assert (meta.actuation, meta.actuation_declared) == (value, declared)
    (tmp_path / "f.csv.json").write_text(json.dumps({"actuation": "zoh"}))
    with pytest.raises(LogFormatError, match="'actuation' is 'zoh'"):
        read_table(path)


def test_an_estimate_that_moves_with_the_reading_of_the_input_is_not_identifiable():
    stderr = np.array([1e-5, 0.1e-6, 0.1e-6, 0.3e-6])
    moved = VerdictEvidence(input_alternative=np.r_[0.035, 1.3 * TRUE_INERTIA])
    verdict = judge(0.035, np.diag(TRUE_INERTIA), stderr, moved, None)
    assert verdict.get("mass").verdict == TRUSTED
    assert verdict.get("I_xx").verdict == NOT_IDENTIFIABLE
    assert "if each row was held" in verdict.get("I_xx").reasons[0]
    still = VerdictEvidence(input_alternative=np.r_[0.035, 1.03 * TRUE_INERTIA])
    assert judge(0.035, np.diag(TRUE_INERTIA), stderr, still, None).trusted


def test_a_sampled_100hz_log_read_as_the_rows_mean_gets_the_inertia_held_would_miss(tmp_path):
    flight = generate(FlightSpec(duration=12, log_rate=100, seed=2, floor=None))
    log = read_table(write_csv(flight, tmp_path / "fg.csv"))
    assert log.meta.actuation == "sampled" and not log.meta.actuation_declared
    result = identify_log(log, LogOptions(msteps=("regressor",), information=False))
    mean_rows = np.diag(result.runs[0].inertia)[:2]
    held = result.input_alternative[1:3]
    # the controller runs at 2 kHz: held inputs lead the state by half a row (scripts/
    # actuation_readings.py: held +21..+34 %, the rows' mean 0..+9 % on 20 s flights)
    err_mean = np.abs(mean_rows / TRUE_INERTIA[:2] - 1)
    err_held = held / TRUE_INERTIA[:2] - 1
    assert np.all(err_held > 0.15), held
    assert np.all(err_mean < 0.1) and np.all(err_mean < 0.5 * err_held), mean_rows
    assert result.runs[0].mass == pytest.approx(0.035, rel=0.01)
