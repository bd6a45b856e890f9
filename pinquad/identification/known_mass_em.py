"""Known-mass identification by EM: the thrust curve's scale and the inertia of a flight
logged with motor commands (a PX4 log), with the mass known.

The nominal wrench. Each command u_i [1] passes the motor lag of time constant tau [s]
(``known_mass.motor_lag``) and a nominal thrust curve T_nom(u') = c_1 u' + c_2 u'^2 [N]
(the vehicle file's ``actuator_curve.thrust`` when it gives one, else the known-mass
regression's); the rotor positions (x_i, y_i) [m] and the yaw ratio k [m] give

    F_nom = sum_i T_nom,i                                     [N]
    tau_nom = (sum_i y_i T_nom,i, -sum_i x_i T_nom,i, k sum_i spin_i T_nom,i)   [N m]

(without k the yaw row is driven with ``NOMINAL_YAW_RATIO`` and I_zz is not reported:
motor commands give yaw torque only up to k). The true curve is s T_nom with an
unknown scale s [-], so the true wrench is s (F_nom, tau_nom), and the rigid body reads

    m dv/dt = s F_nom R e3 - m g e3,     I domega/dt + omega x I omega = s tau_nom

Dividing by s: EM on the nominal wrench (the ordinary E-step, EKF + RTS smoother over the
log's velocity, attitude and rates, position when it has any; the regressor M-step)
estimates m_hat = m / s [kg] and I_hat = I / s [kg m^2]. With the mass m known,

    s = m / m_hat,      I = s I_hat = m I_hat / m_hat          [kg m^2]

Standard errors, in relative terms (the estimates are products and ratios):

    (se_I / I)^2 = (se_m / m)^2 + var(ln I_hat - ln m_hat) + arm^2 (roll, pitch) or
                   (se_k / k)^2 (yaw) + shape^2 + tau^2
    (se_s / s)^2 = (se_m / m)^2 + var(ln m_hat) + shape^2 + tau^2

var(...) from the observed information's covariance of (m_hat, I_hat) (statistical);
se_m the mass's assumed uncertainty; arm: the rotor positions' (``DEFAULT_ARM``); the
curve's shape and the time constant: EM rerun with the nominal curve's linear term
moved by its standard error (the quadratic term moved to keep the thrust at the mean
command) and with tau +- its standard error, half the change. The scale itself is not an
error source: EM estimates it. The verdicts are the house's (``verdict.judge_estimate``,
as the regression's): the rescaled vehicle estimate's (``verdict.judge`` on the smoother's
evidence: torque shares, innovation consistency, torque excitation, the search range),
the band halves (EM on the band's lower and upper halves: inertias more than
``max_band_shift`` combined jackknife errors apart are "model not adequate",
``band_halves``), EM's convergence, and a total relative error over ``max_rel_se`` is not
identifiable.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.actuator_curve import ActuatorCurve
from pinquad.estep.fast_smoother import smooth_quad
from pinquad.identification.budget import DEFAULT_YAW_TORQUE
from pinquad.identification.em import EMResult, EMSettings, run_em
from pinquad.identification.fisher import observed_information, standard_errors
from pinquad.identification.identify import em_from_guess, loglik_function
from pinquad.identification.known_mass import (
    KnownMassResult,
    KnownMassSettings,
    motor_lag,
    yaw_inertia_without_ratio,
)
from pinquad.identification.search_range import generic_range
from pinquad.identification.verdict import BandHalves, Estimate, judge, judge_estimate
from pinquad.identification.verdict_evidence import data_evidence
from pinquad.io.command_log import CommandLog
from pinquad.models.attitude_range import near_euler_singularity
from pinquad.models.sources import interval_inputs
from pinquad.models.ssm import Observations, Theta, corrected
from pinquad.mstep.band import BandMStep
from pinquad.mstep.protocol import MStep

Array = NDArray[np.float64]

EM_MAX_ITERATIONS = 200
"""E-steps at most per EM run of the known-mass mode."""
NOMINAL_YAW_RATIO = 0.015
"""Yaw torque per thrust [m] the EM route's yaw row is driven with when the vehicle file
gives none: a typical propeller's (0.01-0.02 m). I_zz is then not reported; the change of
I_xx and I_yy when it is doubled is their ``yaw_ratio_unknown`` error part."""
EM_TOL = 1e-4
"""EM stops when (m, I) change by less than this share (and the log-likelihood by a tenth
of it): far below the standard errors, as for a measured flight."""


@dataclass(frozen=True)
class KnownMassEM:
    """The EM route's result.

    estimates: thrust scale s [-], I_xx, I_yy, I_zz [kg m^2] (I_zz NaN without the yaw
    ratio), each an ``Estimate`` with its error parts and verdict; mass_hat, inertia_hat
    (3,): EM's estimates on the nominal wrench [kg, kg m^2]; nominal (P,) [N]: the nominal
    curve's coefficients c_1, c_2; nominal_source: where they came from; tau [s]: the
    motor time constant used; channels: the measurement channels the E-step saw;
    iterations, converged, failure, loglik (I,) [nats]: EM's; seconds: wall time of all EM
    runs; notes.
    """

    estimates: tuple[Estimate, ...]
    mass_hat: float
    inertia_hat: Array
    nominal: Array
    nominal_source: str
    tau: float
    channels: tuple[str, ...]
    iterations: int
    converged: bool
    failure: str | None
    seconds: float
    loglik: Array
    notes: tuple[str, ...] = ()

    def get(self, name: str) -> Estimate:
        """The estimate called ``name``."""
        return next(e for e in self.estimates if e.name == name)


def nominal_wrench(command: Array, curve: Array, tau: float, dt: float, positions: Array,
                   spin: Array, yaw_ratio: float | None) -> Array:
    """(N, 4) [F [N], tau_x, tau_y, tau_z [N m]] of commands (N, k) through the motor lag
    and the curve (c_1, c_2) (module docstring); tau_z = 0 without the yaw ratio."""
    lagged = motor_lag(command, tau, dt)
    thrust = curve[0] * lagged + curve[1] * lagged * lagged
    yaw = 0.0 if yaw_ratio is None else yaw_ratio
    return np.column_stack([thrust.sum(axis=1), thrust @ positions[:, 1],
                            -(thrust @ positions[:, 0]), yaw * (thrust @ spin)])


def command_observations(flight: CommandLog, wrench: Array) -> Observations:
    """The E-step's observations of a command log driven by ``wrench`` (N, 4) sampled at
    the rows: velocity, attitude and rates (position first when the log has any); the
    inputs are each interval's mean (``models.sources.interval_inputs``, a sampled
    record of a continuous flight); transitions near the Euler singularity excluded and
    reset, as for any log."""
    log = flight.log
    has_pos = bool(np.isfinite(log.position).any())
    channels = (("pos",) if has_pos else ()) + ("vel", "euler", "gyro")
    blocks = {"pos": log.position, "vel": log.velocity, "euler": log.euler, "gyro": log.gyro}
    ys = np.column_stack([blocks[c] for c in channels])
    x0 = np.zeros(12)
    for c, sl in (("pos", slice(0, 3)), ("vel", slice(3, 6)), ("euler", slice(6, 9)),
                  ("gyro", slice(9, 12))):
        ok = np.isfinite(blocks[c]).all(axis=1)
        if c in channels and ok.any():
            x0[sl] = blocks[c][np.argmax(ok)]
    singular = near_euler_singularity(log.t, log.euler).touching()
    return Observations(t=log.t, dt=float(np.median(np.diff(log.t))),
                        inputs=interval_inputs(wrench, "sampled"), channels=channels, ys=ys,
                        x0=x0, p0=np.ones(12), exclude=singular.copy(), resets=singular.copy(),
                        samples=wrench.copy(), continuous=True)


def _start_inertia(mass: float, positions: Array) -> Array:
    """EM's starting inertia (3, 3) [kg m^2], from the mass and the rotor geometry alone:
    half the mass at the mean rotor radius r, diag(m r^2 / 4, m r^2 / 4, m r^2 / 2)."""
    r2 = float(np.mean(np.sum(positions * positions, axis=1)))
    return np.diag([0.25 * mass * r2, 0.25 * mass * r2, 0.5 * mass * r2])


def _run(flight: CommandLog, curve: Array, tau: float, mass: float, positions: Array,
         spin: Array, yaw_ratio: float, warm: Theta | None,
         band: tuple[float, float]) -> tuple[EMResult, Observations, BandMStep]:
    """One EM run on the nominal wrench of ``curve`` and ``tau`` with the band M-step on
    ``band`` [Hz]: from an earlier fit's parameters ``warm`` (a rerun with one assumption
    moved: its noise is already close, so EM starts there and converges in a few steps),
    or, with ``warm`` None, from the guess (mass [kg], ``_start_inertia`` (3, 3) [kg m^2]),
    which begins with the paper's noise and a force-free E-step (``em_from_guess``)."""
    dt = float(np.median(np.diff(flight.log.t)))
    obs = command_observations(flight, nominal_wrench(flight.command, curve, tau, dt,
                                                      positions, spin, yaw_ratio))
    mstep = BandMStep(band)
    if warm is not None:
        res = run_em(obs, warm.without_nuisance(), smooth_quad, MStep(mstep),
                     max_iterations=EM_MAX_ITERATIONS, tol=EM_TOL, tol_loglik=0.1 * EM_TOL,
                     accelerate=False)
    else:
        res = em_from_guess(obs, mass, _start_inertia(mass, positions),
                            flight.log.meta.gravity, "rts", MStep(mstep),
                            EMSettings(EM_MAX_ITERATIONS, tol=EM_TOL, tol_loglik=0.1 * EM_TOL,
                                       accelerate=False))
    return res, obs, mstep


