"""The model-free mass check of a measured flight: the mass that balances the mean
vertical thrust (:func:`quasi_static_mass`), and that balance split by motor
(:func:`motor_split`), to tell a rebuilt motor's share from the rest."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.realdata.observations import RealObservations

Array = NDArray[np.float64]


def _vertical_balance(real: RealObservations) -> tuple[NDArray[np.int64], Array, Array]:
    """The transitions of :func:`quasi_static_mass`: (rows k (K,), R_k,zz (K,),
    g + a_z,k (K,) [m/s^2]) over the used transitions with a finite vertical
    acceleration, attitude and thrust."""
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

    share (n,) [-]: each of the n motors' part of the vertical thrust over the used
    transitions relative to the mean over the n motors, s_i = n sum_k F_k R_k,zz w_ik /
    sum_k F_k R_k,zz with w_ik = omega_ik^2 / sum_j omega_jk^2 (1 for all when they carry
    equal thrust);
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
        mean over the n motors): m_meas / (1 - n_rebuilt share / n)."""
        return self.measured_mass / (1.0 - len(self.rebuilt) * share / self.share.size)

    def share_for(self, mass: float) -> float:
        """The share each rebuilt motor would carry if the mass were ``mass`` [kg]."""
        return self.share.size * (1.0 - self.measured_mass / mass) / max(len(self.rebuilt), 1)


def motor_split(real: RealObservations) -> MotorSplit:
    """:class:`MotorSplit` of a measured flight (the rows of :func:`quasi_static_mass`;
    each bin's thrust divided between the motors by their bin-mean speeds squared)."""
    rows, rzz, lift = _vertical_balance(real)
    n_rotors = np.asarray(real.log.rpm).shape[1]
    if not rows.size:
        return MotorSplit(share=np.full(n_rotors, np.nan), measured_mass=float("nan"),
                          rebuilt=tuple(real.repaired))
    omega2 = np.asarray(real.log.rpm, dtype=float)[rows] ** 2
    weight = omega2 / omega2.sum(axis=1, keepdims=True)
    vertical = real.obs.inputs[rows, 0] * rzz
    share = float(n_rotors) * (vertical @ weight) / vertical.sum()
    measured = [i for i in range(n_rotors) if i not in real.repaired]
    mass = float(np.sum(vertical * weight[:, measured].sum(axis=1)) / np.sum(lift))
    if real.rebuilt_fraction is None:
        own = np.ones(rows.size, dtype=bool) if not real.repaired else np.zeros(rows.size, bool)
    else:
        own = real.rebuilt_fraction[rows] == 0.0
    own_mass = float(vertical[own].sum() / lift[own].sum()) if own.any() else float("nan")
    return MotorSplit(share=share, measured_mass=mass, rebuilt=tuple(real.repaired),
                      all_measured_mass=own_mass, all_measured_rows=int(own.sum()))
