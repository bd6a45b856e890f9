"""Monte Carlo summaries, printed tables, report.json and figures."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from pinquad.core import paper_results as paper
from pinquad.experiments.offline_mc import CycleResult
from pinquad.io.logs import write_log
from pinquad.io.runs import REPORT_SCHEMA, RunWriter, atomic_write_json

Array = NDArray[np.float64]

PARAMS = ("mass", "Ixx", "Iyy", "Izz")
UNITS = {"mass": "kg", "Ixx": "kg m^2", "Iyy": "kg m^2", "Izz": "kg m^2"}


@dataclass(frozen=True)
class ParamStats:
    """Monte Carlo statistics of one parameter for one (sensor, M-step).

    values (C,); truth; bias = mean - truth; std (ddof 1); max_rel_err = max |v/truth - 1|;
    crlb_std: sqrt of the Cramer-Rao bound (from the mean observed information at the
    truth over the cycles), NaN if not computed; efficiency = std / crlb_std.
    """

    values: Array
    truth: float
    bias: float
    std: float
    max_rel_err: float
    crlb_std: float

    @property
    def efficiency(self) -> float:
        return self.std / self.crlb_std if self.crlb_std > 0 else float("nan")

    @property
    def low(self) -> float:
        return float(np.min(self.values))

    @property
    def high(self) -> float:
        return float(np.max(self.values))


def _param_values(cycles: Sequence[CycleResult], mstep: str) -> tuple[Array, Array]:
    vals, truth = [], []
    for c in cycles:
        for r in c.runs:
            if r.mstep == mstep:
                vals.append([r.mass, *np.diag(r.inertia)])
                truth.append([c.truth_mass, *np.diag(c.truth_inertia)])
    return np.asarray(vals), np.asarray(truth)


def crlb_std(cycles: Sequence[CycleResult]) -> Array:
    """sqrt(diag(inverse of the mean observed information at the truth)) (4,)."""
    infos = [r.info_truth for c in cycles for r in c.runs if r.info_truth is not None]
    if not infos:
        return np.full(4, np.nan)
    mean_info = np.mean(infos, axis=0)
    try:
        cov = np.linalg.inv(mean_info)
    except np.linalg.LinAlgError:
        return np.full(4, np.nan)
    d = np.diag(cov)
    return np.where(d > 0, np.sqrt(np.abs(d)), np.nan)


def summarize(cycles: Sequence[CycleResult]) -> dict[tuple[str, str], dict[str, ParamStats]]:
    """Statistics per (sensor, M-step) and parameter."""
    out: dict[tuple[str, str], dict[str, ParamStats]] = {}
    sensors = sorted({c.sensor for c in cycles})
    msteps = sorted({r.mstep for c in cycles for r in c.runs}, key=lambda m: m != "regressor")
    for s in sensors:
        cs = [c for c in cycles if c.sensor == s]
        bound = crlb_std(cs)
        for m in msteps:
            vals, truth = _param_values(cs, m)
            if vals.size == 0:
                continue
            stats = {}
            for i, p in enumerate(PARAMS):
                v, t = vals[:, i], float(truth[0, i])
                stats[p] = ParamStats(
                    values=v, truth=t, bias=float(np.mean(v) - t),
                    std=float(np.std(v, ddof=1)) if v.size > 1 else float("nan"),
                    max_rel_err=float(np.max(np.abs(v / t - 1.0))), crlb_std=float(bound[i]))
            out[(s, m)] = stats
    return out


def _rng(lo: float, hi: float, fmt: str) -> str:
    return f"({lo:{fmt}}, {hi:{fmt}})"


def offline_tables(summary: dict[tuple[str, str], dict[str, ParamStats]]) -> str:
    """The paper's Table II (mass) and Table III (inertia) layouts with ours beside it,
    then bias / std / CRLB / efficiency per parameter (markdown)."""
    sensors = sorted({s for s, _ in summary})
    lines = ["Table II - offline estimated mass [kg] (range over cycles)", "",
             "| source | paper | ours, regressor M-step | ours, paper's M-step |",
             "|---|---|---|---|"]
    truth_m = next(iter(summary.values()))["mass"].truth
    lines.append(f"| Real value | {truth_m} | {truth_m} | {truth_m} |")
    for s in sensors:
        row = [paper.SOURCE_LABELS[s], _rng(*paper.OFFLINE_MASS[s], ".4f")]
        for m in ("regressor", "paper"):
            st = summary.get((s, m))
            row.append(_rng(st["mass"].low, st["mass"].high, ".5f") if st else "-")
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "Table III - offline estimated inertia [kg m^2] (range over cycles)", "",
              "| source | M-step | I_xx | I_yy | I_zz |", "|---|---|---|---|---|"]
    first = next(iter(summary.values()))
    lines.append("| Real value | | " + " | ".join(f"{first[p].truth:.4g}" for p in PARAMS[1:])
                 + " |")
    for s in sensors:
        lines.append(f"| {paper.SOURCE_LABELS[s]} | paper (published) | "
                     + " | ".join(_rng(lo, hi, ".4g") for lo, hi in paper.OFFLINE_INERTIA[s])
                     + " |")
        for m in ("regressor", "paper"):
            st = summary.get((s, m))
            if st:
                lines.append(f"| | ours, {m} | " + " | ".join(
                    _rng(st[p].low, st[p].high, ".4g") for p in PARAMS[1:]) + " |")
    lines += ["", "Accuracy and efficiency (bias and std over cycles; sqrt(CRLB) from the "
              "mean observed information at the truth)", "",
              "| source | M-step | parameter | max abs rel. error | bias/truth | std/truth | "
              "sqrt(CRLB)/truth | std/sqrt(CRLB) | abs bias < std |",
              "|---|---|---|---|---|---|---|---|---|"]
    for (s, m), st in summary.items():
        for p in PARAMS:
            x = st[p]
            lines.append(
                f"| {s} | {m} | {p} | {100 * x.max_rel_err:.3f} % | {100 * x.bias / x.truth:+.3f} % "
                f"| {100 * x.std / x.truth:.3f} % | {100 * x.crlb_std / x.truth:.3f} % | "
                f"{x.efficiency:.2f} | {'yes' if abs(x.bias) < x.std else 'no'} |")
    return "\n".join(lines)


def stats_json(summary: dict[tuple[str, str], dict[str, ParamStats]]) -> list[dict]:
    rows = []
    for (s, m), st in summary.items():
        for p, x in st.items():
            rows.append({"sensor": s, "mstep": m, "param": p, "truth": x.truth,
                         "min": x.low, "max": x.high, "bias": x.bias, "std": x.std,
                         "max_rel_err": x.max_rel_err, "crlb_std": x.crlb_std,
                         "efficiency": x.efficiency})
    return rows


def cycle_entries(cycles: Sequence[CycleResult]) -> list[dict]:
    """report.json ``cycles``: one entry per (cycle, M-step)."""
    out = []
    for c in cycles:
        for r in c.runs:
            out.append({
                "sensor": c.sensor, "mstep": r.mstep, "seed": c.seed, "cycle": c.cycle,
                "estimates": {"mass": r.mass, "inertia": np.asarray(r.inertia).tolist(),
                              "com": None,
                              "stderr": {"mass": r.stderr[0], "inertia_diag": r.stderr[1:4].tolist()}},
                "truth": {"mass": c.truth_mass, "inertia": np.asarray(c.truth_inertia).tolist(),
                          "com": [0.0, 0.0, 0.0]},
                "em": {"iterations": int(r.loglik.size), "loglik": r.loglik.tolist(),
                       "converged": bool(r.converged), "loglik_decreases": list(r.decreases),
                       "failure": r.failure},
                "history": {"mass": r.history_mass.tolist(),
                            "inertia_diag": r.history_inertia.tolist()},
                "flight": c.flight, "seconds": r.seconds, "excluded": c.excluded,
            })
    return out


def plot_em_history(cycles: Sequence[CycleResult], mstep: str, path: Path) -> None:
    """Estimate vs EM iteration for all cycles, the truth as a red line (paper's figures)."""
    sensors = sorted({c.sensor for c in cycles})
    fig = Figure(figsize=(16, 3.2 * len(sensors)))
    axes = fig.subplots(len(sensors), 4, squeeze=False)
    for i, s in enumerate(sensors):
        for c in (c for c in cycles if c.sensor == s):
            for r in c.runs:
                if r.mstep != mstep:
                    continue
                hist = np.column_stack([r.history_mass, r.history_inertia])
                for j in range(4):
                    axes[i, j].plot(hist[:, j], "--", lw=0.8, alpha=0.7)
        truth = [cycles[0].truth_mass, *np.diag(cycles[0].truth_inertia)]
        for j, p in enumerate(PARAMS):
            ax = axes[i, j]
            ax.axhline(truth[j], color="red", lw=1.5, label="truth")
            ax.set_title(f"sensor {s}: {p} [{UNITS[p]}]")
            ax.set_xlabel("EM iteration")
            ax.set_yscale("log")
    fig.suptitle(f"EM estimates per iteration, {mstep} M-step, all cycles")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def plot_trajectory(log, waypoints: Array | None, path: Path, estimate: Array | None = None,
                    estimate_label: str = "smoothed estimate") -> None:
    """The flown trajectory in 3-D (truth, measurements, estimate) with the waypoints."""
    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    if log.truth is not None:
        ax.plot(*log.truth[:, 0:3].T, color="k", lw=1.2, label="true")
    ok = ~np.isnan(log.position).any(axis=1)
    ax.plot(*log.position[ok].T, ".", ms=1, alpha=0.3, label="measured position")
    if estimate is not None:
        ax.plot(*estimate[:, 0:3].T, color="tab:orange", lw=1, label=estimate_label)
    if waypoints is not None:
        ax.scatter(*np.asarray(waypoints).T, color="red", s=40, label="waypoints")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def write_offline_run(writer: RunWriter, results: Sequence[CycleResult],
                      summary: dict[tuple[str, str], dict[str, ParamStats]], tables: str,
                      msteps: tuple[str, ...], sensors: Sequence[str], source: dict,
                      waypoints_start: tuple[Array, Array], seconds: float) -> None:
    """The offline experiment's run directory into ``writer``'s staging directory (the
    caller publishes or aborts): EM-history and trajectory figures, the first cycle of
    each sensor's log and smoothed means, report.json (``pinquad.io.runs.REPORT_SCHEMA``; ``estimates`` and
    ``em`` of the first cycle's first M-step, every cycle under ``cycles``) and report.md.
    source: report.json's ``source`` entries beyond kind, path and sensor;
    waypoints_start: (waypoints (W, 3), start (3,)) [m] of the flown scenario."""
    waypoints, start = waypoints_start
    figs = writer.path("figures")
    figs.mkdir(exist_ok=True)
    for m in msteps:
        plot_em_history(results, m, figs / f"em_history_{m}.png")
    logs_dir = writer.path("logs")
    logs_dir.mkdir(exist_ok=True)
    run_logs = {}
    for c in results:
        if c.log is None:
            continue
        name = f"sensor{c.sensor}-cycle{c.cycle:02d}"
        write_log(c.log, logs_dir / f"{name}.parquet")
        if c.smoothed is not None:
            np.save(logs_dir / f"{name}-smoothed.npy", c.smoothed)
        plot_trajectory(c.log, waypoints, figs / f"trajectory_{c.sensor}.png", c.smoothed)
        run_logs[c.sensor] = {"log": f"logs/{name}.parquet",
                              "smoothed": f"logs/{name}-smoothed.npy"}
    first = results[0]
    best = next((r for r in first.runs if r.mstep == msteps[0]), first.runs[0])
    report = {
        "schema": REPORT_SCHEMA,
        "source": {"kind": "simulation", "path": None, "sensor": "".join(sensors), **source},
        "estimates": {"mass": best.mass, "inertia": np.asarray(best.inertia).tolist(),
                      "com": None, "stderr": {"mass": best.stderr[0],
                                              "inertia_diag": best.stderr[1:4].tolist()}},
        "truth": {"mass": first.truth_mass, "inertia": first.truth_inertia.tolist(),
                  "com": [0.0, 0.0, 0.0]},
        "em": {"iterations": int(best.loglik.size), "loglik": best.loglik.tolist(),
               "converged": bool(best.converged)},
        "discovery": {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                      "validation": "not run on simulated paper experiment"},
        "cycles": cycle_entries(results),
        "statistics": stats_json(summary),
        "scenario": {"start": np.asarray(start).tolist(),
                     "waypoints": np.asarray(waypoints).tolist()},
        "run_logs": run_logs,
        "seconds": seconds,
    }
    atomic_write_json(writer.path("report.json"), report)
    writer.path("report.md").write_text("# pinquad offline experiment\n\n" + tables + "\n")
