"""Implausible-actuation detection and rotor-speed repair on the real Crazyflie logs."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from pinquad.core.params import CRAZYFLIE21
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.sdlog import SdFlight, read_sdflight
from pinquad.realdata.faults import (
    ActuationFaultReport,
    detect_actuation_faults,
    pulse_divided_readings,
    reconstruct_rpm,
    repair_log,
)
from pinquad.vehicle.actuators import ActuatorModel, rad_s_from_rpm

FLIGHTS = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "crazyflie" / \
    "imrc_brushed"
CLEAN = ("jana00", "jana01", "jana02", "jana03", "jana04", "jana05", "jana10")
FAULTY = ("jana20", "jana23", "jana24", "jana25", "jana27", "jana28", "jana29")
ABOUT_30_PERCENT = ("jana20", "jana27", "jana28", "jana29")


@cache
def flight(name: str) -> SdFlight:
    assert FLIGHTS.is_dir(), f"the Crazyflie flight data are missing: expected {FLIGHTS}"
    return read_sdflight(FLIGHTS / name)


@cache
def report(name: str) -> ActuationFaultReport:
    return detect_actuation_faults(flight(name).log)


def hover_mass(log: FlightLog, rpm: np.ndarray) -> float:
    """Least-squares mass [kg] from thrust = m * acc_z (body specific force)."""
    thrust, _ = ActuatorModel().wrench(rpm)
    a = log.accel[:, 2]
    return float(thrust @ a / (a @ a))


@pytest.mark.parametrize("name", CLEAN)
def test_clean_logs_have_no_flags(name):
    rep = report(name)
    assert rep.n_flagged == 0 and not rep.mask.any()
    assert rep.counts.tolist() == [0, 0, 0, 0]
    assert not rep.unreliable.any() and not rep.vbat_stuck and rep.clean
    assert rep.airborne.all()
    assert rep.trusted.all()


@pytest.mark.parametrize("name", FAULTY)
def test_faulty_logs_flag_motor_1_and_stuck_battery(name):
    log = flight(name).log
    rep = report(name)
    assert rep.counts[1:].tolist() == [0, 0, 0], "only motor 1 is broken"
    n = log.n
    zero_fraction = float(np.mean(log.rpm[:, 0] == 0))
    drop_fraction = rep.dropout_counts[0] / n
    # Every row where M1 reads exactly 0 in flight is a dropout, and little else is.
    assert zero_fraction <= drop_fraction < zero_fraction + 0.05
    if name in ABOUT_30_PERCENT:
        assert 0.15 < drop_fraction < 0.40
    else:
        assert drop_fraction > 0.7
    # The readings that are not 0 sit near half the diagonal partner's speed: the
    # whole channel is distrusted.
    assert rep.unreliable.tolist() == [True, False, False, False]
    assert rep.counts[0] > 0.98 * n
    assert rep.vbat_stuck and rep.vbat_value == pytest.approx(3.7)
    assert any(note.startswith("motor M1") for note in rep.notes)
    assert any("battery" in note for note in rep.notes)


def test_synthetic_dropout_mask_is_exact():
    rng = np.random.default_rng(5)
    n = 400
    rpm = 19500 + 300 * rng.standard_normal((n, 4))
    rpm[50:80, 2] = 0.0      # M3 drops out
    rpm[200:210, 1] *= 0.5   # M2 reads half
    rpm[300:, :] = 2000.0    # landed, idling: not checked
    rpm[350, 0] = 0.0
    nan3 = np.full((n, 3), np.nan)
    log = FlightLog(t=np.arange(n) * 0.002, position=nan3, velocity=nan3, euler=nan3,
                    gyro=nan3, accel=nan3, rpm=rpm, vbat=3.9 - 1e-4 * np.arange(n),
                    meta=LogMeta(source="synthetic"))
    rep = detect_actuation_faults(log)
    expected = np.zeros(n, dtype=bool)
    expected[50:80] = expected[200:210] = True
    np.testing.assert_array_equal(rep.mask, expected)
    assert rep.dropout_counts.tolist() == [0, 0, 30, 0]
    assert rep.counts.tolist() == [0, 10, 30, 0]
    assert rep.airborne.sum() == 300
    # M3 is implausible in 10 % of the 300 airborne rows, M2 in 3 %: only M3 is distrusted.
    assert rep.unreliable.tolist() == [False, False, True, False]
    assert not rep.trusted[:, 2].any() and rep.trusted[:, 1].sum() == n - 10
    assert not rep.vbat_stuck


@pytest.mark.parametrize("name", ["jana01", "jana10"])
def test_reconstruction_from_pwm_on_clean_logs(name):
    """Hide motor 1 on a clean log, rebuild it from PWM, compare with what it measured."""
    fl = flight(name)
    rec = reconstruct_rpm(fl.log, fl.pwm, report(name), replace_motors=(0,))
    assert rec.motors_used == (1, 2, 3)
    assert rec.replaced[:, 0].all() and not rec.replaced[:, 1:].any()
    measured = fl.log.rpm[:, 0]
    err = rec.rpm[:, 0] - measured
    assert np.sqrt(np.mean(err**2)) < 0.05 * np.median(measured)
    w2 = (rad_s_from_rpm(fl.log.rpm) ** 2).sum(axis=1)
    w2_rec = (rad_s_from_rpm(rec.rpm) ** 2).sum(axis=1)
    assert abs(np.mean(w2_rec / w2 - 1.0)) < 0.03
    np.testing.assert_array_equal(rec.rpm[:, 1:], fl.log.rpm[:, 1:])
    # A healthy channel is not mistaken for one that counts every other pulse.
    assert rec.divisor == (1, 1, 1, 1) and not rec.rescaled.any()


def test_pulse_divided_readings_synthetic():
    """Readings at half the rebuilt speed are found and kept; zeros, partial counts and a
    channel at a fraction that is not 1/n are not."""
    rng = np.random.default_rng(7)
    n = 2000
    rebuilt = 19500.0 + 800.0 * rng.standard_normal(n)
    kind = rng.choice(3, size=n, p=[0.6, 0.3, 0.1])  # half, zero, partial count
    reading = np.where(kind == 0, rebuilt / 2 * (1 + 0.01 * rng.standard_normal(n)),
                       np.where(kind == 1, 0.0, rebuilt / 3.3))
    everywhere = np.ones(n, dtype=bool)
    div = pulse_divided_readings(reading, rebuilt, everywhere)
    assert div.divisor == 2 and div.ratio == pytest.approx(0.5, abs=0.01)
    np.testing.assert_array_equal(div.keep, kind == 0)
    only_some = everywhere.copy()
    only_some[: n // 2] = False
    assert not pulse_divided_readings(reading, rebuilt, only_some).keep[: n // 2].any()
    for scale in (0.8, 0.44):  # 0.8: no whole divisor; 0.44: 1/2 too far from the median
        off = pulse_divided_readings(rebuilt * scale, rebuilt, everywhere)
        assert off.divisor == 1 and not off.keep.any()


@pytest.mark.parametrize("name", ["jana20", "jana27"])
def test_faulty_motor_1_counts_every_other_pulse(name):
    """jana20-29's M1 reads about half its partner where it does not read 0: doubled, it
    agrees with the PWM rebuild (which never sees the reading), so those readings are
    kept as measurements and only the rest is rebuilt."""
    fl = flight(name)
    rec = reconstruct_rpm(fl.log, fl.pwm, report(name))
    assert rec.divisor == (2, 1, 1, 1)
    kept = rec.rescaled[:, 0]
    air = report(name).airborne
    assert kept.sum() > 0.4 * air.sum()
    assert not (rec.replaced[:, 0] & kept).any()
    assert (rec.replaced[:, 0] | kept)[air].all()
    np.testing.assert_array_equal(rec.rpm[kept, 0], 2.0 * fl.log.rpm[kept, 0])
    without = reconstruct_rpm(fl.log, fl.pwm, report(name), rescue=False)
    assert np.median(rec.rpm[kept, 0] / without.rpm[kept, 0]) == pytest.approx(1.0, abs=0.02)
    assert any("counts one pulse in 2" in note for note in rec.notes)


@pytest.mark.parametrize("name", ["jana20", "jana25"])
def test_repair_restores_hover_thrust(name):
    """The naive mass from the faulty rpm is 20 % low; the repaired one agrees with the
    clean flights (and with the 34.7 g on the scale within the kf uncertainty)."""
    fl = flight(name)
    naive = hover_mass(fl.log, fl.log.rpm)
    repaired = repair_log(fl.log, fl.pwm, report(name))
    fixed = hover_mass(repaired, repaired.rpm)
    clean = np.mean([hover_mass(flight(c).log, flight(c).log.rpm) for c in ("jana02", "jana10")])
    assert naive < 0.88 * CRAZYFLIE21.mass
    assert fixed == pytest.approx(clean, rel=0.05)
    assert fixed == pytest.approx(CRAZYFLIE21.mass, rel=0.10)
    assert repaired.vbat is None
    assert np.isfinite(repaired.rpm).all()
    assert any("rebuilt from PWM" in note for note in repaired.meta.notes)
    assert any("battery" in note for note in repaired.meta.notes)


def test_repair_without_pwm_keeps_readings_and_says_so():
    fl = flight("jana29")
    repaired = repair_log(fl.log)
    np.testing.assert_array_equal(repaired.rpm, fl.log.rpm)
    assert any("no PWM" in note for note in repaired.meta.notes)
