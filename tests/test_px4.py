"""PX4 input and the known-mass mode (docs/px4.md): a ULog written here from a flightgen
flight reads back to the same estimates as the same flight in the data-driven-dynamics
CSV layout; the frames come out as the flight flew them; the bench ULog is refused; the
data-driven-dynamics sample's inertia against its simulator's truth."""

from __future__ import annotations

import math
import struct
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pinquad
from flightgen import QUAD_250, FlightSpec, Noise, generate
from pinquad.core.actuator_curve import read_curve_vehicle, toml_from_ddd_yaml
from pinquad.core.conventions import (
    euler_from_quat_wxyz,
    quat_wxyz_from_ned_frd,
    rotation_from_euler,
    vector_from_ned_frd,
)
from pinquad.core.vehicle_file import load_vehicle
from pinquad.identification.known_mass import identify_known_mass
from pinquad.identification.known_mass_em import identify_known_mass_em
from pinquad.io.datadir import checkout_data_dir
from pinquad.io.errors import LogFormatError
from pinquad.io.logs import write_log
from pinquad.io.read import read_command_log

REPO = Path(__file__).resolve().parents[1]
PX4 = checkout_data_dir().parent / "px4"
DDD_CSV = PX4 / "ddd_quadrotor_model.csv"
DDD_YAML = PX4 / "ddd_quadrotor_model.yaml"
BENCH = PX4 / "pyulog_sample.ulg"
JANA00 = checkout_data_dir() / "imrc_brushed" / "jana00"
DDD_TRUTH = (0.029125, 0.029125, 0.055225)

CURVE = (2.0, 8.0)
"""The test vehicle's thrust curve T = c_1 u + c_2 u^2 [N]."""
YAW_RATIO = 0.012
"""Its yaw torque per thrust [m]."""
T0_US = 10_000_000
"""Boot-clock time of the flight's first row [us]."""


# --------------------------------------------------------------------- a ULog writer
# The ULog layout (PX4 docs, "ULog File Format"): a 16-byte header (magic, version,
# uint64 start time [us]), then messages of (uint16 size, uint8 type, payload): 'F'
# formats "name:type field;...", 'P' parameters, 'A' subscriptions (multi id, msg id,
# name), 'D' data (msg id, packed fields, little endian, no padding).

_CTYPES = {"uint64_t": "Q", "float": "f", "uint8_t": "B", "bool": "?", "int32_t": "i"}


def _msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _field_list(fields: list[tuple[str, str, int]]) -> tuple[str, str]:
    """The 'F' text and the struct format of (type, name, count) fields."""
    text = ";".join(f"{t}[{n}] {name}" if n > 1 else f"{t} {name}" for t, name, n in fields)
    return text + ";", "<" + "".join(_CTYPES[t] * n for t, _, n in fields)


def write_ulog(path: Path, topics: dict[str, tuple[list[tuple[str, str, int]], np.ndarray]],
               params: dict[str, int]) -> None:
    """A ULog of ``topics`` (name -> (fields after the uint64 timestamp, rows (R, 1 +
    sum of counts) whose first column is the timestamp [us])), in time order."""
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", T0_US))
    out += _msg("B", bytes(40))  # flag bits: no compat or incompat flags, nothing appended
    formats = {}
    for name, (fields, _) in topics.items():
        text, fmt = _field_list([("uint64_t", "timestamp", 1), *fields])
        formats[name] = fmt
        out += _msg("F", f"{name}:{text}".encode())
    for key, value in params.items():
        key_text = f"int32_t {key}".encode()
        out += _msg("P", bytes([len(key_text)]) + key_text + struct.pack("<i", value))
    for msg_id, name in enumerate(topics):
        out += _msg("A", struct.pack("<BH", 0, msg_id) + name.encode())
    events = []
    for msg_id, (name, (_, rows)) in enumerate(topics.items()):
        for row in rows:
            values = [int(row[0])] + [v.item() for v in row[1:]]
            fmt = formats[name]
            cast = [int(v) if c in "QBi" else bool(v) if c == "?" else float(v)
                    for v, c in zip(values, fmt[1:], strict=True)]
            events.append((int(row[0]), msg_id, struct.pack(fmt, *cast)))
    for _, msg_id, payload in sorted(events, key=lambda e: (e[0], e[1])):
        out += _msg("D", struct.pack("<H", msg_id) + payload)
    path.write_bytes(bytes(out))


# ------------------------------------------------------- a flightgen flight as PX4 logs

