"""A vehicle file's simulated cycle through the pipeline (``python -m pinquad.offline
--vehicle FILE.toml``): fly the file's vehicle and log it with rotor speeds
(``experiments.vehicle_file_mc.fly_vehicle_file``), write the CSV log and its sidecar,
then read -> check -> identify it as any user's log (``pinquad.pipeline.single``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pinquad.core.params import PAPER_SCENARIO, Scenario
from pinquad.core.vehicle_file import VehicleSpec
from pinquad.experiments.recorded import LogOptions
from pinquad.experiments.vehicle_file_mc import (
    FILE_VEHICLE_BAND,
    FileVehicleCycle,
    fly_vehicle_file,
)
from pinquad.io.logs import write_log
from pinquad.pipeline.single import identify_run, read


def vehicle_file_cycle(spec: VehicleSpec, seed: int, log_path: Path,
                       scenario: Scenario = PAPER_SCENARIO,
                       options: LogOptions | None = None) -> FileVehicleCycle:
    """One cycle (module docstring): fly with generator seed ``seed``, write ``log_path``
    (CSV + sidecar), read it back, identify it with ``options`` (default: regressor
    M-step, the file vehicle's band ``FILE_VEHICLE_BAND``) and judge the reported run."""
    options = options or LogOptions(msteps=("regressor",), band=FILE_VEHICLE_BAND)
    log, flown = fly_vehicle_file(spec, seed, scenario)
    write_log(log, log_path)
    run = identify_run(read(log_path), options)
    assert run.verdict is not None  # identify_run judges the run
    return FileVehicleCycle(
        seed=seed, log=log_path, truth=np.concatenate([[spec.mass], np.diag(spec.inertia)]),
        estimate=np.concatenate([[run.mass], np.diag(run.inertia)]),
        stderr=np.asarray(run.stderr, dtype=float), converged=bool(run.converged),
        e_steps=int(run.e_steps or 0), verdict=run.verdict.overall,
        max_miss=float(flown["max_miss_m"]), crashed=bool(flown["crashed"]))
