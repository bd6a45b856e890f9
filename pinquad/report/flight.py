"""The simulated world's tables: closest approach to the waypoints, the paper's Table I
for the sensor-A EKF, and the filter's consistency (NEES)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pinquad.core import paper_results as paper
from pinquad.experiments.flight import FlightStats, nees_band


def flight_tables(runs: Sequence[FlightStats], seeds: range) -> tuple[str, dict]:
    """The printed tables and their figures as a JSON-ready dict (``--out``)."""
    text: list[str] = []

    def say(line: str = "") -> None:
        text.append(line)

    say(f"seeds {seeds.start}..{seeds.stop - 1}, sensor A on board, dt = 0.01 s\n")
    say("Waypoints: closest approach to each of the 5 waypoints [m]\n")
    say("| vehicle | runs | worst closest approach | mean closest approach | "
        "runs with all <= 0.1 m | crashes | lifted off |")
    say("|---|---|---|---|---|---|---|")
    out: dict = {"seeds": [seeds.start, seeds.stop - 1], "waypoints": {}, "ekf": {}}
    for veh in ("paper", "crazyflie21"):
        rs = [r for r in runs if r.vehicle == veh and r.tuning == "tuned"]
        miss = np.array([r.miss for r in rs])
        ok = int(np.sum(miss.max(axis=1) <= 0.1))
        say(f"| {veh} | {len(rs)} | {miss.max():.4f} | {miss.mean():.4f} | {ok}/{len(rs)} | "
            f"{sum(r.crashed for r in rs)} | {sum(r.lifted_off for r in rs)}/{len(rs)} |")
        out["waypoints"][veh] = {"worst_m": float(miss.max()), "mean_m": float(miss.mean()),
                                 "all_within_0.1": ok, "runs": len(rs),
                                 "crashes": int(sum(r.crashed for r in rs))}
    say("\nTable I - sensor-A EKF pose estimation, paper vehicle "
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
    say("| | paper | ours (tuned Q, R) | ours (paper's P0, Q0, R0) |")
    say("|---|---|---|---|")
    for key, label in labels.items():
        say(f"| {label} | {paper.EKF_TABLE[key]:.3g} | {cols['tuned'][key]:.3g} | "
            f"{cols['paper'][key]:.3g} |")
    say("\nConsistency: time-averaged NEES of the 12-state estimate per run "
        "(expected 12)\n")
    say("| tuning | mean over all runs and steps | 95 % band of that mean | per run min / max | "
        "95 % band of one run | runs inside |")
    say("|---|---|---|---|---|---|")
    for tuning in ("tuned", "paper"):
        rs = [r for r in runs if r.vehicle == "paper" and r.tuning == tuning]
        vals = np.array([r.nees_mean for r in rs])
        lo, hi = nees_band(rs[0].n_steps)
        plo, phi = nees_band(sum(r.n_steps for r in rs))
        pooled = float(np.sum([r.nees_mean * r.n_steps for r in rs]) / sum(r.n_steps for r in rs))
        inside = int(np.sum((vals >= lo) & (vals <= hi)))
        say(f"| {tuning} | {pooled:.3f} | [{plo:.3f}, {phi:.3f}] | {vals.min():.2f} / "
            f"{vals.max():.2f} | [{lo:.2f}, {hi:.2f}] | {inside}/{len(rs)} |")
        out["ekf"][tuning].update({"nees_mean": pooled, "band_pooled": [plo, phi],
                                   "band_one_run": [lo, hi], "runs_inside": inside})
    return "\n".join(text), out
