"""Issue 24's last loose ends: a vehicle's constants come from its file, never from the
Crazyflie's in code (the ground-effect radius, the verdict's range), and the fault
detection and PWM repair follow the vehicle's rotor count."""

from __future__ import annotations

import io
import tokenize
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.effect_vocabulary import SIMULATED_DRAG, ground_effect_gain
from pinquad.core.params import CRAZYFLIE21, PAPER_VEHICLE, vehicle_from_spec
from pinquad.core.vehicle_file import layout_positions, load_vehicle, parse_vehicle
from pinquad.discovery.refit import corrected_observations
from pinquad.identification.verdict import vehicle_range
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.read import read_log, with_vehicle
from pinquad.models.sources import observations
from pinquad.realdata.faults import (
    QUAD_PARTNERS,
    detect_actuation_faults,
    diagonal_partners,
    reconstruct_rpm,
)
from pinquad.realdata.observation_options import options_for_vehicle
from pinquad.realdata.observations import build_observations
from pinquad.realdata.raw import RawFlight, raw_flight
from pinquad.realdata.vehicle_check import measured_vehicle
from pinquad.sim.effects import drag, ground_effect
from pinquad.vehicle.actuators import ThrustCoefficient

ROOT = Path(__file__).resolve().parents[1]
QUAD250 = ROOT / "docs" / "vehicles" / "quad250_plus.toml"
BRUSHLESS = ROOT / "docs" / "vehicles" / "cf21_brushless.toml"
ECKART00 = ROOT.parent / "shared" / "data" / "crazyflie" / "imrc_brushless" / "eckart00"
CRAZYFLIE_FILE = ROOT / "pinquad" / "data" / "crazyflie21.toml"
GENERIC_NUMBERS = {-1.0, 1.0, 0.0005, 0.003, 0.006, 0.007, 0.011, 0.025, 0.05, 0.06, 0.07, 0.1,
                   0.24, 10000.0}
"""Numbers of crazyflie21.toml that are also round thresholds and defaults elsewhere."""

HEXA = """
name = "hexa"
[body]
mass = 1.2
inertia = [1.2e-2, 1.2e-2, 2.2e-2]
[geometry]
arm = 0.2
layout = "+"
spin = [1, -1, 1, -1, 1, -1]
[actuators]
kf = 1.2e-6
kf_se = 2e-8
yaw_ratio = 0.015
[faults]
repair_rel_se = [0.01, 0.05, 0.05, 0.2]
"""


def hexa_log(n: int = 600, seed: int = 3) -> tuple[FlightLog, np.ndarray, np.ndarray]:
    """A hovering hexacopter's rotor speeds (n, 6) [rev/min] with rotor 5 reading 0 in
    rows 100..159, its PWM commands through rpm = 1000 + 3000 pwm / 1e4, and the truth."""
    rng = np.random.default_rng(seed)
    truth = 9000 + 300 * rng.standard_normal((n, 1)) + 100 * rng.standard_normal((n, 6))
    pwm = (truth - 1000.0) / 3000.0 * 1e4
    rpm = truth.copy()
    rpm[100:160, 4] = 0.0
    nan3 = np.full((n, 3), np.nan)
    log = FlightLog(t=np.arange(n) * 0.002, position=nan3, velocity=nan3, euler=nan3,
                    gyro=nan3, accel=nan3, rpm=rpm, meta=LogMeta(source="hexa"))
    return log, pwm, truth


def test_diagonal_partners_follow_the_geometry():
    cf = load_vehicle("crazyflie21")
    assert diagonal_partners(cf.positions, cf.spin) == QUAD_PARTNERS == (2, 3, 0, 1)
    assert diagonal_partners(layout_positions(0.125, "+"), [1, -1, 1, -1]) == (2, 3, 0, 1)
    # a hexacopter's opposite rotors spin against each other: no pairs
    hexa = parse_vehicle(HEXA, Path("hexa.toml"))
    assert diagonal_partners(hexa.positions, hexa.spin) == (None,) * 6


def test_six_rotor_dropout_found_and_rebuilt_from_pwm():
    hexa = parse_vehicle(HEXA, Path("hexa.toml"))
    log, pwm, truth = hexa_log()
    rep = detect_actuation_faults(log, flight_rpm=4000, max_rpm=40000,
                                  partners=diagonal_partners(hexa.positions, hexa.spin))
    assert rep.motor_mask.shape == (600, 6)
    assert rep.dropout_counts.tolist() == [0, 0, 0, 0, 60, 0]
    # 10 % of the airborne rows: the whole channel is distrusted
    assert rep.unreliable.tolist() == [False] * 4 + [True, False]
    rec = reconstruct_rpm(log, pwm, rep)
    assert rec.motors_used == (0, 1, 2, 3, 5)
    assert rec.replaced[:, 4].all() and not rec.replaced[:, [0, 1, 2, 3, 5]].any()
    np.testing.assert_allclose(rec.rpm[:, 4], truth[:, 4], rtol=1e-6)
    assert len(rec.divisions) == 6 and rec.divisor == (1,) * 6


