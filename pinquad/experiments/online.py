"""``python -m pinquad.online``: online EM in the closed loop (the paper's online scheme).

During the flight, every ``every`` control steps (4), EM runs on the latest ``window``
(800) airborne observations and hands the new mass and inertia to the LQG controller
(and to the onboard model-based filter of sensors B and C). The estimator starts from
the paper's m0 = 0.001 kg and I0 = diag(1e-4, 2e-4, 1e-4) kg m^2.

Ground contact: the vehicle starts on the floor, where its motion says nothing about
its mass (the floor carries the difference). While the estimate says "on the floor"
(estimated height below ``liftoff_height``), the controller ramps the collective
thrust up at ``ramp_rate`` x the actuator's maximum thrust per second, level attitude
held. At lift-off the thrust that lifted the vehicle gives a provisional weight
(m ~ F / g); from then on only airborne samples enter the EM window (samples in contact
are excluded, never modelled), the reference trajectory starts, and EM takes over once
``min_samples`` airborne samples exist.

Each update warm-starts from the previous one (parameters and noise covariances, and
the window's prior from the previous posterior) and runs ``iterations`` EM iterations
(one E-step and one M-step each; the first update starts with the force-free warm-up
E-step), so convergence is spread over updates rather than repeated at each.

Memory (``memory_s``, ``--memory``): the E-step sees only the window, but a sample that
leaves it leaves its M-step statistics behind (``identify.remember_leaving``: the
expected quadratic forms of its transition, from the last posterior that smoothed it),
and every M-step adds them to the window's, forgotten with time constant ``memory_s``.
With the default (inf) the M-step uses every airborne transition so far, each with its
last smoothed moments: incremental EM (Neal and Hinton 1998), whose estimate at the end
of the flight draws on as much data as the offline one. A finite time constant tracks
parameters that change; ``--memory none`` is the paper's window-only scheme, whose
converged estimate rests on the last 8 s (its I_zz spread for sensor A was 9.9x the
offline one).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.cli.common import memory_arg, memory_label
from pinquad.cli.help import HelpFormatter
from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_VEHICLE
from pinquad.experiments.offline_mc import SENSOR_INDEX
from pinquad.identification.em import initial_theta
from pinquad.identification.identify import get_smoother
from pinquad.identification.window import window_em, window_prior
from pinquad.io.runs import REPORT_SCHEMA
from pinquad.models.sources import SOURCE_CHANNELS
from pinquad.models.ssm import Observations, QuadSSM, Theta
from pinquad.mstep.stats import QuadraticSums
from pinquad.mstep.updates import regressor_mstep, remember_leaving
from pinquad.sim.simulator import ControllerUpdate, FlightSoFar, SimConfig, flight_log, simulate

Array = NDArray[np.float64]


@dataclass(frozen=True)
class OnlineConfig:
    """window: EM window [samples]; every: control steps between updates; iterations:
    EM iterations per update; min_samples: airborne samples before the first update;
    ramp_rate: take-off thrust ramp [fraction of maximum thrust per second];
    liftoff_height [m]: estimated height that means airborne; thrust_max [N];
    memory_s [s]: time constant with which the M-step forgets the statistics of samples
    that have left the window (inf: keeps them all; None: the window alone, as the
    paper)."""

    window: int = 800
    every: int = 4
    iterations: int = 1
    min_samples: int = 50
    ramp_rate: float = 0.2
    liftoff_height: float = 0.03
    thrust_max: float = 2.5 * PAPER_VEHICLE.mass * PAPER_VEHICLE.gravity
    memory_s: float | None = math.inf
    mass0: float = PAPER_INITIAL_MASS
    inertia0: Array = field(default_factory=lambda: PAPER_INITIAL_INERTIA.copy())
    gravity: float = PAPER_VEHICLE.gravity


@dataclass
class OnlineEstimator:
    """The closed-loop estimator, called by the simulator after each step's measurements.

    history rows: [k, t, mass, Ixx, Iyy, Izz, seconds of the update].

    With the compiled smoother the posteriors live in two sets of arrays used in turn
    (``previous`` keeps the last one valid while the next is computed): a posterior's
    arrays are overwritten two updates later, which saves the page faults of ~2 MB of
    fresh memory per update.
    """

    config: OnlineConfig
    sensor: str
    dt: float
    theta: Theta | None = None
    liftoff: int | None = None
    liftoff_thrust: float = 0.0
    on_ground_since: int = 0
    history: list[list[float]] = field(default_factory=list)
    latencies: list[float] = field(default_factory=list)
    previous: tuple[int, Posterior, Observations] | None = None
    earlier: QuadraticSums | None = None
    mass: float = 0.0
    inertia: Array = field(default_factory=lambda: np.eye(3))
    _smoother: object = field(default=None, init=False, repr=False)
    _out: list = field(default_factory=lambda: [None, None], init=False, repr=False)
    _turn: int = field(default=0, init=False, repr=False)

    def __post_init__(self) -> None:
        self.mass = self.config.mass0
        self.inertia = np.array(self.config.inertia0, float)
        self._smoother = get_smoother("rts")

    def _smooth(self, model: QuadSSM, ys: Array) -> Posterior:
        """The E-step, into the posterior arrays of this update's turn when compiled."""
        try:
            from pinquad.estep.fast_smoother import posterior_arrays, smooth_quad
        except ImportError:  # the compiled path is optional
            return self._smoother(model, ys)
        if self._smoother is not smooth_quad:
            return self._smoother(model, ys)
        out = self._out[self._turn]
        if out is None or out[0].shape[0] != ys.shape[0]:
            out = self._out[self._turn] = posterior_arrays(ys.shape[0])
        return smooth_quad(model, ys, out=out)

    def _observations(self, buf: FlightSoFar, start: int, stop: int) -> Observations:
        channels = SOURCE_CHANNELS[self.sensor]
        if self.sensor == "A":
            ys = np.column_stack([buf.nav_state[start:stop, 0:6], buf.gyro[start:stop]])
        else:
            blocks = {"pos": buf.position, "vel": buf.velocity, "euler": buf.euler,
                      "gyro": buf.gyro}
            ys = np.column_stack([blocks[c][start:stop] for c in channels])
        inputs = np.column_stack([buf.thrust[start:stop], buf.torque[start:stop]])
        x0, p0 = window_prior(self.previous, start, buf.nav_state[start].copy(),
                              np.full(12, 0.05**2))
        return Observations(t=buf.t[start:stop], dt=self.dt, inputs=inputs, channels=channels,
                            ys=ys, x0=x0, p0=p0, exclude=np.zeros(stop - start, dtype=bool))

    def __call__(self, k: int, buf: FlightSoFar) -> ControllerUpdate:
        cfg = self.config
        if self.liftoff is None:
            if buf.nav_state[k, 2] < cfg.liftoff_height:
                # On the floor: ramp the thrust; nothing to learn yet.
                thrust = cfg.ramp_rate * cfg.thrust_max * (k - self.on_ground_since) * self.dt
                self.liftoff_thrust = thrust
                return ControllerUpdate(self.mass, self.inertia, thrust_override=thrust)
            self.liftoff = k
            self.mass = self.liftoff_thrust / cfg.gravity
            self.history.append([k, buf.t[k], self.mass, *np.diag(self.inertia), 0.0])
        airborne = k - self.liftoff + 1
        if airborne >= cfg.min_samples and (k - self.liftoff) % cfg.every == 0:
            t0 = time.perf_counter()
            start = max(self.liftoff, k + 1 - cfg.window)
            obs = self._observations(buf, start, k + 1)
            theta = self.theta
            warm_up = theta is None
            if warm_up:
                theta = initial_theta(obs, self.mass, self.inertia, cfg.gravity)
            if cfg.memory_s is not None and self.previous is not None:
                prev_start, prev_post, prev_obs = self.previous
                self.earlier = remember_leaving(self.earlier, prev_post, prev_obs,
                                                start - prev_start, cfg.gravity, cfg.memory_s)
            theta, post = window_em(obs, theta, warm_up, cfg.iterations, self._smooth,
                                    regressor_mstep, self.earlier)
            self.theta = _match_meas(theta, obs)
            self.previous = (start, post, obs)
            self._turn = 1 - self._turn
            self.mass, self.inertia = theta.mass, np.asarray(theta.inertia)
            elapsed = time.perf_counter() - t0
            self.latencies.append(elapsed)
            self.history.append([k, buf.t[k], self.mass, *np.diag(self.inertia), elapsed])
        return ControllerUpdate(self.mass, self.inertia, reference_start=self.liftoff)


