"""Observation sources: what the E-step sees of a FlightLog.

A: the paper's sensor-A EKF estimate of position and velocity (the onboard one when the
   log carries it in ``est_*`` columns, else the filter re-run on the log's position /
   accelerometer / gyro samples), with sensor A's own gyro samples for the rates. The
   filter's attitude estimate is left out: its errors follow the manoeuvres, and used as
   a white-noise measurement it biased the inertia by -2 to -3 % (seeds 1 and 2);
B: position, velocity, Euler angles, gyro as logged ("full state");
C: position, velocity, gyro ("partial", no attitude).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.ekf import run_filter
from pinquad.core.conventions import rotation_from_euler
from pinquad.core.effect_vocabulary import vehicle_ground_radius
from pinquad.io.logs import FlightLog
from pinquad.io.timebase import clock_times, gap_steps, uniform_step
from pinquad.models.attitude_range import SingularAttitude
from pinquad.models.contact import (
    NO_FLOOR,
    ContactDetection,
    ContactSettings,
    FloorLevel,
    detect_floor_contact,
    floor_level,
    touching_transitions,
)
from pinquad.models.navigation import NavTuning, SensorANavModel
from pinquad.models.ssm import Observations

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SOURCE_CHANNELS = {
    "A": ("pos", "vel", "gyro"),
    "B": ("pos", "vel", "euler", "gyro"),
    "C": ("pos", "vel", "gyro"),
}


def _first_valid(a: Array) -> Array:
    ok = ~np.isnan(a).any(axis=1)
    return a[np.argmax(ok)] if ok.any() else np.zeros(a.shape[1])


def sensor_a_estimate(log: FlightLog, tuning: NavTuning | None = None) -> Array:
    """The paper's sensor-A EKF run over the log: filtered states (N, 12)."""
    dt = log.dt
    x0 = np.zeros(12)
    x0[0:3] = _first_valid(log.position)
    model = SensorANavModel(log.accel, dt, tuning or NavTuning.tuned(dt), x0=x0,
                            gravity=log.meta.gravity)
    ys = np.column_stack([log.position, log.gyro])
    return run_filter(model, ys).filtered_mean


@dataclass(frozen=True)
class FloorContact:
    """The log's rows touching the floor and where that came from.

    rows (N,) bool: the rows treated as contact; source: ``flags`` (the log's contact
    column) or ``data`` (found by ``models.contact.detect_floor_contact``, margin
    included); detection: the detector's result (also run beside the flags, to compare),
    None if the log has no height or thrust to run it on.
    """

    rows: BoolArray
    source: str
    detection: ContactDetection | None

    def transitions(self) -> int:
        """Transitions k -> k+1 touching a contact row at either end."""
        return int(touching_transitions(self.rows).sum())

    def describe(self) -> str:
        """The report's exclusion line (without the count)."""
        if self.source == "flags":
            words = "touching the floor (the log's contact flags)"
            if self.detection is not None:
                flagged = touching_transitions(self.rows)
                found = touching_transitions(self.detection.widened)
                words += (f"; found from the data: {int(found.sum())} transitions, "
                          f"{int((found & flagged).sum())} of the {int(flagged.sum())} flagged")
            return words
        assert self.detection is not None
        return (f"touching the floor, found from the data (no contact flags: "
                f"{self.detection.describe()})")


def floor_contact(log: FlightLog, mass_guess: float,
                  settings: ContactSettings | None = None) -> FloorContact:
    """The log's contact rows: its contact flags if it has them, else those found from
    the data (``detect_floor_contact`` on height, vertical velocity, thrust and R_33 with
    ``mass_guess`` [kg], widened by the settings' margin)."""
    detection = None
    if log.thrust is not None and np.isfinite(log.position[:, 2]).any():
        tilt = rotation_from_euler(log.euler)[:, 2, 2]
        detection = detect_floor_contact(log.t, log.position[:, 2], log.velocity[:, 2],
                                         log.thrust, tilt, mass_guess, log.meta.gravity,
                                         settings, np.hypot(log.velocity[:, 0],
                                                            log.velocity[:, 1]))
    if log.contact is not None:
        return FloorContact(log.contact.copy(), "flags", detection)
    rows = detection.widened if detection is not None else np.zeros(log.n, dtype=bool)
    return FloorContact(rows, "data", detection)


def interval_inputs(logged: Array, actuation: str) -> Array:
    """(N, 4) the thrust [N] and torques [N m] each transition k -> k+1 applies.

    Every model of pinquad integrates x_{k+1} = x_k + dt f(x_k, u_k), u_k held over the
    interval. ``held`` logs (pinquad's simulator) are that: u_k = the logged row. A
    ``sampled`` log holds a faster controller's command at each row's instant, so what
    acted over [t_k, t_k+1] is its mean, (u_k + u_k+1) / 2 to O(dt^2) (trapezoid; the
    last row keeps its value). Taken as held, a sampled input leads the state by half a
    step: on flightgen's 100 Hz logs that alone put I_xx 32 % high (docs/discovery.md).
    """
    if actuation == "held":
        return logged
    out = logged.copy()
    out[:-1] = 0.5 * (logged[:-1] + logged[1:])
    return out


