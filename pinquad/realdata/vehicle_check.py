"""Whether a measured rotor-speed log and its vehicle agree: the vehicle's mixer and thrust
coefficient for the log, refused when the file contradicts the log (another number of
rotors, a hover thrust above the file's maximum, rotors spinning beyond it), and the
observations and search range of such a log read with them."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from pinquad.core.params import VehicleRange
from pinquad.core.vehicle_file import is_vehicle_file, load_vehicle
from pinquad.identification.verdict import vehicle_range
from pinquad.io.logs import FlightLog, LogFormatError
from pinquad.realdata.observation_options import RealDataOptions, options_for_sensor, options_for_vehicle
from pinquad.realdata.observations import RealObservations, build_observations
from pinquad.realdata.raw import raw_flight
from pinquad.realdata.thrust import vehicle_thrust_coefficient
from pinquad.vehicle.actuators import ThrustCoefficient

VELOCITY_CHANNELS = ("vel", "euler", "gyro")
"""The channels of a measured log without any position sample (``measured_observations``)."""


def measured_vehicle(log: FlightLog) -> tuple[RealDataOptions, ThrustCoefficient | None]:
    """The mixer options and kf of a measured log's vehicle (``log.meta.vehicle``: a
    shipped name or a vehicle file). The shipped crazyflie21 keeps the defaults (kf from
    the data directory's thrust stand). Raises ValueError when the file contradicts the
    log: another number of rotors, or a hover thrust above the file's maximum."""
    vehicle = log.meta.vehicle
    assert log.rpm is not None
    n = log.rpm.shape[1]
    if not is_vehicle_file(vehicle):
        if n != len(RealDataOptions().spin):
            raise ValueError(f"{log.meta.source}: the log has {n} rotor speeds (rpm_1..rpm_{n}) "
                             f"but vehicle {vehicle!r} (read as the shipped crazyflie21) has "
                             f"{len(RealDataOptions().spin)} rotors; give the vehicle file that "
                             "matches the log (--vehicle FILE)")
        return RealDataOptions(), None
    spec = load_vehicle(vehicle)
    options = options_for_vehicle(spec)
    if n != spec.n_rotors:
        raise ValueError(f"{log.meta.source}: the log has {n} rotor speeds (rpm_1..rpm_{n}) but "
                         f"the vehicle file {spec.source} has {spec.n_rotors} rotors")
    kf = vehicle_thrust_coefficient(spec)
    top = spec.max_total_thrust()
    mass = spec.reference.mass if spec.reference.mass is not None else spec.mass
    if top is not None and mass * log.meta.gravity > top:
        raise ValueError(f"{spec.source}: hover needs {mass * log.meta.gravity:.3f} N for "
                         f"{mass * 1e3:.1f} g but the file's rotors give at most {top:.3f} N "
                         f"({spec.n_rotors} x max_thrust {spec.actuators.max_thrust} N)")  # type: ignore[union-attr]
    if top is not None:
        over_max_thrust(log, spec.actuators.max_thrust, kf.kf, spec.source)  # type: ignore[union-attr]
    return options, kf


def over_max_thrust(log: FlightLog, max_thrust: float, kf: float, where: object,
                    share: float = 0.01) -> None:
    """Raise ValueError when the log's rotors spin faster than the file's ``max_thrust``
    [N] allows, omega_max = sqrt(max_thrust / kf) [rad/s], in more than ``share`` of the
    rows with a reading (a rotor that often makes more thrust than its maximum says the
    file's kf or max_thrust is not this vehicle's); the message names the column."""
    assert log.rpm is not None
    rpm_max = math.sqrt(max_thrust / kf) * 60.0 / (2.0 * math.pi)
    rpm = np.asarray(log.rpm, dtype=float)
    finite = np.isfinite(rpm)
    over = (np.where(finite, rpm, 0.0) > rpm_max).sum(axis=0) / np.maximum(finite.sum(axis=0), 1)
    if over.max() > share:
        i = int(np.argmax(over))
        raise ValueError(f"{log.meta.source}: column rpm_{i + 1} reads above {rpm_max:.0f} "
                         f"rev/min, the speed of the vehicle file's max_thrust {max_thrust:g} N "
                         f"at kf = {kf:.4e} N/(rad/s)^2 ({where}), in {100 * over[i]:.1f} % of "
                         f"its rows (median {np.nanmedian(rpm[:, i]):.0f} rev/min); expected at "
                         f"most {100 * share:g} %: the file's kf or max_thrust is not this "
                         "vehicle's")


def measured_observations(log: FlightLog, sensor: str | None = None,
                          kf: ThrustCoefficient | None = None, faults: str | None = None
                          ) -> RealObservations:
    """The EM observations of a measured rotor-speed log on the 100 Hz grid
    (``realdata.observations.build_observations``), its rotor speeds read with its
    vehicle's mixer and kf (:func:`measured_vehicle`; ``kf`` given: that thrust
    coefficient instead, e.g. the shipped crazyflie21's from another data directory's
    thrust stand) and the channels of the paper's source ``sensor`` (None: every channel
    the log has; a log without any position sample, a velocity-only export, is observed
    through its velocity, attitude and rates: the smoother carries the unobserved
    position as the velocity's integral, its variance growing but finite, and the
    translational dynamics rest on the velocity); faults: how implausible readings are
    handled (``RealDataOptions.faults``; None: the vehicle's default). Raises LogFormatError for a log
    without rotor speeds, ValueError when the vehicle contradicts the log or nothing
    usable remains."""
    if log.rpm is None:
        raise LogFormatError(f"{log.meta.source}: no rpm_1..rpm_4 columns; expected rotor "
                             "speeds for the actuator model")
    options, vehicle_kf = measured_vehicle(log)
    kf = vehicle_kf if kf is None else kf
    raw = raw_flight(log)
    options = options_for_sensor(sensor, options if faults is None
                                 else replace(options, faults=faults))
    pose = raw.pose.position if raw.pose is not None else log.position
    if not (sensor is None and not np.isfinite(pose).any()
            and np.isfinite(log.velocity).any()):
        return build_observations(raw, options, kf)
    real = build_observations(raw, replace(options, channels=VELOCITY_CHANNELS), kf)
    return replace(real, notes=(*real.notes, "no position sample in the log: observed "
                                "through its velocity, attitude and rates; the position "
                                "state is unobserved"))


def measured_search_range(log: FlightLog) -> VehicleRange | None:
    """The range EM searches on a measured log: that of the vehicle whose mixer reads its
    rotor speeds (a vehicle file, else the shipped crazyflie21: a name that is not a file
    reads as crazyflie21)."""
    vehicle = log.meta.vehicle
    return vehicle_range(vehicle if is_vehicle_file(vehicle) else "crazyflie21")