def _match_meas(theta: Theta, obs: Observations) -> Theta:
    """Keep the noise model's measurement vector consistent with the window's rows."""
    if theta.noise.meas.shape[0] == obs.ys.shape[1]:
        return theta
    return replace(theta, noise=replace(theta.noise, meas=np.full(obs.ys.shape[1], 1e-4)))


@dataclass(frozen=True)
class OnlineCycle:
    """One closed-loop flight with online EM: sensor, seed, the estimator's history
    (U, 7) [k, t, m, Ixx, Iyy, Izz, s], waypoint misses (5,), crashed, lifted off,
    lift-off step, latencies (U,) [s], wall time [s], flight duration [s], max height."""

    sensor: str
    seed: int
    history: Array
    miss: Array
    crashed: bool
    lifted_off: bool
    liftoff: int
    latencies: Array
    wall_s: float
    flight_s: float
    max_z: float
    log: object | None = None


def run_online_cycle(job: tuple[str, int, int, float | None]) -> OnlineCycle:
    """One closed-loop flight; job = (sensor, cycle, base seed, memory_s)."""
    sensor, cycle, seed, memory_s = job
    flight_seed = seed * 100_000 + SENSOR_INDEX[sensor] * 1000 + cycle
    cfg = OnlineConfig(memory_s=memory_s)
    sim = SimConfig(sensor=sensor, controller_mass=cfg.mass0,
                    controller_inertia=cfg.inertia0, settle_time=6.0)
    est = OnlineEstimator(cfg, sensor, sim.scenario.dt)
    t0 = time.perf_counter()
    flight = simulate(sim, np.random.default_rng(flight_seed), on_step=est)
    wall = time.perf_counter() - t0
    return OnlineCycle(sensor, flight_seed, np.asarray(est.history), flight.waypoint_miss,
                       flight.crashed, flight.lifted_off, est.liftoff or -1,
                       np.asarray(est.latencies), wall, float(flight.t[-1]),
                       float(flight.states[:, 2].max()),
                       log=flight_log(flight) if cycle == 0 else None)


