"""Measured rotor-speed logs through the pipeline's read and check, for the commands that
work on a log's EM observations rather than on its whole identification (``python -m
pinquad.response``, ``python -m pinquad.axis_inertia``, ``python -m
pinquad.realdiscovery``): read -> check (``pinquad.pipeline.single``) -> the 100 Hz
observations of the log's vehicle (``realdata.vehicle_check.measured_observations``: its
mixer, fault thresholds and kf, refused when the vehicle contradicts the log) -> the
command's own step (apparent inertia, per-axis inertia, or base EM with the flight's own
effect discovery, ``experiments.realdiscovery.fit_flight``)."""

from __future__ import annotations

from pathlib import Path

from pinquad.pipeline.single import check, read
from pinquad.realdata.observations import RealObservations
from pinquad.realdata.vehicle_check import measured_observations
from pinquad.vehicle.actuators import ThrustCoefficient


def measured_log(path: str | Path, vehicle: str | None = None,
                 kf: ThrustCoefficient | None = None) -> RealObservations:
    """The EM observations of the measured log at ``path`` (module docstring), its vehicle
    ``vehicle`` (a shipped name or a vehicle file relative to the working directory;
    None: the log's own) and kf ``kf`` when given (None: the vehicle's). Raises
    LogFormatError (unreadable, implausible or without rotor speeds) or ValueError (the
    vehicle contradicts the log, nothing usable remains), the file named."""
    return measured_observations(check(read(path, vehicle)), kf=kf)