def observations(log: FlightLog, source: str, contact: FloorContact | None = None,
                 singular: SingularAttitude | None = None) -> Observations:
    """Build the E-step's observations of a log for source A, B or C.

    Transitions into or out of a contact row are excluded from the M-step; those into one
    are also resets for the E-step (``Observations.resets``). The contact rows are
    ``contact.rows``; without it, the log's contact flags, else none (the data-based
    detection needs a mass guess: pass ``floor_contact(log, mass_guess)``). Transitions
    touching ``singular.rows`` (``attitude_range.near_euler_singularity``) are excluded
    and resets too, as are the steps over a log gap (``io.timebase.gap_steps``). The inputs are
    what each transition applies (``interval_inputs`` by ``log.meta.actuation``); a
    sampled log's rows themselves are kept as ``samples``, and its flight is continuous
    (``Observations.continuous``).
    """
    if log.thrust is None or log.torque is None:
        raise ValueError("the log has no thrust/torque actuation; convert rotor speeds first")
    if source == "A":
        # The vehicle's own estimate is what its controller used; re-run the filter
        # only when the log does not carry it.
        est = log.onboard if log.onboard is not None else sensor_a_estimate(log)
        ys = np.column_stack([est[:, 0:6], log.gyro])
        channels = SOURCE_CHANNELS["A"]
    elif source in ("B", "C"):
        channels = SOURCE_CHANNELS[source]
        blocks = {"pos": log.position, "vel": log.velocity, "euler": log.euler, "gyro": log.gyro}
        ys = np.column_stack([blocks[ch] for ch in channels])
    else:
        raise ValueError(f"unknown observation source {source!r}; expected A, B or C")
    x0 = np.zeros(12)
    p0 = np.full(12, 1.0)
    for ch, sl in (("pos", slice(0, 3)), ("vel", slice(3, 6)), ("euler", slice(6, 9)),
                   ("gyro", slice(9, 12))):
        if ch in channels:
            i = channels.index(ch)
            x0[sl] = _first_valid(ys[:, 3 * i:3 * i + 3])
    exclude = np.zeros(log.n, dtype=bool)
    resets = np.zeros(log.n, dtype=bool)
    # a log gap (io.timebase, judged on the log's own step) is no transition of the
    # flight: the rows are taken as evenly spaced at the step of the log's clock
    # (io.timebase.clock_times: jitter is not carried), so a gap would be one such step
    exclude[:-1] |= gap_steps(log.t)
    resets[:-1] |= gap_steps(log.t)
    rows = contact.rows if contact is not None else log.contact
    if rows is not None:
        # a transition touching the floor at either end is not free flight
        exclude |= rows
        exclude[:-1] |= rows[1:]
        # touching down, the floor stops and levels the vehicle within the step: the
        # smoother must not carry the flight dynamics across that (ssm.RESET_VAR)
        resets[:-1] = rows[1:]
    if singular is not None:
        # within the excursion every transition is one the Euler-angle state cannot follow
        touching = singular.touching()
        exclude |= touching
        resets |= touching
    logged = np.column_stack([log.thrust, log.torque])
    inputs = interval_inputs(logged, log.meta.actuation)
    samples = logged.copy() if log.meta.actuation == "sampled" else None
    # the ground-effect radius of the vehicle the log names (a log naming none: the default)
    radius = vehicle_ground_radius(log.meta.vehicle if log.meta.vehicle_named else None)
    # a sampled log is a faster controller's record of a continuous flight; a held one is
    # pinquad's simulator, which moves by explicit Euler at the log's step
    clock = clock_times(log.t)
    return Observations(t=clock, dt=uniform_step(clock), inputs=inputs, channels=channels, ys=ys, x0=x0,
                        p0=p0, exclude=exclude, resets=resets, ground_radius=radius,
                        samples=samples, continuous=log.meta.actuation == "sampled",
                        floor=log_floor(log, contact))


def log_floor(log: FlightLog, contact: FloorContact | None) -> FloorLevel:
    """Where the log shows the floor (``models.contact.floor_level``): the rows its
    contact flags mark (a simulator flags the rows resting on the floor), else the floor
    level of the contact found from the data; no contact (or no ``contact`` given and
    no flags, or flags too brief to place it): z = 0."""
    z = log.position[:, 2]
    min_rows = round(ContactSettings().sustain / log.dt) if log.n > 1 else 1
    if contact is not None and contact.source == "data":
        found = contact.detection
        if found is None:
            return NO_FLOOR
        return floor_level(z, None, min_rows, found.contact, found.floor_height)
    flags = contact.rows if contact is not None else log.contact
    return floor_level(z, flags, min_rows)
