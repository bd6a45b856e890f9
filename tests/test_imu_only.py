"""Ordinary logs (docs/imu_only.md): a Crazyflie micro-SD log read as IMU-only (acc, gyro,
motor commands) and identified with the mass known; the flight segments and useful
excitation found; --range; several logs in one fit; the refusal of a log with no motor
signal. Real data: sysid.tools' log10, log15, log16 and the IMRC jana00."""

from __future__ import annotations

import json
import math
import struct
import zlib
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from pinquad.cli.offline import main as offline_main
from pinquad.core.actuator_curve import read_curve_vehicle
from pinquad.identification.excitation import excitation_ranges, flight_segments, segments_of
from pinquad.identification.known_mass import (
    Stack,
    identify_known_mass,
    newey_west,
)
from pinquad.io.command_log import CommandLog, between
from pinquad.io.datadir import checkout_data_dir
from pinquad.io.errors import LogFormatError
from pinquad.io.read import read_command_log

SYSID = checkout_data_dir().parent / "sysid_tools"
JANA00 = checkout_data_dir() / "imrc_brushed" / "jana00"
SYSID_INERTIA = (1.029e-5, 1.105e-5)
"""sysid.tools' I_xx, I_yy on log15 (27 g, 0.028 m lever; its notebook's output)."""


@cache
def sysid_log(name: str) -> CommandLog:
    return read_command_log(SYSID / name)


def sysid_vehicle(folder: Path) -> Path:
    """sysid.tools' model as a vehicle file: rotors at (+-0.028, +-0.028) m, M1
    front-right, yaw directions (-1, +1, -1, +1)."""
    rotors = [(0.028, -0.028, -1), (-0.028, -0.028, 1), (-0.028, 0.028, -1), (0.028, 0.028, 1)]
    path = folder / "sysid.toml"
    path.write_text('name = "sysid"\n[body]\nmass = 0.027\ninertia = [1e-5, 1e-5, 2e-5]\n'
                    + "".join(f"\n[[rotor]]\nx = {x}\ny = {y}\nspin = {s}\n"
                              for x, y, s in rotors))
    return path


def test_data_present():
    assert all((SYSID / n).is_file() for n in ("log10", "log15", "log16")), SYSID
    assert JANA00.is_file()


def test_sysid_log_reads_as_imu_only():
    f = sysid_log("log15")
    log = f.log
    assert f.imu_only and f.n_motors == 4 and f.command_range == (0.0, 65535.0)
    np.testing.assert_allclose(np.diff(log.t), 0.004, atol=1e-9)
    assert np.isnan(log.velocity).all() and np.isnan(log.euler).all()
    assert np.isnan(log.position).all() and f.vbat is None
    assert 0.0 <= f.command.min() and f.command.max() <= 1.0
    assert log.meta.t_origin == pytest.approx(39.2469, abs=1e-3)  # first record + 2 ms
    flying = f.command.min(axis=1) > 0.05
    # the specific force along body z in flight: above g on average (thrust excitation
    # and tilts), not g-scaled wrong; the gyro in rad/s (sysid.tools' flights reach a few)
    assert 9.5 < log.accel[flying, 2].mean() < 11.5
    assert 1.0 < np.abs(log.gyro[flying]).max() < 30.0
    assert any("motor.m1..motor.m4" in n for n in f.notes)


def test_imrc_log_drops_pose_and_rotor_speed_keeps_pwm_and_battery():
    f = read_command_log(JANA00)
    assert f.imu_only and f.vbat is not None
    assert 3.0 < float(np.median(f.vbat)) < 4.3
    left_out = next(n for n in f.notes if n.startswith("left out"))
    assert "rpm" in left_out and "stateEstimate" in left_out
    assert any("pwm.m1_pwm..pwm.m4_pwm" in n for n in f.notes)


