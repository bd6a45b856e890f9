"""The online experiment's tables, report.json, logs and figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pinquad.core.params import PAPER_SCENARIO
from pinquad.experiments.online import (
    OnlineConfig,
    OnlineCycle,
    converged_estimate,
    time_to_converge,
)
from pinquad.io.logs import write_log
from pinquad.io.runs import REPORT_SCHEMA, RunWriter
from pinquad.report.offline import plot_trajectory

Array = NDArray[np.float64]


def online_tables(results: list[OnlineCycle], truth: Array, paper,
                  offline: dict[str, Array] | None = None) -> tuple[str, dict]:
    """The paper's online tables (converged ranges) beside the paper's and, when given,
    our offline ranges (per sensor (2, 4) [min; max]) with the width ratio online/offline."""
    sensors = sorted({r.sensor for r in results})
    lines = ["Online estimated mass [kg] and inertia [kg m^2]: converged range over cycles "
             "(median of the last 10 % of updates)", "",
             "| source | | mass | I_xx | I_yy | I_zz |", "|---|---|---|---|---|---|",
             f"| Real value | | {truth[0]} | {truth[1]:.4g} | {truth[2]:.4g} | {truth[3]:.4g} |"]
    stats: dict = {}
    for s in sensors:
        rs = [r for r in results if r.sensor == s]
        conv = np.array([converged_estimate(r.history) for r in rs])
        lo, hi = conv.min(axis=0), conv.max(axis=0)
        pm, pi = paper.ONLINE_MASS[s], paper.ONLINE_INERTIA[s]
        lines.append(f"| {paper.SOURCE_LABELS[s]} | paper | ({pm[0]}, {pm[1]}) | "
                     + " | ".join(f"({a:.3g}, {b:.3g})" for a, b in pi) + " |")
        lines.append("| | ours | " + " | ".join(f"({lo[i]:.5g}, {hi[i]:.5g})" for i in range(4))
                     + " |")
        width_ratio = None
        if offline is not None and s in offline:
            off = offline[s]
            lines.append("| | ours offline | " + " | ".join(
                f"({off[0, i]:.5g}, {off[1, i]:.5g})" for i in range(4)) + " |")
            width_ratio = (hi - lo) / np.maximum(off[1] - off[0], 1e-300)
            lines.append("| | width online / offline | " + " | ".join(
                f"{w:.2f}" for w in width_ratio) + " |")
        rel = np.abs(conv / truth - 1.0)
        ttc = np.array([time_to_converge(r.history, truth) for r in rs])
        lat = np.concatenate([r.latencies for r in rs]) if rs else np.zeros(0)
        stats[s] = {
            "range": [lo.tolist(), hi.tolist()],
            "max_rel_err": rel.max(axis=0).tolist(),
            "mass_within_0.5pct": int(np.sum(rel[:, 0] <= 0.005)),
            "inertia_within_5pct": int(np.sum(np.all(rel[:, 1:] <= 0.05, axis=1))),
            "cycles": len(rs),
            "range_width_over_offline": None if width_ratio is None else width_ratio.tolist(),
            "time_to_converge_s": {"median": float(np.nanmedian(ttc)) if np.isfinite(ttc).any()
                                   else None, "max": float(np.nanmax(ttc))
                                   if np.isfinite(ttc).any() else None,
                                   "never": int(np.sum(~np.isfinite(ttc)))},
            "worst_waypoint_miss_m": float(max(r.miss.max() for r in rs)),
            "crashes": int(sum(r.crashed for r in rs)),
            "lifted_off": int(sum(r.lifted_off for r in rs)),
            "max_height_m": float(max(r.max_z for r in rs)),
            "update_ms": {"p50": float(np.percentile(lat, 50) * 1e3),
                          "p99": float(np.percentile(lat, 99) * 1e3)} if lat.size else None,
            "realtime_factor": float(np.median([r.wall_s / r.flight_s for r in rs])),
        }
    lines += ["", "| source | mass within 0.5 % | inertia within 5 % | worst waypoint miss [m] | "
              "crashes | lifted off | time to converge [s] median (max, never) | "
              "update p50 / p99 [ms] | wall / flight time |", "|---|---|---|---|---|---|---|---|---|"]
    for s, st in stats.items():
        ttc = st["time_to_converge_s"]
        upd = st["update_ms"] or {"p50": float("nan"), "p99": float("nan")}
        lines.append(
            f"| {s} | {st['mass_within_0.5pct']}/{st['cycles']} | "
            f"{st['inertia_within_5pct']}/{st['cycles']} | {st['worst_waypoint_miss_m']:.3f} | "
            f"{st['crashes']} | {st['lifted_off']}/{st['cycles']} | "
            f"{_seconds(ttc['median'])} ({_seconds(ttc['max'])}, {ttc['never']}) | {upd['p50']:.1f} / "
            f"{upd['p99']:.1f} | {st['realtime_factor']:.2f} |")
    return "\n".join(lines), stats


def _seconds(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def online_report(results: list[OnlineCycle], truth: Array, stats: dict, memory: str,
                  elapsed: float) -> dict:
    """report.json of the online experiment (``io.runs.REPORT_SCHEMA``): each cycle's converged estimate
    and update history, the statistics of :func:`online_tables`; memory: how the M-step
    remembered samples that left the window, in words."""
    cycles = []
    for r in results:
        conv = converged_estimate(r.history)
        cycles.append({
            "sensor": r.sensor, "seed": r.seed, "mstep": "regressor",
            "truth": {"mass": float(truth[0]), "inertia": np.diag(truth[1:]).tolist()},
            "estimates": {"mass": float(conv[0]), "inertia": np.diag(conv[1:]).tolist(),
                          "com": None},
            "history": {"t": r.history[:, 1].tolist(), "mass": r.history[:, 2].tolist(),
                        "inertia_diag": r.history[:, 3:6].tolist()},
            "flight": {"max_miss_m": float(r.miss.max()), "crashed": r.crashed,
                       "lifted_off": r.lifted_off, "liftoff_step": r.liftoff,
                       "max_height_m": r.max_z},
            "update_ms": {"p50": float(np.percentile(r.latencies, 50) * 1e3),
                          "p99": float(np.percentile(r.latencies, 99) * 1e3)},
            "excluded": {"ground_samples": r.liftoff,
                         "why": "samples before lift-off (on the floor) never enter the window"},
        })
    first = cycles[0]
    return {
        "schema": REPORT_SCHEMA,
        "source": {"kind": "simulation", "path": None, "sensor": "".join(sorted(stats)),
                   "estep": "rts", "mode": "online", "vehicle": "paper",
                   "window": OnlineConfig().window, "every": OnlineConfig().every,
                   "memory": memory},
        "estimates": first["estimates"], "truth": first["truth"],
        "em": {"iterations": OnlineConfig().iterations, "loglik": [], "converged": True},
        "discovery": {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                      "validation": "not run in the online experiment"},
        "cycles": cycles, "statistics": stats,
        "scenario": {"start": PAPER_SCENARIO.start.tolist(),
                     "waypoints": PAPER_SCENARIO.waypoints.tolist()},
        "seconds": elapsed,
    }


def write_online_logs(results: list[OnlineCycle], writer: RunWriter) -> dict:
    """The first cycle's log per sensor, and the onboard estimate as its 'smoothed'
    track (an online run has no whole-flight smoother); its flown trajectory as a
    figure."""
    out = {}
    for r in results:
        if r.log is None:
            continue
        name = f"sensor{r.sensor}-cycle00"
        logs_dir = writer.path("logs")
        logs_dir.mkdir(exist_ok=True)
        write_log(r.log, logs_dir / f"{name}.parquet")
        np.save(logs_dir / f"{name}-smoothed.npy", r.log.onboard)
        plot_trajectory(r.log, PAPER_SCENARIO.waypoints,
                        writer.path("figures") / f"trajectory_{r.sensor}.png", r.log.onboard,
                        "onboard filter estimate")
        out[r.sensor] = {"log": f"logs/{name}.parquet", "smoothed": f"logs/{name}-smoothed.npy"}
    return out


def online_figures(results: list[OnlineCycle], truth: Array, figs: Path) -> None:
    """Every cycle's estimates per online update (online_history.png) and their errors
    zoomed to the acceptance bands (online_error.png) into ``figs``."""
    figs.mkdir(parents=True, exist_ok=True)
    sensors = sorted({r.sensor for r in results})
    names = ["mass [kg]", "I_xx [kg m^2]", "I_yy [kg m^2]", "I_zz [kg m^2]"]
    fig = Figure(figsize=(16, 3.2 * len(sensors)))
    axes = fig.subplots(len(sensors), 4, squeeze=False)
    for i, s in enumerate(sensors):
        for r in (r for r in results if r.sensor == s):
            for j in range(4):
                axes[i, j].plot(np.arange(r.history.shape[0]), r.history[:, 2 + j], "--",
                                lw=0.7, alpha=0.7)
        for j in range(4):
            axes[i, j].axhline(truth[j], color="red", lw=1.5)
            axes[i, j].set_yscale("log")
            axes[i, j].set_title(f"sensor {s}: {names[j]}")
            axes[i, j].set_xlabel("online update")
    fig.tight_layout()
    fig.savefig(figs / "online_history.png", dpi=90)

    # The same histories as errors, zoomed to the acceptance bands: the start (m0 = 1 g,
    # 99 % off) would otherwise hide the converged part.
    bands = [0.5, 5.0, 5.0, 5.0]
    fig = Figure(figsize=(16, 3.2 * len(sensors)))
    axes = fig.subplots(len(sensors), 4, squeeze=False)
    for i, s in enumerate(sensors):
        for r in (r for r in results if r.sensor == s):
            err = 100.0 * (r.history[:, 2:6] / truth - 1.0)
            for j in range(4):
                axes[i, j].plot(np.arange(err.shape[0]), err[:, j], lw=0.7, alpha=0.7)
        for j in range(4):
            ax = axes[i, j]
            ax.axhline(0.0, color="red", lw=1.5)
            for sign in (-1.0, 1.0):
                ax.axhline(sign * bands[j], color="black", ls=":", lw=1.0)
            ax.set_ylim(-2.0 * bands[j], 2.0 * bands[j])
            ax.set_title(f"sensor {s}: {names[j].split(' [')[0]} error [%] (band +-{bands[j]:g})")
            ax.set_xlabel("online update")
    fig.tight_layout()
    fig.savefig(figs / "online_error.png", dpi=90)

