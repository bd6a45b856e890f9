"""A recorded log replayed through the online estimator as a stream (``python -m
pinquad.online --log PATH``; no controller feedback): every ``every`` samples, EM
(warm-started, one iteration) on the latest ``window`` samples, as in flight.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.params import VehicleRange
from pinquad.estep.fast_smoother import loglik_quad
from pinquad.identification.budget import (
    ErrorBudget,
    calibration_of,
    error_budget,
)
from pinquad.identification.edges import collapsed_errors
from pinquad.identification.em import initial_theta, project
from pinquad.identification.fisher import (
    STDERR_UNAVAILABLE,
    observed_information,
    standard_errors,
)
from pinquad.identification.identify import get_smoother
from pinquad.identification.reference import log_reference
from pinquad.identification.search_range import at_bound
from pinquad.identification.verdict import EstimateVerdict, judge
from pinquad.identification.verdict_evidence import data_evidence
from pinquad.identification.window import window_em, window_prior
from pinquad.io.logs import LogMeta
from pinquad.models.nuisance import torque_features
from pinquad.models.ssm import Observations, Theta, corrected
from pinquad.mstep.band import BandMStep
from pinquad.mstep.updates import regressor_mstep, remember_leaving

Array = NDArray[np.float64]


def window_of(obs: Observations, start: int, stop: int, x0: Array, p0: Array) -> Observations:
    """Rows start..stop-1 of the observations with a given prior."""
    return replace(obs, t=obs.t[start:stop], inputs=obs.inputs[start:stop],
                   ys=obs.ys[start:stop], x0=x0, p0=p0,
                   exclude=obs.exclude[start:stop] if obs.exclude.size else obs.exclude,
                   resets=obs.resets[start:stop] if obs.resets.size else obs.resets,
                   samples=None if obs.samples is None else obs.samples[start:stop])


def _measured_theta(theta: Theta, previous: tuple[int, Posterior, Observations] | None,
                    start: int, win: Observations, rotor_acc: Array) -> Theta:
    """A measured flight's parameters moved onto the next window: the nuisance block's
    moment tau_off = z moment_coef^T + [0, 0, J_r rotor_acc] (``mstep.band.BandMStep``)
    evaluated on the new window's rows, with the features z from the previous
    posterior's means (its last row repeated for the rows it has not seen yet)."""
    nuisance = theta.nuisance
    if nuisance is None or previous is None:
        return theta
    prev_start, post, _ = previous
    guess = post.mean[start - prev_start:]
    guess = np.vstack([guess, np.repeat(guess[-1:], win.n - guess.shape[0], axis=0)])
    offset = torque_features(guess, win.inputs[:, 0]) @ nuisance.moment_coef.T
    if nuisance.rotor_inertia is not None:
        offset[:, 2] += nuisance.rotor_inertia * rotor_acc
    return replace(theta, nuisance=replace(nuisance, torque_offset=offset))


@dataclass(frozen=True)
class StreamFit:
    """A replayed stream: history (U, 6) [k, t, m, Ixx, Iyy, Izz] and latencies (U,) [s]
    per update; theta, posterior and window: the last update's parameters, its E-step
    and the observations it saw (None when the log was too short for one)."""

    history: Array
    latencies: Array
    theta: Theta | None = None
    posterior: Posterior | None = None
    window: Observations | None = None


def stream_em(obs: Observations, mass0: float, inertia0: Array, gravity: float,
              window: int = 800, every: int = 4, min_samples: int = 50,
              iterations: int = 1, memory_s: float | None = math.inf,
              rotor_acc: Array | None = None, bounds: VehicleRange | None = None
              ) -> tuple[Array, Array]:
    """History and latencies of ``stream_fit`` (its arguments)."""
    fit = stream_fit(obs, mass0, inertia0, gravity, window, every, min_samples, iterations,
                     memory_s, rotor_acc, bounds)
    return fit.history, fit.latencies


