"""pinquad: EM identification of a quadcopter's mass and inertia, and discovery of what the
identified model still gets wrong.

    import pinquad

    log = pinquad.read_log("flight.csv")        # CSV, Parquet or Crazyflie micro-SD log
    fit = pinquad.identify(log)                 # fit.mass [kg], fit.inertia (3, 3), fit.stderr
    found = pinquad.discover(log, fit)          # found.selected, found.rms_before / rms_after
    batch = pinquad.identify_many(paths, executor=pool)  # one row per log, any executor
    px4 = pinquad.read_command_log("flight.ulg")  # a PX4 log: motor commands, no thrust
    # with the mass known: pinquad.identify_known_mass(px4, 1.5, positions, spins)
    # and by EM beside it: pinquad.identify_known_mass_em(px4, 1.5, positions, spins, that)

The names below are loaded on first use (``import pinquad`` stays cheap for the command
lines, whose entry modules live in this package too).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_EXPORTS = {
    "read_log": "pinquad.api",
    "identify": "pinquad.api",
    "discover": "pinquad.api",
    "simulate": "pinquad.api",
    "FlightLog": "pinquad.io.logs",
    "LogFormatError": "pinquad.io.logs",
    "Identification": "pinquad.identification.identify",
    "identify_many": "pinquad.pipeline.batch",
    "Batch": "pinquad.pipeline.batch",
    "PipelineOptions": "pinquad.pipeline.single",
    "Result": "pinquad.pipeline.single",
    "LogOptions": "pinquad.experiments.recorded",
    "DiscoveryResult": "pinquad.discovery.result",
    "DiscoveryConfig": "pinquad.discovery.result",
    "NullSettings": "pinquad.discovery.null",
    "SimConfig": "pinquad.sim.simulator",
    "Vehicle": "pinquad.core.params",
    "VEHICLES": "pinquad.core.params",
    "PAPER_VEHICLE": "pinquad.core.params",
    "CRAZYFLIE21": "pinquad.core.params",
    "PAPER_SCENARIO": "pinquad.core.params",
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
__all__ = [
    "CRAZYFLIE21", "PAPER_SCENARIO", "PAPER_VEHICLE", "VEHICLES", "Batch", "DiscoveryConfig",
    "DiscoveryResult", "FlightLog", "Identification", "LogFormatError", "LogOptions",
    "NullSettings", "PipelineOptions", "Result", "SimConfig", "Vehicle", "discover",
    "identify", "identify_many", "read_log", "simulate",
    # PX4 logs, known-mass mode (docs/px4.md)
    "ActuatorCurve", "CommandLog", "CurveVehicle", "KnownMassEM", "KnownMassResult",
    "KnownMassSettings", "identify_known_mass", "identify_known_mass_em", "read_command_log",
    "read_curve_vehicle",
]

if TYPE_CHECKING:
    from pinquad.api import discover, identify, read_log, simulate
    from pinquad.core.actuator_curve import ActuatorCurve, CurveVehicle, read_curve_vehicle
    from pinquad.core.params import CRAZYFLIE21, PAPER_SCENARIO, PAPER_VEHICLE, VEHICLES, Vehicle
    from pinquad.discovery.null import NullSettings
    from pinquad.discovery.result import DiscoveryConfig, DiscoveryResult
    from pinquad.experiments.recorded import LogOptions
    from pinquad.identification.identify import Identification
    from pinquad.identification.known_mass import (
        KnownMassResult,
        KnownMassSettings,
        identify_known_mass,
    )
    from pinquad.identification.known_mass_em import KnownMassEM, identify_known_mass_em
    from pinquad.io.command_log import CommandLog
    from pinquad.io.logs import FlightLog, LogFormatError
    from pinquad.io.read import read_command_log
    from pinquad.pipeline.batch import Batch, identify_many
    from pinquad.pipeline.single import PipelineOptions, Result
    from pinquad.sim.simulator import SimConfig


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'pinquad' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
