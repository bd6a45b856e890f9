"""The rotor inertia J_r in the yaw torque, one value pooled over several flights.

Yaw: the rotors' drag torque gamma kf omega_i^2 is not the whole yaw torque. A rotor the
motor speeds up takes J_r omega_i' [N m] from the motor, and the body takes the reaction:

    tau_z = sum_i spin_i (gamma kf omega_i^2 + J_r omega_i')

with omega_i' from the measured rotor speeds (``observations.rotor_acceleration``). In the 3-8 Hz
band the second term is as large as the first (the yaw acceleration leads the drag torque
by 40-70 deg on the yaw flights, with |omega_z'| / |tau_drag| rising in proportion to the
frequency, which is what a derivative term does). Regressing the band-passed gyro yaw
acceleration on the drag torque alone leaves 72-86 % of its variance unexplained on
jana01/04/05; adding J_r omega' with one J_r = 20e-9 kg m^2 for all logs leaves 25-66 %.
J_r can be identified per flight by the M-step (a yaw-row regressor projected out with
the nuisance features, ``BandMStep``), but within one log it trades off against I_zz
(per-flight J_r 7-23e-9, yaw I_zz spread 88 %). By default one J_r is pooled over the
seven logs with every rotor speed measured (:func:`pooled_rotor_inertia`: each log keeps
its own inertia; 15.5 +- 4.1 e-9 kg m^2, delete-one-log jackknife), and each of those
logs is identified with the J_r fitted on the other six (leave-one-out), so no log's
I_zz uses a J_r fitted on its own data. Held out, that J_r leaves 53 / 22 / 27 % of the
band-passed yaw acceleration variance unexplained on jana01/04/05, against 53 / 20 / 25 %
with each log's own J_r and 67 / 34 / 39 % without J_r; the yaw I_zz spread narrows
(88 % -> ~70 %) but stays far from 10 %: no single J_r brings jana01 (I_zz ~27e-6
whatever J_r) and jana04/05 (13-18e-6) together. No published Crazyflie J_r was found.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from pinquad.mstep.band import BandMStep, BandStats, profiled_inertia
from pinquad.realdata.dataset import default_guess
from pinquad.realdata.observations import RealObservations

Array = NDArray[np.float64]

ROTOR_INERTIA_BOUNDS = (-2e-7, 2e-7)
"""Search interval of the pooled J_r [kg m^2] (ten times any per-flight value)."""


def yaw_band_stats(real: RealObservations, post, band: tuple[float, float] = (3.0, 8.0)
                   ) -> BandStats:
    """The band-passed torque-row regression data of ``post`` with the rotor acceleration
    e as a separate column and t the rotor drag torques alone (a J_r fixed in
    ``real.options`` is taken back out of the yaw row), so that any J_r can be tried:
    yaw torque = t_z + J_r e."""
    if real.rotor_acc is None:
        raise ValueError(f"{real.source}: no rotor acceleration; expected measured rotor speeds")
    bs = BandMStep(band, real.rotor_acc).band_stats(post, real.obs, real.log.meta.gravity)
    t = bs.t.copy()
    if real.options.rotor_inertia:
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
    inertia, objective = profiled_inertia(a, b, c, start)
    q = float(inertia @ a[2] @ inertia - 2.0 * b[2] @ inertia + c[2])
    return inertia, objective, q / (bs.x.shape[0] * inertia[2] ** 2)


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
        inertia, _ = profiled_inertia(*bs.quadratic(), band_fit(bs, value)[0])
        per[n] = bs.rotor_inertia(inertia)
    if len(names) < 2:
        return PooledRotorInertia(value, float("nan"), names, {}, per)
    loo = {h: _pool_value([stats[n] for n in names if n != h]) for h in names}
    jk = np.array(list(loo.values()))
    se = float(np.sqrt((jk.size - 1) / jk.size * np.sum((jk - jk.mean()) ** 2)))
    return PooledRotorInertia(value, se, names, loo, per)
