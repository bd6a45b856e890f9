"""Mass and inertia of the vehicle from one measured flight, with standard errors.

Identification (:func:`identify_real`) is a configuration of the one EM entry
(``identification.identify.em_from_guess``) with the compiled EKF + RTS E-step and the band-limited M-step
(``pinquad.mstep.band.BandMStep``) of the inertia and the model's nuisance block
(``Theta.nuisance``): the shared closed form for the mass (body-z force row), the shared
profiled objective for the inertia but on the torque rows band-passed to 3-8 Hz, and a
nuisance body moment (thrust, body-frame air speed, body rates) that the measured
flights demand: the rotor torques that cancel rotor-drag / blade-flapping moments are
ten times the inertial torque I omega' and, left in, inflate the inertia thirty-fold.

Flight data identify only kf / m and kf L / I (every input is proportional to kf), so
the identified mass and inertia scale exactly with the kf taken from the thrust stand
(``pinquad.realdata.thrust``); :func:`identify_real` propagates its uncertainty into the
standard errors (:func:`total_standard_errors`).
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from pinquad.identification.em import EMSettings
from pinquad.identification.fisher import observed_information, standard_errors
from pinquad.identification.identify import Identification, em_from_guess, loglik_function
from pinquad.identification.measured import Exclusion, MeasuredFit
from pinquad.models.ssm import Theta, corrected
from pinquad.mstep.band import BandMStep
from pinquad.mstep.protocol import MStep
from pinquad.realdata.mass_balance import motor_split, quasi_static_mass
from pinquad.realdata.observations import RealObservations
from pinquad.realdata.rotor_inertia import yaw_band_stats
from pinquad.vehicle.actuators import CRAZYFLIE_SPEC, YAW_RATIO_CRAZYFLIE

Array = NDArray[np.float64]

YAW_RATIO_REL_SE = CRAZYFLIE_SPEC.actuators.yaw_ratio_se / YAW_RATIO_CRAZYFLIE  # type: ignore[union-attr]
"""Relative standard uncertainty of the yaw torque/thrust ratio: published values span
0.0060-0.0070 m around the 0.006 m used, taken as +-0.0005 m (one standard deviation)."""
# REPAIR_REL_SE, the uncertainty PWM repair adds, is the vehicle file's
# [faults] repair_rel_se (pinquad/data/crazyflie21.toml says how it was measured); on
# jana20-29 themselves the rebuilt M1 is checked against M1's own readings: the stuck
# channel updates a few hundred times per flight, and each fresh value is half the speed
# (a ratio to M3 of 0.48 where the clean flights give 0.92-0.99); twice the fresh values
# agree with the partner-map rebuild to +0.5..+1.3 % (median, six logs) and -0.5 % (jana25),
# residual 50-160 rev/min. The +2.3..+3.3 % mass excess of those flights is not the repair:
# the mocap-acceleration force balance with the measured M2 + M3 + M4 alone gives
# 26.9-27.0 g-equivalents there against 26.1-26.5 on jana02-05 (same M1/M3 and M2/M4 speed
# balance), +2.5-3 % from motors that were never rebuilt, and it persists in slow level
# flight (< 0.3 m/s, |v_z| < 0.1 m/s) and away from the floor. Thrust per rpm^2 (air
# density, propellers) or the vehicle's mass differed in that session; flight data
# identify only kf / m and cannot tell which.


def measured_fit(run: Identification) -> MeasuredFit:
    """The measured-flight block of a run of :func:`identify_real`. Raises ValueError for
    a run of another path (no such block)."""
    if run.measured is None:
        raise ValueError(f"the {run.mstep} run on {run.sensor or 'this log'} is not a "
                         "measured rotor-speed flight's fit")
    return run.measured


def total_standard_errors(params: Array, se_stat: Array, kf_rel: float,
                          yaw_rel: float = YAW_RATIO_REL_SE,
                          repair_rel: Array | None = None) -> Array:
    """se_total (4,) of [m, I_xx, I_yy, I_zz]: every input is proportional to kf, so
    each estimate is too (relative uncertainty kf_rel); I_zz is also proportional to the
    yaw torque ratio (yaw_rel); rotor speeds rebuilt from PWM add repair_rel (4,), the
    vehicle file's ``[faults] repair_rel_se`` (None: not repaired):

        se_total_i^2 = se_stat_i^2 + p_i^2 (kf_rel^2 [+ yaw_rel^2 for I_zz]
                                            [+ repair_rel_i^2 if repaired])
    """
    rel = np.full(4, kf_rel**2)
    rel[3] += yaw_rel**2
    if repair_rel is not None:
        rel += np.asarray(repair_rel, dtype=float)**2
    stat = np.where(np.isfinite(se_stat), se_stat, 0.0)
    return np.sqrt(stat**2 + params**2 * rel)


def used_rotor_inertia(fitted: Theta | None, fixed: float | None) -> float:
    """J_r [kg m^2] a measured flight was identified with: the EM's fitted value
    (``fitted``, the final Theta when J_r was fitted: its nuisance block's; NaN if its
    band fit was not finite), else the fixed value (0 included), else NaN (none)."""
    if fitted is not None:
        # EM that stopped before its first M-step holds no nuisance block yet
        jr = None if fitted.nuisance is None else fitted.nuisance.rotor_inertia
        return float(jr) if jr is not None else float("nan")
    return float(fixed) if fixed is not None else float("nan")


def identify_real(real: RealObservations, mass0: float, inertia0: Array,
                  max_iterations: int = 100, information: bool = True,
                  band: tuple[float, float] = (3.0, 8.0), tol: float = 1e-4,
                  estep: str = "rts", fit_rotor_inertia: bool = True,
                  keep_band_stats: bool = False) -> Identification:
    """EM on a measured flight (``BandMStep``; E-step ``estep``: ``rts`` = compiled EKF +
    RTS, or ``gtsam``) from (mass0 [kg], inertia0 (3, 3) [kg m^2]), then standard errors
    (the observed information always uses the EKF likelihood).

    keep_band_stats: store :func:`yaw_band_stats` at the final posterior in the result
    (the input of :func:`pooled_rotor_inertia`). J_r: fixed at ``real.options.rotor_inertia``
    when that is a value (0 included), else fitted per flight if ``fit_rotor_inertia`` and
    the log has rotor speeds, else none (``MeasuredFit.rotor_inertia`` NaN).

    Returns the ``Identification`` (regressor M-step; stderr: the total standard errors;
    theta: with its nuisance block; posterior and observations kept; notes: the
    observations' (among them where kf came from, every estimate scaling with it, and any
    repair of the rotor speeds)) with its :class:`MeasuredFit`. EM stops when the
    relative change of (m, I) is below ``tol`` (1e-4, far below the standard errors) and
    the relative log-likelihood change below tol / 10, or after ``max_iterations``
    E-steps.
    """
    t0 = time.perf_counter()
    obs = real.obs
    gravity = real.log.meta.gravity
    # J_r: fixed when the options give a value (0 included), else fitted if asked
    fixed_jr = real.options.rotor_inertia
    fit_jr = fit_rotor_inertia and real.rotor_acc is not None and fixed_jr is None
    mstep = BandMStep(band, real.rotor_acc if fit_jr else None)
    res = em_from_guess(obs, mass0, inertia0, gravity, estep, MStep(mstep),
                        EMSettings(max_iterations, tol=tol, tol_loglik=0.1 * tol,
                                   accelerate=False))
    theta = res.theta
    params = np.concatenate([[theta.mass], np.diag(theta.inertia)])
    se_info = np.full(4, np.nan)
    if information:
        info = observed_information(corrected(obs, theta), theta.without_nuisance(),
                                    loglik_function("rts"))
        se_info = standard_errors(info)
    se_jack = mstep.jackknife(res.posterior, obs, theta)
    se_stat = np.fmax(se_info, se_jack)
    yaw_rel = real.options.yaw_ratio_se / real.options.yaw_ratio
    repair_rel = (np.asarray(real.options.repair_rel_se)
                  if real.repaired and real.options.repair_rel_se else None)
    se_total = total_standard_errors(params, se_stat, real.kf.rel_se, yaw_rel=yaw_rel,
                                     repair_rel=repair_rel)
    fit = MeasuredFit(
        kf=real.kf, se_info=se_info, se_jack=se_jack, se_stat=se_stat,
        moment_coef=(np.zeros((3, 7)) if theta.nuisance is None
                     else theta.nuisance.moment_coef), n_used=real.n_used,
        n_excluded=real.n_excluded, excluded=real.excluded, band=band,
        rotor_inertia=used_rotor_inertia(theta if fit_jr else None, fixed_jr),
        band_stats=yaw_band_stats(real, res.posterior, band) if keep_band_stats else None,
        quasi_static_mass=quasi_static_mass(real), motor_split=motor_split(real),
        yaw_rel=yaw_rel, repair_rel=repair_rel, exclusions=real.exclusions)
    return Identification(
        mstep="regressor", mass=theta.mass, inertia=np.diag(np.diag(theta.inertia)),
        stderr=se_total, history_mass=np.concatenate([[mass0], res.mass]),
        history_inertia=np.vstack([np.diag(inertia0), res.inertia_diag]), loglik=res.loglik,
        converged=res.converged, seconds=time.perf_counter() - t0, theta=theta,
        failure=failure_with_gaps(res.failure, real.exclusions),
        sensor=",".join(obs.channels), e_steps=res.e_steps, notes=real.notes,
        posterior=res.posterior, observations=obs, measured=fit)


def failure_with_gaps(failure: str | None, exclusions: tuple[Exclusion, ...]) -> str | None:
    """EM's failure (None: none) with the log's gaps (``realdata.input_holes``): the
    smoother restarts after each (``models.ssm.restart_mask``), from a wide prior the
    first rows after it must pin down, the likeliest place for a filter to break."""
    gaps = [e.detail for e in exclusions if e.kind == "log gaps" and e.transitions]
    if failure is None or not gaps:
        return failure
    return (f"{failure}; the log has {gaps[0]}, after which the smoother restarts from a "
            "wide prior (cut the log at the gap to see whether it is the cause)")
