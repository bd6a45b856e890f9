"""pinquad's Python API: read a flight, identify its mass and inertia, look for what the
identified model leaves unexplained, simulate flights. The command lines are built on
the same pipeline (``pinquad.pipeline``); ``pinquad/__init__.py`` re-exports these names,
and ``pinquad.identify_many`` identifies many logs on any executor or Dask cluster.

    import pinquad

    log = pinquad.read_log("flight.csv")        # CSV, Parquet or Crazyflie micro-SD
    fit = pinquad.identify(log)                 # mass [kg], inertia (3, 3) [kg m^2], stderr,
                                                # fit.verdict: can the log carry each one?
    found = pinquad.discover(log, fit)          # selected effects, before/after residuals
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pinquad.core.params import VEHICLES, Vehicle
from pinquad.discovery.null import NullSettings
from pinquad.discovery.result import DiscoveryConfig, DiscoveryResult
from pinquad.experiments.recorded import LogOptions
from pinquad.identification.identify import Identification
from pinquad.io.logs import FlightLog
from pinquad.pipeline.single import LOG_MAX_ITERATIONS, discover_from, identify_run, read
from pinquad.sim.simulator import SimConfig, flight_log
from pinquad.sim.simulator import simulate as simulate_flight


def read_log(path: str | Path) -> FlightLog:
    """The flight recorded in ``path``: a Crazyflie micro-SD binary log, or a CSV or
    Parquet table (the log columns of ``pinquad.io.logs``) with its optional JSON sidecar. Raises
    ``pinquad.io.logs.LogFormatError`` naming the file and the column, row or byte
    offset when the file is not a readable log."""
    return read(path)


def identify(log: FlightLog, *, mstep: str = "regressor", sensor: str | None = None,
             estep: str = "rts", max_iterations: int = LOG_MAX_ITERATIONS,
             information: bool = True) -> Identification:
    """Mass [kg] and inertia (3, 3) [kg m^2] of the vehicle that flew ``log``, by EM.

    mstep: ``regressor`` (joint maximum likelihood over mass, inertia and the noise),
    ``paper`` (the paper's M-step) or ``full`` (all ten inertial parameters: mass, centre
    of mass and the full tensor; logs with thrust and torques only); sensor: which
    measurements to use (``A``, ``B``, ``C``; None: what the log carries); estep: ``rts``
    (compiled EKF + RTS), ``ieks`` or ``gtsam``; information: standard errors from the
    observed information (measured flights: combined with the block jackknife and the
    thrust-stand kf's uncertainty). The result keeps the smoothed posterior, the EM
    history and the observations its E-step saw, which :func:`discover` starts from, and
    its ``verdict`` (``pinquad.identification.verdict``: per parameter, trusted or not
    identifiable / model not adequate / implausible, with reasons).
    """
    options = LogOptions(sensors=() if sensor is None else (sensor,), msteps=(mstep,),
                         estep=estep, max_iterations=max_iterations, information=information)
    return identify_run(log, options)


def discover(log: FlightLog, identification: Identification,
             config: DiscoveryConfig | None = None, null: NullSettings | None = None
             ) -> DiscoveryResult:
    """What ``identification``'s model of ``log`` leaves unexplained: the effects of the
    effect vocabulary (drag, ground_effect, com_offset, wind, motor_lag, gyro_bias)
    that explain held-out residuals significantly, their coefficients with standard
    errors, the refitted mass and inertia, and the held-out residual RMS before and
    after. config: selection settings (default: those ``python -m pinquad.offline --log``
    uses for this kind of log); null: the calibration of the selection against shadow
    flights of the base fit (default ``NullSettings()``: 19, seed 0; an effect they
    explain is not selected). Raises ValueError when discovery fails numerically."""
    outcome = discover_from(log, identification, config, null)
    if outcome.result is None:
        raise ValueError(outcome.error or "effect discovery failed")
    return outcome.result


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
