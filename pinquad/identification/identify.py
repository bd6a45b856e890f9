"""EM on one set of observations by E-step and M-step name, with standard errors from
the observed information (and the information at the truth, when a simulation gives it)."""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from estimators.iterated import smooth as iterated_smooth
from estimators.protocol import Posterior
from pinquad.core.params import VehicleRange
from pinquad.estep.fast_smoother import loglik_quad, smooth_quad
from pinquad.identification.em import (
    SETTLED_SHARE,
    EMResult,
    EMSettings,
    Smoother,
    initial_theta,
    project,
    remaining_move,
    run_em,
)
from pinquad.identification.fisher import (
    STDERR_UNAVAILABLE,
    observed_information,
    standard_errors,
)
from pinquad.identification.full_inertia import FullIdentification
from pinquad.identification.measured import MeasuredFit
from pinquad.identification.verdict import EstimateVerdict
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.protocol import PAPER, REGRESSOR, MStep
from pinquad.mstep.updates import MStepResult, regressor_mstep

Array = NDArray[np.float64]

MSTEPS = {"regressor": REGRESSOR, "paper": PAPER}
ESTEPS = ("rts", "ieks", "gtsam")
"""E-step smoothers by name (:func:`get_smoother`)."""


def get_smoother(estep: str) -> Smoother:
    """The E-step smoother by name: ``rts`` (the compiled EKF + RTS; other models than
    the kernels know go to the generic one), ``ieks`` (EKF + RTS iterated to the MAP
    trajectory, ``estimators.iterated``) or ``gtsam`` (factor-graph batch smoother, the
    same MAP by GTSAM)."""
    if estep == "gtsam":
        from estimators.factor_graph import smooth as gtsam_smooth  # GTSAM only when asked for

        return gtsam_smooth
    if estep == "ieks":
        return iterated_smooth
    if estep != "rts":
        raise ValueError(f"unknown E-step {estep!r}; expected {', '.join(ESTEPS)}")
    return smooth_quad


def loglik_function(estep: str):
    """log p(y | theta) for information computations (always the EKF's, whatever
    ``estep``): the compiled forward pass (``fast_smoother.loglik_quad``)."""
    return loglik_quad


@dataclass(frozen=True)
class Identification:
    """One identification of a vehicle's mass and inertia from one flight: the result
    every path returns (the paper's Monte Carlo, a recorded log, the Python API).

    mstep: ``regressor``, ``paper`` or ``full``; sensor: the observation source (A/B/C)
    or the measured log's channel list; mass [kg]; inertia (3, 3) [kg m^2] about the CoM
    (diagonal unless ``mstep == "full"``); stderr (4,): standard errors of [m, I_xx,
    I_yy, I_zz] (NaN where not computed); history_mass (I+1,), history_inertia (I+1, 3):
    after each EM iteration; loglik (I,); converged; decreases: iterations where the
    log-likelihood fell; seconds: wall time; info_truth (4, 4): observed information at
    the true parameters (simulation only, else None); theta: the final parameters with
    their noise model; failure: why EM stopped early, if it did; e_steps: E-steps run
    (None: one per iteration); notes: how the run was set up, in words; posterior: the
    smoothed states at the estimate and observations: what its E-step saw (None when not
    kept); full: the ten-parameter fit
    (CoM and full tensor with their standard errors) when ``mstep == "full"``;
    measured: what a measured flight's fit adds (kf, jackknife, nuisance moment,
    model-free mass: ``pinquad.identification.measured.MeasuredFit``, filled by
    ``realdata.identify.identify_real``) when the flight is a rotor-speed log; verdict:
    whether the log carries each estimate (``pinquad.identification.verdict``; set by
    ``pinquad.identify`` and the recorded-log report, None where nobody judged it);
    stderr_problem: why standard errors that were asked for are missing
    (``fisher.STDERR_UNAVAILABLE``), else None; borrowed_moment: the torque inputs carried
    another fit's nuisance moment (``models.ssm.corrected``: a measured flight's paper
    M-step run on its regressor run's moment), False: the logged torques alone.
    """

    mstep: str
    mass: float
    inertia: Array
    stderr: Array
    history_mass: Array
    history_inertia: Array
    loglik: Array
    converged: bool
    decreases: tuple[int, ...] = ()
    seconds: float = 0.0
    info_truth: Array | None = None
    theta: Theta | None = None
    failure: str | None = None
    sensor: str = ""
    e_steps: int | None = None
    notes: tuple[str, ...] = ()
    posterior: Posterior | None = field(default=None, repr=False, compare=False)
    observations: Observations | None = field(default=None, repr=False, compare=False)
    full: FullIdentification | None = field(default=None, repr=False)
    measured: MeasuredFit | None = field(default=None, repr=False)
    verdict: EstimateVerdict | None = field(default=None, repr=False, compare=False)
    stderr_problem: str | None = None
    borrowed_moment: bool = False

    @property
    def iterations(self) -> int:
        """EM iterations run (M-steps)."""
        return int(self.loglik.size)

    @property
    def inertia_diag(self) -> Array:
        """[I_xx, I_yy, I_zz] (3,) [kg m^2]."""
        return np.diag(self.inertia).copy()

    @property
    def com(self) -> Array | None:
        """The identified centre of mass (3,) [m] from the thrust centre, None unless the
        ten-parameter model was fitted."""
        return None if self.full is None else np.asarray(self.full.com)


UNMOVED_RTOL = 1e-9
"""An estimate within this relative distance of the initial guess has not moved."""


