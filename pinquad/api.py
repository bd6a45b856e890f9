"""pinquad's Python API: identify a flight's mass and inertia, look for what the
identified model leaves unexplained, simulate flights. Every function runs the pipeline of
``python -m pinquad.offline --log`` (``pinquad.pipeline``): the same checks, guards and
verdicts, the same ``Result``; ``pinquad/__init__.py`` re-exports these names beside
``pinquad.read_log`` (``pinquad.io.read.read_log``, the reader of every log format), and
``pinquad.identify_many`` identifies many logs on any executor or Dask cluster.

    import pinquad

    log = pinquad.read_log("flight.csv")        # CSV, Parquet or Crazyflie micro-SD
    fit = pinquad.identify(log)                 # a Result: fit.mass [kg], fit.inertia
                                                # (3, 3) [kg m^2], fit.stderr, fit.verdict
    found = pinquad.discover(log, fit)          # a Result: found.selected, its refit
    print(found.summary())                      # what offline --log prints
    found.save("runs/flight")                   # its run directory (report.json, ...)
"""

from __future__ import annotations

import warnings

import numpy as np

from pinquad.core.params import VEHICLES, Vehicle
from pinquad.discovery.null import NullSettings
from pinquad.io.logs import FlightLog
from pinquad.pipeline.identify import LogOptions
from pinquad.pipeline.single import (
    LOG_MAX_ITERATIONS,
    PipelineOptions,
    run,
    with_discovery,
)
from pinquad.report.console import warning_lines
from pinquad.results.result import Result
from pinquad.sim.simulator import SimConfig, flight_log
from pinquad.sim.simulator import simulate as simulate_flight


def identify(log: FlightLog, *, mstep: str = "regressor", sensor: str | None = None,
             estep: str = "rts", max_iterations: int = LOG_MAX_ITERATIONS,
             information: bool = True) -> Result:
    """Mass [kg] and inertia (3, 3) [kg m^2] of the vehicle that flew ``log``, by EM, as
    ``python -m pinquad.offline --log ... --no-discover --mstep MSTEP`` finds them: a
    ``Result`` (``mass``, ``inertia``, ``inertia_diag``, ``stderr``: the total standard
    errors of its error budget, ``verdict``: per parameter trusted or not identifiable /
    model not adequate / implausible with reasons, ``run``: the EM run with its history
    and smoothed posterior, ``summary()``, ``save(run_dir)``).

    mstep: ``regressor`` (joint maximum likelihood over mass, inertia and the noise),
    ``paper`` (the paper's M-step) or ``full`` (all ten inertial parameters: mass, centre
    of mass and the full tensor; logs with thrust and torques only); sensor: which
    measurements to use (``A``, ``B``, ``C``; None: what the log carries); estep: ``rts``
    (compiled EKF + RTS), ``ieks`` or ``gtsam``; information: standard errors from the
    observed information (measured flights: combined with the block jackknife and the
    thrust-stand kf's uncertainty). Warns (``UserWarning``) when an assumption moves every
    number, as the command prints it: a thrust coefficient not from a thrust stand (no
    stand data found: the vehicle's own value with its assumed error, counted in
    ``stderr``), no vehicle named. Raises ``ImplausibleLogError`` / ValueError naming the
    log on bad input.
    """
    options = LogOptions(sensors=() if sensor is None else (sensor,), msteps=(mstep,),
                         estep=estep, max_iterations=max_iterations, information=information)
    result = Result.of(run(log, PipelineOptions(options, discover=False)))
    for line in warning_lines(result.identified):
        warnings.warn(line.removeprefix("warning: "), UserWarning, stacklevel=2)
    return result


def discover(log: FlightLog, fit: Result | None = None, *,
             null: NullSettings | None = None) -> Result:
    """What the identified model of ``log`` leaves unexplained, as ``python -m
    pinquad.offline --log`` finds it (the same guarded step): the effects of the effect
    vocabulary (drag, ground_effect, com_offset, wind, motor_lag, gyro_bias) that explain
    held-out residuals beyond what shadow flights of the base fit do, their coefficients
    with standard errors (``effects``), and the headline re-judged under the final model
    (``mass``, ``inertia``, ``verdict``: discovery's refit when effects were selected).

    fit: ``identify(log)``'s result (None: identified here with the defaults); null: the
    calibration against shadow flights (default ``NullSettings()``: 19, seed 0). Discovery
    does not run on a base fit that did not converge, nor keep effects read from one
    outside the vehicle's physical range, nor on a ten-parameter fit: ``selected`` is
    then empty and ``discovery_note`` says why. Raises ValueError when ``fit`` is not an
    identification of ``log``.
    """
    if fit is None:
        fit = identify(log)
    elif not _same_flight(log, fit):
        raise ValueError(f"discover: the fit is of {fit.source}, not of {log.meta.source}")
    return Result.of(with_discovery(fit, null))


def _same_flight(log: FlightLog, fit: Result) -> bool:
    """Whether ``fit`` identified ``log``: the same source, and for a log with thrust and
    torque columns (which the E-step sees as they are) the same time stamps and thrust."""
    seen = fit.identified.log
    if fit.source != str(log.meta.source):
        return False
    return fit.identified.kind != "simulated" or (
        seen.n == log.n and np.array_equal(seen.t, log.t)
        and np.array_equal(seen.thrust, log.thrust, equal_nan=True))


def simulate(vehicle: str | Vehicle = "paper", sensor: str = "B", seed: int = 0,
             config: SimConfig | None = None) -> FlightLog:
    """A simulated flight's log: the paper's scenario (the Crazyflie 2.1 flies it scaled
    by 0.3) flown closed-loop with Euler-Maruyama noise on thrust and torques, measured by
    sensor set ``A``, ``B`` or ``C``, seeded by ``seed``; ``config`` overrides all of it
    (vehicle, scenario, sensors, noise, injected effects). The log carries the truth in
    ``FlightLog.truth`` (never read by the estimators)."""
    if config is None:
        veh = VEHICLES[vehicle] if isinstance(vehicle, str) else vehicle
        config = SimConfig(vehicle=veh, sensor=sensor)
        if veh.name != "paper":
            config = SimConfig(vehicle=veh, sensor=sensor, scenario=config.scenario.scaled(0.3))
    return flight_log(simulate_flight(config, np.random.default_rng(seed)))