def measure_update_latency(n_updates: int = 200, window: int = 800) -> Array:
    """Wall time [s] of ``n_updates`` online updates on a full ``window``-sample window
    (sensor B flight at the paper's parameters, warm-started as in flight)."""
    cfg = OnlineConfig(window=window)
    sim = SimConfig(sensor="B")
    flight = simulate(sim, np.random.default_rng(12345))
    buf = flight.onboard
    est = OnlineEstimator(cfg, "B", sim.scenario.dt)
    est.liftoff = int(np.argmax(~flight.contact)) + 1
    est.mass, est.inertia = PAPER_VEHICLE.mass, PAPER_VEHICLE.inertia.copy()
    start_k = est.liftoff + window
    ks = [start_k + cfg.every * i for i in range(n_updates + 5)]
    ks = [k for k in ks if k < flight.t.shape[0]]
    for k in ks:
        est(k if (k - est.liftoff) % cfg.every == 0 else k, buf)
    return np.asarray(est.latencies[5:])


def main(argv: list[str] | None = None) -> int:
    from pinquad.core import paper_results as paper

    p = argparse.ArgumentParser(prog="python -m pinquad.online",
                                description="Online EM in the closed loop (paper's online "
                                "experiment): sliding window, estimates fed to the controller.",
                                formatter_class=HelpFormatter)
    p.add_argument("--sensor", choices=["A", "B", "C"], action="append",
                   help="observation source(s) (default: A, B and C)")
    p.add_argument("--cycles", type=int, default=20, help="seeded cycles per sensor")
    p.add_argument("--seed", type=int, default=0, help="base seed")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    p.add_argument("--out", type=Path, help="output run directory (default runs/online-<time>)")
    p.add_argument("--log", type=Path, help="replay a recorded log through the online "
                   "estimator as a stream (no controller feedback)")
    p.add_argument("--offline-report", type=Path,
                   help="an offline report.json whose ranges the online ranges are compared with "
                   "(default: the newest runs/offline-*/report.json, if any)")
    p.add_argument("--memory", type=memory_arg, default=math.inf, metavar="SECONDS",
                   help="time constant [s] with which the M-step forgets samples that left "
                        "the window; inf keeps them all (incremental EM), none uses the "
                        "window alone (the paper's scheme)")
    p.add_argument("--view", action="store_true", help="open the browser view of the run")
    args = p.parse_args(argv)
    if args.log is not None:
        from pinquad.experiments.online_replay import replay

        return replay(args)
    if args.cycles < 1:
        print("error: --cycles must be at least 1", file=sys.stderr)
        return 2
    from tqdm import tqdm

    from pinquad.io.runs import RunWriter, atomic_write_json, new_run_dir

    offline_path = args.offline_report or newest_offline_report()
    offline = None
    if offline_path is not None:
        try:
            offline = offline_ranges(offline_path)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    sensors = args.sensor or ["A", "B", "C"]
    jobs = [(s, i, args.seed, args.memory) for s in sensors for i in range(args.cycles)]
    out_dir = args.out or new_run_dir("online")
    writer = RunWriter(out_dir)
    t0 = time.perf_counter()
    try:
        with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            results = list(tqdm(pool.map(run_online_cycle, jobs), total=len(jobs),
                                desc="online cycles", file=sys.stderr))
        elapsed = time.perf_counter() - t0
        truth = np.array([PAPER_VEHICLE.mass, *PAPER_VEHICLE.inertia_diag])
        text, stats = online_tables(results, truth, paper, offline)
        text += ("\n\nOffline ranges from " + str(offline_path) if offline is not None else
                 "\n\nNo offline report to compare with (run python -m pinquad.offline first, "
                 "or pass --offline-report)")
        print(text)
        print(f"\n{len(results)} closed-loop flights, seeds "
              f"{min(r.seed for r in results)}..{max(r.seed for r in results)}; {elapsed:.1f} s; "
              f"M-step memory: {memory_label(args.memory)}")
        report = online_report(results, truth, stats, args, elapsed)
        atomic_write_json(writer.path("report.json"), report)
        writer.path("report.md").write_text("# pinquad online experiment\n\n" + text + "\n")
        _online_figures(results, truth, writer.path("figures"))
        report["run_logs"] = _write_logs(results, writer)
        atomic_write_json(writer.path("report.json"), report)
        final = writer.publish()
    except BaseException:
        writer.abort()
        raise
    print(f"run written to {final}")
    if args.view:
        from viz.__main__ import main as viz_main

        return viz_main([str(final)])
    return 0


