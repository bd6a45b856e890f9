"""Measured Crazyflie flights as EM observations, and the real-vehicle identification table.

A micro-SD log (``pinquad.io.sdlog``, ~500 Hz ``fixedFrequency`` rows plus motion capture
at ~55 Hz on average) becomes :class:`~pinquad.models.ssm.Observations` on a uniform grid t_k = k dt,
dt = 0.01 s:

* gyro, accelerometer, onboard velocity: mean of the samples with
  t in [t_k - dt/2, t_k + dt/2) (centred, so the mean estimates the value at t_k);
* inputs u_k = [F, M_x, M_y, M_z]: mean over [t_k, t_k + dt) of the wrench of each
  ~2 ms sample, F = kf sum_i omega_i^2 [N], M = mixer (``ActuatorModel``) [N m]. The
  forward bin is what the explicit-Euler transition x_{k+1} = x_k + dt f(x_k, u_k)
  integrates: v_{k+1} - v_k = int_{t_k}^{t_k+dt} a dt ~ dt * mean(a);
* motion-capture position [m] and Euler angles [rad] (from the ``locSrv`` quaternion):
  the pose sample nearest t_k within dt/2, else NaN (a dropout is a missing sample);
  a pose more than ``outlier_m`` / ``outlier_rad`` away from the median of its
  neighbours is a tracking glitch and is dropped too.

Transitions k -> k+1 the M-step must skip (``Observations.exclude``): ground contact and
the take-off / landing around it (height below ``contact_height`` at low speed, or rotors
below flight speed, widened by ``contact_margin`` seconds), implausible rotor readings
(``faults.detect_actuation_faults``) unless repaired from the PWM commands, bins with no
actuation sample (the input there is interpolated only so the E-step can pass over it).

Identification (:func:`identify_real`) is EM with the compiled EKF + RTS E-step and
:class:`RealMStep`: the shared closed form for the mass (body-z force row), the shared
profiled objective for the inertia but on the torque rows band-passed to 3-8 Hz, and a
nuisance body moment (thrust, body-frame air speed, body rates) that the measured
flights demand: the rotor torques that cancel rotor-drag / blade-flapping moments are
ten times the inertial torque I omega' and, left in, inflate the inertia thirty-fold.

Yaw: the rotors' drag torque gamma kf omega_i^2 is not the whole yaw torque. A rotor the
motor speeds up takes J_r omega_i' [N m] from the motor, and the body takes the reaction:

    tau_z = sum_i spin_i (gamma kf omega_i^2 + J_r omega_i')

with omega_i' from the measured rotor speeds (:func:`rotor_acceleration`). In the 3-8 Hz
band the second term is as large as the first (the yaw acceleration leads the drag torque
by 40-70 deg on the yaw flights, with |omega_z'| / |tau_drag| rising in proportion to the
frequency, which is what a derivative term does). Regressing the band-passed gyro yaw
acceleration on the drag torque alone leaves 72-86 % of its variance unexplained on
jana01/04/05; adding J_r omega' with one J_r = 20e-9 kg m^2 for all logs leaves 25-66 %.
J_r can be identified per flight by the M-step (a yaw-row regressor projected out with
the nuisance features, ``RealMStep``), but within one log it trades off against I_zz
(per-flight J_r 7-23e-9, yaw I_zz spread 88 %). By default one J_r is pooled over the
seven logs with every rotor speed measured (:func:`pooled_rotor_inertia`: each log keeps
its own inertia; 15.5 +- 4.1 e-9 kg m^2, delete-one-log jackknife), and each of those
logs is identified with the J_r fitted on the other six (leave-one-out), so no log's
I_zz uses a J_r fitted on its own data. Held out, that J_r leaves 53 / 22 / 27 % of the
band-passed yaw acceleration variance unexplained on jana01/04/05, against 53 / 20 / 25 %
with each log's own J_r and 67 / 34 / 39 % without J_r; the yaw I_zz spread narrows
(88 % -> ~70 %) but stays far from 10 %: no single J_r brings jana01 (I_zz ~27e-6
whatever J_r) and jana04/05 (13-18e-6) together. No published Crazyflie J_r was found.

Flight data identify only kf / m and kf L / I (every input is proportional to kf), so
the identified mass and inertia scale exactly with the kf taken from the thrust stand;
:func:`thrust_coefficient` picks kf and its uncertainty, and :func:`identify_real`
propagates that uncertainty into the standard errors.

``python -m pinquad.realdata [--data DIR] [--jobs N] [--rotor-inertia pooled|per-flight|
none|VALUE]`` identifies every flight of the IMRC Lab data set and prints the table
(pooled J_r: a first pass fits J_r per flight on the pool logs, then every log is
identified with J_r fixed).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import euler_from_quat_wxyz
from pinquad.core.params import CRAZYFLIE21
from pinquad.io.datadir import default_data_dir
from pinquad.io.logs import FlightLog, LogFormatError, LogMeta
from pinquad.models.ssm import Observations, Theta
from pinquad.realdata.faults import (
    PARTNER,
    ActuationFaultReport,
    detect_actuation_faults,
    reconstruct_rpm,
)
from pinquad.vehicle.actuators import (
    KF_CRAZYFLIE,
    SPIN_CRAZYFLIE,
    YAW_RATIO_CRAZYFLIE,
    ActuatorModel,
    ThrustStandFit,
    fit_thrust_stand,
)

if TYPE_CHECKING:
    from pinquad.sim.simulator import Flight

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SCALE_MASS = CRAZYFLIE21.mass
"""The vehicle on a scale, battery and decks included [kg] (dataset README)."""
PUBLISHED_INERTIA = np.diag(CRAZYFLIE21.inertia).copy()
"""Crazyflie 2.0 without decks, bifilar pendulum (Foerster) [kg m^2]."""
YAW_RATIO_REL_SE = 0.0005 / YAW_RATIO_CRAZYFLIE
"""Relative standard uncertainty of the yaw torque/thrust ratio: published values span
0.0060-0.0070 m around the 0.006 m used, taken as +-0.0005 m (one standard deviation)."""
REPAIR_REL_SE = np.array([0.011, 0.07, 0.05, 0.24])
"""Relative standard uncertainty of [m, I_xx, I_yy, I_zz] added when rotor speeds were
rebuilt from PWM, measured by hiding M1 on the seven clean flights (zero in ~30 % of the
rows, a stuck half value elsewhere, as on jana20-29), rebuilding it with the partner map
and identifying again: root-mean-square change of the estimate over the seven flights
(mass 1.1 %: mean +0.55 %, largest +2.6 % on jana01; I_xx 7 %, I_yy 5 %, I_zz 24 %).