def stream_fit(obs: Observations, mass0: float, inertia0: Array, gravity: float,
               window: int = 800, every: int = 4, min_samples: int = 50,
               iterations: int = 1, memory_s: float | None = math.inf,
               rotor_acc: Array | None = None, bounds: VehicleRange | None = None
               ) -> StreamFit:
    """The stream's history, latencies and last update (``StreamFit``); memory_s as
    ``online.OnlineConfig.memory_s``. bounds: the range every window's EM searches mass
    and inertia in (``regressor_mstep``'s; a measured flight's M-step is projected onto
    it), None: unbounded.

    rotor_acc (N,) [rad/s^2]: given for a measured flight (``RealObservations``): each
    window then gets the measured-flight M-step (``mstep.band.BandMStep``: band-passed
    inertia, nuisance body moment and rotor inertia, fed back into the next window's
    E-step as a torque offset), and the memory applies to the mass only (the inertia's
    band-passed sums do not add across windows)."""
    smoother = get_smoother("rts")
    theta = None
    previous = None
    earlier = None
    rows, lat = [], []
    for k in range(min_samples - 1, obs.n, every):
        t0 = time.perf_counter()
        start = max(0, k + 1 - window)
        x0, p0 = window_prior(previous, start, obs.x0, obs.p0)
        if memory_s is not None and previous is not None:
            prev_start, prev_post, prev_win = previous
            earlier = remember_leaving(earlier, prev_post, prev_win, start - prev_start,
                                       gravity, memory_s)
        win = window_of(obs, start, k + 1, x0, p0)
        warm_up = theta is None
        if warm_up:
            theta = initial_theta(win, mass0, inertia0, gravity)
            if bounds is not None:
                theta = project(theta, bounds)
        mstep = functools.partial(regressor_mstep, bounds=bounds)
        if rotor_acc is not None:
            theta = _measured_theta(theta, previous, start, win, rotor_acc[start:k + 1])
            mstep = BandMStep(rotor_acc=rotor_acc[start:k + 1])
        theta, post = window_em(win, theta, warm_up, iterations, smoother, mstep, earlier)
        if bounds is not None:
            theta = project(theta, bounds)
        previous = (start, post, win)
        lat.append(time.perf_counter() - t0)
        rows.append([k, obs.t[k], theta.mass, *np.diag(theta.inertia)])
    last = (None, None, None) if previous is None else (theta, previous[1], previous[2])
    return StreamFit(np.asarray(rows), np.asarray(lat), *last)


def replay_verdict(fit: StreamFit, meta: LogMeta, vrange: VehicleRange | None,
                   bounds: VehicleRange | None, measured_thrust: tuple[float, float] | None = None
                   ) -> tuple[EstimateVerdict, ErrorBudget]:
    """The verdict on a replay's final estimate, judged on its last window: statistical
    errors from the observed information of the window's EKF likelihood, combined with
    what the log assumed (``identification.budget``; measured_thrust: (kf's, the yaw
    ratio's) relative uncertainty of a rotor-speed flight), the window's evidence
    (torque shares, innovations) and whether EM ended on the edge of ``bounds``;
    vrange: the vehicle's plausible range (None: none known)."""
    assert fit.theta is not None and fit.window is not None and fit.posterior is not None
    theta, win = fit.theta, fit.window
    # a measured flight's nuisance moment moves into the torques
    win = corrected(win, theta)
    plain = theta.without_nuisance()
    values = np.r_[plain.mass, np.diag(plain.inertia)]
    try:
        stat = standard_errors(observed_information(win, plain, loglik_quad))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError):
        stat = np.full(4, np.nan)
    budget = error_budget(values, stat, calibration_of(meta, measured_thrust))
    # a measured flight's window M-step reads the inertia from its torque band only
    band = None if measured_thrust is None else BandMStep().band
    evidence = data_evidence(win, plain, fit.posterior.mean, band)
    if bounds is not None:
        evidence = replace(evidence, at_bound=tuple(at_bound(values, bounds)),
                           bound_source=bounds.source)
    evidence = replace(evidence, reference=log_reference(meta),
                       error_failures=collapsed_errors(values, {"observed information": stat}))
    verdict = judge(plain.mass, plain.inertia, budget.total, evidence, vrange,
                    missing_stderr=STDERR_UNAVAILABLE, parts=budget.parts)
    return verdict, budget
