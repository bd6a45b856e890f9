"""The jobs of the real-vehicle table (``python -m pinquad.realdata``), one measured log
per job in worker processes: read -> check (the pipeline's steps,
``pinquad.pipeline.single``) -> observations with the table's channels, fault handling
and kf -> identify (``realdata.identify_real``, with the rotor inertia J_r pooled over
the flights or fitted per flight) -> discover (``pipeline.discover
.measured_effects``) -> judge against the vehicle's range and reference.

The identification is not the pipeline's ``identify`` of one log: J_r comes from the
other flights (a first pass fits it per flight on the pool logs), and the table keeps
the band-passed regressions that pass needs."""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pinquad.discovery.null import NullSettings
from pinquad.identification.identify import Identification
from pinquad.identification.reference import vehicle_reference
from pinquad.identification.verdict import VerdictEvidence, judge, vehicle_range
from pinquad.identification.verdict_evidence import data_evidence
from pinquad.io.logs import LogFormatError
from pinquad.models.ssm import corrected
from pinquad.pipeline.discover import measured_effects
from pinquad.pipeline.judge import error_failures
from pinquad.pipeline.single import check, read
from pinquad.realdata.consistency import FlightRow
from pinquad.realdata.dataset import default_guess
from pinquad.realdata.identify import identify_real, measured_fit
from pinquad.realdata.observation_options import RealDataOptions
from pinquad.realdata.observations import build_observations
from pinquad.realdata.raw import raw_flight
from pinquad.realdata.thrust import thrust_coefficient
from pinquad.vehicle.actuators import ThrustCoefficient

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TableJob:
    """One row of the table: the log's path, EM settings and the data directory;
    discover: the null calibration of effect discovery on the fit, whose summary
    (``measured_effects``) becomes ``FlightRow.effects`` (None: discovery not run); kf:
    the thrust coefficient (None: fitted to the ``stand`` folder); vehicle: a shipped name or a vehicle file,
    whose [guess] EM starts from and whose body the verdict's plausible range is."""

    path: Path
    options: RealDataOptions
    max_iterations: int
    information: bool
    band: tuple[float, float]
    stand: Path
    fit_rotor_inertia: bool = True
    keep_band_stats: bool = False
    rotor_source: str = ""
    discover: NullSettings | None = None
    kf: ThrustCoefficient | None = None
    vehicle: str = "crazyflie21"


def run_table_job(job: TableJob) -> FlightRow | str:
    """One flight through the table's steps (module docstring; a worker of ``python -m
    pinquad.realdata``); a log that cannot be read, checked or identified gives the
    reason as a string instead. J_r: fitted per flight if ``job.fit_rotor_inertia`` and
    ``job.options.rotor_inertia`` is None, else the options' fixed value (0 included)."""
    try:
        kf = job.kf if job.kf is not None else thrust_coefficient(job.stand)
        real = build_observations(raw_flight(check(read(job.path))), job.options, kf)
        mass0, inertia0, _ = default_guess(job.vehicle)
        run = identify_real(real, mass0, inertia0, job.max_iterations, job.information,
                            job.band, fit_rotor_inertia=job.fit_rotor_inertia,
                            keep_band_stats=job.keep_band_stats)
    except (LogFormatError, ValueError) as exc:
        return str(exc)
    assert run.theta is not None and run.posterior is not None  # identify_real keeps them
    effects = None if job.discover is None else measured_effects(real.obs, run.theta,
                                                                 run.posterior, job.discover)
    evidence = replace(real_evidence(run), reference=vehicle_reference(job.vehicle),
                       error_failures=error_failures(run))
    verdict = judge(run.mass, run.inertia, run.stderr, evidence, vehicle_range(job.vehicle))
    # the row goes back from the worker without the smoothed posterior and observations
    # (tens of MB per flight; the table reads only the estimates and their errors)
    kept = replace(run, verdict=verdict, posterior=None, observations=None)
    return FlightRow(job.path.name, kept, job.rotor_source, effects, evidence, job.vehicle)


def real_evidence(run: Identification) -> VerdictEvidence:
    """What a measured flight's verdict (``pinquad.identification.verdict``) rests on
    beside its total standard errors: the torques (with the fitted nuisance moment)
    explaining the angular acceleration on the M-step's band, and the EKF's innovation
    consistency at the estimate (the run's smoothed states)."""
    theta, obs, post = run.theta, run.observations, run.posterior
    assert theta is not None and obs is not None and post is not None
    plain = replace(theta.without_nuisance(), inertia=run.inertia)
    return data_evidence(corrected(obs, theta), plain, post.mean, tuple(measured_fit(run).band))


def run_jobs(jobs: Sequence[TableJob], executor: Executor) -> list[FlightRow | str]:
    """run_table_job over ``jobs`` run by ``executor`` (``pinquad.core.execution``: process
    pool, this process or a Dask cluster), the results in job order."""
    # Longest logs first so the workers finish together; the results are keyed by job.
    order = sorted(range(len(jobs)), key=lambda i: -jobs[i].path.stat().st_size)
    done = dict(zip(order, executor.map(run_table_job, [jobs[i] for i in order]), strict=True))
    return [done[i] for i in range(len(jobs))]
