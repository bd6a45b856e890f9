"""The compiled M-step statistics against ``identify.regressor_stats``, and the compiled
inertia Newton step against ``identify._inertia_newton``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pinquad.core.params import PAPER_VEHICLE
from pinquad.identification.em import initial_theta, run_em
from pinquad.identification.identify import get_smoother
from pinquad.models.sources import observations
from pinquad.models.ssm import QuadSSM
from pinquad.mstep import updates as identify
from pinquad.mstep.compiled import inertia_newton as fast_inertia_newton
from pinquad.mstep.compiled import measurement_variances as fast_measurement_variances
from pinquad.mstep.compiled import physical, regressor_quadratics
from pinquad.mstep.protocol import REGRESSOR
from pinquad.mstep.updates import _inertia_newton, inertia_newton, regressor_stats
from pinquad.sim.simulator import SimConfig, flight_log, simulate

TOL = 1e-11


@pytest.fixture(scope="module")
def flight():
    """One flight per sensor set, flown with it (SimConfig(sensor=...)): B's log carries
    velocity and Euler angles, C's velocity."""
    return {s: simulate(SimConfig(sensor=s), np.random.default_rng(7)) for s in "ABC"}


@pytest.mark.parametrize("continuous", [False, True])
@pytest.mark.parametrize("source", ["A", "B", "C"])
def test_quadratics_match_regressor_stats(flight, source, continuous):
    """Posterior of a few EM steps (non-trivial covariances and cross-covariances), some
    transitions excluded; every entry of a, b, c to 1e-11 of its row's scale; held and
    continuous flights (the latter's applied force along the interval's mean thrust
    direction, with its own covariance terms in b and c)."""
    obs = observations(flight_log(flight[source]).slice(0, 900), source)
    assert np.all(np.isfinite(obs.ys).mean(axis=0) >= 0.45)  # every channel sampled
    exclude = obs.exclude.copy()
    exclude[100:140] = True
    obs = replace(obs, exclude=exclude, continuous=continuous)
    theta0 = initial_theta(obs, PAPER_VEHICLE.mass * 0.9, PAPER_VEHICLE.inertia * 1.2, 9.81)
    post = run_em(obs, theta0, get_smoother("rts"), REGRESSOR, max_iterations=4).posterior
    ref = regressor_stats(post, obs, 9.81)
    fast = regressor_quadratics(post, obs, 9.81)
    assert fast.n == ref.n
    for j in range(6):
        scale = np.max(np.abs(ref.a[j]))
        np.testing.assert_allclose(fast.a[j], ref.a[j], rtol=0, atol=TOL * scale)
        np.testing.assert_allclose(fast.b[j], ref.b[j], rtol=0,
                                   atol=TOL * max(np.max(np.abs(ref.b[j])), 1e-300))
    np.testing.assert_allclose(fast.c, ref.c, rtol=TOL, atol=0)


def _torque_problems(flight):
    """(mass, a_t, b_t, c_t) of the torque rows from a few EM steps on each source, as
    the M-step hands them to the inertia Newton step."""
    out = []
    for source in "ABC":
        obs = observations(flight_log(flight[source]).slice(0, 900), source)
        theta0 = initial_theta(obs, PAPER_VEHICLE.mass * 0.9, PAPER_VEHICLE.inertia * 1.2, 9.81)
        post = run_em(obs, theta0, get_smoother("rts"), REGRESSOR, max_iterations=2).posterior
        s = regressor_stats(post, obs, 9.81)
        out.append((float(s.c[2] / s.b[2, 0]), s.a[3:6], s.b[3:6], s.c[3:6]))
    return out


def _objective_and_hessian(mass, a_t, b_t, c_t, i_diag):
    """identify._inertia_newton's J(I) = 1/2 sum_j log q_j - sum_i log I_i and its Hessian."""
    pi = np.concatenate([[mass], i_diag])
    q = np.einsum("p,apq,q->a", pi, a_t, pi) - 2.0 * b_t @ pi + c_t
    dq = (2.0 * np.einsum("apq,q->ap", a_t, pi) - 2.0 * b_t)[:, 1:4]
    hess = (np.einsum("apq,a->pq", a_t[:, 1:4, 1:4], 1.0 / q)
            - 0.5 * np.einsum("ap,aq,a->pq", dq, dq, 1.0 / q**2) + np.diag(1.0 / i_diag**2))
    return 0.5 * float(np.sum(np.log(q))) - float(np.sum(np.log(i_diag))), hess