def _rotors() -> tuple[np.ndarray, np.ndarray]:
    """QUAD_250's x layout, front-right first, clockwise from above: (4, 2) [m], spin."""
    h = QUAD_250.arm / math.sqrt(2.0)
    return np.array([[h, -h], [-h, -h], [-h, h], [h, h]]), np.array([1.0, -1.0, 1.0, -1.0])


def _vehicle_file(path: Path) -> Path:
    positions, spin = _rotors()
    j = [float(v) for v in np.diag(QUAD_250.inertia_matrix)]
    rotors = "".join(f"\n[[rotor]]\nx = {float(x)!r}\ny = {float(y)!r}\nspin = {int(s)}\n"
                     for (x, y), s in zip(positions, spin, strict=True))
    path.write_text(
        'name = "quad250_px4"\n[body]\nmass = 0.5\n'
        f"inertia = [{j[0]!r}, {j[1]!r}, {j[2]!r}]\n"
        f"[reference]\nmass = 0.5\ninertia = [{j[0]!r}, {j[1]!r}, {j[2]!r}]\n"
        f"[actuator_curve]\ncommand_range = [1000, 2000]\nyaw_ratio = {YAW_RATIO!r}\n"
        f"yaw_ratio_se = {0.05 * YAW_RATIO!r}\n"
        + rotors)
    return path


def write_px4_flight(tmp: Path) -> dict:
    """A 20 s flightgen flight of QUAD_250 at 100 Hz (sensor noise, no process noise:
    the logged commands are what acted), as PX4 would log it: NED / FRD
    columns rounded to float32 (the ULog's type), PWM commands through CURVE, armed
    from 1 s to 19 s; written as a ULog and as a data-driven-dynamics CSV of the armed
    rows, into the directory ``tmp``, with the vehicle file quad250.toml.
    Returns the paths (ulg, csv, vehicle), flightgen's log columns and the armed rows."""
    flight = generate(FlightSpec(duration=20.0, trajectory="sines", aggressive=True,
                                 log_rate=100, vehicle=QUAD_250, seed=3,
                                 noise=Noise(thrust=0.0, torque=(0.0, 0.0, 0.0))))
    c = flight.columns
    n = c["t"].shape[0]
    t_us = T0_US + np.round(c["t"] * 1e6).astype(np.int64)
    positions, spin = _rotors()
    mix = np.vstack([np.ones(4), positions[:, 1], -positions[:, 0], YAW_RATIO * spin])
    wrench = np.column_stack([c["thrust"], c["torque_x"], c["torque_y"], c["torque_z"]])
    rotor_thrust = np.linalg.solve(mix, wrench.T).T
    arm, disarm = T0_US + 1_000_000, T0_US + 19_000_000
    armed = (t_us >= arm) & (t_us < disarm)
    assert rotor_thrust[armed].min() > 0.0, "the flight asks a rotor for negative thrust"
    c1, c2 = CURVE
    # the first row's start-up transient (before arming, not read) may ask for less than 0
    u = (-c1 + np.sqrt(c1 * c1 + 4.0 * c2 * np.maximum(rotor_thrust, 0.0))) / (2.0 * c2)
    f32 = np.float32

    def ned(prefix: str) -> np.ndarray:
        return vector_from_ned_frd(np.column_stack([c[f"{prefix}_{a}"] for a in "xyz"]))

    quat = quat_wxyz_from_ned_frd(np.column_stack([c[f"quat_{a}"] for a in "wxyz"]))
    cols = {"pos": ned("pos"), "vel": ned("vel"), "q": quat, "gyro": ned("gyro"),
            "acc": ned("acc"), "pwm": 1000.0 + 1000.0 * u}
    cols = {k: v.astype(f32).astype(float) for k, v in cols.items()}
    ts = t_us[:, None].astype(float)
    tmp.mkdir(parents=True, exist_ok=True)
    status = np.array([[T0_US, 1], [arm, 2], [disarm, 1]], dtype=float)
    ulg = tmp / "flight.ulg"
    write_ulog(ulg, {
        "vehicle_status": ([("uint8_t", "arming_state", 1)], status),
        "vehicle_attitude": ([("float", "q", 4)], np.hstack([ts, cols["q"]])),
        "vehicle_angular_velocity": ([("float", "xyz", 3)], np.hstack([ts, cols["gyro"]])),
        "vehicle_acceleration": ([("float", "xyz", 3)], np.hstack([ts, cols["acc"]])),
        "vehicle_local_position": (
            [("float", "x", 1), ("float", "y", 1), ("float", "z", 1), ("float", "vx", 1),
             ("float", "vy", 1), ("float", "vz", 1), ("bool", "xy_valid", 1),
             ("bool", "z_valid", 1)],
            np.hstack([ts, cols["pos"], cols["vel"], np.ones((n, 2))])),
        "actuator_outputs": ([("float", "output", 4)], np.hstack([ts, cols["pwm"]])),
    }, {"PWM_MAIN_MIN": 1000, "PWM_MAIN_MAX": 2000})
    header = ["timestamp", *(f"u{i}" for i in range(4)), "x", "y", "z", "vx", "vy", "vz",
              *(f"q{i}" for i in range(4)), "ang_vel_x", "ang_vel_y", "ang_vel_z",
              "acc_b_x", "acc_b_y", "acc_b_z"]
    table = np.hstack([ts, cols["pwm"], cols["pos"], cols["vel"], cols["q"], cols["gyro"],
                       cols["acc"]])[armed]
    csv_path = tmp / "flight.csv"
    csv_path.write_text(",".join(header) + "\n" + "\n".join(
        ",".join(repr(float(v)) for v in row) for row in table) + "\n")
    return {"ulg": ulg, "csv": csv_path, "vehicle": _vehicle_file(tmp / "quad250.toml"),
            "columns": c, "armed": armed}