def unmoved_note(mass0: float, inertia0: Array, mass: float, inertia: Array,
                 iterations: int) -> str | None:
    """Why a run's estimate says nothing, or None: EM stopped before its first M-step,
    or the estimate is still the initial guess (|theta - theta0| <= UNMOVED_RTOL
    |theta0| for mass and inertia diagonal) or not finite: the log carries no
    information about mass and inertia that EM could use."""
    start = np.concatenate([[mass0], np.diag(np.asarray(inertia0, dtype=float))])
    end = np.concatenate([[mass], np.diag(np.asarray(inertia, dtype=float))])
    if iterations == 0:
        return "EM stopped at iteration 0: the estimate is the initial guess, not a fit"
    if not np.isfinite(end).all():
        return "EM ended at a non-finite estimate: the log carries no usable information"
    if np.all(np.abs(end - start) <= UNMOVED_RTOL * np.abs(start)):
        return ("EM did not move from the initial guess: the log carries no information "
                "about mass and inertia (the estimate is the guess, not a fit)")
    return None


def bounded_mstep(mstep: str, bounds: VehicleRange | None) -> MStep:
    """The M-step ``mstep`` (``MSTEPS``) kept inside ``bounds``: the regressor M-step
    maximises over the box itself (and stays over-relaxable); the paper's closed form is
    projected onto it (its per-axis updates are not a joint maximiser anyway). None: the
    M-step as it is."""
    base = MSTEPS[mstep]
    if bounds is None:
        return base
    if mstep == "regressor":
        return replace(base, update=functools.partial(regressor_mstep, bounds=bounds))

    def projected(post: Posterior, obs: Observations, theta: Theta) -> MStepResult:
        out = base(post, obs, theta)
        return replace(out, theta=project(out.theta, bounds))

    return replace(base, update=projected)


def em_from_guess(obs: Observations, mass0: float, inertia0: Array, gravity: float,
                  estep: str, mstep: MStep, settings: EMSettings) -> EMResult:
    """EM on a flight from the guess (mass0 [kg], inertia0 (3, 3) [kg m^2]) with the
    paper's noise for the first, force-free E-step (``initial_theta``), E-step ``estep``
    (:func:`get_smoother`), the given M-step and settings: the one EM entry of a flight's
    identification. :func:`identify` (the regressor and paper M-steps) and a measured
    flight's ``realdata.identify_real`` (``mstep.band.BandMStep``: the inertia on the
    torque band and the model's nuisance block) are configurations of it."""
    return run_em(obs, initial_theta(obs, mass0, inertia0, gravity), get_smoother(estep),
                  mstep, max_iterations=settings.max_iterations, tol=settings.tol,
                  tol_loglik=settings.tol_loglik, accelerate=settings.accelerate,
                  per_parameter=settings.per_parameter, bounds=settings.bounds)


def identify(obs: Observations, mass0: float, inertia0: Array, gravity: float, estep: str,
             mstep: str, max_iterations: int, information: bool,
             truth: tuple[float, Array] | None = None,
             per_parameter: bool = False,
             bounds: VehicleRange | None = None) -> tuple[Identification, Posterior]:
    """EM on one set of observations, with standard errors (and information at truth).
    per_parameter: the regressor M-step's over-relaxation with one factor per
    log-parameter (``run_em``); False keeps the shared factor the paper's reproduction
    was measured with. bounds: the vehicle's plausible range, which EM does not leave
    (``run_em``); None: no range (the paper's reproduction)."""
    t0 = time.perf_counter()
    res = em_from_guess(obs, mass0, inertia0, gravity, estep, bounded_mstep(mstep, bounds),
                        EMSettings(max_iterations, per_parameter=per_parameter, bounds=bounds))
    stderr = np.full(4, np.nan)
    info_truth = None
    if information and mstep == "regressor":
        ll = loglik_function(estep)
        stderr = standard_errors(observed_information(obs, res.theta, ll))
        if truth is not None:
            th_true = Theta(truth[0], np.asarray(truth[1]), res.theta.noise, gravity)
            info_truth = observed_information(obs, th_true, ll)
    unmoved = unmoved_note(mass0, inertia0, res.theta.mass, res.theta.inertia,
                           int(res.loglik.size) - 1)
    out = Identification(
        mstep=mstep, mass=res.theta.mass, inertia=np.asarray(res.theta.inertia),
        stderr=stderr, history_mass=res.mass, history_inertia=res.inertia_diag,
        loglik=res.loglik, converged=res.converged and unmoved is None,
        decreases=res.decreases, seconds=time.perf_counter() - t0, info_truth=info_truth,
        theta=res.theta, failure=res.failure or unmoved, e_steps=res.e_steps,
        notes=() if unmoved is None else (unmoved,),
        stderr_problem=(STDERR_UNAVAILABLE if information and mstep == "regressor"
                        and not np.all(np.isfinite(stderr)) else None),
    )
    return out, res.posterior


def unconverged(run: Identification) -> str | None:
    """Why a fit is not the likelihood's maximum (and no ground for effect discovery: its
    residual is that of an arbitrary point): EM did not converge and its iterates have not
    settled; None when it converged, or when the rest of the way (``em.remaining_move``)
    is under ``SETTLED_SHARE`` of every statistical standard error (only a noise variance
    still creeps)."""
    if run.converged:
        return None
    history = np.column_stack([run.history_mass, run.history_inertia])
    stat = (run.measured.se_stat if run.measured is not None
            else np.asarray(run.stderr, dtype=float))
    if (run.failure is None and np.all(np.isfinite(stat))
            and np.all(remaining_move(history) < SETTLED_SHARE * np.asarray(stat))):
        return None
    why = run.failure or "EM stopped at its E-step limit"
    return (f"the base fit did not converge ({why}): discovery needs a base fit at the "
            "likelihood's maximum")