def test_compiled_inertia_newton_matches_python(flight):
    """The compiled Newton step (same candidates, steps, line search and stopping rule)
    against identify._inertia_newton: from the truth, from far-off and from unphysical
    previous estimates, and on noise-free statistics (the least-squares solution returned
    as is). To 1e-12 relative, or to twice what the reference itself moves when its
    inputs move by 1e-15 relative, entry by entry (its stopping rule can end on a flat
    stretch of the objective: up to ~3e-9 from the truth as start); or, where the two
    stop at different points of that flat stretch, an equally good minimiser: the
    objective J at the compiled answer no larger than at the reference's by more than
    4 ulp of J, and each entry within the distance over which J changes by that much,
    sqrt(8 eps |J| / H_ii) (on an AMD EPYC the compiled code stopped 5.7e-12 relative
    from the reference with J equal to the last bit, where that distance is ~1e-7)."""
    truth = np.diag(PAPER_VEHICLE.inertia)
    starts = [truth, 1.3 * truth, 0.5 * truth, np.array([1e-4, 2e-4, 1e-4]),
              np.array([1.0, 1e-6, 1e-6]), np.array([-1.0, 1.0, 1.0])]
    problems = _torque_problems(flight)
    mass, a_t, b_t, _ = problems[0]
    pi = np.concatenate([[mass], truth])
    b_exact = np.einsum("apq,q->ap", a_t, pi)  # makes truth the exact LS solution
    c_exact = np.einsum("p,apq,q->a", pi, a_t, pi)
    problems.append((mass, a_t, b_exact, c_exact))
    rng = np.random.default_rng(11)
    wiggles = []
    for _ in range(4):
        fa = 1.0 + 1e-15 * rng.uniform(-1.0, 1.0, size=(3, 4, 4))
        wiggles.append((0.5 * (fa + np.transpose(fa, (0, 2, 1))),
                        1.0 + 1e-15 * rng.uniform(-1.0, 1.0, size=(3, 4)),
                        1.0 + 1e-15 * rng.uniform(-1.0, 1.0, size=3)))
    for mass, a_t, b_t, c_t in problems:
        for start in starts:
            ref = _inertia_newton(mass, a_t, b_t, c_t, start)
            wobble = max(np.max(np.abs(_inertia_newton(mass, a_t * fa, b_t * fb, c_t * fc, start)
                                       - ref)) for fa, fb, fc in wiggles)
            tol = 1e-12 * np.abs(ref) + 2.0 * wobble
            # the M-step's entry (updates.inertia_newton, which hands the arrays to the
            # compiled kernel) and the kernel called directly, each against the
            # independent Python reference
            for fast in (inertia_newton(mass, a_t, b_t, c_t, start),
                         fast_inertia_newton(mass, np.ascontiguousarray(a_t),
                                             np.ascontiguousarray(b_t),
                                             np.ascontiguousarray(c_t), start.astype(float),
                                             np.zeros(3), np.full(3, np.inf))):
                _assert_equally_good(fast, ref, tol, mass, a_t, b_t, c_t)
            # a box that binds: its upper edge below the unconstrained minimiser's largest
            # entry; both stay inside it and agree
            hi = np.full(3, 0.8 * np.max(ref))
            lo = np.full(3, 0.01 * np.min(ref))
            boxed = _inertia_newton(mass, a_t, b_t, c_t, start, lo, hi)
            assert np.all(boxed <= hi) and np.all(boxed >= lo)
            # a descent from the start projected onto the box; near the truth (where J is
            # convex) also no worse than the unconstrained minimiser projected onto it
            # (far-off starts end on J's flat stretch towards large inertia, as unboxed)
            j_boxed = _objective_and_hessian(mass, a_t, b_t, c_t, boxed)[0]
            near = np.all(np.abs(start / truth - 1.0) <= 0.5)
            for other in ((np.clip(start, lo, hi), np.clip(ref, lo, hi)) if near
                          else (np.clip(start, lo, hi),)):
                if physical(other):
                    assert j_boxed <= _objective_and_hessian(mass, a_t, b_t, c_t, other)[0] + 1e-12
            fast = inertia_newton(mass, a_t, b_t, c_t, start, lo, hi)
            assert np.all(fast <= hi) and np.all(fast >= lo)
            if near:
                _assert_equally_good(fast, boxed, 1e-9 * np.abs(boxed), mass, a_t, b_t, c_t)


def _assert_equally_good(fast, ref, tol, mass, a_t, b_t, c_t):
    """fast equals ref entry by entry within tol, or is an equally good minimiser (see
    test_compiled_inertia_newton_matches_python)."""
    if not np.all(np.abs(fast - ref) <= tol):
        j_ref, hess = _objective_and_hessian(mass, a_t, b_t, c_t, ref)
        j_fast, _ = _objective_and_hessian(mass, a_t, b_t, c_t, fast)
        slack = 4.0 * np.finfo(float).eps * abs(j_ref)
        flat = np.sqrt(2.0 * slack / np.diag(hess))
        assert j_fast <= j_ref + slack, (fast, ref, j_fast - j_ref)
        assert np.all(np.abs(fast - ref) <= flat), (fast, ref, flat)


def test_compiled_measurement_variances_match_numpy(flight):
    """fast_mstep.measurement_variances against identify.measurement_variances (Euler
    residuals wrapped, NaN and rejected entries skipped, a never-observed row keeping its
    previous value) to 1e-12 relative."""
    obs = observations(flight_log(flight["B"]).slice(0, 900), "B")
    assert obs.channels[2] == "euler" and np.isfinite(obs.ys[:, 6:9]).mean() >= 0.45
    ys = obs.ys.copy()
    rng = np.random.default_rng(3)
    ys[rng.random(ys.shape) < 0.05] = np.nan
    ys[:, 4] = np.nan
    ys[::7, 6:9] += 2.0 * np.pi  # residuals that need wrapping
    obs = replace(obs, ys=ys)
    theta0 = initial_theta(obs, PAPER_VEHICLE.mass, PAPER_VEHICLE.inertia, 9.81)
    post = get_smoother("rts")(QuadSSM(obs, theta0), obs.ys)
    rejected = np.zeros(ys.shape, dtype=bool)
    rejected[rng.random(ys.shape) < 0.02] = True
    post = replace(post, rejected=rejected)
    previous = np.full(ys.shape[1], 0.123)
    ref = identify.measurement_variances(post, obs, previous)
    fast = fast_measurement_variances(post, obs, previous)
    assert fast[4] == 0.123
    np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=0)
