"""The micro-SD log reader on the real Crazyflie flights and on damaged or synthetic files."""

from __future__ import annotations

import struct
import zlib
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.conventions import euler_from_quat_wxyz, wrap_angle
from pinquad.io.logs import LogFormatError
from pinquad.io.sdlog import SdFlight, is_sdlog, read_sdflight, read_sdlog, read_sdlog_raw

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "crazyflie"
FLIGHTS = DATA / "imrc_brushed"
LOGS = ("jana00", "jana01", "jana02", "jana03", "jana04", "jana05", "jana10", "jana20",
        "jana23", "jana24", "jana25", "jana27", "jana28", "jana29")


def flight_path(name: str) -> Path:
    assert FLIGHTS.is_dir(), (
        f"the Crazyflie flight data are missing: expected {FLIGHTS} (the shared data "
        "directory next to the repository)")
    path = FLIGHTS / name
    assert path.is_file(), f"missing flight log {path}"
    return path


@cache
def flight(name: str) -> SdFlight:
    return read_sdflight(flight_path(name))


def test_data_directory_present():
    assert FLIGHTS.is_dir(), f"expected the real Crazyflie logs in {FLIGHTS}"
    present = sorted(p.name for p in FLIGHTS.glob("jana*"))
    assert set(LOGS) <= set(present), f"missing logs: {sorted(set(LOGS) - set(present))}"


@pytest.mark.parametrize("name", LOGS)
def test_every_real_log_parses(name):
    fl = flight(name)
    log = fl.log
    assert fl.raw.version == 2
    assert fl.raw.crc_ok, "the real files carry a little-endian CRC-32 of all preceding bytes"
    assert log.n > 3000
    assert log.t[0] == 0.0 and np.all(np.diff(log.t) > 0)
    for arr in (log.position, log.velocity, log.euler, log.gyro, log.accel):
        assert arr.shape == (log.n, 3)
    assert log.rpm.shape == (log.n, 4) and np.isfinite(log.rpm).all()
    assert fl.pwm.shape == (log.n, 4) and np.isfinite(fl.pwm).all()
    assert np.isfinite(log.gyro).all() and np.isfinite(log.accel).all()
    assert np.isfinite(log.velocity).all()
    assert log.meta.vehicle == "crazyflie21" and log.meta.mass_guess is None
    assert log.meta.source == str(flight_path(name))
    # The raw result keeps the PWM the FlightLog has no field for, row for row.
    raw_pwm = fl.raw.events["fixedFrequency"].get("pwm.m2_pwm")[fl.rows]
    np.testing.assert_array_equal(fl.pwm[:, 1], raw_pwm)


@pytest.mark.parametrize("name", ["jana00", "jana04", "jana20"])
def test_sample_rates_as_documented(name):
    fl = flight(name)
    grid_hz = 1.0 / fl.log.dt
    assert 480.0 < grid_hz < 520.0
    pose_t = fl.raw.events["estPose"].time
    pose_hz = 1.0 / float(np.median(np.diff(pose_t)))
    assert 85.0 < pose_hz < 110.0
    # Poses go missing now and then, so on average fewer than half the grid rows at 500 Hz
    # / 100 Hz carry one; they sit within half a grid interval of their own time.
    placed = np.isfinite(fl.log.position[:, 0])
    assert placed.sum() == fl.pose_rows.size > 0.8 * pose_t.size
    assert placed.sum() < fl.log.n / 4


@pytest.mark.parametrize("name", ["jana00", "jana10", "jana25"])
def test_units_and_hover_sanity(name):
    log = flight(name).log
    assert 9.5 < log.accel[:, 2].mean() < 10.2, "acc z should read about +9.81 m/s^2 in flight"
    assert np.abs(log.accel[:, :2].mean(axis=0)).max() < 0.3
    assert np.abs(log.gyro).max() < 10.0, "gyro must be in rad/s"
    assert 3.0 < np.nanmedian(log.vbat) < 4.3, "vbat must be in volts"
    assert 15000 < np.median(log.rpm) < 23000
    pos = log.position[np.isfinite(log.position[:, 0])]
    assert 0.0 < pos[:, 2].min() and pos[:, 2].max() < 1.5
    att = log.euler[np.isfinite(log.euler[:, 0])]
    assert np.abs(att[:, :2]).max() < 0.6, "roll and pitch stay small in these flights"