On jana20-29 themselves the rebuilt M1 is checked against M1's own readings: the stuck
channel updates a few hundred times per flight, and each fresh value is half the speed
(a ratio to M3 of 0.48 where the clean flights give 0.92-0.99); twice the fresh values
agree with the partner-map rebuild to +0.5..+1.3 % (median, six logs) and -0.5 % (jana25),
residual 50-160 rev/min. The +2.3..+3.3 % mass excess of those flights is not the repair:
the mocap-acceleration force balance with the measured M2 + M3 + M4 alone gives
26.9-27.0 g-equivalents there against 26.1-26.5 on jana02-05 (same M1/M3 and M2/M4 speed
balance), +2.5-3 % from motors that were never rebuilt, and it persists in slow level
flight (< 0.3 m/s, |v_z| < 0.1 m/s) and away from the floor. Thrust per rpm^2 (air
density, propellers) or the vehicle's mass differed in that session; flight data
identify only kf / m and cannot tell which."""
GRID_DT = 0.01
"""Resampled step [s]: 100 Hz."""

FLIGHTS: dict[str, str] = {
    "jana00": "figure-8 at 0.7 m, time scale 1.0 (fast)",
    "jana01": "yaw sweep at 0.7 m, time scale 5",
    "jana02": "figure-8 at 0.3 m, time scale 0.8",
    "jana03": "figure-8 at 0.3 m, time scale 0.8 (2nd controller)",
    "jana04": "yaw sweep at 0.5 m, time scale 5",
    "jana05": "yaw sweep at 0.5 m, time scale 4",
    "jana10": "circle at 0.5 m, time scale 5",
    "jana20": "random in 1 m box (M1 rpm faulty)",
    "jana23": "random in 1 m box (M1 rpm faulty)",
    "jana24": "random in 1 m box (M1 rpm faulty)",
    "jana25": "random in 1 m box (M1 rpm faulty)",
    "jana27": "random in 1 m box (M1 rpm faulty)",
    "jana28": "random in 1 m box (M1 rpm faulty)",
    "jana29": "random in 1 m box (M1 rpm faulty)",
}
"""The IMRC Lab flights and what was flown (dataset README)."""
YAW_FLIGHTS = ("jana01", "jana04", "jana05")


def flights_dir(data: Path | None = None) -> Path:
    """Directory of the micro-SD flight logs: ``data`` (the Crazyflie data directory or
    the flights directory itself), else ``imrc_brushed`` in ``default_data_dir()``."""
    base = data if data is not None else default_data_dir()
    return base / "imrc_brushed" if (base / "imrc_brushed").is_dir() else base


def stand_dir(data: Path | None = None) -> Path:
    """Directory of the thrust-stand CSVs (``thrust_stand`` next to the flights)."""
    base = data if data is not None else default_data_dir()
    for cand in (base / "thrust_stand", base.parent / "thrust_stand"):
        if cand.is_dir():
            return cand
    return base / "thrust_stand"


# ----------------------------------------------------------------------------- kf

@dataclass(frozen=True)
class ThrustCoefficient:
    """The rotor thrust coefficient used for a real flight, and how well it is known.

    kf [N/(rad/s)^2]: the equal-weight mean of the per-run thrust-stand fits;
    kf_se [N/(rad/s)^2]: the standard error of that mean from the spread between runs
    (std(ddof=1) / sqrt(runs)); runs: each run's fit (``fit_thrust_stand`` per CSV);
    pooled [N/(rad/s)^2]: the row-weighted fit of all CSVs together, for comparison;
    note: how kf was chosen, in words.
    """

    kf: float
    kf_se: float
    runs: tuple[ThrustStandFit, ...]
    pooled: float
    note: str

    @property
    def rel_se(self) -> float:
        """kf_se / kf [1]."""
        return self.kf_se / self.kf


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


# ----------------------------------------------------------------------------- options

@dataclass(frozen=True)
class RealDataOptions:
    """How a measured log becomes observations.

    dt [s]: grid step; channels: measurement blocks among ``pos`` (motion capture),
    ``vel`` (onboard estimate), ``euler`` (motion capture), ``gyro``; onboard_pos: take
    ``pos`` from the onboard estimate instead of the motion capture (source A);
    faults: ``repair`` (rebuild untrusted rotor speeds from PWM through a map learned on
    the diagonal partner, which spins the same way), ``repair-all`` (map learned on all
    trusted motors: ``faults.repair_log``), or ``exclude`` (skip flagged rows);
    kf [N/(rad/s)^2] or None for :func:`thrust_coefficient`; yaw_ratio [m]; spin;
    contact_height [m], contact_speed [m/s], flight_rpm [rev/min], contact_margin [s]:
    ground-contact detection (module docstring); outlier_m [m], outlier_rad [rad]:
    motion-capture glitch thresholds.
    """

    dt: float = GRID_DT
    channels: tuple[str, ...] = ("pos", "euler", "gyro")
    onboard_pos: bool = False
    faults: str = "repair"
    kf: float | None = None
    yaw_ratio: float = YAW_RATIO_CRAZYFLIE
    rotor_inertia: float = 0.0
    spin: tuple[float, float, float, float] = SPIN_CRAZYFLIE
    contact_height: float = 0.03
    contact_speed: float = 0.2
    flight_rpm: float = 10000.0
    contact_margin: float = 0.3
    outlier_m: float = 0.05
    outlier_rad: float = 0.2

    def __post_init__(self) -> None:
        bad = [c for c in self.channels if c not in ("pos", "vel", "euler", "gyro")]
        if bad or not self.channels:
            raise ValueError(f"channels {self.channels}: expected some of pos, vel, euler, gyro")
        if self.faults not in ("repair", "repair-all", "exclude"):
            raise ValueError(f"faults {self.faults!r}: expected repair, repair-all or exclude")
        if not self.dt > 0:
            raise ValueError(f"dt must be positive; got {self.dt}")


SENSOR_CHANNELS = {
    "A": (("pos", "vel", "gyro"), True),
    "B": (("pos", "vel", "euler", "gyro"), False),
    "C": (("pos", "vel", "gyro"), False),
}
"""--sensor on a measured log: B = everything, C = no attitude, A = the onboard
estimate's position and velocity with the gyro (the paper's sources)."""


def options_for_sensor(sensor: str | None, base: RealDataOptions | None = None
                       ) -> RealDataOptions:
    """Options for a paper source name (None: the default measured-log channels)."""
    base = base or RealDataOptions()
    if sensor is None:
        return base
    if sensor not in SENSOR_CHANNELS:
        raise ValueError(f"unknown sensor {sensor!r}; expected A, B or C")
    channels, onboard = SENSOR_CHANNELS[sensor]
    return replace(base, channels=channels, onboard_pos=onboard)


# ----------------------------------------------------------------------------- inputs

@dataclass(frozen=True)
class PoseSamples:
    """Motion-capture poses at their own times.

    t (P,) [s, log clock]; position (P, 3) [m, world]; euler (P, 3) roll, pitch, yaw
    [rad] (NaN where the quaternion was missing or not unit).
    """

    t: Array
    position: Array
    euler: Array


@dataclass(frozen=True)
class RawFlight:
    """What :func:`build_observations` needs of a measured flight, before resampling.

    log: the flight at its own rate (rows at log.t [s]) with ``rpm`` (N, 4) [rev/min];
    pose: motion-capture samples (None: use the log's own position / euler rows);
    pwm (N, 4) [0..65535] or None; onboard_pos (N, 3) [m] or None: the vehicle's own
    position estimate; vbat_stuck: the battery reading is not a measurement.
    """

    log: FlightLog
    pose: PoseSamples | None = None
    pwm: Array | None = None
    onboard_pos: Array | None = None


def raw_from_sdflight(flight) -> RawFlight:
    """A :class:`RawFlight` from ``pinquad.io.sdlog.SdFlight``: motion capture from the raw
    ``estPose`` records (not the copies already snapped to the 500 Hz rows)."""
    from pinquad.io.sdlog import POSE_EVENT

    raw = flight.raw
    pose = None
    ev = raw.events.get(POSE_EVENT)
    if ev is not None and ev.count:
        t = ev.time - flight.t0
        keep = np.concatenate([[True], t[1:] > np.maximum.accumulate(t)[:-1]])
        pos = np.column_stack([ev.get(f"locSrv.{a}") for a in "xyz"])[keep]
        quat = np.column_stack([ev.get(f"locSrv.q{a}") for a in "wxyz"])[keep]
        norm = np.linalg.norm(quat, axis=1)
        good = np.isfinite(quat).all(axis=1) & (np.abs(norm - 1.0) < 0.1)
        euler = np.full((quat.shape[0], 3), np.nan)
        if good.any():
            euler[good] = euler_from_quat_wxyz(quat[good] / norm[good, None])
        pose = PoseSamples(t=t[keep], position=pos, euler=euler)
    grid = raw.events["fixedFrequency"]
    onboard = None
    if all(grid.has(f"stateEstimate.{a}") for a in "xyz"):
        onboard = np.column_stack([grid.get(f"stateEstimate.{a}")[flight.rows] for a in "xyz"])
    return RawFlight(log=flight.log, pose=pose, pwm=flight.pwm, onboard_pos=onboard)


def raw_from_simulated(flight: Flight, actuator: ActuatorModel | None = None) -> RawFlight:
    """A simulated flight (``pinquad.sim.simulator.simulator.Flight`` flown with sensor B) as a measured log,
    so that the measured-flight pipeline can be checked against a known truth: rotor
    speeds from the logged commanded wrench through the inverse X mixer,

        T = A^-1 [F, tau],   omega_i = sqrt(T_i / kf) [rad/s]  (as rev/min; T_i >= 0),

    with A and kf of ``actuator`` (default: ``ActuatorModel()``, the shared constants);
    the pose stream from the flight's position and Euler samples, the gyro and the
    velocity samples as logged. Raises ValueError if the flight has no pose samples."""
    actuator = actuator or ActuatorModel()
    onboard = flight.onboard
    if not (np.isfinite(onboard.euler).any() and np.isfinite(onboard.position).any()):
        raise ValueError(f"sensor {flight.config.sensor} logs no pose: the measured-flight "
                         "pipeline needs position and attitude samples (fly sensor B)")
    thrust = np.linalg.solve(actuator.allocation(), np.asarray(flight.inputs, float).T).T
    rpm = np.sqrt(np.maximum(thrust, 0.0) / actuator.kf) * 60.0 / (2.0 * np.pi)
    n = flight.t.size
    nan3 = np.full((n, 3), np.nan)
    log = FlightLog(t=flight.t.copy(), position=nan3, velocity=onboard.velocity.copy(),
                    euler=nan3, gyro=onboard.gyro.copy(), accel=nan3, rpm=rpm,
                    meta=LogMeta(vehicle=flight.config.vehicle.name,
                                 gravity=flight.config.vehicle.gravity,
                                 source=f"simulation (sensor {flight.config.sensor})"))
    pose = PoseSamples(t=flight.t.copy(), position=onboard.position.copy(),
                       euler=onboard.euler.copy())
    return RawFlight(log=log, pose=pose)


def simulated_crazyflie(factor: float, seed: int, sensor: str = "B") -> Flight:
    """A simulated closed-loop flight of the Crazyflie 2.1 (``pinquad.sim.simulator.simulator.Flight``): the
    offline command's scenario (the paper's, scaled by 0.3), the sensor set ``sensor``,
    the simulator's torque process noise multiplied by ``factor``, generator seed
    ``seed``; the diagnostics' known-truth counterpart of a measured flight."""
    from pinquad.core.params import PAPER_SCENARIO, process_noise_for
    from pinquad.sim.simulator import SimConfig, simulate

    config = SimConfig(vehicle=CRAZYFLIE21, sensor=sensor, scenario=PAPER_SCENARIO.scaled(0.3),
                       process_noise=process_noise_for(CRAZYFLIE21).scaled(1.0, factor))
    return simulate(config, np.random.default_rng(seed))


def simulated_observations(flight: Flight) -> RealObservations:
    """A sensor-B simulated flight through the measured-flight path
    (:func:`raw_from_simulated`, then :func:`build_observations` with the shared kf)."""
    return build_observations(raw_from_simulated(flight), RealDataOptions(kf=KF_CRAZYFLIE))


def _bin_mean(t: Array, values: Array, start: Array, dt: float, k: int) -> Array:
    """(k, C) mean of the finite values with start[j] <= t < start[j] + dt; NaN if none.

    start is a uniform grid (start[j] = start[0] + j dt), so each sample's bin is
    floor((t - start[0]) / dt).
    """
    values = np.asarray(values, dtype=float).reshape(t.size, -1)
    idx = np.floor((t - start[0]) / dt + 1e-9).astype(np.int64)
    inside = (idx >= 0) & (idx < k)
    out = np.full((k, values.shape[1]), np.nan)
    for c in range(values.shape[1]):
        ok = inside & np.isfinite(values[:, c])
        total = np.bincount(idx[ok], weights=values[ok, c], minlength=k)
        count = np.bincount(idx[ok], minlength=k)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, c] = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return out


def _nearest(grid_t: Array, times: Array, tol: float) -> tuple[NDArray[np.int64],
                                                                 NDArray[np.int64]]:
    """(rows, which): grid row ``rows[i]`` takes sample ``which[i]``, the sample nearest
    that row's time within ``tol`` [s] (one sample per row, the closest)."""
    dt = grid_t[1] - grid_t[0] if grid_t.size > 1 else 1.0
    rows = np.rint((times - grid_t[0]) / dt).astype(np.int64)
    ok = (rows >= 0) & (rows < grid_t.size)
    dist = np.full(times.size, np.inf)
    dist[ok] = np.abs(grid_t[rows[ok]] - times[ok])
    cand = np.flatnonzero(ok & (dist <= tol))
    order = cand[np.lexsort((dist[cand], rows[cand]))]
    first = np.concatenate([[True], rows[order][1:] != rows[order][:-1]]) if order.size else \
        np.zeros(0, dtype=bool)
    which = order[first]
    return rows[which], which


def _glitches(x: Array, limit: float, angle: bool = False, half: int = 3) -> BoolArray:
    """(P,) samples further than ``limit`` from the median of their 2*half finite
    neighbours in any component (angles unwrapped first); NaN samples are never
    flagged."""
    p = x.shape[0]
    bad = np.zeros(p, dtype=bool)
    offsets = np.concatenate([np.arange(-half, 0), np.arange(1, half + 1)])
    for c in range(x.shape[1]):
        ok = np.flatnonzero(np.isfinite(x[:, c]))
        if ok.size < 2 * half + 1:
            continue
        col = np.unwrap(x[ok, c]) if angle else x[ok, c]
        idx = np.clip(np.arange(ok.size)[:, None] + offsets[None, :], 0, ok.size - 1)
        bad[ok] |= np.abs(col - np.median(col[idx], axis=1)) > limit
    return bad


# ----------------------------------------------------------------------------- result

@dataclass(frozen=True)
class Exclusion:
    """One reason for skipping transitions: reason (words) and transitions (count; a
    transition may have several reasons)."""

    reason: str
    transitions: int


