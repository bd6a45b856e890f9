"""A recorded log made ready for the online replay (``python -m pinquad.online --log``):
read -> check -> observations, the pipeline's read and check steps
(``pinquad.pipeline.single``) followed by the observations the streaming estimator
(``pinquad.experiments.online_replay``) runs on.

A Crazyflie micro-SD log is a measured flight: its rotor speeds through its vehicle's
mixer and kf on the 100 Hz grid (``realdata.vehicle_check.measured_observations``, as
the offline identification reads it). Every log starts EM from the offline
identification's initial guess (``pipeline.identify.initial_guess``) and is judged
on its plausible range (``identify.plausible_range``). Any other log is
observed through the paper's sources (``models.sources.observations``; the sensor asked
for, else B when it has attitude samples, else C).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.core.params import VehicleRange
from pinquad.identification.search_range import search_range
from pinquad.io.logs import FlightLog
from pinquad.models.sources import observations
from pinquad.models.ssm import Observations
from pinquad.pipeline.identify import initial_guess, plausible_range
from pinquad.pipeline.single import check, read
from pinquad.realdata.vehicle_check import measured_observations, measured_search_range

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ReplayInput:
    """What the online replay streams and judges.

    log: the log as the E-step sees it (a measured flight's: resampled to its grid);
    obs: its observations; mass0 [kg], inertia0 (3, 3) [kg m^2]: where EM starts;
    bounds: the range EM searches (None: unbounded); vrange: the vehicle's plausible
    range the verdict judges against (None: none known); rotor_acc (N,) [rad/s^2]: a
    measured flight's summed signed rotor acceleration (None for other logs);
    measured_thrust: a measured flight's (kf's, the yaw ratio's) relative uncertainty
    [-] (None for other logs).
    """

    log: FlightLog
    obs: Observations
    mass0: float
    inertia0: Array
    bounds: VehicleRange | None
    vrange: VehicleRange | None
    rotor_acc: Array | None = None
    measured_thrust: tuple[float, float] | None = None


def replay_input(path: str | Path, sensor: str | None = None) -> ReplayInput:
    """read -> check -> observations of the log at ``path`` (module docstring); sensor:
    the paper's source for a log that is not a measured flight (None: B with attitude
    samples, else C). Raises LogFormatError / ImplausibleLogError / ValueError naming the
    log when it cannot be replayed."""
    log = check(read(path))
    mass0, inertia0, _ = initial_guess(log)
    if log.measured is not None:  # a Crazyflie micro-SD log
        real = measured_observations(log)
        return ReplayInput(real.log, real.obs, mass0, inertia0, measured_search_range(log),
                           plausible_range(log),
                           real.rotor_acc, (real.kf.rel_se,
                                            real.options.yaw_ratio_se / real.options.yaw_ratio))
    sensor = sensor or ("B" if not np.isnan(log.euler).all() else "C")
    return ReplayInput(log, observations(log, sensor), mass0, inertia0, search_range(log),
                       plausible_range(log))
