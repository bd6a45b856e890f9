"""One Monte Carlo cycle of the offline experiment: fly, log, identify with EM.

A cycle flies the paper's scenario once with a given sensor set (A, B or C), then runs
EM from the paper's initial guess with each requested M-step on that same log, and
(optionally) the observed information at the estimate and at the truth.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, VEHICLES
from pinquad.identification.identify import Identification, identify
from pinquad.io.logs import FlightLog
from pinquad.models.sources import observations
from pinquad.sim.simulator import SimConfig, flight_log, simulate, waypoint_report

Array = NDArray[np.float64]

SENSOR_INDEX = {"A": 0, "B": 1, "C": 2}


def flight_seed(seed: int, sensor: str, cycle: int) -> int:
    """The seed of cycle ``cycle`` for ``sensor`` under base seed ``seed``."""
    return int(seed) * 100_000 + SENSOR_INDEX[sensor] * 1000 + int(cycle)


@dataclass(frozen=True)
class CycleJob:
    """What one worker does: sensor, cycle index, base seed, vehicle, E-step, M-steps."""

    sensor: str
    cycle: int
    seed: int
    vehicle: str = "paper"
    estep: str = "rts"
    msteps: tuple[str, ...] = ("regressor", "paper")
    max_iterations: int = 100
    information: bool = True
    keep_log: bool = False


@dataclass(frozen=True)
class CycleResult:
    """A cycle: the flight's figures and each M-step's identification."""

    sensor: str
    cycle: int
    seed: int
    truth_mass: float
    truth_inertia: Array
    flight: dict
    runs: tuple[Identification, ...]
    log: FlightLog | None = None
    smoothed: Array | None = None
    seconds: float = 0.0
    excluded: dict = field(default_factory=dict)


def run_cycle(job: CycleJob) -> CycleResult:
    """Fly one seeded flight with the job's sensor and identify it with each M-step."""
    t0 = time.perf_counter()
    vehicle = VEHICLES[job.vehicle]
    seed = flight_seed(job.seed, job.sensor, job.cycle)
    config = SimConfig(vehicle=vehicle, sensor=job.sensor)
    if job.vehicle != "paper":
        config = SimConfig(vehicle=vehicle, sensor=job.sensor,
                           scenario=config.scenario.scaled(0.3))
    flight = simulate(config, np.random.default_rng(seed))
    log = flight_log(flight)
    obs = observations(log, job.sensor)
    mass0, inertia0 = PAPER_INITIAL_MASS, PAPER_INITIAL_INERTIA
    if job.vehicle != "paper":
        mass0, inertia0 = vehicle.mass * PAPER_INITIAL_MASS / 0.18, vehicle.inertia * 0.5
    runs = []
    smoothed = None
    # the paper's procedure, not the pipeline's identify step: its guess, EM with the
    # shared over-relaxation the paper's figures were measured with
    # (``pipeline.identify.RECORDED_PER_PARAMETER``), the truth's likelihood beside it
    for mstep in job.msteps:
        ident, post = identify(obs, mass0, inertia0, vehicle.gravity, job.estep, mstep,
                               job.max_iterations, job.information,
                               truth=(vehicle.mass, vehicle.inertia))
        runs.append(ident)
        if mstep == job.msteps[0]:
            smoothed = post.mean
    return CycleResult(
        sensor=job.sensor, cycle=job.cycle, seed=seed, truth_mass=vehicle.mass,
        truth_inertia=np.asarray(vehicle.inertia), flight=waypoint_report(flight),
        runs=tuple(runs), log=log if job.keep_log else None,
        smoothed=smoothed if job.keep_log else None, seconds=time.perf_counter() - t0,
        excluded={"contact_transitions": int(obs.exclude.sum())},
    )


def run_cycles(jobs: Sequence[CycleJob], executor: Executor, progress: bool = True
               ) -> list[CycleResult]:
    """Every job's cycle, in job order, run by ``executor`` (``pinquad.core.execution``:
    the process pool, this process or a Dask cluster; the same numbers on each), with a
    progress bar on stderr unless ``progress`` is False."""
    results: list[CycleResult] = []
    with tqdm(total=len(jobs), desc="cycles", unit="cycle", file=sys.stderr,
              disable=not progress) as bar:
        for res in executor.map(run_cycle, jobs):
            results.append(res)
            bar.update()
    return results
