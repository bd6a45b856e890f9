"""Vehicle files (issue 24): the format, the shipped vehicles read from it, a file that
contradicts the log, kf from a user's steady-thrust CSV, and the brushless Crazyflie
identified from a file written only from what its user knows."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.params import CRAZYFLIE21, PAPER_VEHICLE
from pinquad.core.vehicle_file import (
    VehicleFileError,
    layout_positions,
    load_vehicle,
    parse_vehicle,
)
from pinquad.io.logs import write_log
from pinquad.io.read import read_log, with_vehicle
from pinquad.pipeline.identify import LogOptions, identify_log
from pinquad.realdata.vehicle_check import measured_vehicle
from pinquad.vehicle.actuators import KF_CRAZYFLIE, ActuatorModel, motor_positions
from pinquad.vehicle.steady_thrust import fit_steady_thrust

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "crazyflie"
BRUSHLESS = DATA / "imrc_brushless"
CALIB = DATA / "brushless_calibration"
BRUSHLESS_FILE = ROOT / "docs" / "vehicles" / "cf21_brushless.toml"

GOOD = """
name = "quad250"
[body]
mass = 0.5
inertia = [3e-3, 3e-3, 5e-3]
[geometry]
arm = 0.125
layout = "+"
spin = [1, -1, 1, -1]
[actuators]
kf = 6e-6
kf_se = 1e-7
yaw_ratio = 0.016
max_thrust = 4.0
"""


def test_shipped_vehicles_come_from_their_files():
    cf = load_vehicle("crazyflie21")
    assert (CRAZYFLIE21.mass, CRAZYFLIE21.arm) == (cf.mass, cf.arm) == (0.0347, 0.046)
    assert PAPER_VEHICLE.mass == load_vehicle("paper").mass == 0.18
    assert KF_CRAZYFLIE == cf.actuators.kf == 2.06e-8
    # the file's X layout numbers the rotors as the Bitcraze mixer does (M1 front-right)
    np.testing.assert_allclose(cf.positions, motor_positions(0.046), atol=1e-15)
    np.testing.assert_allclose(layout_positions(0.1, "+"),
                               [[0.1, 0], [0, -0.1], [-0.1, 0], [0, 0.1]], atol=1e-15)


@pytest.mark.parametrize("edit, key", [
    (("mass = 0.5", "mass = 500"), "body.mass"),
    (("kf = 6e-6", "kf = \"6e-6\""), "actuators.kf"),
    (("spin = [1, -1, 1, -1]", "spin = [1, 1, 1, -1]"), "spin"),
    (("layout = \"+\"", "layout = \"h\""), "geometry.layout"),
    (("inertia = [3e-3, 3e-3, 5e-3]", "inertia = [3e-3, 5e-3]"), "body.inertia"),
    (("kf_se = 1e-7\n", ""), "actuators.kf_se"),
])
def test_bad_file_names_file_and_key(edit, key):
    with pytest.raises(VehicleFileError) as err:
        parse_vehicle(GOOD.replace(*edit), Path("/x/quad250.toml"))
    assert "/x/quad250.toml" in str(err.value) and f"'{key}'" in str(err.value)


def test_rotor_inertia_absent_is_fitted_a_value_zero_included_is_fixed():
    where = Path("/x/quad250.toml")
    assert parse_vehicle(GOOD, where).actuators.rotor_inertia is None  # fitted per flight
    fixed = GOOD.replace("max_thrust = 4.0", "max_thrust = 4.0\nrotor_inertia = 0.0")
    assert parse_vehicle(fixed, where).actuators.rotor_inertia == 0.0
    given = fixed.replace("rotor_inertia = 0.0", "rotor_inertia = 2e-7")
    assert parse_vehicle(given, where).actuators.rotor_inertia == 2e-7
    with pytest.raises(VehicleFileError, match="'actuators.rotor_inertia'.*>= 0"):
        parse_vehicle(fixed.replace("rotor_inertia = 0.0", "rotor_inertia = -1e-7"), where)


def test_plus_layout_mixer_from_file():
    spec = parse_vehicle(GOOD, Path("q.toml"))
    act = ActuatorModel.from_spec(spec)
    rpm = np.full((1, 4), 6000.0)
    rpm[0, 3] = 6500.0  # the left rotor (+y) faster: positive roll torque
    thrust, torque = act.wrench(rpm)
    omega = rpm[0] * 2 * np.pi / 60
    assert thrust[0] == pytest.approx(6e-6 * (omega**2).sum())
    assert torque[0, 0] == pytest.approx(0.125 * 6e-6 * (omega[3] ** 2 - omega[1] ** 2))
    assert torque[0, 1] == pytest.approx(0.125 * 6e-6 * (omega[2] ** 2 - omega[0] ** 2))


@pytest.fixture(scope="module")
def eckart00():
    return read_log(BRUSHLESS / "eckart00")


def test_file_that_contradicts_the_log(tmp_path, eckart00):
    hexa = replace(eckart00, rpm=np.column_stack([eckart00.rpm, eckart00.rpm[:, :2]]))
    hexa = with_vehicle(hexa, str(BRUSHLESS_FILE), ROOT, "test")
    with pytest.raises(ValueError, match=r"6 rotor speeds \(rpm_1..rpm_6\).*4 rotors"):
        measured_vehicle(hexa)
    weak = tmp_path / "weak.toml"
    weak.write_text(BRUSHLESS_FILE.read_text().replace("max_thrust = 0.26", "max_thrust = 0.05"))
    with pytest.raises(ValueError, match="hover needs 0.363 N"):
        measured_vehicle(with_vehicle(eckart00, str(weak), ROOT, "test"))
    # the same contradiction from the command line: exit 2, no traceback
    csv = write_log(replace(hexa, measured=None), tmp_path / "hexa.csv")
    res = subprocess.run([sys.executable, "-m", "pinquad.offline", "--log", str(csv),
                          "--vehicle", str(BRUSHLESS_FILE), "--no-discover",
                          "--out", str(tmp_path / "run")],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert res.returncode == 2, res.stderr
    assert "rpm_1..rpm_6" in res.stderr and "Traceback" not in res.stderr


def test_steady_thrust_fit_recovers_known_kf(tmp_path):
    rpm = np.linspace(5000, 20000, 7)
    thrust_g = 4 * 3.0e-8 * (rpm * 2 * np.pi / 60) ** 2 / 9.81e-3
    path = tmp_path / "stand.csv"
    path.write_text("rpm,weight[g]\n" + "".join(f"{a},{b}\n" for a, b in zip(rpm, thrust_g, strict=True)))
    fit = fit_steady_thrust(path)
    assert fit.kf == pytest.approx(3.0e-8, rel=1e-9) and fit.kf_se < 1e-15


def _calibration_kf_by_lstsq() -> tuple[float, float, int]:
    """kf [N/(rad/s)^2], its standard error and the number of steps, fitted here from
    the raw brushless calibration: each step of the manual file (its "rpm" column holds
    the PWM command, "weight[g]" the four rotors' thrust in grams-force) takes the
    median rpm4 over the second half of the logged rows at that PWM (the first half
    spins up); the steps at 10000-20000 rev/min (around the flights' speeds) give
    T = kf 4 omega^2 by least squares through the origin."""
    manual = np.genfromtxt(CALIB / "manual_data_calib_brushless.csv", delimiter=",",
                           skip_header=1)
    logged = np.genfromtxt(CALIB / "data_calib_brushless.csv", delimiter=",", names=True)
    speed = []
    for pwm in manual[:, 0]:
        rows = logged["rpm4"][logged["pwm"] == pwm]
        assert rows.size > 1, f"no logged rows at PWM {pwm}"
        speed.append(np.median(rows[rows.size // 2:]))
    speed = np.array(speed)
    steps = (speed >= 10000) & (speed <= 20000)
    x = 4 * (speed[steps] * 2 * np.pi / 60) ** 2
    y = manual[steps, 1] * 9.81e-3
    (kf,), rss, _, _ = np.linalg.lstsq(x[:, None], y, rcond=None)
    return float(kf), float(np.sqrt(rss[0] / (x.size - 1) / (x @ x))), int(steps.sum())


def test_brushless_calibration_through_the_fit():
    """The product's steady-thrust fit and the vehicle file's kf agree with the fit
    written above to within its standard error (both fit the same five steps, so any
    real disagreement is a mistake of units, columns or step matching, not noise)."""
    assert CALIB.is_dir(), f"the brushless calibration is missing: expected it in {CALIB}"
    fit = fit_steady_thrust(CALIB / "manual_data_calib_brushless.csv",
                            speeds_from=CALIB / "data_calib_brushless.csv", join=("rpm", "pwm"),
                            speed_columns=("rpm4",), speed_range=(10000, 20000))
    want, se, steps = _calibration_kf_by_lstsq()
    assert fit.n_points == steps == 5
    assert 0.0 < se < 0.02 * want
    assert abs(fit.kf - want) < se, (fit.kf, want, se)
    assert fit.kf_se == pytest.approx(se, rel=0.05)
    act = load_vehicle(str(BRUSHLESS_FILE)).actuators
    assert abs(act.kf - want) < se, (act.kf, want, se)
    assert fit.residual_rms / 9.81e-3 < 1.0  # gf


def test_brushless_flight_identified_from_its_file(eckart00):
    log = with_vehicle(eckart00, str(BRUSHLESS_FILE), ROOT, "test")
    res = identify_log(log, LogOptions(msteps=("regressor",), information=False))
    run = res.runs[0]
    assert abs(run.mass - 0.037) < 2.0 * run.stderr[0], (run.mass, run.stderr[0])
    assert run.measured.kf.rel_se == pytest.approx(6.6e-10 / 3.8091e-8)