def converged_estimate(history: Array) -> Array:
    """Median of the last 10 % of updates (4,): m, Ixx, Iyy, Izz."""
    h = history[:, 2:6]
    n = max(1, int(round(0.1 * h.shape[0])))
    return np.median(h[-n:], axis=0)


def time_to_converge(history: Array, truth: Array, mass_band: float = 0.005,
                     inertia_band: float = 0.05) -> float:
    """Time [s] of the first update after which every later estimate stays within
    +-mass_band (mass) and +-inertia_band (inertia) of the truth; NaN if never."""
    rel = np.abs(history[:, 2:6] / truth - 1.0)
    ok = (rel[:, 0] <= mass_band) & np.all(rel[:, 1:4] <= inertia_band, axis=1)
    bad = np.flatnonzero(~ok)
    first = 0 if bad.size == 0 else bad[-1] + 1
    return float(history[first, 1]) if first < history.shape[0] else float("nan")


def offline_ranges(report_path: Path, mstep: str = "regressor") -> dict[str, Array]:
    """Per sensor, the (2, 4) [min; max] of [m, Ixx, Iyy, Izz] over the cycles of an offline
    ``report.json`` (DESIGN.md 4.3 ``cycles``) identified with ``mstep`` [kg, kg m^2].

    Raises ValueError naming the file if it is not an offline report with such cycles."""
    try:
        cycles = json.loads(Path(report_path).read_text())["cycles"]
        rows: dict[str, list[Array]] = {}
        for c in cycles:
            if c.get("mstep", "regressor") != mstep:
                continue
            inertia = np.asarray(c["estimates"]["inertia"], dtype=float)
            diag = np.diag(inertia) if inertia.ndim == 2 else inertia
            rows.setdefault(c["sensor"], []).append(np.array([c["estimates"]["mass"], *diag]))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{report_path}: not an offline report.json with 'cycles' "
                         f"(sensor, mstep, estimates.mass, estimates.inertia): {exc}") from None
    if not rows:
        raise ValueError(f"{report_path}: no cycles identified with the {mstep!r} M-step")
    return {s: np.array([np.min(v, axis=0), np.max(v, axis=0)]) for s, v in rows.items()}


