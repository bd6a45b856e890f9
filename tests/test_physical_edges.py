"""No trusted number at a physical bound: an inertia on a face of the triangle
inequalities, or an error estimate that collapsed, is not a fit (identification.edges),
whatever the pre-fit checks said: the verdict is called directly here."""

from __future__ import annotations

import numpy as np
import pytest

from pinquad.identification.edges import collapsed_errors, triangle_face
from pinquad.identification.identify import Identification
from pinquad.identification.measured import MeasuredFit
from pinquad.identification.verdict import NOT_IDENTIFIABLE, TRUSTED, VerdictEvidence, judge
from pinquad.mstep.band import profiled_inertia
from pinquad.pipeline.judge import error_failures

# The flipped-yaw-spin fit of a Crazyflie 2.1 flight: I_zz at I_xx + I_yy, 2-3x the
# vehicle's inertia, with the small errors the collapsed jackknife left [kg, kg m^2]
FLIPPED = np.diag([74.2e-6, 73.5e-6, 147.7e-6])
SMALL = np.r_[0.0017, 4.4e-6, 4.4e-6, 0.9e-6]
NAMES = ("I_xx", "I_yy", "I_zz")


def test_an_inertia_on_the_triangle_face_is_not_trusted():
    """74.2 + 73.5 = 147.7 e-6 kg m^2: the face itself. Every moment it ties is 'not
    identifiable' with the face named; the mass, which it does not tie, stays trusted."""
    verdict = judge(0.0347, FLIPPED, SMALL, VerdictEvidence(), None)
    assert verdict.get("mass").verdict == TRUSTED
    for name in NAMES:
        p = verdict.get(name)
        assert p.verdict == NOT_IDENTIFIABLE
        assert any("triangle inequality (I_zz = I_xx + I_yy" in r for r in p.reasons)
    # the same numbers 0.5 % inside the face (I_zz 146.96 e-6): a fit, trusted
    inside = FLIPPED.copy()
    inside[2, 2] = 147.7e-6 * 0.995
    assert judge(0.0347, inside, SMALL, VerdictEvidence(), None).trusted


@pytest.mark.parametrize("gap, on_face", [(0.0, True), (0.9e-3, True), (1.1e-3, False),
                                          (0.05, False), (-0.9e-3, True), (-0.05, False)])
def test_the_face_tolerance_is_a_tenth_of_a_percent_of_the_largest_moment(gap, on_face):
    """I_xx = I_yy + I_zz - gap I_xx, the face on another axis: within 0.1 % of I_xx
    it is on the face, inside not, and beyond (a broken triangle) not either: that is
    implausible, a check of its own."""
    i_yy, i_zz = 20e-6, 30e-6
    i_xx = (i_yy + i_zz) / (1.0 + gap)  # I_yy + I_zz - I_xx = gap I_xx
    face = triangle_face(np.diag([i_xx, i_yy, i_zz]))
    assert (face is not None) == on_face
    if on_face:
        assert "I_xx = I_yy + I_zz" in face


def test_a_full_tensor_on_the_face_is_named_by_its_principal_moments():
    """A tensor rotated 30 degrees about z with principal moments 10, 20, 30 e-6 (on the
    face 30 = 10 + 20): its diagonal entries alone do not show it."""
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    tensor = rot @ np.diag([10e-6, 20e-6, 30e-6]) @ rot.T
    face = triangle_face(tensor)
    assert face is not None and "largest principal moment" in face
    assert triangle_face(rot @ np.diag([10e-6, 20e-6, 29e-6]) @ rot.T) is None


