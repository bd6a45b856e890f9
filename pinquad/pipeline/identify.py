"""Identify mass and inertia from a recorded flight, whatever it carries.

Dispatch on what the log holds:

* rotor speeds (``rpm``; a Crazyflie micro-SD log or a table with ``rpm_1..4``): a
  measured flight, turned into observations on a 100 Hz grid by
  :mod:`pinquad.realdata.observations` (motion capture, gyro, rotor speeds through the
  thrust-stand kf) and identified with its M-step (mass from the force row, inertia
  from the 3-8 Hz torque rows with the air-speed moments profiled out). A micro-SD log
  (with ``FlightLog.measured`` samples) is kind ``sdlog``, a table ``measured-table``
  (no PWM repair);
* ``thrust`` and ``torque``: a log with the applied wrench (kind ``simulated``),
  observed through the paper's sources (``sources.observations``; sensor A if it
  carries an onboard estimate and accelerometer samples, else B if it has attitude,
  else C) and identified with the shared regressor M-step (or the paper's, or all ten
  inertial parameters).

Initial guesses come from the log's sidecar (``mass_guess``, ``inertia_guess``), else
from ``realdata.default_guess`` (crazyflie21: 25 g and half the published inertia;
others: the paper's m0 = 0.001 kg, I0 = diag(1e-4, 2e-4, 1e-4) kg m^2).
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import is_vehicle_file
from pinquad.discovery.staged import staged_start
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.identification.full_inertia import identify_full
from pinquad.identification.identify import Identification, identify
from pinquad.identification.search_range import search_range
from pinquad.identification.verdict import VehicleRange, vehicle_range
from pinquad.io.logs import FlightLog, log_contents
from pinquad.io.sanity import check_log
from pinquad.io.timebase import gap_lines
from pinquad.models.attitude_range import near_euler_singularity
from pinquad.models.sources import floor_contact, interval_inputs, observations
from pinquad.models.ssm import Observations, corrected
from pinquad.realdata.dataset import default_guess
from pinquad.realdata.identify import identify_real
from pinquad.realdata.observation_options import FAULT_MODES
from pinquad.realdata.vehicle_check import (
    measured_observations,
    measured_search_range,
)
from pinquad.vehicle.actuators import ThrustCoefficient

Array = NDArray[np.float64]

MSTEPS = ("regressor", "paper", "full")


@dataclass(frozen=True)
class LogOptions:
    """How to identify a recorded log.

    sensors: observation sources to run (``A``/``B``/``C``; empty: the log's default,
    :func:`default_sensor`, or for a measured flight every channel it has); msteps: any
    of ``regressor``, ``paper``, ``full`` (``full``: all ten inertial parameters, logs
    with thrust and torques only); estep: ``rts``, ``ieks`` or ``gtsam``;
    max_iterations: E-steps at most per EM run (>= 1); information: compute standard
    errors from the observed information; band (lo, hi) [Hz]: the torque rows' band of a
    rotor-speed log's inertia M-step (``realdata.identify_real``; 3-8 Hz for the measured
    Crazyflie flights, whose unmodelled torques the band keeps out); faults: how a
    rotor-speed log's implausible readings are handled (``realdata.observations.
    FAULT_MODES``; None: the vehicle's default, ``options_for_vehicle``).
    """

    sensors: tuple[str, ...] = ()
    msteps: tuple[str, ...] = ("regressor", "paper")
    estep: str = "rts"
    max_iterations: int = 100
    information: bool = True
    band: tuple[float, float] = (3.0, 8.0)
    faults: str | None = None

    def __post_init__(self) -> None:
        unknown = [m for m in self.msteps if m not in MSTEPS]
        if unknown or not self.msteps:
            raise ValueError(f"M-steps must be some of {', '.join(MSTEPS)}; got {self.msteps}")
        if self.faults is not None and self.faults not in FAULT_MODES:
            raise ValueError(f"faults {self.faults!r}: expected one of {', '.join(FAULT_MODES)}")
        if self.max_iterations < 1:
            raise ValueError(f"max_iterations must be at least 1; got {self.max_iterations}")
        if not 0.0 <= self.band[0] < self.band[1]:
            raise ValueError(f"torque band must be 0 <= LO < HI [Hz] (LO = 0: low-pass "
                             f"only); got {self.band}")


@dataclass(frozen=True)
class LogResult:
    """A recorded log's identification: runs (first = the reported one), the log and the
    observations the E-step saw, the smoothed means (N, 12) of the reported run, the
    initial guess in words, exclusions and notes, the kind of log (``sdlog``,
    ``measured-table``, or ``simulated`` for any log with thrust and torque columns, the
    key ``DISCOVERY_SETTINGS`` and the report dispatch on), the thrust coefficient and
    actuation-fault notes of a measured flight, and contents: what the recorded log carries, in words
    (``log_contents``; ``log`` is the log as the E-step saw it, for a measured flight
    resampled with the thrust and torques its rotor speeds give), search: the range EM
    searched (``identification.search_range``; None: unbounded); vehicle_unnamed: a
    measured log that names no vehicle, judged against no vehicle's range (its note says
    so); plausible: what the log's vehicle can physically be, the range every verdict
    judges on (:func:`plausible_range`; None: no vehicle named and no guesses);
    actuation: how the E-step's inputs acted between rows (:func:`input_reading`:
    ``held`` or ``sampled``). Discovery starts from ``discovery_start(runs[0])``."""

    runs: tuple[Identification, ...]
    log: FlightLog
    obs: Observations
    smoothed: Array
    guess: str
    excluded: tuple[str, ...]
    notes: tuple[str, ...]
    kind: str
    kf: ThrustCoefficient | None = None
    faults: tuple[str, ...] = ()
    input_alternative: Array | None = None
    contents: str = ""
    search: VehicleRange | None = None
    vehicle_unnamed: bool = False
    plausible: VehicleRange | None = None
    actuation: str = "held"


def torque_words(run: Identification) -> str:
    """What drove a measured flight's paper-M-step run's torque rows, in words: the rotor
    torques alone, or with the regressor run's nuisance moment (``borrowed_moment``)."""
    return ("with the regressor run's nuisance moment" if run.borrowed_moment
            else "rotor torques only")


