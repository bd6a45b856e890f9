"""The quadcopter as a Pinocchio free-flyer, and the paper's state-space dynamics.

State x = [p (3, world, m), v (3, world, m/s), Theta (3, roll/pitch/yaw, rad),
omega (3, body, rad/s)]; input u = [F (N, along body z), M (3, body, N m)].

Continuous dynamics (the paper's ODE, plus an optional centre-of-mass offset handled by
Pinocchio):

    p'     = v
    v'     = R(Theta) e3 F / m - g e3
    Theta' = E^{-1}(Theta) omega
    omega' = I^{-1} (M - omega x I omega)

Two evaluations are provided and tested against each other: ``forward_dynamics`` runs
Pinocchio's ABA on the free-flyer (the reference, used by the simulator), and
``state_derivative`` / ``state_derivative_and_jacobian`` are the closed form the
estimators call thousands of times per second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from pinquad.core.conventions import (
    STATE_DIM,
    euler_from_rotation,
    euler_rate_kinematics,
    euler_rate_matrix_inv,
    quat_wxyz_from_rotation,
    rotation_from_euler,
    skew,
    wxyz_to_xyzw,
)
from pinquad.core.params import Vehicle

Array = NDArray[np.float64]


def urdf_path(name: str) -> str:
    """Path of the packaged URDF ``pinquad/data/<name>.urdf``."""
    path = resources.files("pinquad") / "data" / f"{name}.urdf"
    if not path.is_file():
        raise FileNotFoundError(f"no vehicle description {name!r} in pinquad/data")
    return str(path)


@lru_cache(maxsize=8)
def _urdf_model(name: str) -> pin.Model:
    return pin.buildModelFromUrdf(urdf_path(name), pin.JointModelFreeFlyer())


@lru_cache(maxsize=1)
def _rigid_body_model() -> pin.Model:
    """One rigid body on a free-flyer root, for a vehicle without a packaged URDF (a
    vehicle file's): its inertia is set by :func:`load_model` like a URDF's."""
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root_joint")
    model.appendBodyToJoint(joint, pin.Inertia.Identity(), pin.SE3.Identity())
    return model


def dynamic_parameters(vehicle: Vehicle) -> Array:
    """Pinocchio's 10 dynamic parameters pi of the vehicle about the body origin.

    pi = [m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] with the
    inertia taken about the body origin (thrust centre), i.e. I_o = I_c + m [c]x^T [c]x.
    """
    inertia = pin.Inertia(float(vehicle.mass), np.asarray(vehicle.com, float),
                          np.asarray(vehicle.inertia, float))
    return np.asarray(inertia.toDynamicParameters(), dtype=float).copy()


def vehicle_from_dynamic_parameters(template: Vehicle, params: Array) -> Vehicle:
    """Inverse of :func:`dynamic_parameters` (inertia returned about the CoM)."""
    inertia = pin.Inertia.FromDynamicParameters(np.asarray(params, dtype=float))
    return Vehicle(
        name=template.name,
        mass=float(inertia.mass),
        inertia=np.asarray(inertia.inertia, dtype=float).copy(),
        arm=template.arm,
        com=np.asarray(inertia.lever, dtype=float).copy(),
        gravity=template.gravity,
    )


def load_model(vehicle: Vehicle) -> pin.Model:
    """Pinocchio model of the vehicle: its URDF on a free-flyer root (one rigid body when
    pinquad ships no URDF of that name: a vehicle from a file), with the body's inertia
    replaced by the vehicle's mass, CoM and inertia."""
    shipped = (resources.files("pinquad") / "data" / f"{vehicle.name}.urdf").is_file()
    model = (_urdf_model(vehicle.name) if shipped else _rigid_body_model()).copy()
    model.inertias[1] = pin.Inertia.FromDynamicParameters(dynamic_parameters(vehicle))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -vehicle.gravity]), np.zeros(3))
    return model


def configuration_from_state(x: Array) -> tuple[Array, Array]:
    """Pinocchio (q, v) of a paper state x (12,).

    q = [p, quaternion (x, y, z, w)]; v = [R^T v_world, omega] (body-frame twist of
    the body origin, Pinocchio's free-flyer convention).
    """
    rot = rotation_from_euler(x[6:9])
    q = np.concatenate([x[0:3], wxyz_to_xyzw(quat_wxyz_from_rotation(rot))])
    v = np.concatenate([rot.T @ x[3:6], x[9:12]])
    return q, v