@pytest.fixture(scope="module")
def px4_flight(tmp_path_factory) -> dict:
    """The flightgen flight as PX4 logs (``write_px4_flight``)."""
    return write_px4_flight(tmp_path_factory.mktemp("px4"))


def _identify(path: Path, vehicle_path: Path):
    vehicle = read_curve_vehicle(vehicle_path)
    return identify_known_mass(read_command_log(path), 0.5, vehicle.spec.positions,
                               vehicle.spec.spin, vehicle.curve)


def test_ulog_round_trip_equals_csv(px4_flight):
    """The same flight through the ULog reader and the CSV reader: the same rows and
    the same estimates, every one of them."""
    from_ulog = read_command_log(px4_flight["ulg"])
    from_csv = read_command_log(px4_flight["csv"])
    assert from_ulog.log.n == from_csv.log.n == int(px4_flight["armed"].sum())
    np.testing.assert_allclose(from_ulog.command, from_csv.command, rtol=0, atol=1e-12)
    np.testing.assert_allclose(from_ulog.log.euler, from_csv.log.euler, rtol=0, atol=1e-9)
    a = _identify(px4_flight["ulg"], px4_flight["vehicle"])
    b = _identify(px4_flight["csv"], px4_flight["vehicle"])
    assert [e.name for e in a.estimates] == [e.name for e in b.estimates]
    for ea, eb in zip(a.estimates, b.estimates, strict=True):
        assert ea.value == pytest.approx(eb.value, rel=1e-6), ea.name
        assert ea.stderr == pytest.approx(eb.stderr, rel=1e-6), ea.name
        assert ea.verdict == eb.verdict, ea.name
    # and they are the flight's: the curve and the inertia within 3 total se of the truth
    truth = {"thrust c_1": CURVE[0], "thrust c_2": CURVE[1],
             **dict(zip(("I_xx", "I_yy", "I_zz"), np.diag(QUAD_250.inertia_matrix),
                        strict=True))}
    for name, value in truth.items():
        est = a.get(name)
        assert abs(est.value - value) < 3.0 * est.stderr, (name, est.value, value, est.stderr)
    # the vehicle file's yaw ratio is known to 5 % (yaw_ratio_se): 5 % of I_zz, in kg m^2
    izz = a.get("I_zz")
    assert dict(izz.parts)["yaw_torque_coefficient"] == pytest.approx(0.05 * izz.value, rel=1e-12)


