"""The plausible range's lower bound and the gyro's sign, each checked on hand-built
inputs whose answer is known: a vehicle lighter or smaller than its range allows is
"implausible" and EM's search stops at the lower edge; a log whose gyro turns the other
way from its attitude is rejected. (scripts/mutation_check.py removes each and shows
these tests fail.)"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinquad.core.conventions import euler_from_rotation
from pinquad.core.params import CRAZYFLIE21
from pinquad.identification.em import project
from pinquad.identification.search_range import GYRATION_RADIUS, MASS_SPAN, generic_range
from pinquad.identification.verdict import (
    DEFAULT_THRESHOLDS,
    IMPLAUSIBLE,
    TRUSTED,
    VerdictEvidence,
    judge,
    vehicle_range,
)
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.sanity import ImplausibleLogError, check_log, gyro_ratio
from pinquad.models.ssm import NoiseModel, Theta

M, J = CRAZYFLIE21.mass, np.diag(CRAZYFLIE21.inertia).copy()
GOOD = VerdictEvidence(np.full(3, 0.9), "all frequencies", {"pos": 1.0, "euler": 1.0, "gyro": 1.0})
SMALL_SE = np.r_[0.01 * M, 0.02 * J]


def test_the_vehicle_range_has_its_lower_bound():
    """crazyflie21: mass M / 2 .. 2 M, inertia J / 4 .. 4 J (the verdict's factors)."""
    cf = vehicle_range("crazyflie21")
    fm, fi = DEFAULT_THRESHOLDS.mass_factor, DEFAULT_THRESHOLDS.inertia_factor
    assert cf.mass == pytest.approx((M / fm, M * fm), rel=1e-12)
    np.testing.assert_allclose(cf.inertia_lo, J / fi, rtol=1e-12)
    np.testing.assert_allclose(cf.inertia_hi, J * fi, rtol=1e-12)


def test_an_estimate_below_the_range_is_implausible():
    """A third of the mass (below M / 2) and a sixth of the inertia (below J / 4, the
    tensor still a rigid body's) with tiny error bars: implausible, said why; inside the
    range at M / 1.5 and J / 3: trusted."""
    cf = vehicle_range("crazyflie21")
    light = judge(M / 3, np.diag(J), SMALL_SE, GOOD, cf).get("mass")
    assert light.verdict == IMPLAUSIBLE
    assert any("outside the vehicle's" in r for r in light.reasons)
    small = judge(M, np.diag(J / 6), np.r_[SMALL_SE[0], SMALL_SE[1:] / 6], GOOD, cf)
    for name in ("I_xx", "I_yy", "I_zz"):
        assert small.get(name).verdict == IMPLAUSIBLE, small.get(name)
        assert any("outside the vehicle's" in r for r in small.get(name).reasons)
    inside = judge(M / 1.5, np.diag(J / 3), np.r_[SMALL_SE[0], SMALL_SE[1:] / 3], GOOD, cf)
    assert inside.overall == TRUSTED, inside.reasons


def test_em_projection_stops_at_the_lower_edge():
    """EM's projection (``em.project``) lifts a mass and inertia below the range to its
    lower edge, for a named vehicle's range and for the generic one of a hover mass."""
    for box in (vehicle_range("crazyflie21"), generic_range(0.5)):
        theta = Theta(mass=0.01 * box.mass[0], inertia=np.diag(0.01 * box.inertia_lo),
                      noise=NoiseModel(np.full(6, 1e-6), np.full(6, 1e-8), np.full(6, 1e-4)))
        lifted = project(theta, box)
        assert lifted.mass == box.mass[0] > 0
        np.testing.assert_array_equal(np.diag(lifted.inertia), box.inertia_lo)
        assert np.all(box.inertia_lo > 0)


def test_the_generic_range_has_its_lower_bound():
    """Hover mass 0.5 kg: mass 0.5 / 3 .. 1.5 kg, I_ii from (0.5 / 3) (5 mm)^2."""
    box = generic_range(0.5)
    assert box.mass == pytest.approx((0.5 / MASS_SPAN, 0.5 * MASS_SPAN), rel=1e-12)
    np.testing.assert_allclose(box.inertia_lo, 0.5 / MASS_SPAN * GYRATION_RADIUS[0] ** 2,
                               rtol=1e-12)


def _turning_log(gyro_sign: float) -> FlightLog:
    """10 s at 100 Hz of a body turning at known rates omega(t) [rad/s] about all three
    axes, its attitude the exact integral of omega (rotation by omega dt per step), and
    its gyro gyro_sign * omega; no position, velocity, accelerometer or actuation."""
    t = np.arange(0.0, 10.0, 0.01)
    omega = np.column_stack([1.5 * np.sin(2 * np.pi * 0.5 * t),
                             1.0 * np.sin(2 * np.pi * 0.3 * t + 1.0),
                             2.0 * np.cos(2 * np.pi * 0.2 * t)])
    rot = [Rotation.identity()]
    for w in omega[:-1]:
        rot.append(rot[-1] * Rotation.from_rotvec(w * 0.01))
    euler = euler_from_rotation(np.stack([r.as_matrix() for r in rot]))
    nan3 = np.full((t.size, 3), np.nan)
    return FlightLog(t=t, position=nan3, velocity=nan3, euler=euler, gyro=gyro_sign * omega,
                     accel=nan3, meta=LogMeta(source=f"turning (gyro x {gyro_sign:+g})"))


def test_a_gyro_of_the_wrong_sign_is_rejected():
    """The gyro turns as far as the attitude (ratio 1) when its sign is right, and -1
    when it is negated: that log is rejected with the gyro named; the right one passes."""
    right, flipped = _turning_log(1.0), _turning_log(-1.0)
    assert gyro_ratio(right) == pytest.approx(1.0, abs=0.05)
    assert gyro_ratio(flipped) == pytest.approx(-1.0, abs=0.05)
    check_log(right)
    with pytest.raises(ImplausibleLogError, match="gyro") as err:
        check_log(flipped)
    assert "flipped" in str(err.value) or "negated" in str(err.value)
