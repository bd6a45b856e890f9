"""What a sidecar or a vehicle file declares is checked against the log
(``pinquad.io.declaration_check``): a real IMRC flight (jana00, exported as pinquad's
Parquet log) with a false declaration added to its sidecar, or read with a vehicle file
made false in one key, is refused before any EM naming the declaration, the file and
key, the evidence and the fix; the same flight declared truly passes. Each expectation
comes from how the variant was written, not from the code under test."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinquad.core.vehicle_file import shipped_path
from pinquad.io import declaration_check as dc
from pinquad.io.declared import Conventions
from pinquad.io.foreign import write_foreign
from pinquad.io.logs import read_table, write_log
from pinquad.io.read import read_log, with_vehicle
from pinquad.io.sanity import findings

ROOT = Path(__file__).resolve().parents[1]
JANA00 = ROOT.parent / "shared" / "data" / "crazyflie" / "imrc_brushed" / "jana00"
BRUSHLESS = ROOT / "docs" / "vehicles" / "cf21_brushless.toml"


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("declarations")


@pytest.fixture(scope="module")
def clean(folder):
    """jana00 (fails without the shared data) as pinquad's own Parquet log, all 9.2 s."""
    assert JANA00.exists(), f"shared IMRC data missing: {JANA00}"
    return read_table(write_log(replace(read_log(JANA00), measured=None), folder / "jana00.parquet"))


def _declared(clean, folder: Path, name: str, keys: dict, written: Conventions | None = None):
    """The flight written in ``written``'s conventions (undeclared), its sidecar then
    declaring ``keys``: read back as the reader reads it."""
    path = write_foreign(clean, folder / f"{name}.parquet", written or Conventions(), False)
    side = Path(str(path) + ".json")
    side.write_text(json.dumps({**json.loads(side.read_text()), **keys}))
    return read_table(path)


def _only(log) -> dc.Problem:
    found = findings(log)
    assert len(found) == 1, [f.message for f in found]
    return found[0].check, found[0].column, found[0].message


def test_true_declarations_pass(clean, folder):
    """Every convention written and declared truly: no check fires (no false alarm)."""
    for k, conv in enumerate((Conventions(frame="NED/FRD"), Conventions(quaternion_order="xyzw"),
                              Conventions(quaternion_rotation="world_to_body"),
                              Conventions(rotor_speed="rad/s"),
                              Conventions(motor_order=(2, 3, 4, 1)))):
        log = read_table(write_foreign(clean, folder / f"true{k}.parquet", conv, True))
        assert findings(log) == (), conv


def test_a_false_quaternion_order_is_named_with_the_upside_down_evidence(clean, folder):
    """Columns named by component (w, x, y, z) and declared "xyzw": read so the vehicle
    flies upside down; without the declared-attitude test the undeclared gravity test
    fired with a generic hint (check name "gravity-direction")."""
    check, _, msg = _only(_declared(clean, folder, "xyzw", {"quaternion": {"order": "xyzw"}}))
    assert check == "attitude-declaration"
    assert 'the sidecar says "quaternion": {"order": "xyzw"}' in msg
    assert "upside down" in msg and "remove the sidecar's 'quaternion' key" in msg
    mass = float(re.search(r"model-free mass \(mean vertical force over g\) is (-?[\d.]+) g",
                           msg).group(1))
    assert mass < 0  # the flight's 35 g, upside down


def test_a_false_inverse_rotation_and_a_false_euler_unit_are_named(clean, folder):
    check, _, msg = _only(_declared(clean, folder, "w2b",
                                    {"quaternion": {"rotation": "world_to_body"}}))
    assert check == "attitude-declaration" and '"rotation": "world_to_body"' in msg
    # roll/pitch/yaw written in degrees, declared radians: the degree reading is named
    path = write_foreign(clean, folder / "deg_only.parquet", Conventions(euler_unit="deg"), False,
                         ("quat_w", "quat_x", "quat_y", "quat_z"))
    side = Path(str(path) + ".json")
    side.write_text(json.dumps({**json.loads(side.read_text()), "euler": {"unit": "rad"}}))
    check, column, msg = _only(read_table(path))
    assert check == "attitude-declaration" and column == "roll, pitch, yaw"
    assert 'declare "euler": {"order": "ZYX", "unit": "deg"}' in msg


def test_a_false_ned_frame_is_named_and_the_motor_order_advice_does_not_hide_it(clean, folder):
    """An ENU log declared NED/FRD: refused naming the frame (not "declare motor_order
    [2, 1, 4, 3]", what the undeclared motor test said), and still refused once that
    motor order is declared too."""
    for name, keys in (("ned", {"frame": "NED/FRD"}),
                       ("ned_mo", {"frame": "NED/FRD", "motor_order": [2, 1, 4, 3]})):
        check, _, msg = _only(_declared(clean, folder, name, keys))
        assert check == "frame-declaration", msg
        assert "the sidecar says \"frame\": \"NED/FRD\"; the log's gravity and attitude say " \
               "ENU/FLU" in msg
        assert "motor_order" not in msg
    # and the other way: an NED log declared ENU/FLU
    log = _declared(clean, folder, "enu", {"frame": "ENU/FLU"}, Conventions(frame="NED/FRD"))
    check, _, msg = _only(log)
    assert check == "frame-declaration" and 'declare "frame": "NED/FRD"' in msg


