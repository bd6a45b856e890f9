"""Every verdict rule (``pinquad.identification.verdict``, the one module that turns evidence
into verdict words) fed one ``VerdictEvidence`` just inside and just outside each of its
thresholds: the vehicle estimate's (``judge``: range share, torque share, torque excitation,
innovations, sampled-input shift, collapsed error, edge of the search, convergence,
model-free mass balance, reference, plausibility, missing error), the known-mass route's
single numbers (``judge_estimate``: relative error, explained share, band halves, the fit not
determining the number, positivity, the vehicle verdict it is part of) and the batch's
between-flight scaling (``scaled_error_verdicts``). Any rule whose comparison, threshold or
word changes flips one of these. Hand-built numbers only: no fit, well under a second."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pinquad.core.params import VehicleRange
from pinquad.identification.edges import COLLAPSE_RATIO, TRIANGLE_RTOL, collapsed_errors
from pinquad.identification.reference import Z_REFERENCE, ReferenceValues
from pinquad.identification.verdict import (
    DEFAULT_THRESHOLDS,
    IMPLAUSIBLE,
    NOT_ADEQUATE,
    NOT_IDENTIFIABLE,
    NOT_JUDGED,
    TRUSTED,
    BandHalves,
    ExplainedShare,
    VerdictEvidence,
    judge,
    judge_estimate,
    scaled_error_verdicts,
)

TH = DEFAULT_THRESHOLDS
M = 0.030
J = np.array([16e-6, 16e-6, 30e-6])
RANGE = VehicleRange((0.015, 0.060), J / 4.0, J * 4.0, "a hand-built range")
SE = np.r_[0.002 * M, 0.01 * J]          # small: every range share far under its limit
GOOD = VerdictEvidence(np.full(3, 0.9), "all frequencies",
                       {"pos": 1.0, "vel": 1.0, "euler": 1.0, "gyro": 1.0},
                       torque_excitation=np.full(3, 10.0), excitation_band="0-50 Hz")
NAMES = ("mass", "I_xx", "I_yy", "I_zz")
UP, DOWN = 1.0 + 1e-6, 1.0 - 1e-6        # just past / just inside a limit


def words(evidence=GOOD, mass=M, inertia=J, stderr=SE, vrange=RANGE, **kw) -> dict[str, str]:
    v = judge(mass, np.diag(inertia), stderr, evidence, vrange, **kw)
    assert v.overall == max((p.verdict for p in v.parameters),
                            key=(TRUSTED, NOT_JUDGED, IMPLAUSIBLE, NOT_ADEQUATE,
                                 NOT_IDENTIFIABLE).index)
    return {p.name: p.verdict for p in v.parameters}


ALL_TRUSTED = dict.fromkeys(NAMES, TRUSTED)


def test_the_baseline_is_trusted():
    assert words() == ALL_TRUSTED


@pytest.mark.parametrize("index", range(4))
def test_range_share_limit(index):
    """4 se / (hi - lo) <= max_range_share: at the limit trusted, past it not identifiable."""
    width = (RANGE.mass[1] - RANGE.mass[0] if index == 0
             else RANGE.inertia_hi[index - 1] - RANGE.inertia_lo[index - 1])
    at = TH.max_range_share * width / 4.0
    for factor, word in ((DOWN, TRUSTED), (UP, NOT_IDENTIFIABLE)):
        se = SE.copy()
        se[index] = at * factor
        assert words(stderr=se)[NAMES[index]] == word, (index, factor)


def test_torque_share_limit():
    for share, word in ((TH.min_torque_share, TRUSTED), (TH.min_torque_share * DOWN,
                                                          NOT_IDENTIFIABLE)):
        ev = replace(GOOD, torque_share=np.array([share, 0.9, 0.9]))
        assert words(ev) == {**ALL_TRUSTED, "I_xx": word}


def test_torque_excitation_limit():
    for ratio, word in ((TH.min_torque_excitation, TRUSTED),
                        (TH.min_torque_excitation * DOWN, NOT_IDENTIFIABLE)):
        ev = replace(GOOD, torque_excitation=np.array([10.0, 10.0, ratio]))
        assert words(ev) == {**ALL_TRUSTED, "I_zz": word}


@pytest.mark.parametrize("channel, rests_on", [("vel", ("mass",)),
                                               ("gyro", ("I_xx", "I_yy", "I_zz"))])
def test_innovation_limit(channel, rests_on):
    for nis, word in ((TH.max_nis_ratio, TRUSTED), (TH.max_nis_ratio * UP, NOT_ADEQUATE)):
        ev = replace(GOOD, nis_ratio={**GOOD.nis_ratio, channel: nis})
        assert words(ev) == {**ALL_TRUSTED, **dict.fromkeys(rests_on, word)}


def test_sampled_input_shift_limit():
    """The other reading of the input moves I_yy: up to max_input_shift of the value (and
    past 2 se) trusted, beyond both not identifiable; within 2 se trusted whatever the share."""
    values = np.r_[M, J]
    for shift, word in ((TH.max_input_shift * DOWN, TRUSTED), (TH.max_input_shift * UP,
                                                               NOT_IDENTIFIABLE)):
        alt = values.copy()
        alt[2] *= 1.0 + shift
        assert words(replace(GOOD, input_alternative=alt)) == {**ALL_TRUSTED, "I_yy": word}
    alt = values.copy()
    alt[2] *= 1.10
    wide = SE.copy()
    wide[2] = 0.051 * J[1]  # the 10 % shift is within 2 se
    assert words(replace(GOOD, input_alternative=alt), stderr=wide)["I_yy"] == TRUSTED


def test_collapsed_error_limit():
    """An error COLLAPSE_RATIO times another estimate's is still an error; below, it has
    collapsed and the parameter is not identifiable."""
    values = np.r_[M, J]
    jack = SE.copy()
    for factor, word in ((1.0, TRUSTED), (DOWN, NOT_IDENTIFIABLE)):
        info = SE.copy()
        info[3] = COLLAPSE_RATIO * jack[3] * factor
        failures = collapsed_errors(values, {"observed information": info,
                                             "block jackknife": jack})
        assert words(replace(GOOD, error_failures=failures)) == {**ALL_TRUSTED, "I_zz": word}


def test_fit_findings_are_not_identifiable():
    assert words(replace(GOOD, at_bound=("mass",), bound_source="a test range")) == {
        **ALL_TRUSTED, "mass": NOT_IDENTIFIABLE}
    assert words(replace(GOOD, not_converged="EM stopped early")) == dict.fromkeys(
        NAMES, NOT_IDENTIFIABLE)


def test_model_free_balance_limit():
    """|m - m_bal| <= 2 combined se: trusted; past it the mass is not adequate."""
    se_bal = 0.001
    combined = float(np.hypot(SE[0], se_bal))
    for factor, word in ((DOWN, TRUSTED), (UP, NOT_ADEQUATE)):
        ev = replace(GOOD, model_free_mass=(M + 2.0 * combined * factor, se_bal))
        assert words(ev) == {**ALL_TRUSTED, "mass": word}


def test_reference_limit():
    """Within Z_REFERENCE combined se of the vehicle's reference: trusted; beyond, not
    adequate; a mass beyond it makes every inertia not adequate too."""
    ref_se = np.r_[0.0005, 0.5e-6, 0.5e-6, 0.5e-6]
    for index in (0, 3):
        combined = float(np.hypot(SE[index], ref_se[index]))
        for factor, word in ((DOWN, TRUSTED), (UP, NOT_ADEQUATE)):
            ref = np.r_[M, J]
            ref[index] += Z_REFERENCE * combined * factor
            got = words(replace(GOOD, reference=ReferenceValues(ref, ref_se, "a test file")))
            moved = ("mass", *NAMES[1:]) if index == 0 else (NAMES[index],)
            assert got == {**ALL_TRUSTED, **dict.fromkeys(moved, word)}, (index, factor)


def test_plausibility_limits():
    """Inside the vehicle's range: trusted; outside it, or breaking the triangle
    inequality, or not positive: implausible."""
    for factor, word in ((DOWN, TRUSTED), (UP, IMPLAUSIBLE)):
        assert words(mass=RANGE.mass[1] * factor)["mass"] == word
        inertia = J.copy()  # the lower edge of I_zz (7.5 against 16, 16: no triangle broken)
        inertia[2] = RANGE.inertia_lo[2] / factor
        assert words(inertia=inertia, stderr=np.r_[SE[0], 0.01 * inertia])["I_zz"] == word
    # I_1 + I_2 >= I_3 with 16 + 16 = 32: inside, on the face EM's set ends at (held
    # there, not fitted: not identifiable), beyond it (implausible)
    for izz, word in ((32e-6 * (1 - 2 * TRIANGLE_RTOL), TRUSTED), (32e-6, NOT_IDENTIFIABLE),
                      (32e-6 * (1 + 2 * TRIANGLE_RTOL), IMPLAUSIBLE)):
        assert words(inertia=np.r_[J[:2], izz])["I_zz"] == word
    assert words(mass=-M)["mass"] == IMPLAUSIBLE


def test_missing_error_is_not_judged_unless_asked_for():
    se = SE.copy()
    se[1] = np.nan
    assert words(stderr=se)["I_xx"] == NOT_JUDGED
    assert words(stderr=se, missing_stderr="the information was singular")["I_xx"] == \
        NOT_IDENTIFIABLE


# ----------------------------------------------------------- the known-mass route's numbers

def one(name="I_xx", value=2.0e-3, rel=0.05, evidence=None, **kw):
    return judge_estimate(name, value, "kg m^2", {"statistical": rel * value}, evidence,
                          **kw)


def test_relative_error_limit():
    assert one(rel=TH.max_rel_se * DOWN).verdict == TRUSTED
    past = one(rel=TH.max_rel_se * UP)
    assert past.verdict == NOT_IDENTIFIABLE and "trusted at most 10 %" in past.reasons[0]
    # the parts combine in quadrature: 0.08 and 0.06 make 0.10
    assert judge_estimate("s", 1.0, "-", {"a": 0.08, "b": 0.06 * DOWN}).verdict == TRUSTED
    assert judge_estimate("s", 1.0, "-", {"a": 0.08, "b": 0.06 * UP}).verdict == \
        NOT_IDENTIFIABLE


def test_explained_share_limit():
    for share, word in ((TH.min_fit_share, TRUSTED), (TH.min_fit_share * DOWN, NOT_ADEQUATE)):
        ev = VerdictEvidence(explained=(ExplainedShare(("thrust c_2",), "the curve explains",
                                                       "the vertical force", share),))
        assert one("thrust c_2", 0.1, evidence=ev).verdict == word
        assert one("I_xx", evidence=ev).verdict == TRUSTED  # not a number resting on it


def test_band_halves_limit():
    for factor, word in ((DOWN, TRUSTED), (UP, NOT_ADEQUATE)):
        shift = TH.max_band_shift * np.hypot(3e-5, 4e-5) * factor
        ev = VerdictEvidence(band_halves=(BandHalves("I_xx", (2.0e-3, 3e-5),
                                                     (2.0e-3 + shift, 4e-5), (0.3, 0.77, 2.0)),))
        assert one(evidence=ev).verdict == word
        assert one("I_yy", evidence=ev).verdict == TRUSTED


def test_known_mass_fit_findings_and_plausibility():
    assert one(evidence=VerdictEvidence(undetermined=(("I_xx", "no lag resolvable"),))
               ).verdict == NOT_IDENTIFIABLE
    assert one(evidence=VerdictEvidence(not_converged="EM did not converge")).verdict == \
        NOT_IDENTIFIABLE
    assert one(value=-2.0e-3).verdict == IMPLAUSIBLE
    assert one("thrust c_1", value=-0.5).verdict == TRUSTED  # a curve term may be negative
    nothing = judge_estimate("I_zz", float("nan"), "kg m^2", {})
    assert nothing.verdict == NOT_IDENTIFIABLE and np.isnan(nothing.stderr)


def test_known_mass_takes_the_vehicle_verdict_it_is_part_of():
    house = judge(M, np.diag(J), SE, replace(GOOD, nis_ratio={**GOOD.nis_ratio, "gyro": 9.0}),
                  RANGE)
    got = one(part_of=house)
    assert got.verdict == NOT_ADEQUATE and got.reasons == house.get("I_xx").reasons
    assert one(part_of=judge(M, np.diag(J), SE, GOOD, RANGE)).verdict == TRUSTED
    # the most severe finding wins, every reason kept in order
    both = one(rel=0.2, part_of=house)
    assert both.verdict == NOT_IDENTIFIABLE and len(both.reasons) == 2


def test_between_flight_scaling_only_lowers():
    """A trusted parameter whose scaled error now covers more than max_range_share of the
    range is not identifiable (and a trusted overall verdict with it); at the limit, or
    not scaled up, nothing changes."""
    at = TH.max_range_share * (RANGE.inertia_hi[0] - RANGE.inertia_lo[0]) / 4.0
    totals = SE.copy()
    for factor, word, overall in ((DOWN, TRUSTED, TRUSTED), (UP, NOT_IDENTIFIABLE,
                                                               NOT_IDENTIFIABLE)):
        totals[1] = at * factor
        got, top = scaled_error_verdicts(ALL_TRUSTED, TRUSTED, totals, np.r_[1, 2, 1, 1.0],
                                         RANGE)
        assert got == {**ALL_TRUSTED, "I_xx": word} and top == overall
    got, top = scaled_error_verdicts(ALL_TRUSTED, TRUSTED, totals, np.ones(4), RANGE)
    assert got == ALL_TRUSTED and top == TRUSTED
    low = {**ALL_TRUSTED, "mass": NOT_ADEQUATE}
    got, top = scaled_error_verdicts(low, NOT_ADEQUATE, totals, np.full(4, 2.0), RANGE)
    assert got == {**low, "I_xx": NOT_IDENTIFIABLE} and top == NOT_ADEQUATE
