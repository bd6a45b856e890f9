"""Issue 24's last loose ends: a vehicle's constants come from its file, never from the
Crazyflie's in code (the ground-effect radius, the verdict's range), and the fault
detection and PWM repair follow the vehicle's rotor count."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.vehicle_file import layout_positions, load_vehicle, parse_vehicle
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.realdata.faults import (
    QUAD_PARTNERS,
    detect_actuation_faults,
    diagonal_partners,
    reconstruct_rpm,
)
from pinquad.realdata.observations import build_observations, options_for_vehicle
from pinquad.realdata.raw import RawFlight
from pinquad.realdata.thrust import ThrustCoefficient

ROOT = Path(__file__).resolve().parents[1]
QUAD250 = ROOT / "docs" / "vehicles" / "quad250_plus.toml"
BRUSHLESS = ROOT / "docs" / "vehicles" / "cf21_brushless.toml"

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