def test_pwm_that_does_not_match_the_rotor_count_is_refused():
    hexa = parse_vehicle(HEXA, Path("hexa.toml"))
    options = options_for_vehicle(hexa)
    assert options.faults == "repair"  # a six-rotor file with repair_rel_se is repaired
    log, pwm, _ = hexa_log()
    kf = ThrustCoefficient(1.2e-6, 2e-8, (), 1.2e-6, "test")
    with pytest.raises(ValueError, match="4 PWM commands per row but 6 rotor speeds"):
        build_observations(RawFlight(log=log, pwm=pwm[:, :4]), options, kf)
    # and a log with fewer rotor speeds than the file's rotors, before any fault check
    quad = replace(log, rpm=log.rpm[:, :4])
    with pytest.raises(ValueError, match="4 rotor speeds per row but the vehicle has 6"):
        build_observations(RawFlight(log=quad, pwm=pwm[:, :4]), options, kf)


def file_numbers(path: Path) -> set[float]:
    """Every number in a TOML file."""
    out: set[float] = set()

    def walk(x: object) -> None:
        if isinstance(x, dict):
            for v in x.values():
                walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)
        elif isinstance(x, (int, float)) and not isinstance(x, bool):
            out.add(float(x))

    walk(tomllib.loads(path.read_text()))
    return out


def test_no_crazyflie_constant_in_the_code():
    """The shipped Crazyflie's numbers (mass, inertia, arm, kf, drag, rotor radius, motor
    reach, ...) live in crazyflie21.toml only: none is a number literal in pinquad's
    code (comments and docstrings may quote them)."""
    constants = file_numbers(CRAZYFLIE_FILE) - GENERIC_NUMBERS
    assert {0.0347, 0.046, 2.06e-8, 0.0062, 0.0235, 1.657e-5, 30000.0} <= constants
    found = []
    for path in sorted((ROOT / "pinquad").rglob("*.py")):
        for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
            if tok.type == tokenize.NUMBER:
                try:
                    value = float(tok.string.replace("_", ""))
                except ValueError:  # complex literals
                    continue
                if value in constants:
                    found.append(f"{path.relative_to(ROOT)}:{tok.start[0]}: {tok.string}")
    assert not found, found


def test_ground_effect_radius_is_the_vehicles():
    # the rotor footprint from each file's geometry, an [aero] value where a file gives one
    assert load_vehicle(str(QUAD250)).ground_effect_radius == 0.125
    assert load_vehicle("crazyflie21").ground_effect_radius == CRAZYFLIE21.ground_effect_radius
    assert CRAZYFLIE21.ground_effect_radius == load_vehicle("crazyflie21").arm
    assert PAPER_VEHICLE.ground_effect_radius == load_vehicle("paper").arm == 0.086
    given = parse_vehicle(HEXA + "[aero]\nground_effect_radius = 0.3\n", Path("h.toml"))
    assert given.ground_effect_radius == 0.3 and vehicle_from_spec(given).ground_effect_radius == 0.3
    assert SIMULATED_DRAG == tuple(load_vehicle("crazyflie21").aero.drag)
    # the simulator's ground effect on a vehicle from a file takes that vehicle's radius
    quad = vehicle_from_spec(load_vehicle(str(QUAD250)))
    x = np.zeros(12)
    x[2] = 0.1
    f_z = ground_effect().for_vehicle(quad).wrench(x, np.array([5.0, 0, 0, 0]), 0.0)[2]
    assert f_z == pytest.approx(5.0 * (0.125 / 0.4) ** 2)
    assert drag().name == "drag" and ground_effect(radius=0.2).for_vehicle is None


def test_discovery_reads_the_ground_effect_with_the_files_geometry(tmp_path):
    """A measured log of a vehicle file: discovery's ground-effect feature uses that
    file's rotor footprint, not the Crazyflie's 0.046 m."""
    wide = tmp_path / "wide.toml"
    wide.write_text(BRUSHLESS.read_text().replace("arm = 0.046 ", "arm = 0.08  "))
    log = with_vehicle(read_log(ECKART00), str(wide), ROOT, "test")
    options, kf = measured_vehicle(log)
    obs = build_observations(raw_flight(log), options, kf).obs
    assert obs.ground_radius == 0.08
    state = np.zeros((obs.n, 12))
    state[:, 2] = 0.05
    out = corrected_observations(obs, state, {"ground_effect": np.array([1.0])})
    ok = np.isfinite(obs.inputs[:, 0])
    np.testing.assert_allclose(out.inputs[ok, 0], obs.inputs[ok, 0] * (1.0 + (0.08 / 0.2) ** 2))
    # a log with thrust and torque that names the file goes the same way
    named = replace(log, thrust=np.full(log.n, 0.36), torque=np.zeros((log.n, 3)), rpm=None,
                    measured=None)
    assert observations(named, "B").ground_radius == 0.08
    assert observations(replace(named, meta=replace(named.meta, vehicle="crazyflie21")),
                        "B").ground_radius == 0.046
    np.testing.assert_allclose(ground_effect_gain(0.05, 0.08), 0.16)


def test_verdict_range_of_a_file_vehicle_is_its_files():
    """The verdict's physically possible range of a vehicle file's vehicle: its
    [reference] (else [body]) values with the usual factors, not the Crazyflie's."""
    quad = vehicle_range(str(QUAD250))
    assert quad is not None and quad.mass == pytest.approx((0.25, 1.0))
    np.testing.assert_allclose(quad.inertia_lo, np.array([3.0e-3, 3.2e-3, 5.5e-3]) / 4)
    brushless = vehicle_range(str(BRUSHLESS))  # 37 g on the scale, the body's inertia
    assert brushless is not None and brushless.mass == pytest.approx((0.0185, 0.074))
    np.testing.assert_allclose(brushless.inertia_hi,
                               np.diag(load_vehicle(str(BRUSHLESS)).inertia) * 4)
    assert "cf21_brushless file" in brushless.source