def initial_guess(log: FlightLog) -> tuple[float, Array, str]:
    """(mass0 [kg], inertia0 (3, 3) [kg m^2], where they came from in words): the
    sidecar's guesses, else the vehicle's default. Raises ValueError if not positive."""
    meta = log.meta
    mass0, inertia0, words = default_guess(meta.vehicle)
    parts = []
    if meta.mass_guess is not None:
        mass0 = float(meta.mass_guess)
        parts.append("mass from the log's sidecar")
    if meta.inertia_guess is not None:
        inertia0 = np.asarray(meta.inertia_guess, dtype=float).reshape(3, 3)
        parts.append("inertia from the log's sidecar")
    if len(parts) < 2:
        parts.append(words)
    if not (mass0 > 0 and np.all(np.diag(inertia0) > 0)):
        raise ValueError(f"{meta.source}: initial guess must be positive; got mass {mass0} kg, "
                         f"inertia diagonal {np.diag(inertia0).tolist()} kg m^2")
    return mass0, inertia0, "; ".join(parts)


def default_sensor(log: FlightLog) -> str:
    """A if the log carries an onboard estimate and accelerometer samples, else B if it
    has attitude samples, else C."""
    if log.onboard is not None and np.isfinite(log.accel).any():
        return "A"
    if np.isfinite(log.euler).any():
        return "B"
    return "C"


def log_kind(log: FlightLog) -> str:
    """``simulated`` (thrust and torque columns), ``sdlog`` (a Crazyflie micro-SD log) or
    ``measured-table`` (a table of rotor speeds): what ``identify_log`` dispatches on."""
    if log.thrust is not None and not (log.meta.wrench_from_rpm and log.rpm is not None):
        return "simulated"
    return "sdlog" if log.measured is not None else "measured-table"


def _measured(log: FlightLog, options: LogOptions, kind: str) -> LogResult:
    mass0, inertia0, guess = initial_guess(log)
    sensors = list(options.sensors) or [None]
    if "full" in options.msteps:
        raise ValueError(f"{log.meta.source}: --mstep full needs a CSV or Parquet log with "
                         "thrust and torque columns; measured rotor-speed logs are identified "
                         "with the regressor or paper M-step")
    runs: list[Identification] = []
    first = None
    # the paper M-step's closed form is projected onto the range of the vehicle whose
    # mixer reads the rotor speeds
    vehicle = log.meta.vehicle
    box = measured_search_range(log)
    for sensor in sensors:
        real = measured_observations(log, sensor, faults=options.faults)
        label = sensor or ",".join(real.obs.channels)
        theta = None
        if "regressor" in options.msteps:
            run = identify_real(real, mass0, inertia0, options.max_iterations,
                                options.information, band=options.band, estep=options.estep)
            theta = run.theta
            runs.append(replace(run, sensor=label))
            if first is None:
                first = (real, run.posterior.mean)  # type: ignore[union-attr]
        if "paper" in options.msteps:
            # the paper's M-step knows no air-speed moment: the regressor run's is added
            obs = real.obs if theta is None else corrected(real.obs, theta)
            ident_p, post_p = identify(obs, mass0, inertia0, log.meta.gravity, options.estep,
                                       "paper", options.max_iterations, False, bounds=box)
            ident_p = replace(ident_p, sensor=label, posterior=post_p, observations=obs,
                              borrowed_moment=theta is not None)
            runs.append(replace(ident_p, notes=(f"torques: {torque_words(ident_p)}",)))
            if first is None:
                first = (real, post_p.mean)
    assert first is not None
    real, smoothed = first
    # the grid's log keeps whether the log named its vehicle: one that names none is
    # judged on no vehicle's range, never on the default paper vehicle's
    exported = replace(real.log, meta=replace(real.log.meta, wrench_from_rpm=True,
                                              vehicle_named=log.meta.vehicle_named))
    unnamed = () if log.meta.vehicle_named else (
        "no vehicle named (the log has no sidecar key \"vehicle\"): the verdict judges the "
        "estimate against no vehicle's range; the rotor speeds are read with "
        f"{'crazyflie21' if not is_vehicle_file(vehicle) else vehicle}'s rotor model; name "
        "the vehicle in the sidecar to judge against its range",)
    return LogResult(tuple(runs), exported, real.obs, smoothed, guess, real.excluded,
                     (*real.notes, *unnamed), kind, kf=real.kf,
                     faults=tuple(real.faults.notes), contents=log_contents(log), search=box,
                     vehicle_unnamed=bool(unnamed))


