"""The model-free mass check of a measured flight: the mass that balances the mean
vertical thrust (:func:`quasi_static_mass`), and that balance split by motor
(:func:`motor_split`), to tell a rebuilt motor's share from the rest."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.identification.measured import MotorSplit
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
