"""The simulated world on its own (no identification; ``python -m pinquad.flight``).

Flies the paper's scenario over seeded runs and prints (1) how close the vehicle comes
to every waypoint, for the paper vehicle and the Crazyflie 2.1 (the same scenario
scaled by 0.3), and (2) the paper's Table I layout for the sensor-A EKF (position and
Euler-angle error, mean / std / max over all steps of all runs) beside the paper's
numbers, with the filter's consistency: the time-averaged normalised estimation error
squared (NEES) of each run against its 95 % chi-square band.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from pinquad.core.conventions import wrap_angle
from pinquad.core.params import PAPER_SCENARIO, VEHICLES
from pinquad.sim.simulator import SimConfig, simulate

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FlightStats:
    """One run: vehicle, seed, nav tuning; closest approach to each waypoint (M,) [m];
    crashed, lifted_off; position and Euler error norms per step (N,) [m, rad]; time-
    averaged NEES (12 states) and its number of steps."""

    vehicle: str
    seed: int
    tuning: str
    miss: Array
    crashed: bool
    lifted_off: bool
    pos_err: Array
    euler_err: Array
    nees_mean: float
    n_steps: int


def fly(job: tuple[str, int, str]) -> FlightStats:
    """One seeded flight of the paper's scenario (the Crazyflie flies it scaled by 0.3):
    job = (vehicle name, seed, navigation tuning ``tuned`` or ``paper``)."""
    vehicle, seed, tuning = job
    veh = VEHICLES[vehicle]
    scenario = PAPER_SCENARIO if vehicle == "paper" else PAPER_SCENARIO.scaled(0.3)
    f = simulate(SimConfig(vehicle=veh, scenario=scenario, sensor="A", nav_tuning=tuning,
                           nav_initial_error=True),
                 np.random.default_rng(seed))
    err = f.states - f.nav_state
    err[:, 6:9] = wrap_angle(err[:, 6:9])
    nees = np.einsum("ki,kij,kj->k", err, np.linalg.inv(f.nav_cov), err)
    return FlightStats(vehicle, seed, tuning, f.waypoint_miss, f.crashed, f.lifted_off,
                       np.linalg.norm(err[:, 0:3], axis=1), np.linalg.norm(err[:, 6:9], axis=1),
                       float(nees.mean()), int(nees.size))


def nees_band(n_steps: int, dim: int = 12, level: float = 0.95) -> tuple[float, float]:
    """95 % band of the time average of n_steps independent chi-square(dim) values."""
    lo = chi2.ppf((1 - level) / 2, dim * n_steps) / n_steps
    hi = chi2.ppf(1 - (1 - level) / 2, dim * n_steps) / n_steps
    return float(lo), float(hi)