def _full(obs: Observations, sensor: str, mass0: float, inertia0: Array, gravity: float,
          options: LogOptions) -> Identification:
    """EM over all ten inertial parameters (``pinquad.identification.full_inertia``) from
    the staged start (``discovery.staged.staged_start``: the diagonal model's EM from the
    paper's guess, refitted with the horizontal CoM), compiled E-step throughout."""
    start = staged_start(obs, mass0, inertia0, gravity, smooth_quad)
    res = identify_full(obs, start, smooth_quad, max_iterations=options.max_iterations,
                        information=options.information)
    stderr = np.concatenate([[res.stderr_mass], np.diag(res.stderr_inertia)])
    return Identification(
        mstep="full", mass=res.mass, inertia=np.asarray(res.inertia), stderr=stderr,
        history_mass=np.array([start.mass, res.mass]),
        history_inertia=np.array([np.diag(start.inertia), np.diag(res.inertia)]),
        loglik=res.loglik, converged=res.converged, theta=res.theta, failure=res.failure,
        sensor=sensor, e_steps=res.e_steps, posterior=res.posterior, observations=obs, full=res)


RECORDED_PER_PARAMETER = True
"""The base EM of a log with thrust and torque columns over-relaxes one factor per
log-parameter (``identification.em.run_em``'s ``per_parameter``, as discovery's refit
does): the force noise of a log whose simulator puts none on an axis creeps towards zero
by plain EM steps of a fraction of a percent, and the shared factor (cap 16) followed it
for 80 E-steps on the benchmark's 60 s log where this takes 27, to the same estimate
(within 0.003 %, 0.05 standard errors) (docs/benchmark.md). The paper's
reproduction on pinquad's own simulator (``offline_mc``) keeps the shared factor its
figures were measured with."""


def fit_run(obs: Observations, sensor: str, mstep: str, mass0: float, inertia0: Array,
            gravity: float, options: LogOptions, bounds: VehicleRange | None = None
            ) -> Identification:
    """One run of a log with thrust and torque columns: EM with ``mstep`` on the
    observations of ``sensor`` from the guess (mass0 [kg], inertia0 (3, 3) [kg m^2]).
    The regressor M-step is over-relaxed per parameter (``RECORDED_PER_PARAMETER``);
    EM searches inside ``bounds`` (``identification.search_range``)."""
    if mstep == "full":
        return _full(obs, sensor, mass0, inertia0, gravity, options)
    ident, post = identify(obs, mass0, inertia0, gravity, options.estep, mstep,
                           options.max_iterations, options.information,
                           per_parameter=RECORDED_PER_PARAMETER, bounds=bounds)
    return replace(ident, sensor=sensor, posterior=post, observations=obs)