def test_flight_segments_and_excitation_found():
    """log15 flies once (sysid.tools used 55-90 s of it); log16 twice, with a landing in
    between (sysid.tools used 32-38 s and 45-49 s)."""
    f15, f16 = sysid_log("log15"), sysid_log("log16")
    ex15 = excitation_ranges(f15, flight_segments(f15), (0.3, 2.0))
    ex16 = excitation_ranges(f16, flight_segments(f16), (0.3, 2.0))
    (lo, hi), = ex15.segment_times
    assert lo < 55.0 and hi > 90.0
    assert len(ex16.segment_times) == 2
    (a0, a1), (b0, b1) = ex16.segment_times
    assert a0 <= 32.0 and 38.0 <= a1 < 40.0 and 44.0 < b0 <= 45.0 and b1 >= 49.0
    # roll and pitch are excited over most of log15, yaw on log16
    roll = sum(b - a for a, b in ex15.ranges["roll"])
    assert roll > 20.0 and ex15.ranges["pitch"]
    assert sum(b - a for a, b in ex16.ranges["yaw"]) > 5.0
    assert "useful yaw excitation" in ex16.text()


def test_range_selects_rows_on_the_log_clock():
    f = sysid_log("log15")
    cut = between(f, 55.0, 90.0)
    clock = cut.log.meta.t_origin + cut.log.t
    assert clock[0] >= 55.0 and clock[-1] <= 90.0 and cut.log.n == pytest.approx(8750, abs=1)
    assert cut.log.t[0] == 0.0 and cut.command.shape == (cut.log.n, 4)
    with pytest.raises(ValueError, match="runs from 39.2"):
        between(f, 200.0, 300.0)


def test_stack_runs_per_segment_and_group():
    stack = Stack(((0, 3), (3, 5)), np.array([0, 0, 0, 1, 1]))
    np.testing.assert_array_equal(stack.each(np.cumsum, np.ones(5)), [1, 2, 3, 1, 2])
    np.testing.assert_array_equal(stack.per_group(np.arange(5.0)),
                                  [[0, 0], [1, 0], [2, 0], [0, 3], [0, 4]])


def test_newey_west_by_fft_equals_the_direct_sum():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(400, 3))
    resid = np.convolve(rng.normal(size=420), np.ones(20) / 20, "valid")[:400]
    cov, lag = newey_west(x, resid, min_lag=30)
    xe = x * resid[:, None]
    s = xe.T @ xe
    for k in range(1, lag + 1):
        g = xe[k:].T @ xe[:-k]
        s += (1.0 - k / (lag + 1.0)) * (g + g.T)
    bread = np.linalg.inv(x.T @ x)
    np.testing.assert_allclose(cov, bread @ s @ bread, rtol=1e-10)
    assert lag >= 30


def test_inertia_under_sysid_tools_assumptions_agrees_with_it(tmp_path):
    """log15 on sysid.tools' range 55-90 s through the command line, with its mass and
    geometry: I_xx and I_yy trusted and within 15 % of the numbers its own method
    reports (its loader reads acc.z 6.4 % low, which lowers its torques and inertia)."""
    out = tmp_path / "run"
    code = offline_main(["--log", str(SYSID / "log15"), "--mass", "0.027", "--vehicle",
                         str(sysid_vehicle(tmp_path)), "--range", "55", "90", "--out",
                         str(out)])
    assert code in (0, 3)
    report = json.loads((out / "report.json").read_text())
    known = report["known_mass"]
    (seg,), = known["segments"]
    assert seg[0] == pytest.approx(55.0, abs=0.01) and seg[1] == pytest.approx(90.0, abs=0.01)
    assert known["excitation"][0]["ranges"]["roll"]
    est = {e["name"]: e for e in known["estimates"]}
    for name, theirs in zip(("I_xx", "I_yy"), SYSID_INERTIA, strict=True):
        assert est[name]["verdict"] == "trusted", est[name]["reasons"]
        assert abs(est[name]["value"] / theirs - 1.0) < 0.15, (name, est[name]["value"])
    assert "drag d_z" not in est  # no velocity: no drag term
    assert report["em"]["iterations"] == 0  # no E-step channel for an IMU-only log