def newest_offline_report(root: Path = Path("runs")) -> Path | None:
    """The report.json of the newest ``runs/offline-*`` directory, if any."""
    found = sorted(root.glob("offline-*/report.json"), key=lambda q: q.stat().st_mtime)
    return found[-1] if found else None


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


def online_report(results: list[OnlineCycle], truth: Array, stats: dict,
                  args: argparse.Namespace, elapsed: float) -> dict:
    from pinquad.core.params import PAPER_SCENARIO

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
                   "memory": memory_label(args.memory)},
        "estimates": first["estimates"], "truth": first["truth"],
        "em": {"iterations": OnlineConfig().iterations, "loglik": [], "converged": True},
        "discovery": {"selected": [], "residual_rms_before": {}, "residual_rms_after": {},
                      "validation": "not run in the online experiment"},
        "cycles": cycles, "statistics": stats,
        "scenario": {"start": PAPER_SCENARIO.start.tolist(),
                     "waypoints": PAPER_SCENARIO.waypoints.tolist()},
        "seconds": elapsed,
    }


def _write_logs(results: list[OnlineCycle], writer) -> dict:
    """The first cycle's log per sensor, and the onboard estimate as its 'smoothed'
    track (an online run has no whole-flight smoother); its flown trajectory as a
    figure."""
    from pinquad.core.params import PAPER_SCENARIO
    from pinquad.io.logs import write_log
    from pinquad.report.offline import plot_trajectory

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


def _online_figures(results: list[OnlineCycle], truth: Array, figs: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs.mkdir(parents=True, exist_ok=True)
    sensors = sorted({r.sensor for r in results})
    names = ["mass [kg]", "I_xx [kg m^2]", "I_yy [kg m^2]", "I_zz [kg m^2]"]
    fig, axes = plt.subplots(len(sensors), 4, figsize=(16, 3.2 * len(sensors)), squeeze=False)
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
    plt.close(fig)

    # The same histories as errors, zoomed to the acceptance bands: the start (m0 = 1 g,
    # 99 % off) would otherwise hide the converged part.
    bands = [0.5, 5.0, 5.0, 5.0]
    fig, axes = plt.subplots(len(sensors), 4, figsize=(16, 3.2 * len(sensors)), squeeze=False)
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
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
