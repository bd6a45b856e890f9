"""One Monte Carlo cycle of the offline experiment: fly, log, identify with EM.

A cycle flies the paper's scenario once with a given sensor set (A, B or C), then runs
EM from the paper's initial guess with each requested M-step on that same log, and
(optionally) the observed information at the estimate and at the truth.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, VEHICLES
from pinquad.identification.em import EMResult, Smoother, initial_theta, run_em
from pinquad.identification.fisher import observed_information, standard_errors
from pinquad.io.logs import FlightLog
from pinquad.models.sources import observations
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.updates import paper_mstep, regressor_mstep
from pinquad.sim.simulator import SimConfig, flight_log, simulate, waypoint_report

Array = NDArray[np.float64]

MSTEPS = {"regressor": regressor_mstep, "paper": paper_mstep}
SENSOR_INDEX = {"A": 0, "B": 1, "C": 2}
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


def flight_seed(seed: int, sensor: str, cycle: int) -> int:
    """The seed of cycle ``cycle`` for ``sensor`` under base seed ``seed``."""
    return int(seed) * 100_000 + SENSOR_INDEX[sensor] * 1000 + int(cycle)


@dataclass(frozen=True)
class CycleJob:
    """What one worker does: sensor, cycle index, base seed, vehicle, E-step, M-steps."""

    sensor: str
    cycle: int
    seed: int
    vehicle: str = "paper"
    estep: str = "rts"
    msteps: tuple[str, ...] = ("regressor", "paper")
    max_iterations: int = 100
    information: bool = True
    keep_log: bool = False


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


@dataclass(frozen=True)
class CycleResult:
    """A cycle: the flight's figures and each M-step's identification."""

    sensor: str
    cycle: int
    seed: int
    truth_mass: float
    truth_inertia: Array
    flight: dict
    runs: tuple[Identification, ...]
    log: FlightLog | None = None
    smoothed: Array | None = None
    seconds: float = 0.0
    excluded: dict = field(default_factory=dict)


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


def run_cycle(job: CycleJob) -> CycleResult:
    """Fly one seeded flight with the job's sensor and identify it with each M-step."""
    t0 = time.perf_counter()
    vehicle = VEHICLES[job.vehicle]
    seed = flight_seed(job.seed, job.sensor, job.cycle)
    config = SimConfig(vehicle=vehicle, sensor=job.sensor)
    if job.vehicle != "paper":
        config = SimConfig(vehicle=vehicle, sensor=job.sensor,
                           scenario=config.scenario.scaled(0.3))
    flight = simulate(config, np.random.default_rng(seed))
    log = flight_log(flight)
    obs = observations(log, job.sensor)
    mass0, inertia0 = PAPER_INITIAL_MASS, PAPER_INITIAL_INERTIA
    if job.vehicle != "paper":
        mass0, inertia0 = vehicle.mass * PAPER_INITIAL_MASS / 0.18, vehicle.inertia * 0.5
    runs = []
    smoothed = None
    for mstep in job.msteps:
        ident, post = identify(obs, mass0, inertia0, vehicle.gravity, job.estep, mstep,
                               job.max_iterations, job.information,
                               truth=(vehicle.mass, vehicle.inertia))
        runs.append(ident)
        if mstep == job.msteps[0]:
            smoothed = post.mean
    return CycleResult(
        sensor=job.sensor, cycle=job.cycle, seed=seed, truth_mass=vehicle.mass,
        truth_inertia=np.asarray(vehicle.inertia), flight=waypoint_report(flight),
        runs=tuple(runs), log=log if job.keep_log else None,
        smoothed=smoothed if job.keep_log else None, seconds=time.perf_counter() - t0,
        excluded={"contact_transitions": int(obs.exclude.sum())},
    )
