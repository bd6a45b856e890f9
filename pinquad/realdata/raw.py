"""A measured flight before resampling (:class:`RawFlight`), read from a micro-SD log or
made from a simulated flight so the measured-flight pipeline can be checked against a
known truth."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.params import CRAZYFLIE21, PAPER_SCENARIO, process_noise_for
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.sdlog import SdFlight, measured_samples
from pinquad.sim.simulator import Flight, SimConfig, simulate
from pinquad.vehicle.actuators import ActuatorModel

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PoseSamples:
    """Motion-capture poses at their own times.

    t (P,) [s, log clock]; position (P, 3) [m, world]; euler (P, 3) roll, pitch, yaw
    [rad] (NaN where the quaternion was missing or not unit).
    """

    t: Array
    position: Array
    euler: Array


@dataclass(frozen=True)
class RawFlight:
    """What :func:`build_observations` needs of a measured flight, before resampling.

    log: the flight at its own rate (rows at log.t [s]) with ``rpm`` (N, n) [rev/min] of
    its n rotors; pose: motion-capture samples (None: use the log's own position / euler
    rows); pwm (N, n) [0..65535], one command per rotor, or None; onboard_pos (N, 3) [m]
    or None: the vehicle's own position estimate; vbat_stuck: the battery reading is not
    a measurement.
    """

    log: FlightLog
    pose: PoseSamples | None = None
    pwm: Array | None = None
    onboard_pos: Array | None = None


def raw_flight(log: FlightLog) -> RawFlight:
    """The measured-flight pipeline's input: the log with its raw poses, motor commands
    and onboard position (``FlightLog.measured``, filled by the micro-SD reader) when it
    carries them; a table log uses its own position and attitude rows."""
    m = log.measured
    if m is None:
        return RawFlight(log=log)
    pose = None
    if m.pose_t is not None:
        pose = PoseSamples(t=m.pose_t, position=m.pose_position, euler=m.pose_euler)
    return RawFlight(log=log, pose=pose, pwm=m.pwm, onboard_pos=m.onboard_position)


def raw_from_sdflight(flight: SdFlight) -> RawFlight:
    """A :class:`RawFlight` from ``pinquad.io.sdlog.SdFlight``: motion capture from the raw
    ``estPose`` records (not the copies already snapped to the 500 Hz rows;
    ``sdlog.measured_samples``)."""
    return raw_flight(replace(flight.log, measured=measured_samples(flight)))


def raw_from_simulated(flight: Flight, actuator: ActuatorModel | None = None) -> RawFlight:
    """A simulated flight (``pinquad.sim.simulator.Flight`` flown with sensor B) as a measured log,
    so that the measured-flight pipeline can be checked against a known truth: rotor
    speeds from the logged commanded wrench through the inverse X mixer,

        T = A^-1 [F, tau],   omega_i = sqrt(T_i / kf) [rad/s]  (as rev/min; T_i >= 0),

    with A and kf of ``actuator`` (default: ``ActuatorModel()``, the shared constants);
    the pose stream from the flight's position and Euler samples, the gyro and the
    velocity samples as logged. Raises ValueError if the flight has no pose samples."""
    actuator = actuator or ActuatorModel()
    onboard = flight.onboard
    if not (np.isfinite(onboard.euler).any() and np.isfinite(onboard.position).any()):
        raise ValueError(f"sensor {flight.config.sensor} logs no pose: the measured-flight "
                         "pipeline needs position and attitude samples (fly sensor B)")
    thrust = np.linalg.solve(actuator.allocation(), np.asarray(flight.inputs, float).T).T
    rpm = np.sqrt(np.maximum(thrust, 0.0) / actuator.kf) * 60.0 / (2.0 * np.pi)
    n = flight.t.size
    nan3 = np.full((n, 3), np.nan)
    log = FlightLog(t=flight.t.copy(), position=nan3, velocity=onboard.velocity.copy(),
                    euler=nan3, gyro=onboard.gyro.copy(), accel=nan3, rpm=rpm,
                    meta=LogMeta(vehicle=flight.config.vehicle.name,
                                 gravity=flight.config.vehicle.gravity,
                                 source=f"simulation (sensor {flight.config.sensor})"))
    pose = PoseSamples(t=flight.t.copy(), position=onboard.position.copy(),
                       euler=onboard.euler.copy())
    return RawFlight(log=log, pose=pose)


def simulated_crazyflie(factor: float, seed: int, sensor: str = "B") -> Flight:
    """A simulated closed-loop flight of the Crazyflie 2.1 (``pinquad.sim.simulator.Flight``): the
    offline command's scenario (the paper's, scaled by 0.3), the sensor set ``sensor``,
    the simulator's torque process noise multiplied by ``factor``, generator seed
    ``seed``; the diagnostics' known-truth counterpart of a measured flight."""
    config = SimConfig(vehicle=CRAZYFLIE21, sensor=sensor, scenario=PAPER_SCENARIO.scaled(0.3),
                       process_noise=process_noise_for(CRAZYFLIE21).scaled(1.0, factor))
    return simulate(config, np.random.default_rng(seed))
