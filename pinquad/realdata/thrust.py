"""The rotor thrust coefficient kf of the measured flights, from the thrust stand.

Flight data identify only kf / m and kf L / I (every input is proportional to kf), so
the identified mass and inertia scale exactly with the kf taken from the thrust stand;
:func:`thrust_coefficient` picks kf and its uncertainty, and
``pinquad.realdata.identify.identify_real`` propagates that uncertainty into the standard
errors.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from pinquad.core.vehicle_file import VehicleSpec, shipped_path
from pinquad.realdata.dataset import stand_dir
from pinquad.vehicle.actuators import KF_CRAZYFLIE, ThrustCoefficient, fit_thrust_stand


@lru_cache(maxsize=8)
def thrust_coefficient(directory: Path | None = None) -> ThrustCoefficient:
    """kf from the thrust-stand CSVs in ``directory`` (default: :func:`stand_dir`).

    Each CSV is one run of the stand; the runs disagree (2.10e-8 vs 1.91e-8 here) far
    more than their own standard errors (<1 %), so the between-run scatter, not the
    within-run noise, is the uncertainty that matters, and each run counts once: kf is
    the plain mean of the runs, its standard error std / sqrt(runs). (The row-weighted
    pooled fit gives the longer run more say for no physical reason.) Without CSVs the
    shared constant ``KF_CRAZYFLIE`` is used with a 5 % standard error.
    """
    directory = directory if directory is not None else stand_dir()
    csvs = sorted(Path(directory).glob("*.csv")) if Path(directory).is_dir() else []
    if not csvs:
        return ThrustCoefficient(
            kf=KF_CRAZYFLIE, kf_se=0.05 * KF_CRAZYFLIE, runs=(), pooled=KF_CRAZYFLIE,
            missing_stand=Path(directory),
            note=f"no thrust-stand CSV in {directory}: kf = KF_CRAZYFLIE = {KF_CRAZYFLIE:.3e} "
                 "N/(rad/s)^2 with an assumed 5 % standard error")
    runs = tuple(fit_thrust_stand(p) for p in csvs)
    ks = np.array([r.kf for r in runs])
    kf = float(ks.mean())
    if ks.size > 1:
        se = float(ks.std(ddof=1) / math.sqrt(ks.size))
        pooled = fit_thrust_stand(csvs).kf
    else:
        se, pooled = max(runs[0].kf_se, 0.05 * kf), runs[0].kf
    per_run = ", ".join(f"{r.source} {r.kf:.4e}" for r in runs)
    note = (f"kf = {kf:.4e} +- {se:.2e} N/(rad/s)^2 ({100 * se / kf:.1f} %): equal-weight "
            f"mean of {ks.size} thrust-stand run(s) ({per_run}); standard error from the "
            f"between-run spread. Row-weighted pooled fit: {pooled:.4e} "
            f"({100 * (pooled / kf - 1):+.1f} %); identified mass and inertia scale with kf.")
    return ThrustCoefficient(kf=kf, kf_se=se, runs=runs, pooled=float(pooled), note=note)



def vehicle_thrust_coefficient(spec: VehicleSpec) -> ThrustCoefficient:
    """kf of a vehicle file: fitted to its ``thrust_stand`` folder of Bitcraze CSVs when
    it has one (a shipped file's relative folder is looked up in the data directory,
    :func:`stand_dir`, as :func:`thrust_coefficient` does), else the file's kf and
    kf_se. Raises ValueError if the file has no [actuators] table."""
    act = spec.actuators
    if act is None:
        raise ValueError(f"{spec.source}: no [actuators] table (kf, kf_se, yaw_ratio): rotor "
                         "speeds cannot be turned into thrust and torques")
    stand = act.thrust_stand
    if stand is not None and not stand.is_dir() and spec.source == shipped_path(spec.name):
        stand = stand_dir()
    if stand is not None and stand.is_dir() and any(stand.glob("*.csv")):
        return thrust_coefficient(stand)
    where = "" if stand is None else f" (no thrust-stand CSV in {stand})"
    return ThrustCoefficient(
        kf=act.kf, kf_se=act.kf_se, runs=(), pooled=act.kf, missing_stand=stand,
        note=f"kf = {act.kf:.4e} +- {act.kf_se:.2e} N/(rad/s)^2 ({100 * act.kf_rel_se:.1f} %) "
             f"from the vehicle file {spec.source}{where}; identified mass and inertia "
             "scale with kf.")
