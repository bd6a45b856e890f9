"""EM on one set of observations by E-step and M-step name, with standard errors from
the observed information (and the information at the truth, when a simulation gives it)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.identification.em import EMResult, Smoother, initial_theta, run_em
from pinquad.identification.fisher import observed_information, standard_errors
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.updates import paper_mstep, regressor_mstep

Array = NDArray[np.float64]

MSTEPS = {"regressor": regressor_mstep, "paper": paper_mstep}
ESTEPS = ("rts", "ieks", "gtsam")
"""E-step smoothers by name (:func:`get_smoother`)."""


def get_smoother(estep: str) -> Smoother:
    """The E-step smoother by name: ``rts`` (compiled fast path when available),
    ``ieks`` (EKF + RTS iterated to the MAP trajectory, ``estimators.iterated``) or
    ``gtsam`` (factor-graph batch smoother, the same MAP by GTSAM)."""
    if estep == "gtsam":
        from estimators.factor_graph import smooth as gtsam_smooth

        return gtsam_smooth
    if estep == "ieks":
        from estimators.iterated import smooth as iterated_smooth

        return iterated_smooth
    if estep != "rts":
        raise ValueError(f"unknown E-step {estep!r}; expected {', '.join(ESTEPS)}")
    try:
        from pinquad.estep.fast_smoother import smooth_quad

        return smooth_quad
    except ImportError:  # the compiled path is optional
        from estimators.rts import smooth

        return smooth


def loglik_function(estep: str):
    """log p(y | theta) for information computations (always the EKF's): the compiled
    forward pass (``fast_smoother.loglik_quad``) when available, else the generic EKF."""
    try:
        from pinquad.estep.fast_smoother import loglik_quad

        return loglik_quad
    except ImportError:  # the compiled path is optional
        from pinquad.identification.fisher import ekf_loglik

        return ekf_loglik


@dataclass(frozen=True)
class Identification:
    """One EM run's outcome on one log.

    estimates: mass [kg] and inertia (3, 3) [kg m^2]; stderr (4,) standard errors of
    [m, Ixx, Iyy, Izz] from the observed information (NaN if not computed);
    history_mass (I+1,), history_inertia (I+1, 3): after each EM iteration;
    loglik (I,); converged; decreases; info_truth (4, 4) observed information at the
    true parameters (simulation only, else None); failure: why EM stopped early, if it
    did (``EMResult.failure``).
    """

    mstep: str
    mass: float
    inertia: Array
    stderr: Array
    history_mass: Array
    history_inertia: Array
    loglik: Array
    converged: bool
    decreases: tuple[int, ...]
    seconds: float
    info_truth: Array | None = None
    noise: Theta | None = None
    failure: str | None = None


def identify(obs: Observations, mass0: float, inertia0: Array, gravity: float, estep: str,
             mstep: str, max_iterations: int, information: bool,
             truth: tuple[float, Array] | None = None) -> tuple[Identification, Posterior]:
    """EM on one set of observations, with standard errors (and information at truth)."""
    t0 = time.perf_counter()
    smoother = get_smoother(estep)
    theta0 = initial_theta(obs, mass0, inertia0, gravity)
    res: EMResult = run_em(obs, theta0, smoother, MSTEPS[mstep], max_iterations=max_iterations)
    stderr = np.full(4, np.nan)
    info_truth = None
    if information and mstep == "regressor":
        ll = loglik_function(estep)
        stderr = standard_errors(observed_information(obs, res.theta, ll))
        if truth is not None:
            th_true = Theta(truth[0], np.asarray(truth[1]), res.theta.noise, gravity)
            info_truth = observed_information(obs, th_true, ll)
    out = Identification(
        mstep=mstep, mass=res.theta.mass, inertia=np.asarray(res.theta.inertia),
        stderr=stderr, history_mass=res.mass, history_inertia=res.inertia_diag,
        loglik=res.loglik, converged=res.converged, decreases=res.decreases,
        seconds=time.perf_counter() - t0, info_truth=info_truth, noise=res.theta,
        failure=res.failure,
    )
    return out, res.posterior


