"""The generator's rigid-body model and its RK4 integrator (its own; not pinquad's).

State x (13,) = [p (3) m world, v (3) m/s world, q (4) (w, x, y, z) body to world,
omega (3) rad/s body]. With the applied thrust F [N] along body z and body torque
tau [N m] held over a step:

    p' = v
    m v' = R e3 F (1 + k_ge g(z)) - m g e3 + f_drag + f_wind + f_floor
    q' = 0.5 q (x) (0, omega)
    J omega' = tau + tau_com + tau_floor - omega x J omega

f_drag = -R diag(D) R^T v, f_wind = (w_x, w_y, 0), tau_com = F (1 + k_ge g) (-c_y, c_x, 0)
(``flightgen.effects``), the floor's f_floor and tau_floor from ``flightgen.contact``.
One step is classical RK4 (local error O(dt^5)); q is renormalised after each step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flightgen.contact import Floor, floor_wrench
from flightgen.effects import Effects, ground_gain
from flightgen.rotation import norm3
from flightgen.vehicle import GRAVITY, Vehicle

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Body:
    """What the derivative needs, precomputed: mass [kg], J and J^-1 (3, 3), arm [m],
    ground radius [m], drag D (3,) [N s/m], wind (3,) [N world], k_ge [-], CoM (c_x,
    c_y) [m], the floor (None: no floor, free space)."""

    mass: float
    inertia: Array
    inertia_inv: Array
    arm: float
    ground_radius: float
    drag: Array | None
    wind: Array | None
    k_ge: float
    com: tuple[float, float] | None
    floor: Floor | None


def make_body(vehicle: Vehicle, effects: Effects, floor: Floor | None) -> Body:
    """The integrator's view of a vehicle with its injected effects."""
    j = vehicle.inertia_matrix
    return Body(
        mass=vehicle.mass, inertia=j, inertia_inv=np.linalg.inv(j), arm=vehicle.arm,
        ground_radius=vehicle.ground_radius,
        drag=None if effects.drag is None else np.asarray(effects.drag, dtype=float),
        wind=None if effects.wind is None else np.array([*effects.wind, 0.0]),
        k_ge=float(effects.ground_effect or 0.0), com=effects.com_offset, floor=floor)


def derivative(x: Array, thrust: float, torque: Array, body: Body) -> Array:
    """x' (13,) of the state x under the applied thrust [N] and body torque (3,) [N m].

    Written on Python floats (it runs four times per step: numpy's per-call overhead on
    3-vectors would dominate)."""
    px, py, pz, vx, vy, vz, qw, qx, qy, qz, wx, wy, wz = x.tolist()
    r00 = 1 - 2 * (qy * qy + qz * qz)
    r01 = 2 * (qx * qy - qz * qw)
    r02 = 2 * (qx * qz + qy * qw)
    r10 = 2 * (qx * qy + qz * qw)
    r11 = 1 - 2 * (qx * qx + qz * qz)
    r12 = 2 * (qy * qz - qx * qw)
    r20 = 2 * (qx * qz - qy * qw)
    r21 = 2 * (qy * qz + qx * qw)
    r22 = 1 - 2 * (qx * qx + qy * qy)
    f = float(thrust)
    if body.k_ge:
        f *= 1.0 + body.k_ge * ground_gain(pz, body.ground_radius)
    fx, fy, fz = f * r02, f * r12, f * r22 - body.mass * GRAVITY
    tx, ty, tz = (float(a) for a in torque)
    if body.drag is not None:
        dx, dy, dz = body.drag.tolist()
        bx = dx * (r00 * vx + r10 * vy + r20 * vz)
        by = dy * (r01 * vx + r11 * vy + r21 * vz)
        bz = dz * (r02 * vx + r12 * vy + r22 * vz)
        fx -= r00 * bx + r01 * by + r02 * bz
        fy -= r10 * bx + r11 * by + r12 * bz
        fz -= r20 * bx + r21 * by + r22 * bz
    if body.wind is not None:
        fx += float(body.wind[0])
        fy += float(body.wind[1])
    if body.com is not None:
        tx -= f * body.com[1]
        ty += f * body.com[0]
    if body.floor is not None and pz < 0.0:
        rot = np.array([[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]])
        f_floor, tau_floor = floor_wrench(x[0:3], x[3:6], rot, x[10:13], body.mass,
                                          body.inertia, body.arm, body.floor)
        fx, fy, fz = fx + f_floor[0], fy + f_floor[1], fz + f_floor[2]
        tx, ty, tz = tx + tau_floor[0], ty + tau_floor[1], tz + tau_floor[2]
    (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = body.inertia.tolist()
    hx = j00 * wx + j01 * wy + j02 * wz
    hy = j10 * wx + j11 * wy + j12 * wz
    hz = j20 * wx + j21 * wy + j22 * wz
    ex = tx - (wy * hz - wz * hy)
    ey = ty - (wz * hx - wx * hz)
    ez = tz - (wx * hy - wy * hx)
    (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = body.inertia_inv.tolist()
    m = body.mass
    return np.array([
        vx, vy, vz, fx / m, fy / m, fz / m,
        0.5 * (-qx * wx - qy * wy - qz * wz), 0.5 * (qw * wx + qy * wz - qz * wy),
        0.5 * (qw * wy + qz * wx - qx * wz), 0.5 * (qw * wz + qx * wy - qy * wx),
        i00 * ex + i01 * ey + i02 * ez, i10 * ex + i11 * ey + i12 * ez,
        i20 * ex + i21 * ey + i22 * ez,
    ])


def rk4_step(x: Array, dt: float, thrust: float, torque: Array, body: Body,
             k1: Array | None = None) -> Array:
    """x after one RK4 step of dt [s] with the wrench held; k1 = derivative(x) if the
    caller has it already. The quaternion is renormalised."""
    if k1 is None:
        k1 = derivative(x, thrust, torque, body)
    k2 = derivative(x + 0.5 * dt * k1, thrust, torque, body)
    k3 = derivative(x + 0.5 * dt * k2, thrust, torque, body)
    k4 = derivative(x + dt * k3, thrust, torque, body)
    out = x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    out[6:10] /= norm3(out[6:10])
    return out
