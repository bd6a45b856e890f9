"""``python -m pinquad.flight``: the simulated world on its own (no identification).

Flies the paper's scenario over seeded runs and prints (1) how close the vehicle comes
to every waypoint, for the paper vehicle and the Crazyflie 2.1 (the same scenario
scaled by 0.3), and (2) the paper's Table I layout for the sensor-A EKF (position and
Euler-angle error, mean / std / max over all steps of all runs) beside the paper's
numbers, with the filter's consistency: the time-averaged normalised estimation error
squared (NEES) of each run against its 95 % chi-square band.
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from pinquad.cli.help import HelpFormatter
from pinquad.core import paper_results as paper
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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pinquad.flight", description=__doc__.split("\n\n")[1],
                                formatter_class=HelpFormatter)
    p.add_argument("--seeds", type=int, default=20, help="seeded runs per configuration")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    p.add_argument("--out", type=Path, help="also write the figures as JSON to this file")
    args = p.parse_args(argv)
    if args.seeds < 1:
        print("error: --seeds must be at least 1", file=sys.stderr)
        return 2
    seeds = range(args.seed, args.seed + args.seeds)
    jobs = ([("paper", s, "tuned") for s in seeds] + [("crazyflie21", s, "tuned") for s in seeds]
            + [("paper", s, "paper") for s in seeds])
    from tqdm import tqdm

    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        runs = list(tqdm(pool.map(fly, jobs), total=len(jobs), desc="flights", file=sys.stderr))
    print(f"seeds {seeds.start}..{seeds.stop - 1}, sensor A on board, dt = 0.01 s\n")
    print("Waypoints: closest approach to each of the 5 waypoints [m]\n")
    print("| vehicle | runs | worst closest approach | mean closest approach | "
          "runs with all <= 0.1 m | crashes | lifted off |")
    print("|---|---|---|---|---|---|---|")
    out: dict = {"seeds": [seeds.start, seeds.stop - 1], "waypoints": {}, "ekf": {}}
    for veh in ("paper", "crazyflie21"):
        rs = [r for r in runs if r.vehicle == veh and r.tuning == "tuned"]
        miss = np.array([r.miss for r in rs])
        ok = int(np.sum(miss.max(axis=1) <= 0.1))
        print(f"| {veh} | {len(rs)} | {miss.max():.4f} | {miss.mean():.4f} | {ok}/{len(rs)} | "
              f"{sum(r.crashed for r in rs)} | {sum(r.lifted_off for r in rs)}/{len(rs)} |")
        out["waypoints"][veh] = {"worst_m": float(miss.max()), "mean_m": float(miss.mean()),
                                 "all_within_0.1": ok, "runs": len(rs),
                                 "crashes": int(sum(r.crashed for r in rs))}
    print("\nTable I - sensor-A EKF pose estimation, paper vehicle "
          "(all steps of all runs)\n")
    cols = {}
    for tuning in ("tuned", "paper"):
        rs = [r for r in runs if r.vehicle == "paper" and r.tuning == tuning]
        pe = np.concatenate([r.pos_err for r in rs])
        ee = np.concatenate([r.euler_err for r in rs])
        cols[tuning] = {"pos_mean": pe.mean(), "pos_std": pe.std(), "pos_max": pe.max(),
                        "euler_mean": ee.mean(), "euler_std": ee.std(), "euler_max": ee.max()}
        out["ekf"][tuning] = {k: float(v) for k, v in cols[tuning].items()}
    labels = {"pos_mean": "Mean position error [m]", "pos_std": "Std of position error [m]",
              "pos_max": "Max position error [m]", "euler_mean": "Mean Euler angle error [rad]",
              "euler_std": "Std of Euler angle error [rad]",
              "euler_max": "Max Euler angle error [rad]"}
    print("| | paper | ours (tuned Q, R) | ours (paper's P0, Q0, R0) |")
    print("|---|---|---|---|")
    for key, label in labels.items():
        print(f"| {label} | {paper.EKF_TABLE[key]:.3g} | {cols['tuned'][key]:.3g} | "
              f"{cols['paper'][key]:.3g} |")
    print("\nConsistency: time-averaged NEES of the 12-state estimate per run "
          "(expected 12)\n")
    print("| tuning | mean over all runs and steps | 95 % band of that mean | per run min / max | "
          "95 % band of one run | runs inside |")
    print("|---|---|---|---|---|---|")
    for tuning in ("tuned", "paper"):
        rs = [r for r in runs if r.vehicle == "paper" and r.tuning == tuning]
        vals = np.array([r.nees_mean for r in rs])
        lo, hi = nees_band(rs[0].n_steps)
        plo, phi = nees_band(sum(r.n_steps for r in rs))
        pooled = float(np.sum([r.nees_mean * r.n_steps for r in rs]) / sum(r.n_steps for r in rs))
        inside = int(np.sum((vals >= lo) & (vals <= hi)))
        print(f"| {tuning} | {pooled:.3f} | [{plo:.3f}, {phi:.3f}] | {vals.min():.2f} / "
              f"{vals.max():.2f} | [{lo:.2f}, {hi:.2f}] | {inside}/{len(rs)} |")
        out["ekf"][tuning].update({"nees_mean": pooled, "band_pooled": [plo, phi],
                                   "band_one_run": [lo, hi], "runs_inside": inside})
    if args.out:
        from pinquad.io.runs import atomic_write_json

        atomic_write_json(args.out, out)
        print(f"\nwritten {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
