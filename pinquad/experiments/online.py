"""Online EM in the closed loop (the paper's online scheme; ``python -m pinquad.online``).

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

import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import Posterior
from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_VEHICLE
from pinquad.estep.fast_smoother import posterior_arrays, smooth_quad
from pinquad.experiments.offline_mc import SENSOR_INDEX
from pinquad.identification.em import initial_theta
from pinquad.identification.identify import get_smoother
from pinquad.identification.window import window_em, window_prior
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
    ``report.json`` (``cycles``) identified with ``mstep`` [kg, kg m^2].

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