def test_a_false_motor_order_is_named_with_the_right_one(clean, folder):
    """Columns in the vehicle's numbering declared [2, 3, 4, 1]: remove the key. Columns
    written numbered [2, 3, 4, 1] (column i holds motor k_i) but declared [3, 4, 1, 2]:
    the message gives [2, 3, 4, 1], the order they were written in."""
    check, _, msg = _only(_declared(clean, folder, "mo", {"motor_order": [2, 3, 4, 1]}))
    assert check == "motor-order-declaration" and "remove the key" in msg
    log = _declared(clean, folder, "mo2", {"motor_order": [3, 4, 1, 2]},
                    Conventions(motor_order=(2, 3, 4, 1)))
    check, _, msg = _only(log)
    assert check == "motor-order-declaration"
    assert 'the sidecar says "motor_order": [3, 4, 1, 2]' in msg
    assert 'declare "motor_order": [2, 3, 4, 1]' in msg


def test_a_false_rotor_speed_unit_is_named(clean, folder):
    check, column, msg = _only(_declared(clean, folder, "radps", {"rotor_speed": "rad/s"}))
    assert (check, column) == ("rotor-speed-declaration", "rpm_*")
    assert "read as rev/min they give 1.0" in msg and "remove the key" in msg


def test_a_negative_model_free_mass_is_refused_without_an_accelerometer(clean):
    """The attitude turned over about world x (the gyro still agrees: R_a^T R_b is
    unchanged) and no accelerometer to see it: only the model-free mass's sign can."""
    ok = np.isfinite(clean.euler).all(axis=1)
    turned = np.full_like(clean.euler, np.nan)
    rot = Rotation.from_euler("ZYX", clean.euler[ok, ::-1])
    turned[ok] = (Rotation.from_euler("x", np.pi) * rot).as_euler("ZYX")[:, ::-1]
    log = replace(clean, euler=turned, accel=np.full_like(clean.accel, np.nan))
    found = dc.check_declared_frame(log)
    assert found is not None and found[0] == "model-free-mass", found
    assert dc.check_declared_frame(replace(clean, accel=log.accel)) is None
    assert dc.model_free_mass(clean) == pytest.approx(0.0347, rel=0.05)  # 34.7 g on the scale


@pytest.fixture(scope="module")
def flipped_yaw(folder) -> Path:
    """crazyflie21.toml with its yaw spin signs flipped (the URDF beside it)."""
    src = shipped_path("crazyflie21")
    text = src.read_text()
    assert "spin = [-1, 1, -1, 1]" in text
    path = folder / "cf21_flipped_yaw.toml"
    path.write_text(text.replace("spin = [-1, 1, -1, 1]", "spin = [1, -1, 1, -1]"))
    (folder / "crazyflie21.urdf").write_text((src.parent / "crazyflie21.urdf").read_text())
    return path


def test_a_vehicle_file_with_flipped_yaw_spins_is_refused(clean, flipped_yaw):
    log = with_vehicle(clean, str(flipped_yaw), ROOT, "test")
    check, _, msg = _only(log)
    assert check == "vehicle-geometry"
    assert str(flipped_yaw) in msg and "'geometry.spin'" in msg
    assert "[-1, 1, -1, 1] fits this log" in msg  # the shipped file's spins
    ev = dc.axis_correlations(log, dc.rotor_model(log))
    assert ev.correlation[2] < -dc.AXIS_CORRELATION and ev.correlation[:2].min() > 0.5
    # the shipped file given as a file: the same axes, yaw positive; nothing fires
    right = with_vehicle(clean, str(shipped_path("crazyflie21")), ROOT, "test")
    assert findings(right) == ()
    np.testing.assert_allclose(dc.axis_correlations(right, dc.rotor_model(right)).correlation,
                               ev.correlation * [1, 1, -1], rtol=1e-12)


def test_another_vehicles_file_is_refused_on_the_hover_balance(clean):
    """The brushless build's file (kf 3.81e-8, 37 g) on the brushed flight (kf 2.06e-8,
    34.7 g on the scale): the rotors hold up about 34.7 g * 3.81 / 2.06 = 64 g, 1.7 times
    the file's 37 g."""
    log = with_vehicle(clean, str(BRUSHLESS), ROOT, "test")
    check, _, msg = _only(log)
    assert check == "vehicle-mass" and str(BRUSHLESS) in msg and "[reference] mass 37 g" in msg
    ratio = float(re.search(r"g \(model-free mass.*?\), ([\d.]+) times", msg).group(1))
    assert ratio == pytest.approx(34.7 * 3.8091 / 2.06 / 37.0, rel=0.05)


def test_a_declared_payload_moves_the_hover_balance_reference(clean):
    """The same flight and file with a declared 27 g load: the rotors' 64 g are then 1.0
    times the 37 g + 27 g the file and the declaration say, so the file is not refused."""
    log = with_vehicle(clean, str(BRUSHLESS), ROOT, "test")
    loaded = replace(log, meta=replace(log.meta, payload_mass=0.027))
    assert dc.check_vehicle_mass(loaded) is None
    assert dc.check_vehicle_mass(log) is not None


def test_the_cli_refuses_a_false_vehicle_file_with_one_paragraph_and_writes_nothing(
        clean, flipped_yaw, folder):
    out = folder / "run"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "pinquad.offline", "--log", clean.meta.source,
                           "--vehicle", str(flipped_yaw), "--no-discover", "--out", str(out)],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert "'geometry.spin'" in lines[0] and str(flipped_yaw) in lines[0]
    assert not out.exists()