def test_ulog_frames_are_the_flights(px4_flight):
    """NED / FRD in the file, pinquad's frames out: velocity, attitude, rates and
    specific force equal what flightgen flew, and gravity comes out along world -z."""
    read = read_command_log(px4_flight["ulg"]).log
    c, armed = px4_flight["columns"], px4_flight["armed"]

    def flown(prefix: str) -> np.ndarray:
        return np.column_stack([c[f"{prefix}_{a}"] for a in "xyz"])[armed]

    np.testing.assert_allclose(read.velocity, flown("vel"), atol=1e-5)
    np.testing.assert_allclose(read.position, flown("pos"), atol=1e-5)
    np.testing.assert_allclose(read.gyro, flown("gyro"), atol=1e-5)
    np.testing.assert_allclose(read.accel, flown("acc"), atol=1e-5)
    euler = euler_from_quat_wxyz(np.column_stack([c[f"quat_{a}"] for a in "wxyz"])[armed])
    np.testing.assert_allclose(read.euler, euler, atol=1e-6)
    # gravity along pinquad's -z: R a_b - dv/dt = (0, 0, +9.81) in the world frame
    world = np.einsum("nij,nj->ni", rotation_from_euler(read.euler), read.accel)
    gravity = world - np.gradient(read.velocity, read.t, axis=0)
    np.testing.assert_allclose(np.median(gravity, axis=0), [0.0, 0.0, 9.81], atol=0.05)
    assert read.t[0] == 0.0 and read.dt == pytest.approx(0.01)


def test_bench_ulog_refused():
    """pyulog's sample (a controller on the bench, never armed): exit 2, the message
    names the file and says why, no traceback, nothing written."""
    for extra in ([], ["--mass", "1.5", "--vehicle", str(DDD_YAML)]):
        proc = subprocess.run(
            [sys.executable, "-m", "pinquad.offline", "--log", str(BENCH), *extra],
            capture_output=True, text=True, timeout=120, cwd=REPO)
        assert proc.returncode == 2, proc.stderr
        assert "no armed flight segment" in proc.stderr
        assert str(BENCH) in proc.stderr
        assert "Traceback" not in proc.stderr


def test_ddd_yaml_converts_to_body_frame():
    """data-driven-dynamics' rotor_0 is 'front right' at FRD y = +0.22: body (x
    forward, y left) puts it at y = -0.22; its turning direction -1 makes a drag moment
    -(-1) c u^2 about FRD z (down), so a yaw reaction of sign -1 about body z (up): the
    front-right rotor of PX4's quad X, which turns counter-clockwise seen from above."""
    text = toml_from_ddd_yaml(DDD_YAML.read_text(), DDD_YAML)
    assert "y = -0.22" in text
    vehicle = read_curve_vehicle(DDD_YAML)
    assert vehicle.spec.positions[0].tolist() == [0.13, -0.22]
    assert vehicle.spec.spin.tolist() == [-1.0, -1.0, 1.0, 1.0]
    assert vehicle.spec.mass == 1.5
    assert vehicle.curve.yaw_ratio is None


def test_ddd_sample_inertia_against_truth():
    """The data-driven-dynamics sample with its mass: I_xx and I_yy within 10 % of the
    simulator's; the naive regression over 20 % low; I_zz says what it needs."""
    vehicle = read_curve_vehicle(DDD_YAML)
    result = identify_known_mass(read_command_log(DDD_CSV), 1.5, vehicle.spec.positions,
                                 vehicle.spec.spin, vehicle.curve)
    for a, name in enumerate(("I_xx", "I_yy")):
        est = result.get(name)
        assert abs(est.value / DDD_TRUTH[a] - 1.0) < 0.10, (name, est.value)
        assert abs(est.value - DDD_TRUTH[a]) < 3.0 * est.stderr, (name, est)
        assert result.naive_inertia[a] < 0.8 * DDD_TRUTH[a]
    zz = result.get("I_zz")
    assert not math.isfinite(zz.value) and "yaw torque coefficient" in zz.reasons[0]
    # the curve's thrust at the mean command is the curve at the number carried, not at
    # the note's rounding of it
    c_1, c_2 = result.get("thrust c_1").value, result.get("thrust c_2").value
    u_m = result.mean_command
    assert 0.0 < u_m < 1.0 and f"mean command u = {u_m:.3f}:" in " ".join(result.notes)
    assert result.get("thrust at mean u").value == pytest.approx(c_1 * u_m + c_2 * u_m**2,
                                                                 rel=1e-12)


def test_bad_px4_input_named(tmp_path):
    """A damaged cell, missing columns and a flight too short for the torque band: exit
    2 (or LogFormatError) with the file, the place and what was expected."""
    lines = DDD_CSV.read_text().splitlines()
    cells = lines[30].split(",")
    cells[3] = "abc"
    lines[30] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--log", str(bad), "--mass", "1.5",
         "--vehicle", str(DDD_YAML), "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert f"{bad}: data row 30, column 'u1': 'abc' is not a number" in proc.stderr
    assert not (tmp_path / "run").exists()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(DDD_CSV.read_text().splitlines()[:501]) + "\n")
    vehicle = read_curve_vehicle(DDD_YAML)
    with pytest.raises(ValueError, match=r"short.csv: 5.0 s of flight; the torque band"):
        identify_known_mass(read_command_log(short), 1.5, vehicle.spec.positions,
                            vehicle.spec.spin)
    cut = tmp_path / "cut.csv"
    cut.write_text("\n".join(",".join(line.split(",")[:10])
                             for line in DDD_CSV.read_text().splitlines()[:50]) + "\n")
    with pytest.raises(LogFormatError, match=r"cut.csv: lacks column\(s\) q1, q2, q3"):
        read_command_log(cut)


