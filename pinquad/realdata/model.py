"""The E-step's model of a measured flight: the shared quadcopter state-space model with
the rotor torques corrected by a nuisance body moment (``RealTheta``), whose regressors
are :data:`TORQUE_FEATURES`. Identification (``pinquad.realdata.identify``) fits the
moment in ``pinquad.realdata.band_mstep.RealMStep``: the rotor torques that cancel
rotor-drag / blade-flapping moments are ten times the inertial torque I omega' on these
flights and, left in, inflate the inertia thirty-fold."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.models.ssm import KinematicSSM, Observations, QuadSSM, Theta

Array = NDArray[np.float64]

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
    samples = None
    if obs.samples is not None:
        samples = obs.samples.copy()
        samples[:, 1:4] += off
    return replace(obs, inputs=inputs, samples=samples)


def real_model(obs: Observations, theta: Theta):
    """E-step model: the force-free warm-up (``KinematicSSM``) while theta carries the
    paper's fixed Q0, then the quadcopter with the corrected torques."""
    if theta.noise.fixed_q is not None:
        return KinematicSSM(obs, theta)
    return QuadSSM(corrected(obs, theta), theta)


def torque_features(mean: Array, thrust: Array) -> Array:
    """z (N, 7) = [F, v_b (3), omega (3)] from state means (N, 12) and thrust (N,) [N]."""
    rot = rotation_from_euler(mean[:, 6:9])
    v_body = np.einsum("kji,kj->ki", rot, mean[:, 3:6])
    return np.column_stack([thrust, v_body, mean[:, 9:12]])


def plain_theta(theta: Theta) -> Theta:
    """The plain :class:`~pinquad.models.ssm.Theta` of a measured run's :class:`RealTheta`
    (its nuisance moment travels in :func:`corrected` observations instead)."""
    return Theta(theta.mass, np.asarray(theta.inertia), theta.noise, theta.gravity)
