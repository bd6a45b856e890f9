"""FlightLog round trips and clear errors on bad files."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pinquad.io.logs import LogFormatError, read_table, write_log
from pinquad.sim.simulator import SimConfig, flight_log, simulate


@pytest.fixture(scope="module")
def short_log():
    flight = simulate(SimConfig(sensor="B"), np.random.default_rng(11))
    return flight_log(flight).slice(0, 300)


def _same(a, b):
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=0)
    for name in ("position", "velocity", "euler", "gyro", "accel", "thrust", "torque", "truth"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-12,
                                   equal_nan=True, err_msg=name)
    np.testing.assert_array_equal(a.contact, b.contact)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_round_trip(short_log, tmp_path, suffix):
    path = write_log(short_log, tmp_path / f"flight{suffix}")
    back = read_table(path)
    _same(short_log, back)
    assert back.meta.vehicle == short_log.meta.vehicle
    assert (tmp_path / f"flight{suffix}.json").exists()


def test_a_log_that_names_no_vehicle_is_written_naming_none(short_log, tmp_path):
    """A log whose vehicle is not named (a Neural-Swarm flight, a sidecar without the
    key) is written without a ``vehicle`` key, and reads back naming none: the default
    written out would claim the paper's vehicle and judge the flight against its range."""
    unnamed = replace(short_log, meta=replace(short_log.meta, vehicle_named=False))
    path = write_log(unnamed, tmp_path / "flight.csv")
    assert "vehicle" not in json.loads((tmp_path / "flight.csv.json").read_text())
    assert read_table(path).meta.vehicle_named is False
    named = read_table(write_log(short_log, tmp_path / "named.csv"))
    assert named.meta.vehicle_named is True and named.meta.vehicle == short_log.meta.vehicle


def test_read_log_is_the_one_reader_and_takes_the_vehicle_override(short_log, tmp_path):
    """``pinquad.read_log`` is ``pinquad.io.read.read_log``: a table reads as the table
    reader reads it, and ``vehicle`` overrides the sidecar's (named, as ``offline --log
    --vehicle`` does); a vehicle pinquad does not know is refused, named."""
    import pinquad
    from pinquad.io.read import read_log

    assert pinquad.read_log is read_log
    path = write_log(short_log, tmp_path / "flight.csv")
    _same(read_table(path), read_log(path))
    over = read_log(path, "crazyflie21")
    assert over.meta.vehicle == "crazyflie21" and over.meta.vehicle_named
    assert short_log.meta.vehicle != "crazyflie21"
    with pytest.raises(LogFormatError, match="--vehicle: vehicle 'boeing'"):
        read_log(path, "boeing")


def _write_csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


BASE = ["t", "pos_x", "pos_y", "pos_z", "thrust", "torque_x", "torque_y", "torque_z"]


def test_missing_time_column(tmp_path):
    p = _write_csv(tmp_path / "a.csv", BASE[1:], [["0", "0", "0", "1", "0", "0", "0"]])
    with pytest.raises(LogFormatError, match=r"a\.csv.*'t'"):
        read_table(p)


def test_non_increasing_time(tmp_path):
    rows = [["0.0", "0", "0", "0", "1", "0", "0", "0"], ["0.01", "0", "0", "0", "1", "0", "0", "0"],
            ["0.01", "0", "0", "0", "1", "0", "0", "0"]]
    p = _write_csv(tmp_path / "b.csv", BASE, rows)
    with pytest.raises(LogFormatError, match=r"b\.csv.*not strictly increasing at row 3"):
        read_table(p)


def test_nan_actuation(tmp_path):
    rows = [["0.0", "0", "0", "0", "1", "0", "0", "0"], ["0.01", "0", "0", "0", "", "0", "0", "0"]]
    p = _write_csv(tmp_path / "c.csv", BASE, rows)
    with pytest.raises(LogFormatError, match=r"c\.csv.*'thrust', row 2"):
        read_table(p)


def test_empty_file(tmp_path):
    p = tmp_path / "d.csv"
    p.write_text("")
    with pytest.raises(LogFormatError, match=r"d\.csv.*empty"):
        read_table(p)


def test_no_actuation(tmp_path):
    p = _write_csv(tmp_path / "e.csv", BASE[:4], [["0", "0", "0", "0"]])
    with pytest.raises(LogFormatError, match=r"e\.csv.*actuation"):
        read_table(p)


def test_not_a_number(tmp_path):
    rows = [["0.0", "abc", "0", "0", "1", "0", "0", "0"]]
    p = _write_csv(tmp_path / "f.csv", BASE, rows)
    with pytest.raises(LogFormatError, match=r"f\.csv.*line 2.*'pos_x'"):
        read_table(p)


def test_corrupt_parquet(tmp_path):
    p = tmp_path / "g.parquet"
    p.write_bytes(b"PAR1 this is not parquet")
    with pytest.raises(LogFormatError, match=r"g\.parquet"):
        read_table(p)