def test_ulog_nan_motor_output_named(tmp_path):
    """A motor output that is not a number inside the armed segment: the reader names
    the field and when, instead of interpolating NaN into the commands."""
    pwm = np.full((300, 4), 1500.0)
    pwm[250, 2] = np.nan
    _rest_ulog(tmp_path / "nan.ulg", pwm, {"PWM_MAIN_MIN": 1000, "PWM_MAIN_MAX": 2000})
    with pytest.raises(LogFormatError, match=r"nan.ulg: motor output output\[2\] is not a "
                                             r"number 2.500 s into the armed segment"):
        read_command_log(tmp_path / "nan.ulg")


def _rest_ulog(path: Path, pwm: np.ndarray, params: dict[str, int]) -> Path:
    """An armed ULog at rest, one row per 10 ms, whose motor outputs are ``pwm`` (n, 4)
    [us], with the PWM parameters ``params``."""
    n = pwm.shape[0]
    ts = (T0_US + 10_000 * np.arange(n, dtype=float))[:, None]
    write_ulog(path, {
        "vehicle_status": ([("uint8_t", "arming_state", 1)], np.array([[T0_US, 2.0]])),
        "vehicle_attitude": ([("float", "q", 4)], np.hstack([ts, np.tile([1.0, 0, 0, 0], (n, 1))])),
        "vehicle_angular_velocity": ([("float", "xyz", 3)], np.hstack([ts, np.zeros((n, 3))])),
        "vehicle_acceleration": ([("float", "xyz", 3)],
                                 np.hstack([ts, np.tile([0.0, 0.0, -9.81], (n, 1))])),
        "vehicle_local_position": ([("float", "vx", 1), ("float", "vy", 1), ("float", "vz", 1)],
                                   np.hstack([ts, np.zeros((n, 3))])),
        "actuator_outputs": ([("float", "output", 4)], np.hstack([ts, pwm])),
    }, params)
    return path


def _pwm_ulog(path: Path, params: dict[str, int]) -> Path:
    """A 3 s armed ULog at rest whose four motor outputs hold 1260, 1420, 1580, 1740 us
    (exact in float32), with the PWM parameters ``params``."""
    return _rest_ulog(path, np.tile([1260.0, 1420.0, 1580.0, 1740.0], (300, 1)), params)


def test_ulog_pwm_range_is_the_logs_own(tmp_path):
    """Motor outputs read as PWM map through the log's own range, not the 1000-2000 us
    default: with PWM_MAIN_MIN/MAX 1100/1900 (and the auxiliary outputs' 1000/2000 beside
    them, as a real log holds them) 1260 us is (1260 - 1100) / 800 = 0.2, and 1420, 1580,
    1740 us are 0.4, 0.6, 0.8; an older log with only PWM_MIN/MAX 1075/1950 (the values
    of the shared PX4 bench log) maps 1260 us to 185 / 875 = 0.2114."""
    main = read_command_log(_pwm_ulog(tmp_path / "main.ulg", {
        "PWM_MAIN_MIN": 1100, "PWM_MAIN_MAX": 1900, "PWM_AUX_MIN": 1000, "PWM_AUX_MAX": 2000}))
    assert main.command_range == (1100.0, 1900.0)
    np.testing.assert_allclose(main.command, np.tile([0.2, 0.4, 0.6, 0.8], (main.log.n, 1)),
                               rtol=0, atol=1e-12)
    assert any("1100-1900 us" in note for note in main.notes)
    old = read_command_log(_pwm_ulog(tmp_path / "old.ulg", {
        "PWM_MIN": 1075, "PWM_MAX": 1950, "PWM_AUX_MIN": 1000, "PWM_AUX_MAX": 2000}))
    assert old.command_range == (1075.0, 1950.0)
    np.testing.assert_allclose(old.command[:, 0], (1260.0 - 1075.0) / 875.0, rtol=0, atol=1e-12)