@dataclass(frozen=True)
class RealObservations:
    """A measured flight ready for EM.

    obs: the E-step's Observations on the grid (N steps of dt); log: the resampled
    flight (N rows: mocap position / Euler, onboard velocity, gyro, accelerometer,
    rotor speeds after repair, thrust [N] and torque [N m] = obs.inputs);
    exclusions: why transitions were skipped, with counts; notes: what else was done
    (repairs, dropouts, glitches) in words; faults: the actuation fault report of the
    original-rate log; kf: the thrust coefficient used; source: the file; repaired:
    motors (0-based) whose readings were rebuilt from PWM; rotor_acc (N,) [rad/s^2]: mean
    over [t_k, t_k + dt) of sum_i spin_i d(omega_i)/dt (:func:`rotor_acceleration`, gaps
    interpolated), the regressor of the rotor-inertia yaw torque J_r * rotor_acc;
    rebuilt_fraction (N,) [-]: share of the log's rotor samples in [t_k, t_k + dt) with a
    speed taken from the PWM map (1 for a bin without samples; None: not recorded).
    """

    obs: Observations
    log: FlightLog
    exclusions: tuple[Exclusion, ...]
    notes: tuple[str, ...]
    faults: ActuationFaultReport
    kf: ThrustCoefficient
    source: str
    options: RealDataOptions = field(default_factory=RealDataOptions)
    repaired: tuple[int, ...] = ()
    rotor_acc: Array | None = None
    rebuilt_fraction: Array | None = None

    @property
    def n_transitions(self) -> int:
        return self.obs.n - 1

    @property
    def n_excluded(self) -> int:
        return int(self.obs.exclude[: self.obs.n - 1].sum())

    @property
    def n_used(self) -> int:
        return self.n_transitions - self.n_excluded

    @property
    def excluded(self) -> tuple[str, ...]:
        """Human-readable exclusion list: one line per reason with its count, then the
        total."""
        lines = [f"{e.transitions} transitions: {e.reason}" for e in self.exclusions
                 if e.transitions]
        lines.append(f"total: {self.n_excluded} of {self.n_transitions} transitions excluded, "
                     f"{self.n_used} used ({self.obs.dt * 1e3:.0f} ms each)")
        return tuple(lines)


# ----------------------------------------------------------------------------- build

def _repair(raw: RawFlight, report: ActuationFaultReport, mode: str
            ) -> tuple[Array, BoolArray, BoolArray, list[str]]:
    """Rotor speeds (N, 4) after the chosen fault handling, rows (N,) still untrusted,
    readings (N, 4) taken from the PWM map, and notes."""
    log = raw.log
    rpm = np.asarray(log.rpm, dtype=float)
    untrusted = report.motor_mask | report.unreliable[None, :]
    notes: list[str] = []
    none = np.zeros((log.n, 4), dtype=bool)
    if not untrusted.any():
        return rpm, np.zeros(log.n, dtype=bool), none, notes
    if mode == "exclude" or raw.pwm is None or not np.isfinite(raw.pwm).all():
        if mode != "exclude":
            notes.append("implausible rotor speeds cannot be rebuilt (no PWM in the log): "
                         "their rows are excluded")
        return rpm, untrusted.any(axis=1), none, notes
    bad_motors = [i for i in range(4) if untrusted[:, i].any()]
    if mode == "repair" and not any(untrusted[:, PARTNER[i]].any() for i in bad_motors):
        # A motor's diagonal partner spins the same way with the same propeller type;
        # on the clean flights the PWM -> rpm map of M3 alone predicts M1's mean speed
        # to +0.5 % on average, the map of all three other motors to +2 %.
        out = rpm.copy()
        rebuilt = none.copy()
        for i in bad_motors:
            others = tuple(j for j in range(4) if j != PARTNER[i])
            rec = reconstruct_rpm(log, raw.pwm, report, replace_motors=others)
            out[untrusted[:, i], i] = rec.rpm[untrusted[:, i], i]
            rebuilt[:, i] = untrusted[:, i] & rec.replaced[:, i]
            notes.append(f"M{i + 1}: {int(rebuilt[:, i].sum())} readings rebuilt from its PWM "
                         f"through the PWM -> rpm map of its diagonal partner M{PARTNER[i] + 1} "
                         f"(first-order lag {rec.tau * 1e3:.0f} ms, map residual "
                         f"{rec.fit_rms:.0f} rev/min)")
            div = rec.divisions[i]
            if div is not None and div.divisor > 1:
                notes.append(div.describe(i))
        return out, np.zeros(log.n, dtype=bool), rebuilt, notes
    if mode == "repair":
        notes.append("a diagonal partner is untrusted too: map learned on all trusted motors")
    rec = reconstruct_rpm(log, raw.pwm, report)
    notes.extend(rec.notes)
    return rec.rpm, np.zeros(log.n, dtype=bool), rec.replaced, notes


def rotor_acceleration(t: Array, rpm: Array, spin: Sequence[float]) -> Array:
    """(N,) sum_i spin_i d(omega_i)/dt [rad/s^2] from rotor speeds rpm (N, 4) [rev/min] at
    times t (N,) [s]: central differences, NaN where a neighbouring interval is a log gap
    (longer than twice the median step) or a speed is not finite.

    Times J_r [kg m^2] it is the reaction torque of the rotors' own angular acceleration on
    the body about z, tau_z = sum_i spin_i J_r d(omega_i)/dt [N m], with the sign of the
    rotor's drag torque (the motor supplies J_r omega_i' + Q_i to the rotor along its spin
    axis and the body takes the opposite).
    """
    omega = np.asarray(rpm, dtype=float) * (2.0 * math.pi / 60.0)
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return np.full(t.size, np.nan)
    acc = np.gradient(omega, t, axis=0) @ np.asarray(spin, dtype=float)
    step = np.diff(t)
    gap = step > 2.0 * float(np.median(step))
    acc[np.concatenate([gap, [False]]) | np.concatenate([[False], gap])] = np.nan
    return acc


def build_observations(raw: RawFlight, options: RealDataOptions | None = None,
                       kf: ThrustCoefficient | None = None) -> RealObservations:
    """Resample a measured flight to the grid and build the EM observations (module
    docstring). Raises ValueError if nothing usable remains."""
    options = options or RealDataOptions()
    log = raw.log
    source = log.meta.source
    if log.rpm is None:
        raise ValueError(f"{source}: the log has no rotor speeds (rpm_1..rpm_4); expected "
                         "rpm columns to compute thrust and torques")
    if log.n < 10:
        raise ValueError(f"{source}: only {log.n} samples; expected a flight of at least 10")
    if kf is None:
        kf = (thrust_coefficient() if options.kf is None else
              ThrustCoefficient(options.kf, 0.05 * options.kf, (), options.kf,
                                f"kf = {options.kf:.4e} N/(rad/s)^2 given (5 % assumed)"))
    notes: list[str] = [kf.note]
    dt = options.dt

    report = detect_actuation_faults(log, flight_rpm=options.flight_rpm)
    rpm, untrusted_rows, rebuilt, repair_notes = _repair(raw, report, options.faults)
    untrusted_motors = report.motor_mask | report.unreliable[None, :]
    notes.extend(repair_notes)
    if report.vbat_stuck:
        notes.append(f"battery voltage stuck at {report.vbat_value:.2f} V: not used")
    actuator = ActuatorModel(kf=kf.kf, yaw_ratio=options.yaw_ratio, spin=options.spin)
    finite_rpm = np.isfinite(rpm).all(axis=1)
    thrust = np.full(log.n, np.nan)
    torque = np.full((log.n, 3), np.nan)
    if finite_rpm.any():
        thrust[finite_rpm], torque[finite_rpm] = actuator.wrench(rpm[finite_rpm])
    rotor_acc = rotor_acceleration(log.t, rpm, options.spin)
    if options.rotor_inertia:
        torque[:, 2] += options.rotor_inertia * rotor_acc
    # Untrusted rows carry no input: their bins become NaN and are excluded below.
    wrench = np.column_stack([thrust, torque])
    wrench[untrusted_rows] = np.nan

    t_src = log.t
    k = int(math.floor((t_src[-1] - t_src[0]) / dt)) + 1
    grid = t_src[0] + dt * np.arange(k)
    centred = grid - 0.5 * dt
    gyro = _bin_mean(t_src, log.gyro, centred, dt, k)
    accel = _bin_mean(t_src, log.accel, centred, dt, k)
    vel = _bin_mean(t_src, log.velocity, centred, dt, k)
    rpm_g = _bin_mean(t_src, np.where(untrusted_rows[:, None], np.nan, rpm), grid, dt, k)
    rebuilt_g = _bin_mean(t_src, rebuilt.any(axis=1).astype(float), grid, dt, k)[:, 0]
    inputs = _bin_mean(t_src, wrench, grid, dt, k)
    rotor_acc_g = _interp_nan(grid, _bin_mean(
        t_src, np.where(untrusted_rows, np.nan, rotor_acc), grid, dt, k)[:, 0])
    vbat = None
    if log.vbat is not None and not report.vbat_stuck:
        vbat = _bin_mean(t_src, log.vbat, centred, dt, k)[:, 0]
    onboard_pos = None
    if raw.onboard_pos is not None:
        onboard_pos = _bin_mean(t_src, raw.onboard_pos, centred, dt, k)

    # Motion capture: nearest sample within half a bin.
    if raw.pose is not None:
        pose = raw.pose
    else:
        pose = PoseSamples(t=t_src, position=log.position, euler=log.euler)
    has_pose = np.isfinite(pose.position).all(axis=1) | np.isfinite(pose.euler).all(axis=1)
    p_t, p_pos, p_eul = pose.t[has_pose], pose.position[has_pose], pose.euler[has_pose]
    glitch_pos = _glitches(p_pos, options.outlier_m)
    glitch_eul = _glitches(p_eul, options.outlier_rad, angle=True)
    p_pos = np.where(glitch_pos[:, None], np.nan, p_pos)
    p_eul = np.where(glitch_eul[:, None], np.nan, p_eul)
    rows, which = _nearest(grid, p_t, 0.5 * dt)
    position = np.full((k, 3), np.nan)
    euler = np.full((k, 3), np.nan)
    position[rows] = p_pos[which]
    euler[rows] = p_eul[which]
    n_pose = int(np.isfinite(position).all(axis=1).sum())
    notes.append(f"motion capture: {p_t.size} poses; {n_pose} of {k} grid steps have one "
                 f"within {0.5 * dt * 1e3:.0f} ms ({100 * n_pose / k:.0f} %), the others are "
                 "missing samples")
    if glitch_pos.any() or glitch_eul.any():
        notes.append(f"motion capture: {int(glitch_pos.sum())} position / "
                     f"{int(glitch_eul.sum())} attitude samples more than "
                     f"{options.outlier_m * 100:.0f} cm / {options.outlier_rad:.2f} rad from the "
                     "median of their 6 neighbours dropped as tracking glitches")

    # --- exclusions (transitions k -> k+1)
    exclusions: list[Exclusion] = []
    n_tr = k - 1
    exclude = np.zeros(k, dtype=bool)

    # Ground contact: near the floor and slow, or rotors below flight speed; widened by
    # the margin because take-off and landing mix contact forces and ground effect.
    z = position[:, 2]
    z_fill = _interp_nan(grid, z)
    speed = np.linalg.norm(np.nan_to_num(vel), axis=1)
    rotors_idle = np.isfinite(rpm_g).all(axis=1)
    rotors_idle[rotors_idle] = np.median(rpm_g[rotors_idle], axis=1) < options.flight_rpm
    low = np.isfinite(z_fill) & (z_fill < options.contact_height) & (speed < options.contact_speed)
    contact = low | rotors_idle
    grow = int(round(options.contact_margin / dt))
    if contact.any():
        near = np.convolve(contact.astype(float), np.ones(2 * grow + 1), mode="same") > 0
        ex = near.copy()
        ex[:-1] |= near[1:]
        exclusions.append(Exclusion(
            f"ground contact, take-off or landing (height < {options.contact_height * 100:.0f} "
            f"cm at < {options.contact_speed:g} m/s, or median rotor speed < "
            f"{options.flight_rpm:.0f} rev/min; {int(contact.sum())} steps, widened by "
            f"{options.contact_margin:g} s)", int(ex[:n_tr].sum())))
        exclude |= ex
    else:
        exclusions.append(Exclusion("ground contact, take-off or landing: none (airborne "
                                    "throughout: the logs start and end in flight)", 0))

    if untrusted_rows.any():
        # A bin with any untrusted sample is skipped, even if trusted samples remain.
        ex = _bin_mean(t_src, untrusted_rows.astype(float), grid, dt, k)[:, 0] > 0
        exclusions.append(Exclusion(
            f"implausible rotor readings ({report.n_flagged} of {log.n} samples flagged by "
            "faults.detect_actuation_faults" + (", not repaired" if options.faults == "exclude"
                                                 else "") + ")", int(ex[:n_tr].sum())))
        exclude |= ex
    elif report.n_flagged:
        exclusions.append(Exclusion(
            f"implausible rotor readings: {report.n_flagged} of {log.n} samples flagged, all "
            "rebuilt from PWM (none excluded)", 0))

    nan_in = np.isnan(inputs).any(axis=1)
    ex = nan_in & ~exclude
    exclusions.append(Exclusion("no actuation sample in the 10 ms bin (log gaps) or "
                                "non-finite rotor speed", int(ex[:n_tr].sum())))
    exclude |= nan_in
    if nan_in.all():
        raise ValueError(f"{source}: no usable actuation sample in the whole log "
                         f"({report.n_flagged} of {log.n} rotor readings implausible); "
                         "expected finite, plausible rpm (rebuild them from the PWM commands: "
                         "RealDataOptions(faults='repair'))")
    inputs = np.column_stack([_interp_nan(grid, inputs[:, c]) for c in range(4)])

    # --- measurements
    if options.onboard_pos and onboard_pos is None:
        raise ValueError(f"{source}: sensor A needs the onboard position estimate "
                         "(stateEstimate.x/y/z), which the log does not have")
    blocks = {"pos": onboard_pos if options.onboard_pos else position, "vel": vel,
              "euler": euler, "gyro": gyro}
    for ch in options.channels:
        if not np.isfinite(blocks[ch]).any():
            raise ValueError(f"{source}: measurement channel {ch!r} has no sample in the "
                             "log; expected motion capture (pos, euler), onboard velocity "
                             "(vel) or gyro samples")
    ys = np.column_stack([blocks[ch] for ch in options.channels])
    x0 = np.zeros(12)
    p0 = np.array([1e-2] * 3 + [0.25] * 3 + [1e-2] * 3 + [0.25] * 3)
    for sl, blk in ((slice(0, 3), blocks["pos"]), (slice(3, 6), vel), (slice(6, 9), euler),
                    (slice(9, 12), gyro)):
        ok = np.isfinite(blk).all(axis=1)
        if ok.any():
            x0[sl] = blk[np.argmax(ok)]
    obs = Observations(t=grid - grid[0], dt=dt, inputs=inputs, channels=options.channels,
                       ys=ys, x0=x0, p0=p0, exclude=exclude)
    if obs.n < 3 or int((~exclude[:n_tr]).sum()) < 10:
        why = "; ".join(e.reason for e in exclusions if e.transitions)
        raise ValueError(f"{source}: only {int((~exclude[:n_tr]).sum())} usable transitions "
                         f"after exclusions ({why}); expected at least 10")

    meta = LogMeta(vehicle=log.meta.vehicle, mass_guess=log.meta.mass_guess,
                   inertia_guess=log.meta.inertia_guess, gravity=log.meta.gravity,
                   source=source, notes=tuple(log.meta.notes) + tuple(notes))
    resampled = FlightLog(t=obs.t, position=position, velocity=vel, euler=euler, gyro=gyro,
                          accel=accel, thrust=inputs[:, 0], torque=inputs[:, 1:4],
                          rpm=_fill_rows(grid, rpm_g), vbat=vbat, meta=meta)
    repaired = tuple(int(i) for i in range(4) if (untrusted_motors[:, i]).any()) \
        if not untrusted_rows.any() else ()
    return RealObservations(obs=obs, log=resampled, exclusions=tuple(exclusions),
                            notes=tuple(notes), faults=report, kf=kf, source=source,
                            options=options, repaired=repaired,
                            rotor_acc=np.nan_to_num(rotor_acc_g),
                            rebuilt_fraction=np.nan_to_num(rebuilt_g, nan=1.0))