def band_halves(flight: CommandLog, curve: Array, tau: float, mass: float,
                positions: Array, spin: Array, yaw_ratio: float,
                warm: Theta, band: tuple[float, float]
                ) -> tuple[list[tuple[float, float]], list[tuple[float, float]], float]:
    """The adequacy check of the torque model: EM on the band's lower and upper halves
    (split at the geometric mean f_m = sqrt(lo hi) [Hz]); per half and axis the rescaled
    inertia m I_hat / m_hat [kg m^2] and its block-jackknife standard error. Returns
    (lower (3 x (I, se)), upper, f_m). A rigid body with the right torques reads the same
    inertia on both."""
    mid = math.sqrt(band[0] * band[1])
    out = []
    for half in ((band[0], mid), (mid, band[1])):
        res, obs, mstep = _run(flight, curve, tau, mass, positions, spin, yaw_ratio, warm,
                               half)
        scale = mass / res.theta.mass
        jack = mstep.jackknife(res.posterior, obs, res.theta)
        out.append([(scale * float(res.theta.inertia[a, a]), scale * float(jack[a + 1]))
                    for a in range(3)])
    return out[0], out[1], mid


def identify_known_mass_em(flight: CommandLog, mass: float, positions: Array, spin: Array,
                           regression: KnownMassResult, curve: ActuatorCurve | None = None,
                           settings: KnownMassSettings | None = None) -> KnownMassEM:
    """EM route of the known-mass mode (module docstring) on ``flight`` with the mass
    [kg] known, the rotor positions (k, 2) [m] and spins (k,), the known-mass
    regression's result on the same flight (its curve, time constant and their
    standard errors are the nominal ones unless the vehicle file's ``curve`` gives
    them)."""
    curve = curve or ActuatorCurve()
    settings = settings or KnownMassSettings()
    t0 = time.perf_counter()
    notes: list[str] = []
    reg = {e.name: e for e in regression.estimates}
    c1_se = reg["thrust c_1"].stderr if "thrust c_1" in reg else 0.0
    if curve.thrust is not None and curve.thrust.size <= 2:
        nominal = np.pad(np.asarray(curve.thrust, float), (0, 2 - curve.thrust.size))
        source = "the vehicle file's actuator_curve.thrust"
        c1_se = 0.0
        notes.append("nominal curve: the vehicle file's; its shape is taken as exact (only "
                     "its scale is identified)")
    else:
        nominal = np.array([reg["thrust c_1"].value if "thrust c_1" in reg else 0.0,
                            reg["thrust c_2"].value])
        source = "the known-mass regression's"
    if curve.time_constant is not None:
        tau, tau_se = curve.time_constant, 0.0
    else:
        tau, tau_se = reg["time constant"].value, reg["time constant"].stderr
    # without the yaw ratio the yaw row still needs a torque: a nominal one (I_zz is
    # then not reported; its effect on I_xx, I_yy is an error part)
    yaw = curve.yaw_ratio if curve.yaw_ratio is not None else NOMINAL_YAW_RATIO
    band = settings.band
    main, obs, mstep = _run(flight, nominal, tau, mass, positions, spin, yaw, None, band)
    theta = main.theta
    m_hat, i_hat = theta.mass, np.diag(theta.inertia).copy()

    # statistical: the observed information (on the torques with the fitted nuisance
    # moment) and the block jackknife, whichever is larger, as for a measured flight
    info = observed_information(corrected(obs, theta), theta.without_nuisance(),
                                loglik_function("rts"))
    se_stat = np.fmax(standard_errors(info), mstep.jackknife(main.posterior, obs, theta))
    rel_stat = se_stat / np.r_[m_hat, i_hat]
    if not np.all(np.isfinite(rel_stat)):
        notes.append("the observed information is not positive definite: no statistical "
                     "standard error")

    # the assumed curve shape, time constant (and yaw ratio): EM rerun once each with
    # the assumption moved by its standard error, warm-started at the estimate; the part
    # is the change of (ln s, ln I) (one-sided: each rerun costs a full EM)
    warm = theta
    u_m = float(motor_lag(flight.command, tau, float(np.median(np.diff(flight.log.t)))).mean())
    base = np.log(np.r_[m_hat, i_hat])

    def change(curve_coef: Array, lag: float, yaw_ratio: float) -> Array:
        """|change| of (ln s, ln I (3,)) on a rerun: ln s = ln m - ln m_hat and
        ln I = ln m + ln I_hat - ln m_hat (the mass m is the same in both)."""
        rerun = _run(flight, curve_coef, lag, mass, positions, spin, yaw_ratio, warm, band)[0]
        d = np.log(np.r_[rerun.theta.mass, np.diag(rerun.theta.inertia)]) - base
        return np.abs(np.r_[-d[0], d[1:] - d[0]])

    # c_1 moved by its se, c_2 keeping the thrust at the mean command T(u_m)
    shape_part = (change(np.array([nominal[0] + c1_se, nominal[1] - c1_se / u_m]), tau, yaw)
                  if c1_se > 0 else np.zeros(4))
    tau_part = change(nominal, tau + tau_se, yaw) if tau_se > 0 else np.zeros(4)
    yaw_part = np.zeros(4)
    if curve.yaw_ratio is None:  # I_xx, I_yy through the gyroscopic terms: k0 doubled
        yaw_part = change(nominal, tau, 2.0 * yaw)

    scale = mass / m_hat
    inertia = scale * i_hat
    mass_rel = settings.mass_rel_se
    yaw_rel = DEFAULT_YAW_TORQUE if curve.yaw_ratio is None or curve.yaw_ratio_se is None \
        else curve.yaw_ratio_se / curve.yaw_ratio
    s_parts = {"statistical": scale * rel_stat[0], "mass": scale * mass_rel,
               "curve_shape": scale * shape_part[0], "time_constant": scale * tau_part[0]}
    # ln I_hat - ln m_hat: their correlation is ignored (m_hat's share is ~0.1 %)
    stat_i = np.hypot(rel_stat[1:], rel_stat[0])

    # the house's verdict on the rescaled estimate, from the smoother's evidence at the
    # fit on the nominal wrench (shares and excitation are scale-free)
    evidence = data_evidence(corrected(obs, theta), theta.without_nuisance(),
                             main.posterior.mean, band=band, actuation="sampled")
    house = judge(mass, np.diag(inertia), np.r_[mass * mass_rel, inertia * stat_i], evidence,
                  generic_range(mass), thresholds=settings.thresholds)
    halves = band_halves(flight, nominal, tau, mass, positions, spin, yaw, warm, band)
    # what the fit itself says, for every number of the route
    findings = replace(evidence, not_converged=(
        f"EM: {main.failure}" if main.failure else None if main.converged else
        f"EM did not converge in {EM_MAX_ITERATIONS} E-steps"), band_halves=tuple(
        BandHalves(name, halves[0][a], halves[1][a], (band[0], halves[2], band[1]))
        for a, name in enumerate(("I_xx", "I_yy", "I_zz"))))
    estimates = [judge_estimate("thrust scale s", scale, "-", s_parts, findings,
                                settings.thresholds)]
    for a, name in enumerate(("I_xx", "I_yy", "I_zz")):
        if a == 2 and curve.yaw_ratio is None:
            estimates.append(yaw_inertia_without_ratio(settings.thresholds))
            continue
        lever = ({"arm_length": inertia[a] * settings.arm_rel_se} if a < 2 else
                 {"yaw_torque_coefficient": inertia[a] * yaw_rel})
        if curve.yaw_ratio is None:
            lever["yaw_ratio_unknown"] = inertia[a] * yaw_part[a + 1]
        parts = {"statistical": inertia[a] * stat_i[a], "mass": inertia[a] * mass_rel,
                 **lever, "curve_shape": inertia[a] * shape_part[a + 1],
                 "time_constant": inertia[a] * tau_part[a + 1]}
        estimates.append(judge_estimate(name, float(inertia[a]), "kg m^2", parts, findings,
                                        settings.thresholds, part_of=house))
    notes.append(f"EM on the nominal wrench ({source} curve c_1 {nominal[0]:.4g} N, c_2 "
                 f"{nominal[1]:.4g} N; time constant {tau:.4g} s; inertia from the "
                 f"{band[0]:g}-{band[1]:g} Hz torque rows): m_hat {m_hat:.5g} kg, "
                 f"{main.iterations} iterations, channels {', '.join(obs.channels)}")
    notes.append(f"band halves {band[0]:g}-{halves[2]:.2g} / {halves[2]:.2g}-{band[1]:g} Hz: "
                 + "; ".join(f"{n} {lo[0]:.4g} +- {lo[1]:.2g} / {hi[0]:.4g} +- {hi[1]:.2g}"
                             for n, lo, hi in zip(("I_xx", "I_yy", "I_zz"), halves[0],
                                                  halves[1], strict=True)
                             if n != "I_zz" or curve.yaw_ratio is not None))
    if "pos" not in obs.channels:
        notes.append("no position in the log: the E-step observes velocity, attitude and "
                     "rates; the position state is unobserved")
    return KnownMassEM(tuple(estimates), m_hat, i_hat, nominal, source, tau, obs.channels,
                       main.iterations, main.converged and not main.failure, main.failure,
                       time.perf_counter() - t0, main.loglik, tuple(notes))
