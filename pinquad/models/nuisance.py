"""The nuisance body moment of a measured flight: an optional parameter block of the
quadcopter model (``Theta.nuisance``) that the rotor torques are corrected by before the
E-step, tau_eff = tau_rotors + z moment_coef^T + [0, 0, J_r rotor_acc].

On the measured flights the rotor torques that cancel rotor-drag / blade-flapping moments
are ten times the inertial torque I omega' and, left in, inflate the inertia thirty-fold;
the block's M-step is the band-limited one (``pinquad.mstep.band.BandMStep``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler

Array = NDArray[np.float64]

TORQUE_FEATURES = ("thrust", "body_velocity", "body_rate")
"""Nuisance body-moment regressors: thrust F [N] (centre of mass off the thrust centre,
per-motor thrust mismatch: a moment proportional to thrust), body-frame velocity v_b
[m/s] (rotor drag / blade flapping: a moment proportional to the air speed, which the
controller cancels with differential thrust and which, on these flights, is ten times
the inertial torque I omega'), body rates omega [rad/s] (rotor damping)."""


@dataclass(frozen=True)
class NuisanceMoment:
    """The nuisance body moment of the current EM iterate.

    torque_offset (N, 3) [N m]: the moment on each row of the observations it was fitted
    on, added to the rotor torques before the E-step, tau_eff = tau_rotors + torque_offset;
    moment_coef (3, Z) [N m per feature unit]: its coefficients on the
    :data:`TORQUE_FEATURES` z (:func:`torque_features`); rotor_inertia: J_r [kg m^2] of the
    yaw reaction torque J_r rotor_acc (None: not fitted), so that
    torque_offset = z moment_coef^T + [0, 0, J_r rotor_acc].
    """

    torque_offset: Array
    moment_coef: Array
    rotor_inertia: float | None = None


def torque_features(mean: Array, thrust: Array) -> Array:
    """z (N, 7) = [F [N], v_b (3) [m/s], omega (3) [rad/s]] from state means (N, 12) and
    thrust (N,) [N]; v_b = R(Theta)^T v."""
    rot = rotation_from_euler(mean[:, 6:9])
    v_body = np.einsum("kji,kj->ki", rot, mean[:, 3:6])
    return np.column_stack([thrust, v_body, mean[:, 9:12]])