def _interp_nan(t: Array, x: Array) -> Array:
    """x with NaNs linearly interpolated in t (held at the ends); all-NaN stays NaN."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x)
    if ok.all() or not ok.any():
        return x.copy()
    out = x.copy()
    out[~ok] = np.interp(t[~ok], t[ok], x[ok])
    return out


def _fill_rows(t: Array, x: Array) -> Array:
    return np.column_stack([_interp_nan(t, x[:, c]) for c in range(x.shape[1])])


def load_real(path: str | Path, options: RealDataOptions | None = None,
              kf: ThrustCoefficient | None = None) -> RealObservations:
    """Observations of a measured log: a Crazyflie micro-SD file, or a CSV / Parquet log
    with ``rpm_1..4`` columns. Raises LogFormatError / ValueError with the file named."""
    from pinquad.io.sdlog import is_sdlog, read_sdflight

    path = Path(path)
    if is_sdlog(path):
        raw = raw_from_sdflight(read_sdflight(path))
    else:
        from pinquad.io.logs import read_log

        log = read_log(path)
        if log.rpm is None:
            raise LogFormatError(f"{path}: no rpm_1..rpm_4 columns; expected rotor speeds for "
                                 "the actuator model")
        raw = RawFlight(log=log)
    return build_observations(raw, options, kf)


# ----------------------------------------------------------------------------- identification

TORQUE_FEATURES = ("thrust", "body_velocity", "body_rate")
"""Nuisance body-moment regressors: thrust F [N] (centre of mass off the thrust centre,
per-motor thrust mismatch: a moment proportional to thrust), body-frame velocity v_b
[m/s] (rotor drag / blade flapping: a moment proportional to the air speed, which the
controller cancels with differential thrust and which, on these flights, is ten times
the inertial torque I omega'), body rates omega [rad/s] (rotor damping)."""


@dataclass(frozen=True)
class RealTheta(Theta):
    """E-step parameters of a measured flight: Theta plus the nuisance body moment of the
    current iterate.

    torque_offset (N, 3) [N m] or None: added to the rotor torques before the E-step,
    tau_eff = tau_rotors + torque_offset; moment_coef (3, Z): its coefficients on the
    :data:`TORQUE_FEATURES` (N m per feature unit); rotor_inertia: J_r [kg m^2] of the
    yaw reaction torque J_r * rotor_acc (None: not fitted), so that torque_offset =
    z @ moment_coef^T + [0, 0, J_r * rotor_acc].
    """

    torque_offset: Array | None = None
    moment_coef: Array | None = None
    rotor_inertia: float | None = None


def corrected(obs: Observations, theta: Theta) -> Observations:
    """obs with the nuisance moment of ``theta`` (a :class:`RealTheta`) added to the
    torque inputs; obs itself for a plain Theta."""
    off = getattr(theta, "torque_offset", None)
    if off is None:
        return obs
    inputs = obs.inputs.copy()
    inputs[:, 1:4] += off
    return replace(obs, inputs=inputs)


def real_model(obs: Observations, theta: Theta):
    """E-step model: the force-free warm-up (``KinematicSSM``) while theta carries the
    paper's fixed Q0, then the quadcopter with the corrected torques."""
    from pinquad.models.ssm import KinematicSSM, QuadSSM

    if theta.noise.fixed_q is not None:
        return KinematicSSM(obs, theta)
    return QuadSSM(corrected(obs, theta), theta)


def torque_features(mean: Array, thrust: Array) -> Array:
    """z (N, 7) = [F, v_b (3), omega (3)] from state means (N, 12) and thrust (N,) [N]."""
    from pinquad.core.conventions import rotation_from_euler

    rot = rotation_from_euler(mean[:, 6:9])
    v_body = np.einsum("kji,kj->ki", rot, mean[:, 3:6])
    return np.column_stack([thrust, v_body, mean[:, 9:12]])


_T_MAT = np.array([[0.0, 1.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 0.0]])


def _profiled_inertia(a: Array, b: Array, c: Array, start: Array) -> tuple[Array, float]:
    """argmin_I J(I) = 1/2 sum_j log q_j(I) - sum_i log I_i, q_j = I^T a_j I - 2 b_j^T I
    + c_j (a (3, 3, 3), b (3, 3), c (3,)): the shared regressor M-step's torque
    objective, over physically consistent diagonal inertias (positive, I_xx <= I_yy +
    I_zz and cyclic).

    Damped Newton from the better of ``start`` and the unweighted least-squares solution:
    gradient g = 1/2 sum_j q_j'/q_j - 1/I, Hessian H = sum_j (a_j/q_j - q_j' q_j'^T /
    (2 q_j^2)) + diag(1/I^2); a step that is not a descent direction falls back to the
    gradient, and each step is halved until J decreases with I physical.
    """

    def parts(inertia: Array) -> tuple[float, Array, Array]:
        q = np.einsum("p,apq,q->a", inertia, a, inertia) - 2.0 * b @ inertia + c
        if np.any(q <= 0) or np.any(inertia <= 0):
            return math.inf, np.zeros(3), np.eye(3)
        dq = 2.0 * np.einsum("apq,q->ap", a, inertia) - 2.0 * b
        val = 0.5 * float(np.sum(np.log(q))) - float(np.sum(np.log(inertia)))
        grad = 0.5 * np.sum(dq / q[:, None], axis=0) - 1.0 / inertia
        hess = (np.einsum("apq,a->pq", a, 1.0 / q)
                - 0.5 * np.einsum("ap,aq,a->pq", dq, dq, 1.0 / q**2) + np.diag(1.0 / inertia**2))
        return val, grad, hess

    def physical(i: Array) -> bool:
        return bool(np.all(i > 0) and np.all(2.0 * i <= i.sum()))

    cands = [np.asarray(start, dtype=float)]
    try:
        cands.append(np.linalg.solve(a.sum(axis=0), b.sum(axis=0)))
    except np.linalg.LinAlgError:
        pass
    cands = [x for x in cands if physical(x)] or [np.full(3, float(np.mean(start)))]
    current = min(cands, key=lambda x: parts(x)[0])
    val, grad, hess = parts(current)
    for _ in range(200):
        try:
            step = -np.linalg.solve(hess, grad)
        except np.linalg.LinAlgError:
            step = -grad
        if not grad @ step < 0:
            step = -grad * float(np.min(current)) ** 2
        t = 1.0
        while t > 1e-10:
            trial = current + t * step
            if physical(trial) and parts(trial)[0] <= val + 1e-4 * t * (grad @ step):
                break
            t *= 0.5
        else:
            break
        done = float(np.max(np.abs(trial - current) / current)) < 1e-10
        current = trial
        val, grad, hess = parts(current)
        if done:
            break
    return current, val


@dataclass(frozen=True)
class BandStats:
    """Band-limited torque-row regression data of one posterior.

    x (K, 3, 3): regressor rows of [I_xx, I_yy, I_zz] for the three torque rows; t (K, 3):
    rotor torques [N m]; z (K, Z): nuisance features; e (K, 1) or (K, 0): the rotor
    acceleration sum_i spin_i omega_i' [rad/s^2], a feature of the yaw row only (its
    coefficient is the rotor inertia J_r); all band-passed; rows: index of each used
    transition (K,).
    """

    x: Array
    t: Array
    z: Array
    rows: NDArray[np.int64]
    e: Array | None = None

    def features(self, j: int, keep: BoolArray | None = None) -> Array:
        """Features projected out of torque row j: z, plus e for the yaw row (j = 2)."""
        z = self.z if keep is None else self.z[keep]
        if j == 2 and self.e is not None and self.e.shape[1]:
            z = np.column_stack([z, self.e if keep is None else self.e[keep]])
        return z

    def rotor_inertia(self, inertia: Array) -> float:
        """J_r [kg m^2]: least-squares coefficient of e in the band-passed yaw residual
        I_zz-row regressor @ inertia - tau_z = z c + J_r e (NaN without e)."""
        if self.e is None or not self.e.shape[1]:
            return float("nan")
        r = self.x[:, 2, :] @ inertia - self.t[:, 2]
        return float(np.linalg.lstsq(self.features(2), r, rcond=None)[0][-1])

    def quadratic(self, keep: BoolArray | None = None) -> tuple[Array, Array, Array]:
        """Quadratic forms (a (3, 3, 3), b (3, 3), c (3,)) of the torque residuals with
        the features projected out (over the rows in ``keep``)."""
        x, t = (self.x, self.t) if keep is None else (self.x[keep], self.t[keep])
        a = np.empty((3, 3, 3))
        b = np.empty((3, 3))
        c = np.empty(3)
        for j in range(3):
            z = self.features(j, keep)
            zz = z.T @ z
            g = z.T @ x[:, j, :]
            h = z.T @ t[:, j]
            sol = np.linalg.lstsq(zz, np.column_stack([g, h]), rcond=None)[0]
            a[j] = x[:, j, :].T @ x[:, j, :] - g.T @ sol[:, :3]
            b[j] = x[:, j, :].T @ t[:, j] - g.T @ sol[:, 3]
            c[j] = t[:, j] @ t[:, j] - h @ sol[:, 3]
        return a, b, c


class RealMStep:
    """M-step for a measured flight (a generalised EM step; equations below).

    Mass: the shared regressor M-step's closed form from the body-z force row,
    m = sum F_k^2 / sum E[a_z,k] F_k, a_z = e3^T R^T ((v_{k+1} - v_k)/dt + g e3).

    Inertia: the shared profiled objective J(I) = 1/2 sum_j log q_j - log det I, but
    with q_j built from the torque rows band-passed to ``band`` [Hz] (zero-phase
    Butterworth, order 2) and the nuisance features projected out. The band is where
    the rigid-body torque model holds on these flights, chosen by the coherence between
    the rotor roll / pitch torques and the gyro's angular acceleration on the seven
    clean flights: 0.9-0.99 from 4 to 8 Hz, 0.5-0.9 at 3 Hz, but 0.0-0.8 at 2 Hz and
    0.1-0.95 at 1 Hz (air-speed dependent moments dominate there) and falling to
    0.2-0.6 on some flights above 10 Hz (the gyro sees motion the rotor speeds do not
    explain). Below the band the features alone cannot rescue the fit: with 2-8 Hz the
    roll / pitch inertia scatter over the flights grows from 10 % to 18 %. Caveat: the
    band-passed update is not the EM M-step of any model, and in closed loop it is
    biased: on simulated flights (``raw_from_simulated``; ``python -m pinquad.response
    --simulate``) it reads the inertia 11-21 % high with the simulator's torque noise
    and 60-170 % high with 3-10 times that, where direct EM stays within 5 %. The
    band-passed regression skips transitions within ``1 / (2 band[0])`` s of an
    excluded one or of the ends (filter transients).

    Rotor inertia (when ``rotor_acc`` (N,) [rad/s^2] is given): the yaw row also projects
    out e = sum_i spin_i omega_i', and with I fixed J_r = the least-squares coefficient of
    e in the band-passed yaw residual (``BandStats.rotor_inertia``).

    Nuisance moment: with pi (and J_r) fixed, moment_coef = least squares of the full-band
    residual Y pi - tau - [0, 0, J_r e] on the features z; the E-step then sees
    tau + z moment_coef^T + [0, 0, J_r e].

    Noise: S = dt * residual variance of each wrench row (full band, with the moment),
    measurement variances as the shared ``update_noise``.
    """

    def __init__(self, band: tuple[float, float] = (3.0, 8.0), rotor_acc: Array | None = None):
        self.band = band
        self.rotor_acc = None if rotor_acc is None else np.asarray(rotor_acc, dtype=float)

    def band_stats(self, post, obs: Observations, gravity: float) -> BandStats:
        from scipy.signal import butter, sosfiltfilt

        from pinquad.mstep.stats import transition_mask
        from pinquad.mstep.updates import body_regressor

        mean = post.mean
        n_tr = obs.n - 1
        y = body_regressor(mean[:-1], mean[1:], obs.dt, gravity)[:, 3:6, 1:4]
        tau = obs.inputs[:-1, 1:4]
        z = torque_features(mean[:-1], obs.inputs[:-1, 0])
        fs = 1.0 / obs.dt
        lo, hi = self.band
        sos = butter(2, [lo, min(hi, 0.45 * fs)], btype="band", fs=fs, output="sos")

        def bp(v: Array) -> Array:
            return sosfiltfilt(sos, v, axis=0)

        use = transition_mask(obs)
        margin = int(math.ceil(0.5 / lo / obs.dt))
        bad = ~use
        bad[:margin] = bad[-margin:] = True
        near = np.convolve(bad.astype(float), np.ones(2 * margin + 1), mode="same") > 0
        rows = np.flatnonzero(~near)
        if rows.size < 50:
            rows = np.flatnonzero(use)
        e = None
        if self.rotor_acc is not None:
            e = bp(self.rotor_acc[:n_tr, None])[rows]
        return BandStats(x=bp(y.reshape(n_tr, 9)).reshape(n_tr, 3, 3)[rows],
                         t=bp(tau)[rows], z=bp(z)[rows], rows=rows, e=e)

    def __call__(self, post, obs: Observations, theta: Theta, earlier=None):
        """The update; ``earlier`` (``identify.QuadraticSums``): statistics of transitions
        no longer in ``obs`` (the online stream's memory), added to the mass row's."""
        from pinquad.mstep.stats import QuadraticSums
        from pinquad.mstep.updates import MStepResult, closed_form_mass, regressor_stats, update_noise

        g = theta.gravity
        stats = regressor_stats(post, obs, g)
        mass = closed_form_mass(stats if earlier is None
                                else QuadraticSums.of(stats).plus(earlier), theta.mass)
        band = self.band_stats(post, obs, g)
        a, b, c = band.quadratic()
        inertia, objective = _profiled_inertia(a, b, c, np.diag(theta.inertia))
        pi = np.concatenate([[mass], inertia])

        from pinquad.mstep.stats import transition_mask

        idx = np.flatnonzero(transition_mask(obs))
        z_all = torque_features(post.mean, obs.inputs[:, 0])
        resid = stats.y[:, 3:6, :] @ pi - stats.tau[:, 3:6]
        jr = band.rotor_inertia(inertia)
        rotor = np.zeros((obs.n, 3))
        if np.isfinite(jr):
            rotor[:, 2] = jr * self.rotor_acc
            resid = resid - rotor[idx]
        coef = np.linalg.lstsq(z_all[idx], resid, rcond=None)[0].T
        offset = z_all @ coef.T + rotor
        # Wrench residual variances with the moment in place (first order in the state
        # uncertainty, as the shared M-step): q_j = pi^T A_j pi - 2 pi^T b'_j + c'_j.
        tau_eff = stats.tau.copy()
        tau_eff[:, 3:6] += offset[idx]
        b_eff = np.einsum("kap,ka->ap", stats.y, tau_eff)
        c_eff = np.einsum("ka,ka->a", tau_eff, tau_eff)
        q = np.einsum("p,apq,q->a", pi, stats.a, pi) - 2.0 * b_eff @ pi + c_eff
        row_var = np.maximum(q / stats.n, 0.0)
        noise = update_noise(post, obs, theta, row_var)
        new = RealTheta(mass=mass, inertia=np.diag(inertia), noise=noise, gravity=g,
                        torque_offset=offset, moment_coef=coef,
                        rotor_inertia=jr if np.isfinite(jr) else None)
        return MStepResult(new, objective, row_var)

    def jackknife(self, post, obs: Observations, theta: Theta, blocks: int = 10) -> Array:
        """Delete-one-block jackknife standard errors (4,) of [m, I_xx, I_yy, I_zz] at
        the final posterior: the M-step repeated with each of ``blocks`` contiguous time
        blocks left out. It counts the correlation of neighbouring residuals (slow
        unmodelled effects) that the white-noise information ignores; the posterior is
        held fixed, so it leaves out the E-step's share of the uncertainty."""
        from pinquad.mstep.stats import transition_mask
        from pinquad.mstep.updates import body_regressor

        g = theta.gravity
        idx = np.flatnonzero(transition_mask(obs))
        x0, x1 = post.mean[idx], post.mean[idx + 1]
        acc_z = body_regressor(x0, x1, obs.dt, g)[:, 2, 0]
        force = obs.inputs[idx, 0]
        band = self.band_stats(post, obs, g)
        n_tr = obs.n - 1
        label_all = (np.arange(n_tr) * blocks // max(n_tr, 1)).astype(np.int64)
        est = []
        start = np.diag(theta.inertia)
        for blk in range(blocks):
            keep_m = label_all[idx] != blk
            keep_i = label_all[band.rows] != blk
            m = float(force[keep_m] @ force[keep_m] / (acc_z[keep_m] @ force[keep_m]))
            inertia, _ = _profiled_inertia(*band.quadratic(keep_i), start)
            est.append([m, *inertia])
        est = np.asarray(est)
        return np.sqrt((blocks - 1) / blocks * ((est - est.mean(axis=0)) ** 2).sum(axis=0))


@dataclass(frozen=True)
class RealIdentification:
    """Mass and inertia of the vehicle from one measured flight.

    name: log name; mass [kg]; inertia (3,) diagonal [kg m^2]; se_info (4,): standard
    errors of [m, I_xx, I_yy, I_zz] from the observed information (NaN if not computed
    or not positive definite); se_jack (4,): block-jackknife standard errors;
    se_stat (4,): the larger of the two (the statistical uncertainty with kf known);
    se_total (4,): se_stat combined with kf's uncertainty (every estimate is
    proportional to kf) and, for I_zz, the yaw ratio's (``YAW_RATIO_REL_SE``);
    kf: the thrust coefficient; iterations, converged, loglik (I,), e_steps: the EM run;
    history (I+1, 4): [m, I_xx, I_yy, I_zz] per iteration; moment_coef (3, 7): the
    nuisance moment (``TORQUE_FEATURES``); n_used / n_excluded transitions; excluded:
    exclusion notes; notes: other notes; seconds: wall time; band: the torque band [Hz];
    rotor_inertia: J_r [kg m^2] used (fitted or fixed; NaN: none); band_stats: the
    band-passed regression at the final posterior (``keep_band_stats``); rotor_source:
    how J_r was obtained, in words (set by the table); quasi_static_mass [kg]: the
    model-free check :func:`quasi_static_mass` on the same transitions; motor_split: that
    check split by motor (:func:`motor_split`).
    """

    name: str
    mass: float
    inertia: Array
    se_info: Array
    se_jack: Array
    se_stat: Array
    se_total: Array
    kf: ThrustCoefficient
    iterations: int
    converged: bool
    loglik: Array
    e_steps: int
    history: Array
    moment_coef: Array
    n_used: int
    n_excluded: int
    excluded: tuple[str, ...]
    notes: tuple[str, ...]
    seconds: float
    band: tuple[float, float] = (3.0, 8.0)
    rotor_inertia: float = float("nan")
    band_stats: BandStats | None = None
    rotor_source: str = ""
    quasi_static_mass: float = float("nan")
    motor_split: MotorSplit | None = None

    @property
    def params(self) -> Array:
        """[m, I_xx, I_yy, I_zz] (4,) [kg, kg m^2]."""
        return np.concatenate([[self.mass], self.inertia])

    @property
    def mass_rel_error(self) -> float:
        """m / 34.7 g - 1."""
        return self.mass / SCALE_MASS - 1.0


def _vertical_balance(real: RealObservations) -> tuple[NDArray[np.int64], Array, Array]:
    """The transitions of :func:`quasi_static_mass`: (rows k (K,), R_k,zz (K,),
    g + a_z,k (K,) [m/s^2]) over the used transitions with a finite vertical
    acceleration, attitude and thrust."""
    from pinquad.core.conventions import rotation_from_euler

    obs, log = real.obs, real.log
    use = np.flatnonzero(~obs.exclude[: obs.n - 1])
    rzz = rotation_from_euler(log.euler[use])[:, 2, 2]
    seen = np.isfinite(rzz)
    if seen.any() and not seen.all():
        rzz = np.interp(obs.t[use], obs.t[use][seen], rzz[seen])
    az = (log.velocity[use + 1, 2] - log.velocity[use, 2]) / obs.dt
    ok = np.isfinite(rzz) & np.isfinite(az) & np.isfinite(obs.inputs[use, 0])
    return use[ok], rzz[ok], log.meta.gravity + az[ok]


def quasi_static_mass(real: RealObservations) -> float:
    """The mass [kg] that balances the flight's mean vertical force, with no estimator:

        m_qs = sum_k F_k R_k,zz / sum_k (g + a_z,k)

    over the used transitions k, with F_k = kf sum_i omega_i^2 the thrust [N], R_k,zz the
    vertical component of the body z axis (motion-capture attitude) and
    a_z,k = (v_z,k+1 - v_z,k) / dt [m/s^2] from the logged vertical velocity (rows without
    it skipped; R_k,zz interpolated in time where the pose is missing). Over a flight
    these differences telescope to (end - start) velocity, so
    m_qs says what the rotor speeds and kf imply for the mass whatever the dynamic model
    (any net vertical force that is not kf omega^2, such as ground effect, shifts it)."""
    rows, rzz, lift = _vertical_balance(real)
    if not rows.size:
        return float("nan")
    return float(np.sum(real.obs.inputs[rows, 0] * rzz) / np.sum(lift))


@dataclass(frozen=True)
class MotorSplit:
    """:func:`quasi_static_mass` split by motor.

    share (4,) [-]: each motor's part of the vertical thrust over the used transitions
    relative to the four-motor mean, s_i = 4 sum_k F_k R_k,zz w_ik / sum_k F_k R_k,zz with
    w_ik = omega_ik^2 / sum_j omega_jk^2 (1 for all four when they carry equal thrust);
    measured_mass [kg]:
    the part of m_qs the motors whose speeds were measured carry,
    m_meas = sum_k F_k R_k,zz sum_(i measured) w_ik / sum_k (g + a_z,k); rebuilt: the
    motors (0-based) whose speeds were rebuilt from PWM (in some or all rows);
    all_measured_mass [kg]: m_qs over only the transitions whose bin holds no reading
    from the PWM map (every motor measured, a pulse-divided channel multiplied back;
    NaN if there is none); all_measured_rows: their number.
    """

    share: Array
    measured_mass: float
    rebuilt: tuple[int, ...]
    all_measured_mass: float = float("nan")
    all_measured_rows: int = 0

    def mass_if(self, share: float) -> float:
        """The model-free mass [kg] if the rebuilt motors carried ``share`` each (of the
        four-motor mean): m_meas / (1 - n_rebuilt share / 4)."""
        return self.measured_mass / (1.0 - len(self.rebuilt) * share / 4.0)

    def share_for(self, mass: float) -> float:
        """The share each rebuilt motor would carry if the mass were ``mass`` [kg]."""
        return 4.0 * (1.0 - self.measured_mass / mass) / max(len(self.rebuilt), 1)


def motor_split(real: RealObservations) -> MotorSplit:
    """:class:`MotorSplit` of a measured flight (the rows of :func:`quasi_static_mass`;
    each bin's thrust divided between the motors by their bin-mean speeds squared)."""
    rows, rzz, lift = _vertical_balance(real)
    if not rows.size:
        return MotorSplit(share=np.full(4, np.nan), measured_mass=float("nan"),
                          rebuilt=tuple(real.repaired))
    omega2 = np.asarray(real.log.rpm, dtype=float)[rows] ** 2
    weight = omega2 / omega2.sum(axis=1, keepdims=True)
    vertical = real.obs.inputs[rows, 0] * rzz
    share = 4.0 * (vertical @ weight) / vertical.sum()
    measured = [i for i in range(4) if i not in real.repaired]
    mass = float(np.sum(vertical * weight[:, measured].sum(axis=1)) / np.sum(lift))
    if real.rebuilt_fraction is None:
        own = np.ones(rows.size, dtype=bool) if not real.repaired else np.zeros(rows.size, bool)
    else:
        own = real.rebuilt_fraction[rows] == 0.0
    own_mass = float(vertical[own].sum() / lift[own].sum()) if own.any() else float("nan")
    return MotorSplit(share=share, measured_mass=mass, rebuilt=tuple(real.repaired),
                      all_measured_mass=own_mass, all_measured_rows=int(own.sum()))


def total_standard_errors(params: Array, se_stat: Array, kf_rel: float,
                          yaw_rel: float = YAW_RATIO_REL_SE, repaired: bool = False) -> Array:
    """se_total (4,) of [m, I_xx, I_yy, I_zz]: every input is proportional to kf, so
    each estimate is too (relative uncertainty kf_rel); I_zz is also proportional to the
    yaw torque ratio (yaw_rel); rotor speeds rebuilt from PWM add ``REPAIR_REL_SE``:

        se_total_i^2 = se_stat_i^2 + p_i^2 (kf_rel^2 [+ yaw_rel^2 for I_zz]
                                            [+ REPAIR_REL_SE_i^2 if repaired])
    """
    rel = np.full(4, kf_rel**2)
    rel[3] += yaw_rel**2
    if repaired:
        rel += REPAIR_REL_SE**2
    stat = np.where(np.isfinite(se_stat), se_stat, 0.0)
    return np.sqrt(stat**2 + params**2 * rel)


def identify_real(real: RealObservations, mass0: float, inertia0: Array,
                  max_iterations: int = 100, information: bool = True,
                  band: tuple[float, float] = (3.0, 8.0), tol: float = 1e-4,
                  name: str | None = None, estep: str = "rts", fit_rotor_inertia: bool = True,
                  keep_band_stats: bool = False):
    """EM on a measured flight (``RealMStep``; E-step ``estep``: ``rts`` = compiled EKF +
    RTS, or ``gtsam``) from (mass0 [kg], inertia0 (3, 3) [kg m^2]), then standard errors
    (the observed information always uses the EKF likelihood).

    keep_band_stats: store :func:`yaw_band_stats` at the final posterior in the result
    (the input of :func:`pooled_rotor_inertia`).

    Returns (RealIdentification, Posterior, RealTheta). EM stops when the relative change
    of (m, I) is below ``tol`` (1e-4, far below the standard errors) and the relative
    log-likelihood change below tol / 10, or after ``max_iterations`` E-steps.
    """
    from pinquad.identification.em import initial_theta, run_em
    from pinquad.identification.fisher import observed_information, standard_errors
    from pinquad.identification.identify import get_smoother, loglik_function

    t0 = time.perf_counter()
    obs = real.obs
    gravity = real.log.meta.gravity
    fit_jr = fit_rotor_inertia and real.rotor_acc is not None and not real.options.rotor_inertia
    mstep = RealMStep(band, real.rotor_acc if fit_jr else None)
    theta0 = initial_theta(obs, mass0, inertia0, gravity)
    res = run_em(obs, theta0, get_smoother(estep), mstep, max_iterations=max_iterations,
                 tol=tol, tol_loglik=0.1 * tol, accelerate=False, model_factory=real_model)
    theta = res.theta
    params = np.concatenate([[theta.mass], np.diag(theta.inertia)])
    se_info = np.full(4, np.nan)
    if information:
        plain = Theta(theta.mass, np.asarray(theta.inertia), theta.noise, gravity)
        info = observed_information(corrected(obs, theta), plain, loglik_function("rts"))
        se_info = standard_errors(info)
    se_jack = mstep.jackknife(res.posterior, obs, theta)
    se_stat = np.fmax(se_info, se_jack)
    se_total = total_standard_errors(params, se_stat, real.kf.rel_se,
                                     repaired=bool(real.repaired))
    history = np.column_stack([np.concatenate([[mass0], res.mass]),
                               np.vstack([np.diag(inertia0), res.inertia_diag])])
    coef = getattr(theta, "moment_coef", None)
    out = RealIdentification(
        name=name or Path(real.source).name, mass=theta.mass,
        inertia=np.diag(theta.inertia).copy(), se_info=se_info, se_jack=se_jack,
        se_stat=se_stat, se_total=se_total, kf=real.kf, iterations=res.iterations,
        converged=res.converged, loglik=res.loglik, e_steps=res.e_steps, history=history,
        moment_coef=np.zeros((3, 7)) if coef is None else coef, n_used=real.n_used,
        n_excluded=real.n_excluded, excluded=real.excluded, notes=real.notes,
        seconds=time.perf_counter() - t0, band=band,
        rotor_inertia=float(getattr(theta, "rotor_inertia", None) or real.options.rotor_inertia
                            or float("nan")),
        band_stats=yaw_band_stats(real, res.posterior, band) if keep_band_stats else None,
        quasi_static_mass=quasi_static_mass(real), motor_split=motor_split(real))
    return out, res.posterior, theta


def yaw_band_stats(real: RealObservations, post, band: tuple[float, float] = (3.0, 8.0)
                   ) -> BandStats:
    """The band-passed torque-row regression data of ``post`` with the rotor acceleration
    e as a separate column and t the rotor drag torques alone (a J_r fixed in
    ``real.options`` is taken back out of the yaw row), so that any J_r can be tried:
    yaw torque = t_z + J_r e."""
    if real.rotor_acc is None:
        raise ValueError(f"{real.source}: no rotor acceleration; expected measured rotor speeds")
    bs = RealMStep(band, real.rotor_acc).band_stats(post, real.obs, real.log.meta.gravity)
    t = bs.t.copy()
    t[:, 2] -= real.options.rotor_inertia * bs.e[:, 0]
    return replace(bs, t=t)


def band_fit(bs: BandStats, rotor_inertia: float, start: Array | None = None
             ) -> tuple[Array, float, float]:
    """(inertia (3,) [kg m^2], objective, yaw residual variance [(rad/s^2)^2]) of the
    inertia M-step on ``bs`` (from :func:`yaw_band_stats`) with J_r fixed at
    ``rotor_inertia`` [kg m^2]: the yaw torque is t_z + J_r e, e not projected out. The
    variance is that of the band-passed, nuisance-projected yaw residual in angular
    acceleration units, q_z / (K I_zz^2)."""
    t = bs.t.copy()
    t[:, 2] += rotor_inertia * bs.e[:, 0]
    fixed = BandStats(x=bs.x, t=t, z=bs.z, rows=bs.rows, e=None)
    a, b, c = fixed.quadratic()
    if start is None:  # the EM's start; the least-squares solution is tried as well
        start = np.diag(default_guess("crazyflie21")[1])
    inertia, objective = _profiled_inertia(a, b, c, start)
    q = float(inertia @ a[2] @ inertia - 2.0 * b[2] @ inertia + c[2])
    return inertia, objective, q / (bs.x.shape[0] * inertia[2] ** 2)


POOL_FLIGHTS = ("jana00", "jana01", "jana02", "jana03", "jana04", "jana05", "jana10")
"""The logs that share one rotor inertia by default: the seven with every rotor speed
measured (on jana20-29 M1's speed, hence its acceleration, is rebuilt from PWM through a
first-order lag: a model, not a measurement)."""
ROTOR_INERTIA_BOUNDS = (-2e-7, 2e-7)
"""Search interval of the pooled J_r [kg m^2] (ten times any per-flight value)."""


@dataclass(frozen=True)
class PooledRotorInertia:
    """One rotor inertia J_r for several flights, each with its own inertia.

    value [kg m^2]: argmin over J_r of sum_l K_l J_l(I_l; J_r), each log's profiled
    band-passed objective (:func:`band_fit`, minimised over its own I_l) weighted by its
    number of band rows K_l; se [kg m^2]: delete-one-log jackknife standard error;
    logs: the flights it was fitted on; leave_one_out: J_r fitted on all the logs but
    that one, per log [kg m^2]; per_flight: each log's own J_r (fitted alone with its
    I_l) [kg m^2].
    """

    value: float
    se: float
    logs: tuple[str, ...]
    leave_one_out: dict[str, float]
    per_flight: dict[str, float]

    def for_log(self, name: str) -> tuple[float, str]:
        """(J_r [kg m^2], how it was obtained) for identifying ``name``: the value fitted
        without that log if it is one of the pool (leave-one-out), else the pooled one."""
        if name in self.leave_one_out:
            return self.leave_one_out[name], "leave-one-out"
        return self.value, "pooled"

    def describe(self) -> str:
        loo = ", ".join(f"{k} {1e9 * v:.1f}" for k, v in self.leave_one_out.items())
        own = ", ".join(f"{k} {1e9 * v:.1f}" for k, v in self.per_flight.items())
        return (f"rotor inertia J_r pooled over {', '.join(self.logs)} (each log with its own "
                f"inertia): {1e9 * self.value:.2f} ± {1e9 * self.se:.2f} e-9 kg m^2 (delete-one-"
                f"log jackknife standard error), fitted on the band-passed regressions of the "
                f"per-flight-J_r EM posteriors. Each of these logs is identified with the J_r "
                f"fitted on the others (leave-one-out, never its own data): {loo} e-9; the other "
                f"logs with the pooled value. Per-flight J_r for comparison: {own} e-9.")


def _pool_value(stats: Sequence[BandStats]) -> float:
    from scipy.optimize import minimize_scalar

    def total(jr: float) -> float:
        return sum(bs.x.shape[0] * band_fit(bs, jr)[1] for bs in stats)

    res = minimize_scalar(total, bounds=ROTOR_INERTIA_BOUNDS, method="bounded",
                          options={"xatol": 1e-13})
    return float(res.x)


def pooled_rotor_inertia(stats: dict[str, BandStats]) -> PooledRotorInertia:
    """J_r shared by the logs ``stats`` (name -> :func:`yaw_band_stats`), with its
    delete-one-log jackknife standard error and leave-one-out values (needs >= 2 logs;
    one log gives its own J_r, no standard error and no leave-one-out)."""
    if not stats:
        raise ValueError("pooled rotor inertia: no log given")
    names = tuple(stats)
    value = _pool_value([stats[n] for n in names])
    per = {}
    for n in names:
        bs = stats[n]
        inertia, _ = _profiled_inertia(*bs.quadratic(), band_fit(bs, value)[0])
        per[n] = bs.rotor_inertia(inertia)
    if len(names) < 2:
        return PooledRotorInertia(value, float("nan"), names, {}, per)
    loo = {h: _pool_value([stats[n] for n in names if n != h]) for h in names}
    jk = np.array(list(loo.values()))
    se = float(np.sqrt((jk.size - 1) / jk.size * np.sum((jk - jk.mean()) ** 2)))
    return PooledRotorInertia(value, se, names, loo, per)


def default_guess(vehicle: str) -> tuple[float, Array, str]:
    """Initial (mass [kg], inertia (3, 3) [kg m^2], words): for ``crazyflie21`` 25 g and
    half the published inertia; otherwise the paper's m0 = 0.001 kg, I0 = diag(1e-4,
    2e-4, 1e-4)."""
    from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS

    if vehicle == "crazyflie21":
        return 0.025, 0.5 * np.diag(PUBLISHED_INERTIA), \
            "default for crazyflie21: 25 g and half the published inertia"
    return PAPER_INITIAL_MASS, np.asarray(PAPER_INITIAL_INERTIA, dtype=float), \
        "the paper's m0 = 0.001 kg and I0 = diag(1e-4, 2e-4, 1e-4) kg m^2"


# ----------------------------------------------------------------------------- table

@dataclass(frozen=True)
class TableJob:
    """One row of the table: the log's path, EM settings and the data directory."""

    path: Path
    options: RealDataOptions
    max_iterations: int
    information: bool
    band: tuple[float, float]
    stand: Path
    fit_rotor_inertia: bool = True
    keep_band_stats: bool = False
    rotor_source: str = ""


def run_table_job(job: TableJob) -> RealIdentification | str:
    """Load one flight and identify it (a worker of ``python -m pinquad.realdata``); a
    log that cannot be identified gives the reason as a string instead. J_r: fitted per
    flight if ``job.fit_rotor_inertia`` and ``job.options.rotor_inertia`` is 0, else the
    options' fixed value."""
    try:
        kf = thrust_coefficient(job.stand)
        real = load_real(job.path, job.options, kf)
        mass0, inertia0, _ = default_guess("crazyflie21")
        ident, _, _ = identify_real(real, mass0, inertia0, job.max_iterations,
                                    job.information, job.band, name=job.path.name,
                                    fit_rotor_inertia=job.fit_rotor_inertia,
                                    keep_band_stats=job.keep_band_stats)
    except (LogFormatError, ValueError) as exc:
        return str(exc)
    return replace(ident, rotor_source=job.rotor_source)


def run_jobs(jobs: Sequence[TableJob], workers: int) -> list[RealIdentification | str]:
    """run_table_job over ``jobs`` in ``workers`` processes (results in job order)."""
    if workers > 1 and len(jobs) > 1:
        # Longest logs first so the pool finishes together.
        order = sorted(range(len(jobs)), key=lambda i: -jobs[i].path.stat().st_size)
        with ProcessPoolExecutor(max_workers=workers) as pool:
            done = dict(zip(order, pool.map(run_table_job, [jobs[i] for i in order]),
                            strict=True))
        return [done[i] for i in range(len(jobs))]
    return [run_table_job(j) for j in jobs]


def _short_reasons(ident: RealIdentification) -> str:
    words = []
    for line in ident.excluded[:-1]:
        count, _, reason = line.partition(" transitions: ")
        key = ("contact" if reason.startswith("ground") else
               "faulty rpm" if reason.startswith("implausible") else
               "log gaps" if reason.startswith("no actuation") else reason[:20])
        words.append(f"{count} {key}")
    return ", ".join(words) if words else "-"


def _pm(value: float, total: float, stat: float, scale: float, fmt: str = ".2f") -> str:
    return (f"{value * scale:{fmt}} ± {total * scale:{fmt}} "
            f"({stat * scale:{fmt}})")


def _rotor_words(r: RealIdentification) -> str:
    if not np.isfinite(r.rotor_inertia):
        return f"{r.name} none"
    return f"{r.name} {1e9 * r.rotor_inertia:.1f} ({r.rotor_source or 'fitted on this log'})"


def format_table(results: Sequence[RealIdentification],
                 rotor: PooledRotorInertia | None = None) -> str:
    """The markdown table of the identified flights and the summaries below it
    (``rotor``: the pooled rotor inertia the flights were identified with, described)."""
    if not results:
        return "(no flights)"
    kf = results[0].kf
    lines = [
        "| log | what was flown | used / excluded transitions (why) | mass [g] | vs 34.7 g | "
        "I_xx [1e-6 kg m^2] | I_yy | I_zz | EM iterations |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        p, tot, st = r.params, r.se_total, r.se_stat
        within = abs(r.mass - SCALE_MASS) <= 2.0 * tot[0]
        lines.append(
            f"| {r.name} | {FLIGHTS.get(r.name, '')} | {r.n_used} / {r.n_excluded} "
            f"({_short_reasons(r)}) | {_pm(p[0], tot[0], st[0], 1e3)} | "
            f"{100 * r.mass_rel_error:+.2f} %{'' if within else ' (!)'} | "
            + " | ".join(_pm(p[i], tot[i], st[i], 1e6, ".1f") for i in (1, 2, 3))
            + f" | {r.iterations}{'' if r.converged else ' (not converged)'} |")
    lines += [
        "",
        "value ± total standard error (statistical standard error): statistical = larger of "
        "the observed-information and the block-jackknife standard errors; total adds kf's "
        f"{100 * kf.rel_se:.1f} % (all estimates are proportional to kf), for I_zz the "
        f"yaw ratio's {100 * YAW_RATIO_REL_SE:.1f} %, and for logs whose rotor speeds were "
        "rebuilt from PWM the repair's (mass 1.1 %, I_xx 7 %, I_yy 5 %, I_zz 24 %, measured "
        "by rebuilding M1 on the clean logs). (!) marks a mass more than two total standard "
        "errors from the scale.",
        "",
        kf.note,
    ]
    if rotor is not None:
        lines += ["", rotor.describe()]
    masses = np.array([r.mass for r in results])
    rel = masses / SCALE_MASS - 1.0
    lines += ["", f"mass: mean {1e3 * masses.mean():.2f} g, spread (sd) {1e3 * masses.std(ddof=1):.2f} g "
              f"over {masses.size} logs; |error| <= 1.5 % in {int(np.sum(np.abs(rel) <= 0.015))} "
              f"of {masses.size}; worst {100 * rel[np.argmax(np.abs(rel))]:+.2f} % "
              f"({results[int(np.argmax(np.abs(rel)))].name})"]
    qs = np.array([r.quasi_static_mass for r in results])
    if np.isfinite(qs).any():
        lines.append(
            "model-free check, mass that balances the mean vertical thrust (kf sum omega^2 "
            "along the vertical over g + the mean vertical acceleration, the same "
            "transitions, no EM): " + ", ".join(
                f"{r.name} {1e3 * q:.2f} g ({100 * (q / SCALE_MASS - 1.0):+.1f} %)"
                for r, q in zip(results, qs, strict=True) if np.isfinite(q)))
    lines += _rebuilt_motor_lines(results)
    yaw = [r for r in results if r.name in YAW_FLIGHTS]
    if len(yaw) >= 2:
        izz = np.array([r.inertia[2] for r in yaw])
        lines.append(
            f"I_zz on the yaw flights ({', '.join(r.name for r in yaw)}): "
            + ", ".join(f"{1e6 * v:.1f}" for v in izz)
            + f" e-6 kg m^2; spread (max - min) / mean = "
              f"{100 * float(np.ptp(izz) / izz.mean()):.0f} %, sd / mean = "
              f"{100 * float(izz.std(ddof=1) / izz.mean()):.0f} % (kf and the yaw ratio are "
              "common to all logs and cancel in this comparison); rotor inertia J_r used "
              "[e-9 kg m^2]: " + ", ".join(_rotor_words(r) for r in yaw))
    inert = np.array([r.inertia for r in results])
    mean, sd = inert.mean(axis=0), inert.std(ddof=1, axis=0) if len(results) > 1 else np.zeros(3)
    lines += [
        "",
        "| inertia [1e-6 kg m^2] | I_xx | I_yy | I_zz |",
        "|---|---|---|---|",
        "| mean over logs ± sd | " + " | ".join(f"{1e6 * m:.1f} ± {1e6 * s:.1f}"
                                            for m, s in zip(mean, sd, strict=True)) + " |",
        "| spread sd / mean | " + " | ".join(f"{100 * s / m:.0f} %"
                                          for m, s in zip(mean, sd, strict=True)) + " |",
        "| Crazyflie 2.0, no decks (published) | "
        + " | ".join(f"{1e6 * v:.2f}" for v in PUBLISHED_INERTIA) + " |",
    ]
    return "\n".join(lines)


def _rebuilt_motor_lines(results: Sequence[RealIdentification]) -> list[str]:
    """What the logs with rebuilt rotor speeds say about the mass without the rebuild: the
    measured motors' part of the model-free mass, and the mass if each rebuilt motor
    carried a share of the thrust anywhere in the range it carries on the clean logs."""
    split = {r.name: r.motor_split for r in results if r.motor_split is not None}
    clean = {n: m for n, m in split.items() if not m.rebuilt}
    faulty = {n: m for n, m in split.items() if m.rebuilt}
    motors = sorted({i for m in faulty.values() for i in m.rebuilt})
    if not faulty or not clean or len(motors) != 1:
        return []
    i = motors[0]
    shares = np.array([m.share[i] for m in clean.values()])
    lo, hi = float(shares.min()), float(shares.max())
    names = list(clean)
    words = [
        f"M{i + 1} repaired ({', '.join(faulty)}): the three measured motors alone carry "
        + ", ".join(f"{n} {1e3 * m.measured_mass:.2f} g" for n, m in faulty.items())
        + f" of the model-free mass; on the clean logs M{i + 1} carries {lo:.3f} "
        f"({names[int(np.argmin(shares))]}) to {hi:.3f} ({names[int(np.argmax(shares))]}) of "
        "the four-motor mean thrust, and with a share anywhere in that range the faulty "
        "logs' mass would be "
        + ", ".join(f"{n} {1e3 * m.mass_if(lo):.2f}-{1e3 * m.mass_if(hi):.2f} g "
                    f"({100 * (m.mass_if(lo) / SCALE_MASS - 1):+.1f} to "
                    f"{100 * (m.mass_if(hi) / SCALE_MASS - 1):+.1f} %)"
                    for n, m in faulty.items())
        + "; within 1.5 % of the scale needs a share of at most "
        + ", ".join(f"{n} {m.share_for(1.015 * SCALE_MASS):.3f}" for n, m in faulty.items())
        + " (the repaired M1 gives "
        + ", ".join(f"{n} {m.share[i]:.3f}" for n, m in faulty.items()) + ")"]
    own = {n: m for n, m in faulty.items() if m.all_measured_rows}
    if own:
        words.append(
            f"model-free mass on the transitions where no rotor speed comes from the PWM map "
            f"(M{i + 1} measured, its pulse-divided readings multiplied back): "
            + ", ".join(f"{n} {1e3 * m.all_measured_mass:.2f} g "
                        f"({100 * (m.all_measured_mass / SCALE_MASS - 1):+.1f} %, "
                        f"{m.all_measured_rows} transitions)" for n, m in own.items()))
    return words


def _rotor_choice(text: str) -> str | float:
    if text in ("pooled", "per-flight", "none"):
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected pooled, per-flight, none or a value in kg m^2") from None


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pinquad.realdata [--data DIR] [--jobs N]``: identify every flight."""
    parser = argparse.ArgumentParser(
        prog="python -m pinquad.realdata",
        description="Identify mass and inertia of the real Crazyflie from every micro-SD "
                    "flight log and print the table (scale 34.7 g, published inertia).")
    parser.add_argument("--data", type=Path, default=None,
                        help="Crazyflie data directory (with imrc_brushed/ and thrust_stand/) "
                             "or a directory of flight logs (default: $PINQUAD_CRAZYFLIE_DATA, "
                             "else ../shared/data/crazyflie next to the repository)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                        help="worker processes")
    parser.add_argument("--max-iterations", type=int, default=150, help="E-steps per log")
    parser.add_argument("--no-information", action="store_true",
                        help="skip the observed information (jackknife errors only)")
    parser.add_argument("--channels", default="pos,euler,gyro",
                        help="measurement channels, comma-separated (pos, vel, euler, gyro)")
    parser.add_argument("--faults", choices=["repair", "repair-all", "exclude"],
                        default="repair", help="handling of implausible rotor speeds")
    parser.add_argument("--band", type=float, nargs=2, default=(3.0, 8.0),
                        metavar=("LO", "HI"), help="torque-row band of the inertia M-step [Hz]")
    parser.add_argument("--only", nargs="*", help="log names to run (default: all)")
    parser.add_argument("--rotor-inertia", type=_rotor_choice, default="pooled",
                        help="rotor inertia J_r of the yaw torque J_r sum spin_i omega_i': "
                             "pooled (default: one J_r fitted jointly on the --pool logs, each "
                             "pool log identified with the J_r of the others, leave-one-out), "
                             "per-flight (fitted on each log), none, or a value [kg m^2]")
    parser.add_argument("--pool", nargs="*", default=list(POOL_FLIGHTS),
                        help="logs the pooled J_r is fitted on (default: the seven with every "
                             "rotor speed measured); run whatever --only says")
    args = parser.parse_args(argv)
    flights = flights_dir(args.data)
    logs = sorted(p for p in flights.iterdir() if p.is_file() and p.name.startswith("jana")) \
        if flights.is_dir() else []
    all_logs = list(logs)
    if args.only:
        logs = [p for p in logs if p.name in set(args.only)]
    if not logs:
        print(f"error: {flights}: no flight log (jana*) found; expected the IMRC Lab micro-SD "
              "logs (give the data directory with --data DIR)", file=sys.stderr)
        return 2
    try:
        options = RealDataOptions(channels=tuple(c.strip() for c in args.channels.split(",")),
                                  faults=args.faults)
        stand = stand_dir(args.data)
        kf = thrust_coefficient(stand)
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    mode = args.rotor_inertia
    print(f"pinquad real data: {len(logs)} logs from {flights}, channels {options.channels}, "
          f"faults {options.faults}, torque band {args.band[0]:g}-{args.band[1]:g} Hz, "
          f"rotor inertia {mode}, {args.jobs} worker(s); {kf.note}", file=sys.stderr)
    rotor, pass1 = None, ""
    try:
        if mode == "pooled":
            pool = [p for p in all_logs if p.name in set(args.pool)]
            if len(pool) < 2:
                print(f"error: --pool {' '.join(args.pool)}: fewer than two of these logs in "
                      f"{flights}; expected at least two to pool J_r over", file=sys.stderr)
                return 2
            print(f"pass 1: J_r fitted per flight on the {len(pool)} pool logs "
                  f"({', '.join(p.name for p in pool)}) to pool it", file=sys.stderr)
            first = run_jobs([TableJob(p, options, args.max_iterations, False, tuple(args.band),
                                       stand, keep_band_stats=True) for p in pool], args.jobs)
            bad = [(p.name, r) for p, r in zip(pool, first, strict=True) if isinstance(r, str)]
            if bad:
                print("error: pool log not identified: " + "; ".join(f"{n}: {w}" for n, w in bad),
                      file=sys.stderr)
                return 2
            rotor = pooled_rotor_inertia({r.name: r.band_stats for r in first})
            pass1 = (f"; pass 1 (J_r per flight on the pool logs, then pooled) "
                     f"{time.perf_counter() - t0:.0f} s")
            print(rotor.describe(), file=sys.stderr)
            jobs = []
            for p in logs:
                jr, how = rotor.for_log(p.name)
                src = how if how == "leave-one-out" else "pooled on " + ", ".join(rotor.logs)
                jobs.append(TableJob(p, replace(options, rotor_inertia=jr), args.max_iterations,
                                     not args.no_information, tuple(args.band), stand,
                                     fit_rotor_inertia=False, rotor_source=src))
        else:
            fixed = 0.0 if isinstance(mode, str) else mode
            src = {"per-flight": "fitted on this log", "none": ""}.get(mode, "given") \
                if isinstance(mode, str) else "given"
            jobs = [TableJob(p, replace(options, rotor_inertia=fixed), args.max_iterations,
                             not args.no_information, tuple(args.band), stand,
                             fit_rotor_inertia=mode == "per-flight", rotor_source=src)
                    for p in logs]
        results = run_jobs(jobs, args.jobs)
    except (LogFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    failed = [(j.path.name, r) for j, r in zip(jobs, results, strict=True) if isinstance(r, str)]
    results = [r for r in results if not isinstance(r, str)]
    print(format_table(results, rotor))
    for name, why in failed:
        print(f"\n{name}: not identified: {why}")
    print(f"\n{len(results)} logs in {time.perf_counter() - t0:.0f} s "
          f"({sum(r.seconds for r in results):.0f} s of EM + standard errors in the workers"
          f"{pass1})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