def _rows(rng: np.random.Generator, inertia: np.ndarray, n: int = 600
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Torque rows tau_j = x_j I + noise of a vehicle whose rows say ``inertia`` (3,),
    the yaw row 100x less noisy than roll and pitch (the yaw rows hold the fit), as the
    band M-step's quadratic sums: a (3, 3, 3), b (3, 3), c (3,), after the per-sample
    regressors (n, 3, 3) and torques (n, 3) that blocks are left out of."""
    x = np.zeros((n, 3, 3))
    for j in range(3):
        x[:, j, j] = rng.normal(0.0, 50.0, n)  # angular acceleration about axis j
        x[:, j, (j + 1) % 3] = rng.normal(0.0, 5.0, n)  # a small gyroscopic coupling
    noise = rng.normal(0.0, 1.0, (n, 3)) * np.array([2e-4, 2e-4, 2e-6])
    tau = np.einsum("njp,p->nj", x, inertia) + noise
    return x, tau, *_sums(x, tau)


def _sums(x: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = np.einsum("njp,njq->jpq", x, x)
    b = np.einsum("njp,nj->jp", x, tau)
    c = np.einsum("nj,nj->j", tau, tau)
    return a, b, c


def _jackknife(x: np.ndarray, tau: np.ndarray, fit: np.ndarray) -> np.ndarray:
    """Delete-one-block jackknife (10 contiguous blocks) of the band M-step's inertia,
    each block refitted from ``fit``, as ``BandMStep.jackknife`` does."""
    est = []
    for blk in np.array_split(np.arange(x.shape[0]), 10):
        keep = np.ones(x.shape[0], dtype=bool)
        keep[blk] = False
        est.append(profiled_inertia(*_sums(x[keep], tau[keep]), fit)[0])
    est = np.asarray(est)
    return np.sqrt(0.9 * ((est - est.mean(axis=0)) ** 2).sum(axis=0))


def test_the_m_step_stops_on_the_face_and_its_jackknife_collapses():
    """Torque rows that say I_zz = 60 e-6 with I_xx, I_yy = 16, 17 (a yaw torque of the
    wrong sign reads that way): the band M-step's physically consistent minimiser ends
    on I_zz = I_xx + I_yy. Each jackknife block, refitted from there, stays there (the
    likelihood pulls every block past the face alike): a standard error of 0.
    Both are caught, without any check before the fit."""
    rng = np.random.default_rng(50)
    x, tau, a, b, c = _rows(rng, np.array([16e-6, 17e-6, 60e-6]))
    fit, _ = profiled_inertia(a, b, c, np.array([8e-6, 8e-6, 15e-6]))
    assert fit[2] == pytest.approx(fit[0] + fit[1], rel=1e-9)  # the M-step's own doing
    assert triangle_face(np.diag(fit)) is not None
    jack = _jackknife(x, tau, fit)
    assert np.all(jack < 1e-12 * fit)  # zero to rounding (2e-20 kg m^2)
    info = np.r_[5e-5, 0.6e-6, 0.6e-6, 0.9e-6]
    failed = dict(collapsed_errors(np.r_[0.0347, fit], {"observed information": info,
                                                        "block jackknife": np.r_[6e-5, jack]}))
    assert set(failed) == set(NAMES)
    verdict = judge(0.0347, np.diag(fit), np.r_[0.0017, info[1:]],
                    VerdictEvidence(error_failures=tuple(failed.items())), None)
    assert [verdict.get(n).verdict for n in NAMES] == [NOT_IDENTIFIABLE] * 3
    # the same rows of a physical vehicle (I_zz 30 < 33) end inside, with a real error
    x, tau, a, b, c = _rows(rng, np.array([16e-6, 17e-6, 30e-6]))
    fit, _ = profiled_inertia(a, b, c, np.array([8e-6, 8e-6, 15e-6]))
    assert triangle_face(np.diag(fit)) is None
    np.testing.assert_allclose(fit, [16e-6, 17e-6, 30e-6], rtol=0.1)
    jack = _jackknife(x, tau, fit)
    assert np.all(jack > 1e-6 * fit)  # 1.3e-8, 1.9e-7, 1.4e-9: the rows' noise
    stat = np.r_[6e-5, jack]  # a jackknife that agrees with the information
    assert collapsed_errors(np.r_[0.0347, fit], {"observed information": 0.7 * stat,
                                                 "block jackknife": stat}) == ()


def test_an_error_estimate_that_collapsed_is_a_failure_not_a_small_error():
    """By hand: the jackknife's 0 and one 1000x below the information collapsed; 0.6x
    and 50x below agree well enough (two estimates of one error scatter by a few)."""
    values = np.r_[0.0347, 74e-6, 73e-6, 147e-6]
    info = np.r_[5e-5, 0.6e-6, 0.5e-6, 0.9e-6]
    failed = dict(collapsed_errors(values, {"observed information": info,
                                            "block jackknife": np.r_[3e-5, 0.0, 0.5e-9, 0.018e-6]}))
    assert set(failed) == {"I_xx", "I_yy"}
    assert "collapsed to 0 e-6 kg m^2" in failed["I_xx"] and "block jackknife" in failed["I_xx"]
    assert "1e+03 x less than the observed information's 0.5" in failed["I_yy"]
    assert collapsed_errors(values, {"observed information": info,
                                     "block jackknife": 0.6 * info}) == ()
    # an information whose error is 0 with nothing to compare it with
    assert dict(collapsed_errors(values, {"observed information": np.r_[info[:3], 0.0]})
                ).keys() == {"I_zz"}
    # the judge turns each into 'not identifiable', naming the failure
    ev = VerdictEvidence(error_failures=(("I_xx", failed["I_xx"]),))
    inertia = np.diag([17e-6, 17e-6, 30e-6])
    stderr = np.r_[0.0017, 1.4e-6, 1.6e-6, 6e-6]
    verdict = judge(0.0347, inertia, stderr, ev, None)
    assert verdict.get("I_xx").verdict == NOT_IDENTIFIABLE
    assert "collapsed to 0" in verdict.get("I_xx").reasons[0]
    assert judge(0.0347, inertia, stderr, VerdictEvidence(), None).trusted


def test_a_measured_flight_with_a_zero_jackknife_gives_its_failures_to_the_verdict():
    """The headline reads a measured fit's two error estimates (its jackknife of 0 for
    the three moments, as the flipped-yaw fits gave) into the verdict's evidence."""
    fit = MeasuredFit(kf=None, se_info=np.r_[4.4e-5, 0.5e-6, 0.6e-6, 0.9e-6],
                      se_jack=np.r_[8e-5, 0.0, 0.0, 0.0],
                      se_stat=np.r_[8e-5, 0.5e-6, 0.6e-6, 0.9e-6],
                      moment_coef=np.zeros((3, 7)), n_used=900, n_excluded=0, excluded=())
    run = Identification(mstep="regressor", mass=0.0347, inertia=FLIPPED, stderr=SMALL,
                         history_mass=np.zeros(1), history_inertia=np.zeros((1, 3)),
                         loglik=np.zeros(1), converged=True, measured=fit)
    assert {n for n, _ in error_failures(run)} == set(NAMES)
    fine = Identification(mstep="regressor", mass=0.0347, inertia=FLIPPED, stderr=SMALL,
                          history_mass=np.zeros(1), history_inertia=np.zeros((1, 3)),
                          loglik=np.zeros(1), converged=True,
                          measured=MeasuredFit(None, fit.se_info, 0.8 * fit.se_info,
                                               fit.se_info, np.zeros((3, 7)), 900, 0, ()))
    assert error_failures(fine) == ()