def _with_applied_wrench(log: FlightLog, options: LogOptions,
                         executor: Executor | None = None) -> LogResult:
    mass0, inertia0, guess = initial_guess(log)
    sensors = list(options.sensors) or [default_sensor(log)]
    gravity = log.meta.gravity
    # floor contact: the log's flags, else found from the data (models.contact); attitudes
    # near the Euler angles' singularity (models.attitude_range)
    contact, singular = floor_contact(log, mass0), near_euler_singularity(log.t, log.euler)
    seen = {sensor: observations(log, sensor, contact, singular) for sensor in sensors}
    tasks = [(sensor, mstep) for sensor in sensors for mstep in options.msteps]
    box = search_range(log)
    obs = seen[sensors[0]]
    first_mstep = options.msteps[0]
    # every run and the input alternative are EM runs of their own: with an executor,
    # all but the reported run go to its workers while this process fits that one
    later, alternative_job = [], None
    if executor is not None:
        later = [executor.submit(fit_run, seen[s], s, m, mass0, inertia0, gravity, options, box)
                 for s, m in tasks[1:]]
        alternative_job = executor.submit(input_alternative, log, obs, first_mstep, mass0,
                                          inertia0, options, box)
    run = fit_run(obs, sensors[0], first_mstep, mass0, inertia0, gravity, options, box)
    if executor is not None:
        runs = [run, *(f.result() for f in later)]
        alternative = alternative_job.result() if alternative_job is not None else None
    else:
        runs = [run, *(fit_run(seen[s], s, m, mass0, inertia0, gravity, options, box)
                       for s, m in tasks[1:])]
        alternative = input_alternative(log, obs, first_mstep, mass0, inertia0, options, box)
    n_ex = int(obs.exclude[: obs.n - 1].sum())
    excluded = (f"{contact.transitions()} transitions: {contact.describe()}",
                *singular.report_lines(), *gap_lines(log.t),
                f"total: {n_ex} of {obs.n - 1} transitions excluded")
    return LogResult(tuple(runs), log, obs, run.posterior.mean, guess, excluded,
                     tuple(log.meta.notes), "simulated", contents=log_contents(log),
                     input_alternative=alternative, search=box)


def input_alternative(log: FlightLog, obs: Observations, mstep: str, mass0: float,
                      inertia0: Array, options: LogOptions, bounds: VehicleRange | None = None
                      ) -> Array | None:
    """For a log whose actuation is taken as sampled without its sidecar saying so
    (``LogMeta.actuation``, ``actuation_declared``): [m (kg), I_xx, I_yy,
    I_zz (kg m^2)] from EM with the reported run's M-step ``mstep`` (no standard errors)
    with each logged row held over its interval instead of the interval's mean
    (``interval_inputs``), the reading the log cannot rule out; the verdict compares it
    with the run's (``VerdictEvidence.input_alternative``). None for held logs and the
    ten-parameter M-step."""
    meta = log.meta
    if meta.actuation != "sampled" or meta.actuation_declared or mstep == "full":
        return None
    held = replace(obs, inputs=interval_inputs(np.column_stack([log.thrust, log.torque]), "held"),
                   samples=None)
    alt, _ = identify(held, mass0, inertia0, log.meta.gravity, options.estep, mstep,
                      options.max_iterations, False, per_parameter=RECORDED_PER_PARAMETER,
                      bounds=bounds)
    return np.r_[alt.mass, np.diag(alt.inertia)]


def identify_log(log: FlightLog, options: LogOptions | None = None,
                 executor: Executor | None = None) -> LogResult:
    """Identify the vehicle of a recorded log (module docstring). Raises
    ``pinquad.io.sanity.ImplausibleLogError`` when its columns contradict physics (wrong
    units, impossible values), ValueError (with the log named) when the log cannot be
    identified as asked; numpy's LinAlgError when EM fails numerically. executor
    (``core.execution.worker_pool``): a log with thrust and torque columns fits its runs beyond the
    reported one, and the input alternative, in its workers (the same answer)."""
    options = options or LogOptions()
    check_log(log)  # units and impossible values, before any EM (pinquad.io.sanity)
    kind = log_kind(log)
    if kind == "simulated":
        result = _with_applied_wrench(log, options, executor)
    else:
        # an export's thrust and torques are its rotor speeds' own: identified from the latter
        result = _measured(replace(log, thrust=None, torque=None), options, kind)
    return replace(result, plausible=plausible_range(result.log),
                   actuation=input_reading(result.kind, result.log))


def plausible_range(log: FlightLog) -> VehicleRange | None:
    """What the log's vehicle can physically be (``identification.verdict.vehicle_range``):
    the named vehicle's range; a log that names none is judged on its sidecar's guesses,
    never on the default ``paper`` vehicle's (a 33 g quad would be "implausible" against
    a 0.18 kg one)."""
    meta = log.meta
    name = meta.vehicle if meta.vehicle_named else ""
    return vehicle_range(name, meta.mass_guess, meta.inertia_guess)


def input_reading(kind: str, log: FlightLog) -> str:
    """How the E-step's inputs of a log of ``kind`` were read: the sidecar's actuation
    for a log with thrust and torque columns (``models.sources.interval_inputs``); a
    measured rotor-speed flight's inputs are built on its own grid (``realdata``) and
    taken as held over each step."""
    return log.meta.actuation if kind == "simulated" else "held"