def test_given_time_constant_is_used(px4_flight):
    """A time constant from the vehicle file replaces the profiled one in both the curve
    and the torques: on the lag-free flight, giving 0 s (what the profile finds) gives the
    same curve and inertia, and giving 50 ms moves them."""
    flight = read_command_log(px4_flight["ulg"])
    vehicle = read_curve_vehicle(px4_flight["vehicle"])

    def run(tau):
        curve = replace(vehicle.curve, time_constant=tau)
        return identify_known_mass(flight, 0.5, vehicle.spec.positions, vehicle.spec.spin,
                                   curve)

    profiled, zero, slow = run(None), run(0.0), run(0.05)
    assert profiled.get("time constant").value == 0.0
    assert all(e.name != "time constant" for e in zero.estimates)
    for name in ("thrust c_2", "I_xx", "I_yy"):
        assert zero.get(name).value == pytest.approx(profiled.get(name).value, rel=1e-12)
        assert slow.get(name).value != pytest.approx(profiled.get(name).value, rel=1e-3)


# ------------------------------------------------------------- the EM route, velocity-only

def test_em_route_velocity_only_rescales_a_wrong_curve(px4_flight):
    """The known-mass EM route on the flightgen ULog with its position removed (the
    E-step sees velocity, attitude and rates only) and a nominal curve 1.25 times too
    weak (the vehicle file's T = (c_1, c_2) / 1.25): EM on the nominal wrench reads
    m_hat = m / 1.25, so s = m / m_hat comes out 1.25 and I = s I_hat the flight's
    inertia, each within 3 of its total standard errors and 3 % of the truth."""
    flight = read_command_log(px4_flight["ulg"])
    flight = replace(flight, log=replace(flight.log,
                                         position=np.full_like(flight.log.position, np.nan)))
    vehicle = read_curve_vehicle(px4_flight["vehicle"])
    weak = 1.25
    curve = replace(vehicle.curve, thrust=np.array(CURVE) / weak, time_constant=0.0)
    regression = identify_known_mass(flight, 0.5, vehicle.spec.positions, vehicle.spec.spin,
                                     curve)
    em = identify_known_mass_em(flight, 0.5, vehicle.spec.positions, vehicle.spec.spin,
                                regression, curve)
    assert em.channels == ("vel", "euler", "gyro") and em.converged
    assert em.mass_hat == pytest.approx(0.5 / weak, rel=0.01)
    scale = em.get("thrust scale s")
    assert abs(scale.value - weak) < 3.0 * scale.stderr and scale.verdict == "trusted"
    for a, name in enumerate(("I_xx", "I_yy", "I_zz")):
        est, truth = em.get(name), float(QUAD_250.inertia_matrix[a, a])
        assert abs(est.value - truth) < 3.0 * est.stderr, (name, est.value, truth, est.stderr)
        assert abs(est.value / truth - 1.0) < 0.03, (name, est.value, truth)
        # I = s I_hat, the equation the route rests on
        assert est.value == pytest.approx(scale.value * em.inertia_hat[a], rel=1e-12)
        # the assumed mass's 1 % is in every inertia's error bar
        assert dict(est.parts)["mass"] == pytest.approx(0.01 * est.value, rel=1e-12)
    # the yaw ratio's 5 % (the vehicle file's yaw_ratio_se) of I_zz itself
    izz = em.get("I_zz")
    assert dict(izz.parts)["yaw_torque_coefficient"] == pytest.approx(0.05 * izz.value, rel=1e-12)


def test_measured_flight_without_position_runs_on_velocity(tmp_path):
    """A measured Crazyflie flight (jana00) exported with its position removed: EM runs
    on velocity, attitude and rates (no 'pos' channel asked of a log without one), the
    smoothed position's variance stays finite, and I_xx, I_yy land within their total
    standard errors of the published values (the shipped crazyflie21 file's reference)."""
    log = pinquad.read_log(JANA00)
    path = write_log(replace(log, position=np.full_like(log.position, np.nan), measured=None),
                     tmp_path / "jana00_velocity.csv")
    result = pinquad.identify(pinquad.read_log(path))
    fit = result.run
    assert fit.sensor == "vel,euler,gyro"
    assert np.isfinite(fit.posterior.cov).all()
    published = load_vehicle("crazyflie21").reference.inertia
    for a in range(2):
        se = fit.stderr[a + 1]  # the total: statistical, kf, arm, between flights
        assert abs(fit.inertia[a, a] - published[a]) < se, (a, fit.inertia[a, a], se)