def test_joint_fit_agrees_with_each_logs_own():
    """log10 and log15 of one vehicle in one fit (curve, time constant, inertia shared;
    damping per log) against each log's own fit on its flight segments: the shared
    thrust curve at the joint mean command and I_yy within two combined total errors of
    each log's trusted numbers."""
    v = read_curve_vehicle("crazyflie21")
    segs = [segments_of(sysid_log(n), None, (0.3, 2.0))[0] for n in ("log10", "log15")]
    own = [identify_known_mass(s, 0.027, v.spec.positions, v.spec.spin, v.curve)
           for s in segs]
    joint = identify_known_mass(segs[0] + segs[1], 0.027, v.spec.positions, v.spec.spin,
                                v.curve, groups=[0] * len(segs[0]) + [1] * len(segs[1]))
    j = joint.get("I_yy")
    o = own[1].get("I_yy")
    assert o.verdict == "trusted"
    assert abs(j.value - o.value) < 2.0 * math.hypot(j.stderr, o.stderr)
    assert j.stderr < own[0].get("I_yy").stderr  # log15 adds what log10 lacks
    for res in (*own, joint):  # the curve's scale: a quarter of the weight, +-5 %
        assert abs(res.get("thrust at mean u").value / (0.027 * 9.81 / 4) - 1) < 0.07


def _sdlog(columns: dict[str, np.ndarray], t_ms: np.ndarray) -> bytes:
    """A version-2 micro-SD log with one event fixedFrequency of float columns."""
    names = list(columns)
    out = bytearray([0xBC]) + struct.pack("<HH", 2, 1)
    out += struct.pack("<H", 0) + b"fixedFrequency\0" + struct.pack("<H", len(names))
    for n in names:
        out += f"{n}(f)".encode() + b"\0"
    fmt = "<" + "f" * len(names)
    for i, t in enumerate(t_ms):
        out += struct.pack("<HQ", 0, int(t * 1000)) + struct.pack(
            fmt, *(float(columns[n][i]) for n in names))
    out += struct.pack("<I", zlib.crc32(bytes(out)))
    return bytes(out)


@pytest.mark.parametrize("motors", ["none", "zero"])
def test_log_without_motor_signal_is_refused(tmp_path, capsys, motors):
    n = 3000
    t = np.arange(n) * 1.0
    cols = {f"acc.{a}": np.full(n, 1.0 if a == "z" else 0.0) for a in "xyz"}
    cols |= {f"gyro.{a}": np.zeros(n) for a in "xyz"}
    if motors == "zero":
        cols |= {f"motor.m{i}": np.zeros(n) for i in range(1, 5)}
    path = tmp_path / "imu_only_log"
    path.write_bytes(_sdlog(cols, t))
    with pytest.raises(LogFormatError, match="no motor signal"):
        read_command_log(path)
    out = tmp_path / "run"
    code = offline_main(["--log", str(path), "--mass", "0.03", "--vehicle", "crazyflie21",
                         "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "no motor signal" in err and "motor.m1..motor.m4" in err
    assert str(path) in err and "Traceback" not in err
    assert not out.exists()


def test_bad_range_and_several_logs_without_joint_are_refused(tmp_path, capsys):
    log15 = str(SYSID / "log15")
    assert offline_main(["--log", log15, "--mass", "0.027", "--vehicle", "crazyflie21",
                         "--range", "90", "55", "--out", str(tmp_path / "a")]) == 2
    assert "LO < HI" in capsys.readouterr().err
    assert offline_main(["--log", log15, log15, "--mass", "0.027", "--vehicle",
                         "crazyflie21", "--out", str(tmp_path / "b")]) == 2
    assert "--joint" in capsys.readouterr().err
    assert offline_main(["--log", log15, "--range", "55", "90"]) == 2
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_imu_only_log_without_mass_points_to_the_known_mass_mode(capsys, tmp_path):
    code = offline_main(["--log", str(SYSID / "log16"), "--no-discover", "--out",
                         str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and "--mass KG --vehicle FILE" in err and "log16" in err
    assert not (tmp_path / "run").exists()