@pytest.mark.parametrize("name", ["jana02", "jana05"])
def test_mocap_pose_agrees_with_onboard_estimate(name):
    """The motion-capture pose and the onboard estimate (fused with it) must agree; this
    checks the quaternion order and the Euler conversion through conventions."""
    fl = flight(name)
    ff = fl.raw.events["fixedFrequency"]
    rows = fl.pose_rows
    est_pos = np.column_stack([ff.get(f"stateEstimate.{a}")[fl.rows][rows] for a in "xyz"])
    assert np.median(np.linalg.norm(fl.log.position[rows] - est_pos, axis=1)) < 0.03
    q = np.column_stack([ff.get(f"stateEstimate.q{a}")[fl.rows][rows] for a in "wxyz"])
    est_euler = euler_from_quat_wxyz(q)
    diff = wrap_angle(fl.log.euler[rows] - est_euler)
    assert np.median(np.abs(diff), axis=0).max() < 0.05


# ----------------------------------------------------------------------------- damaged files

def _record_offsets(path: Path) -> np.ndarray:
    raw = read_sdlog_raw(path)
    return np.sort(np.concatenate([ev.offsets for ev in raw.events.values()]))


def _expect_error(path: Path, offset: int | None = None) -> str:
    with pytest.raises(LogFormatError) as info:
        read_sdlog(path)
    msg = str(info.value)
    assert path.name in msg and "byte offset" in msg, msg
    if offset is not None:
        assert f"byte offset {offset}" in msg, msg
    return msg


def test_truncated_mid_record(tmp_path):
    src = flight_path("jana00")
    data = src.read_bytes()
    offs = _record_offsets(src)
    cut = int(offs[100]) + 37  # inside record 100
    bad = tmp_path / "jana00_truncated"
    bad.write_bytes(data[:cut])
    msg = _expect_error(bad)
    assert "truncated" in msg


def test_wrong_magic(tmp_path):
    data = bytearray(flight_path("jana02").read_bytes())
    data[0] = 0xAB
    bad = tmp_path / "jana02_magic"
    bad.write_bytes(bytes(data))
    msg = _expect_error(bad, 0)
    assert "0xBC" in msg
    assert not is_sdlog(bad)


def test_unknown_event_id(tmp_path):
    src = flight_path("jana02")
    data = bytearray(src.read_bytes())
    off = int(_record_offsets(src)[50])
    data[off:off + 2] = struct.pack("<H", 0x1234)
    bad = tmp_path / "jana02_event"
    bad.write_bytes(bytes(data))
    msg = _expect_error(bad, off)
    assert "unknown event id 4660" in msg


def test_unknown_version_and_too_short(tmp_path):
    data = bytearray(flight_path("jana02").read_bytes())
    data[1:3] = struct.pack("<H", 7)
    bad = tmp_path / "jana02_version"
    bad.write_bytes(bytes(data))
    _expect_error(bad, 1)
    short = tmp_path / "short"
    short.write_bytes(b"\xbc\x02\x00")
    _expect_error(short)


def test_crc_mismatch_is_an_error_unless_waived(tmp_path):
    src = flight_path("jana03")
    data = bytearray(src.read_bytes())
    off = int(_record_offsets(src)[10]) + 12  # a payload byte: structure stays valid
    data[off] ^= 0x01
    bad = tmp_path / "jana03_crc"
    bad.write_bytes(bytes(data))
    msg = _expect_error(bad, len(data) - 4)
    assert "CRC" in msg
    fl = read_sdflight(bad, verify_crc=False)
    assert not fl.raw.crc_ok
    assert any("CRC" in note for note in fl.log.meta.notes)


def test_is_sdlog(tmp_path):
    assert is_sdlog(flight_path("jana00"))
    csv = tmp_path / "log.csv"
    csv.write_text("t,pos_x\n0,1\n")
    assert not is_sdlog(csv)
    assert not is_sdlog(tmp_path / "missing")


# ----------------------------------------------------------------------------- synthetic files

