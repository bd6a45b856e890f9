"""The quadcopter with all ten inertial parameters as a state-space model.

Pinocchio's dynamic parameters of the body about its origin O (the thrust centre),
pi = [m, h_x, h_y, h_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz], h = m c, and the spatial
inertia M_O = [[m 1, -[h]x], [[h]x, I_O]]; body-frame Newton-Euler about O:

    M_O [a_O; omega'] = tau - [omega x (omega x h); omega x I_O omega],
    a_O = R^T (v'_world + g e3),  tau = [0, 0, F, M]

(the derivation, and the M-step over pi, are in ``pinquad.identification.full_inertia``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_and_derivatives, rotation_from_euler, skew
from pinquad.models.ssm import Observations, QuadSSM, Theta
from pinquad.vehicle.model import cross3, state_derivative_and_jacobian

Array = NDArray[np.float64]


def dynamic_parameters(mass: float, com: Array, inertia_c: Array) -> Array:
    """pi (10,) of a body with mass [kg], CoM (3,) [m] and inertia (3, 3) about the CoM."""
    body = pin.Inertia(float(mass), np.asarray(com, dtype=float),
                       np.asarray(inertia_c, dtype=float))
    return np.asarray(body.toDynamicParameters(), dtype=float).copy()


def from_dynamic_parameters(pi: Array) -> tuple[float, Array, Array]:
    """(mass [kg], CoM (3,) [m], inertia about the CoM (3, 3) [kg m^2]) of pi."""
    body = pin.Inertia.FromDynamicParameters(np.asarray(pi, dtype=float))
    return float(body.mass), np.array(body.lever), np.array(body.inertia)


def spatial_inertia(pi: Array) -> Array:
    """M_O (6, 6) [[m 1, -[h]x], [[h]x, I_O]] (Pinocchio's linear-then-angular order)."""
    return np.asarray(pin.Inertia.FromDynamicParameters(np.asarray(pi, float)).matrix())


# the velocity and body-rate rows of the state, where the wrench noise enters
DYNAMIC_ROWS = np.r_[3:6, 9:12]


class FullQuadSSM(QuadSSM):
    """The quadcopter with all ten inertial parameters (``theta.com``, a full
    ``theta.inertia`` about the CoM) as a StateSpaceModel: explicit Euler of the module
    docstring's dynamics, the same state, measurements and kinematic noise as
    :class:`~pinquad.models.ssm.QuadSSM` (which it equals when c = 0)."""

    def __init__(self, obs: Observations, theta: Theta):
        super().__init__(obs, theta)
        self.pi = dynamic_parameters(theta.mass, theta.com, theta.inertia)
        self._m_o = spatial_inertia(self.pi)
        self._m_inv = np.linalg.inv(self._m_o)
        self._first_moment = self.pi[1:4].copy()
        self._i_o = self._m_o[3:6, 3:6].copy()

    @property
    def spatial_inertia_inv(self) -> Array:
        """M_O^-1 (6, 6), the inverse spatial inertia about O (linear rows first); a copy."""
        return self._m_inv.copy()

    @property
    def first_moment(self) -> Array:
        """h = m c (3,) [kg m], the body's first moment of mass about O; a copy."""
        return self._first_moment.copy()

    @property
    def inertia_origin(self) -> Array:
        """I_O (3, 3) [kg m^2], the rotational inertia about O (body frame); a copy."""
        return self._i_o.copy()

    def _accelerations(self, x: Array, u: Array) -> tuple[Array, Array]:
        """[a_O; omega'] (6,) and its derivative w.r.t. omega (6, 3)."""
        w = x[9:12]
        h, i_o = self._first_moment, self._i_o
        i_w = i_o @ w
        bias = np.concatenate([cross3(w, cross3(w, h)), cross3(w, i_w)])
        tau = np.array([0.0, 0.0, float(u[0]), float(u[1]), float(u[2]), float(u[3])])
        d_bias = np.vstack([np.outer(w, h) + float(w @ h) * np.eye(3) - 2.0 * np.outer(h, w),
                            skew(w) @ i_o - skew(i_w)])
        return self._m_inv @ (tau - bias), -self._m_inv @ d_bias

    def body_acceleration(self, x: Array, k: int) -> tuple[Array, Array]:
        """a_O (3,) [m/s^2], the body-frame acceleration of O the inputs and the rates
        give (module docstring), and d a_O / d omega (3, 3)."""
        acc, d_acc = self._accelerations(x, self.obs.inputs[k])
        return acc[0:3], d_acc[0:3]

    def euler_step(self, x: Array, k: int) -> tuple[Array, Array]:
        u = self.obs.inputs[k]
        # the kinematic rows (p' = v, Theta' = E^{-1} omega) and their Jacobian are the
        # diagonal model's; the dynamic rows are replaced
        f, jac = state_derivative_and_jacobian(x, u, self.body)
        acc, d_acc = self._accelerations(x, u)
        rot, d_rot = rotation_and_derivatives(x[6:9])
        f[3:6] = rot @ acc[0:3] - np.array([0.0, 0.0, self.theta.gravity])
        f[9:12] = acc[3:6]
        jac[3:6, :] = 0.0
        jac[9:12, :] = 0.0
        jac[3:6, 6:9] = np.einsum("ijk,j->ik", d_rot, acc[0:3])
        jac[3:6, 9:12] = rot @ d_acc[0:3]
        jac[9:12, 9:12] = d_acc[3:6]
        dt = self.obs.dt
        return x + dt * f, self._eye + dt * jac

    def _flight_process_cov(self, x: Array) -> Array:
        q = super()._flight_process_cov(x)
        if self._fixed_q is not None:
            return q
        rot = rotation_from_euler(x[6:9])
        g = self._m_inv.copy()
        g[0:3] = rot @ g[0:3]
        s = np.asarray(self.theta.noise.wrench, dtype=float)
        dyn = self.obs.dt * (g * s) @ g.T
        q[DYNAMIC_ROWS[:, None], DYNAMIC_ROWS] = dyn
        return q