def cross3(a: Array, b: Array) -> Array:
    """a x b (3,) for 3-vectors: the same products and differences, in the same order, as
    ``np.cross`` (so bit-identical), without its general-shape machinery (~40 us -> ~2 us
    a call; the simulator and controller make four a step)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def forward_dynamics(model: pin.Model, data: pin.Data, x: Array, u: Array,
                     extra_wrench: Array | None = None) -> Array:
    """x' (12,) from Pinocchio's ABA on the free-flyer.

    The applied body wrench is [0, 0, F, M] at the body origin, plus ``extra_wrench``
    (6,) [N, N m] in the body frame when given. ABA returns the spatial acceleration
    a = [a_lin, omega']; the world acceleration of the origin is R (a_lin + omega x v_b).
    """
    q, v = configuration_from_state(x)
    tau = np.array([0.0, 0.0, u[0], u[1], u[2], u[3]])
    if extra_wrench is not None:
        tau = tau + extra_wrench
    acc = pin.aba(model, data, q, v, tau)
    rot = rotation_from_euler(x[6:9])
    acc_world = rot @ (acc[0:3] + cross3(v[3:6], v[0:3]))
    out = np.empty(STATE_DIM)
    out[0:3] = x[3:6]
    out[3:6] = acc_world
    out[6:9] = euler_rate_matrix_inv(x[6:9]) @ x[9:12]
    out[9:12] = acc[3:6]
    return out


def inverse_dynamics_wrench(model: pin.Model, data: pin.Data, x: Array, xdot: Array) -> Array:
    """Body wrench (6,) [N, N m] that produces x' given x, from Pinocchio's RNEA."""
    q, v, a = pinocchio_motion(x, xdot)
    return np.asarray(pin.rnea(model, data, q, v, a)).copy()


def pinocchio_motion(x: Array, xdot: Array) -> tuple[Array, Array, Array]:
    """(q, v, a) of Pinocchio's free-flyer from a state and its time derivative.

    a = [R^T v'_world - omega x v_b, omega'] is the spatial acceleration.
    """
    q, v = configuration_from_state(x)
    rot = rotation_from_euler(x[6:9])
    a = np.concatenate([rot.T @ xdot[3:6] - cross3(v[3:6], v[0:3]), xdot[9:12]])
    return q, v, a


def inertial_regressor(model: pin.Model, data: pin.Data, x: Array, xdot: Array) -> Array:
    """Pinocchio's joint-torque regressor Y (6, 10): body wrench = Y @ pi."""
    q, v, a = pinocchio_motion(x, xdot)
    return np.asarray(pin.computeJointTorqueRegressor(model, data, q, v, a)).copy()


@dataclass(frozen=True)
class RigidBodyParams:
    """What the closed-form dynamics needs: m [kg], I (3, 3) [kg m^2] and I^{-1}, g."""

    mass: float
    inertia: Array
    inertia_inv: Array
    gravity: float

    @staticmethod
    def of(vehicle: Vehicle) -> RigidBodyParams:
        inertia = np.asarray(vehicle.inertia, dtype=float)
        return RigidBodyParams(float(vehicle.mass), inertia, np.linalg.inv(inertia),
                               float(vehicle.gravity))


def state_derivative(x: Array, u: Array, body: RigidBodyParams) -> Array:
    """The paper's ODE x' = f(x, u) (12,), centre of mass at the thrust centre."""
    return state_derivative_and_jacobian(x, u, body)[0]


def state_derivative_and_jacobian(x: Array, u: Array, body: RigidBodyParams
                                  ) -> tuple[Array, Array]:
    """f(x, u) (12,) and its Jacobian df/dx (12, 12), closed form."""
    phi, theta, psi = float(x[6]), float(x[7]), float(x[8])
    wx, wy, wz = float(x[9]), float(x[10]), float(x[11])
    sf, cf = math.sin(phi), math.cos(phi)
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    f_over_m = float(u[0]) / body.mass

    out = np.empty(12)
    jac = np.zeros((12, 12))
    out[0:3] = x[3:6]
    jac[0, 3] = jac[1, 4] = jac[2, 5] = 1.0

    out[3] = f_over_m * (cf * st * cp + sf * sp)
    out[4] = f_over_m * (cf * st * sp - sf * cp)
    out[5] = f_over_m * (cf * ct) - body.gravity
    jac[3, 6] = f_over_m * (-sf * st * cp + cf * sp)
    jac[3, 7] = f_over_m * (cf * ct * cp)
    jac[3, 8] = f_over_m * (-cf * st * sp + sf * cp)
    jac[4, 6] = f_over_m * (-sf * st * sp - cf * cp)
    jac[4, 7] = f_over_m * (cf * ct * sp)
    jac[4, 8] = f_over_m * (cf * st * cp + sf * sp)
    jac[5, 6] = f_over_m * (-sf * ct)
    jac[5, 7] = f_over_m * (-cf * st)

    out[6:9], jac[6:9, 6:9], jac[6:9, 9:12] = euler_rate_kinematics(sf, cf, st, ct, wx, wy, wz)

    omega = x[9:12]
    i_omega = body.inertia @ omega
    gyro = np.array([wy * i_omega[2] - wz * i_omega[1],
                     wz * i_omega[0] - wx * i_omega[2],
                     wx * i_omega[1] - wy * i_omega[0]])
    out[9:12] = body.inertia_inv @ (np.asarray(u[1:4], dtype=float) - gyro)
    # d(omega x I omega)/d omega = [omega]x I - [I omega]x
    d_gyro = skew(omega) @ body.inertia - skew(i_omega)
    jac[9:12, 9:12] = -body.inertia_inv @ d_gyro
    return out, jac


def input_jacobian(x: Array, body: RigidBodyParams) -> Array:
    """df/du (12, 4) of the closed-form dynamics."""
    rot = rotation_from_euler(x[6:9])
    jac = np.zeros((12, 4))
    jac[3:6, 0] = rot[:, 2] / body.mass
    jac[9:12, 1:4] = body.inertia_inv
    return jac


def euler_step(x: Array, u: Array, body: RigidBodyParams, dt: float) -> Array:
    """One explicit Euler step x_k = x_{k-1} + dt f(x_{k-1}, u_{k-1})."""
    return x + dt * state_derivative(x, u, body)


def state_from_pose(position: Array, rotation: Array, vel_world: Array, omega: Array) -> Array:
    """Assemble the paper state (12,) from a pose, world velocity and body rates."""
    return np.concatenate([position, vel_world, euler_from_rotation(rotation), omega])
