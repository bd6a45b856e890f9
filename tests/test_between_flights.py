"""Flights of one vehicle against each other (``pinquad.realdata.consistency``): the
scatter's chi-square and scale factor, and a verdict that turns when the flights'
statistical errors do not cover their scatter."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinquad.identification.identify import Identification
from pinquad.identification.measured import MeasuredFit
from pinquad.identification.verdict import (
    NOT_IDENTIFIABLE,
    TRUSTED,
    VerdictEvidence,
    judge,
    vehicle_range,
)
from pinquad.realdata.consistency import FlightRow, between_flights, flight_scatter, scaled_total


def test_scatter_of_known_values():
    """Three unit-error values 1, 2, 3: mean 2, chi2 2 on 2 dof, p = exp(-1), S = 1. Two
    values 0 and 10 with unit errors: chi2 50 on 1 dof, S = sqrt(50)."""
    sc = flight_scatter("mass", "g", ["a", "b", "c"], np.array([1.0, 2.0, 3.0]), np.ones(3))
    assert sc.mean == pytest.approx(2.0) and sc.chi2 == pytest.approx(2.0) and sc.dof == 2
    assert sc.p_value == pytest.approx(math.exp(-1.0)) and sc.scale == 1.0
    far = flight_scatter("I_zz", "g", ["a", "b"], np.array([0.0, 10.0]), np.ones(2))
    assert far.chi2 == pytest.approx(50.0) and far.scale == pytest.approx(math.sqrt(50.0))
    assert scaled_total(5.0, 3.0, 2.0) == pytest.approx(math.sqrt(25.0 + 3.0 * 9.0))
    with pytest.raises(ValueError, match="two or more"):
        flight_scatter("mass", "g", ["a"], np.array([1.0]), np.array([1.0]))


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(st.floats(-5.0, 5.0), st.floats(0.05, 3.0)), min_size=2, max_size=8))
def test_scaled_errors_cover_the_scatter(pairs):
    """S >= 1, and with every error scaled by S the chi-square is at most its dof (equal
    to it when S > 1): the scaled errors account for the scatter, and no more."""
    x = np.array([p[0] for p in pairs])
    s = np.array([p[1] for p in pairs])
    sc = flight_scatter("I_xx", "g", [str(i) for i in range(x.size)], x, s)
    assert sc.scale >= 1.0
    again = flight_scatter("I_xx", "g", sc.logs, x, sc.scale * s)
    assert again.chi2 <= sc.dof * (1.0 + 1e-9)
    if sc.scale > 1.0:
        assert again.chi2 == pytest.approx(sc.dof, rel=1e-9)


def _flight(name: str, izz: float, izz_stat: float) -> FlightRow:
    """A flight of the Crazyflie whose mass and roll/pitch agree with every other and
    whose I_zz is ``izz`` +- ``izz_stat`` (statistical), judged as the table judges it
    (kf 4.8 %, the yaw ratio 8.3 %: common to every flight)."""
    params = np.array([0.0347, 16.6e-6, 16.7e-6, izz])
    stat = np.array([0.00005, 0.5e-6, 0.5e-6, izz_stat])
    common = params * np.array([0.048, 0.048, 0.048, math.hypot(0.048, 0.083)])
    total = np.hypot(stat, common)
    evidence = VerdictEvidence(torque_share=np.array([0.8, 0.8, 0.5]))
    verdict = judge(params[0], np.diag(params[1:]), total, evidence,
                    vehicle_range("crazyflie21"))
    fit = MeasuredFit(kf=None, se_info=stat, se_jack=stat, se_stat=stat,  # type: ignore[arg-type]
                      moment_coef=np.zeros((3, 7)), n_used=1000, n_excluded=0, excluded=())
    run = Identification(
        mstep="regressor", mass=params[0], inertia=np.diag(params[1:]), stderr=total,
        history_mass=np.zeros(1), history_inertia=np.zeros((1, 3)), loglik=np.zeros(50),
        converged=True, seconds=1.0, e_steps=50, measured=fit, verdict=verdict)
    return FlightRow(name, run, evidence=evidence)


def test_i_zz_that_scatters_beyond_its_errors_is_judged_again():
    """The four trusted I_zz of the measured yaw and figure-8 flights (stop 27's table,
    e-6 kg m^2): 26.9 +- 0.8, 15.8 +- 2.0, 13.2 +- 1.3, 17.7 +- 0.6 (statistical), each
    "trusted" alone. Against each other chi2 is ~121 on 3 dof: S ~6.3; the two whose
    scaled errors then cover more than a quarter of the Crazyflie's I_zz range are not
    identifiable, the other two stay trusted and now agree with each other within their
    errors; mass, I_xx and I_yy, which agree, keep their errors and verdicts."""
    flights = [_flight("a", 26.9e-6, 0.8e-6), _flight("b", 15.8e-6, 2.0e-6),
               _flight("c", 13.2e-6, 1.3e-6), _flight("d", 17.7e-6, 0.6e-6)]
    assert all(f.run.verdict.get("I_zz").verdict == TRUSTED for f in flights)
    judged, scatters = between_flights(flights)
    izz = next(s for s in scatters if s.parameter == "I_zz")
    assert izz.chi2 == pytest.approx(120.7, abs=0.5) and izz.scale == pytest.approx(6.34, abs=0.02)
    assert izz.p_value < 1e-20
    verdicts = {f.name: f.run.verdict.get("I_zz").verdict for f in judged}
    assert verdicts == {"a": TRUSTED, "b": NOT_IDENTIFIABLE, "c": NOT_IDENTIFIABLE, "d": TRUSTED}
    kept = [f for f in judged if verdicts[f.name] == TRUSTED]
    gap = abs(kept[0].params[3] - kept[1].params[3])
    assert gap < 2.0 * math.hypot(kept[0].run.stderr[3], kept[1].run.stderr[3])
    for before, after in zip(flights, judged, strict=True):
        np.testing.assert_array_equal(after.run.stderr[0:3], before.run.stderr[0:3])
        assert after.run.verdict.get("mass").verdict == TRUSTED
        assert after.scatter_scale[3] == pytest.approx(izz.scale)
    assert all(s.scale == 1.0 for s in scatters if s.parameter != "I_zz")


def test_a_degenerate_statistical_error_is_compared_by_its_total():
    """A jackknife pinned on the consistency boundary prints ~1e-20 kg m^2: such a flight
    (and one without a statistical error) is compared with its total error, so one flight
    cannot make chi2 ~1e20 (the batch of the 14 real logs without the information did)."""
    from pinquad.realdata.consistency import comparable_error

    assert comparable_error(15.4e-6, 1.0e-20, 1.1e-6) == 1.1e-6
    assert comparable_error(15.4e-6, float("nan"), 1.1e-6) == 1.1e-6
    assert comparable_error(15.4e-6, 0.3e-6, 1.1e-6) == 0.3e-6
    flights = [_flight("a", 17.7e-6, 0.6e-6), _flight("b", 18.5e-6, 1e-20)]
    _, scatters = between_flights(flights)
    izz = next(s for s in scatters if s.parameter == "I_zz")
    assert izz.stderr[1] == flights[1].run.stderr[3] and izz.chi2 < 1.0