def _build_log(version: int, events: list[tuple[int, str, list[str]]],
               records: list[tuple[int, int, tuple]]) -> bytes:
    """A micro-SD log from event declarations (id, name, ['var(T)', ...]) and records
    (id, timestamp ticks, values)."""
    out = bytearray([0xBC]) + struct.pack("<HH", version, len(events))
    fmts = {}
    for eid, name, variables in events:
        out += struct.pack("<H", eid) + name.encode() + b"\0" + struct.pack("<H", len(variables))
        for var in variables:
            out += var.encode() + b"\0"
        fmts[eid] = "<" + "".join(v[-2] for v in variables)
    ts = "<I" if version == 1 else "<Q"
    for eid, tick, values in records:
        out += struct.pack("<H", eid) + struct.pack(ts, tick) + struct.pack(fmts[eid], *values)
    out += struct.pack("<I", zlib.crc32(bytes(out)))
    return bytes(out)


def test_version1_duplicates_and_missing_variables(tmp_path):
    # fixedFrequency without acc.*, rpm.m3 and pwm; timestamps in ms with a duplicate and a
    # backwards step; estPose at three grid times.
    ff_vars = ["gyro.x(f)", "gyro.y(f)", "gyro.z(f)", "rpm.m1(H)", "rpm.m2(H)", "rpm.m4(H)",
               "pm.vbatMV(H)", "stateEstimate.vx(f)", "stateEstimate.vy(f)",
               "stateEstimate.vz(f)"]
    pose_vars = [f"locSrv.{a}(f)" for a in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    ticks = [1000, 1002, 1004, 1004, 1006, 1005, 1008, 1010, 1012, 1014, 1016]
    records = []
    yaw = 0.3
    for k, tick in enumerate(ticks):
        records.append((7, tick, (90.0, 0.0, -45.0, 20000, 20001, 20003, 3700 + k,
                                  0.1, 0.2, 0.3)))
        if tick in (1000, 1008, 1016):
            records.append((3, tick, (1.0, 2.0, 0.5, 0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2))))
    path = tmp_path / "synthetic_v1"
    path.write_bytes(_build_log(1, [(7, "fixedFrequency", ff_vars), (3, "estPose", pose_vars)],
                                records))
    fl = read_sdflight(path)
    log = fl.log
    assert log.n == len(ticks) - 2
    np.testing.assert_allclose(log.t, [0, 0.002, 0.004, 0.006, 0.008, 0.010, 0.012, 0.014, 0.016])
    assert any("dropped 2 of 11" in note for note in log.meta.notes)
    np.testing.assert_allclose(log.gyro[0], [np.pi / 2, 0.0, -np.pi / 4], rtol=1e-6)
    assert np.isnan(log.accel).all()
    assert np.isnan(log.rpm[:, 2]).all() and (log.rpm[:, 3] == 20003).all()
    assert np.isnan(fl.pwm).all()
    np.testing.assert_allclose(log.vbat[:2], [3.700, 3.701])
    np.testing.assert_allclose(log.velocity[0], [0.1, 0.2, 0.3], rtol=1e-6)
    posed = np.flatnonzero(np.isfinite(log.position[:, 0]))
    np.testing.assert_array_equal(posed, [0, 4, 8])  # ticks 1000, 1008, 1016 after dropping
    np.testing.assert_allclose(log.euler[posed], [[0.0, 0.0, yaw]] * 3, atol=1e-6)
    assert any("acc.x" in note and "rpm.m3" in note for note in log.meta.notes)


def test_missing_grid_event_is_an_error(tmp_path):
    path = tmp_path / "no_grid"
    path.write_bytes(_build_log(2, [(3, "estPose", ["locSrv.x(f)"])], [(3, 10, (1.0,))]))
    with pytest.raises(LogFormatError, match="fixedFrequency"):
        read_sdlog(path)


def test_bad_variable_type_is_an_error(tmp_path):
    path = tmp_path / "bad_type"
    path.write_bytes(_build_log(2, [(7, "fixedFrequency", ["gyro.x(f)"])], []))
    data = bytearray(path.read_bytes())
    at = data.index(b"gyro.x(f)") + len("gyro.x(")
    data[at:at + 1] = b"Z"
    path.write_bytes(bytes(data))
    with pytest.raises(LogFormatError, match="byte offset"):
        read_sdlog(path)
