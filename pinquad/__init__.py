"""pinquad: EM identification of a quadcopter's mass and inertia, and discovery of what the
identified model still gets wrong.

    import pinquad

    log = pinquad.read_log("flight.csv")        # CSV, Parquet or Crazyflie micro-SD log
    fit = pinquad.identify(log)                 # a Result: fit.mass [kg], fit.inertia (3, 3),
                                                # fit.stderr, fit.verdict, fit.summary()
    found = pinquad.discover(log, fit)          # a Result: found.selected, the refit
    found.save("runs/flight")                   # report.json, report.md, figures
    batch = pinquad.identify_many(paths, executor=pool)  # any executor: batch.results, a
                                                # Result per log; batch.summary(), its table
    path = pinquad.crazyflie_log("jana00")      # a public flight, once fetched
    px4 = pinquad.read_command_log("flight.ulg")  # a PX4 log: motor commands, no thrust
    # with the mass known: pinquad.identify_known_mass(px4, 1.5, positions, spins)
    # and by EM beside it: pinquad.identify_known_mass_em(px4, 1.5, positions, spins, that)

The names below are loaded on first use (``import pinquad`` stays cheap for the command
lines, whose entry modules live in this package too).
"""

from __future__ import annotations

import importlib
import warnings
from typing import TYPE_CHECKING, Any

_EXPORTS = {
    "read_log": "pinquad.io.read",
    "identify": "pinquad.api",
    "discover": "pinquad.api",
    "simulate": "pinquad.api",
    "crazyflie_log": "pinquad.io.datadir",
    "identify_many": "pinquad.results.batch",
    "Result": "pinquad.results.result",
    "Batch": "pinquad.results.batch",
    "PipelineOptions": "pinquad.pipeline.single",
    "LogOptions": "pinquad.pipeline.identify",
    "NullSettings": "pinquad.discovery.null",
    "FlightLog": "pinquad.io.logs",
    "LogFormatError": "pinquad.io.logs",
    "SimConfig": "pinquad.sim.simulator",
    "Vehicle": "pinquad.core.params",
    # PX4 logs, known-mass mode (docs/px4.md)
    "read_command_log": "pinquad.io.read",
    "CommandLog": "pinquad.io.command_log",
    "read_curve_vehicle": "pinquad.core.actuator_curve",
    "CurveVehicle": "pinquad.core.actuator_curve",
    "ActuatorCurve": "pinquad.core.actuator_curve",
    "identify_known_mass": "pinquad.identification.known_mass",
    "KnownMassSettings": "pinquad.identification.known_mass",
    "KnownMassResult": "pinquad.identification.known_mass",
    "identify_known_mass_em": "pinquad.identification.known_mass_em",
    "KnownMassEM": "pinquad.identification.known_mass_em",
}
_MOVED = {
    "Identification": "pinquad.identification.identify",
    "DiscoveryResult": "pinquad.discovery.result",
    "DiscoveryConfig": "pinquad.discovery.result",
    "VEHICLES": "pinquad.core.params",
    "PAPER_VEHICLE": "pinquad.core.params",
    "CRAZYFLIE21": "pinquad.core.params",
    "PAPER_SCENARIO": "pinquad.core.params",
}
"""Names once exported here and still resolved, with a DeprecationWarning naming their
module: users reach them through a ``Result`` (``fit.run``, ``found.effects``) or import
them from that module."""

__all__ = [
    "Batch", "FlightLog", "LogFormatError", "LogOptions", "NullSettings", "PipelineOptions",
    "Result", "SimConfig", "Vehicle", "crazyflie_log", "discover", "identify",
    "identify_many", "read_log", "simulate",
    # PX4 logs, known-mass mode (docs/px4.md)
    "ActuatorCurve", "CommandLog", "CurveVehicle", "KnownMassEM", "KnownMassResult",
    "KnownMassSettings", "identify_known_mass", "identify_known_mass_em", "read_command_log",
    "read_curve_vehicle",
]

if TYPE_CHECKING:
    from pinquad.api import discover, identify, simulate
    from pinquad.core.actuator_curve import ActuatorCurve, CurveVehicle, read_curve_vehicle
    from pinquad.core.params import Vehicle
    from pinquad.discovery.null import NullSettings
    from pinquad.identification.known_mass import (
        KnownMassResult,
        KnownMassSettings,
        identify_known_mass,
    )
    from pinquad.identification.known_mass_em import KnownMassEM, identify_known_mass_em
    from pinquad.io.command_log import CommandLog
    from pinquad.io.datadir import crazyflie_log
    from pinquad.io.logs import FlightLog, LogFormatError
    from pinquad.io.read import read_command_log, read_log
    from pinquad.pipeline.identify import LogOptions
    from pinquad.pipeline.single import PipelineOptions
    from pinquad.results.batch import Batch, identify_many
    from pinquad.results.result import Result
    from pinquad.sim.simulator import SimConfig


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        warnings.warn(f"pinquad.{name} is no longer exported: import it from {_MOVED[name]}",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(_MOVED[name]), name)
    if name not in _EXPORTS:
        raise AttributeError(f"module 'pinquad' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
