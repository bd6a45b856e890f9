"""Waypoint reference, differential flatness and the LQG controller of the paper.

ReferenceTrajectory: minimum-jerk segments from the start through the waypoints, with a
hover pause on each waypoint; gives p_ref, v_ref, a_ref [m, m/s, m/s^2].

Position loop (LQR on the double integrator p'' = ua, gains from ``control.lqr``):

    ua = a_ref - K_p (p - p_ref) - K_v (v - v_ref)

Differential flatness (paper, Faessler): t = ua + g e3, z_B = t/|t|,
y_C = [-sin psi_ref, cos psi_ref, 0], x_B = y_C x z_B / |.|, y_B = z_B x x_B,
R_ref = [x_B y_B z_B], Theta_ref from R_ref; the paper's rate reference
omega_ref = E(Theta) (-K_theta (Theta - Theta_ref)) with K_theta = 40.

Attitude loop (LQR on Theta' = omega, omega' = u_w, gains from ``control.lqr``):

    u_w = -K_a (Theta - Theta_ref) - K_w (omega - omega_ref)

Actuation from the controller's *current* mass and inertia estimates (the online mode
feeds them in):  F = m (ua_z + g) / (cos phi cos theta),  M = I u_w + omega x I omega.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import (
    euler_from_rotation,
    euler_rate_matrix,
    wrap_angle,
)
from pinquad.core.params import Scenario
from pinquad.vehicle.model import cross3

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ReferenceTrajectory:
    """Sampled reference: t (N,) [s]; pos, vel, acc (N, 3) [m, m/s, m/s^2];
    yaw (N,) [rad]; segment_end (M,) [s]: time each waypoint is reached."""

    t: Array
    pos: Array
    vel: Array
    acc: Array
    yaw: Array
    waypoint_times: Array


def _min_jerk(s: Array) -> tuple[Array, Array, Array]:
    """Position, velocity, acceleration of the minimum-jerk blend on s in [0, 1]."""
    pos = 10 * s**3 - 15 * s**4 + 6 * s**5
    vel = 30 * s**2 - 60 * s**3 + 30 * s**4
    acc = 60 * s - 180 * s**2 + 120 * s**3
    return pos, vel, acc


def build_reference(scenario: Scenario, final_hover: float | None = None) -> ReferenceTrajectory:
    """Minimum-jerk reference from ``scenario.start`` through every waypoint.

    Segment duration T = 1.875 |d| / v_cruise (so the peak speed is v_cruise), at least
    1 s; a hover of ``scenario.hover_time`` [s] follows each waypoint.
    """
    dt = scenario.dt
    points = np.vstack([scenario.start, scenario.waypoints])
    hover = scenario.hover_time
    final = hover if final_hover is None else final_hover
    pieces_t, pieces_p, pieces_v, pieces_a = [], [], [], []
    wp_times = []
    t0 = 0.0
    # Rise clear of the floor first: the pause lets the vehicle settle at take-off.
    for i in range(1, points.shape[0]):
        d = points[i] - points[i - 1]
        n_seg = int(round(max(1.875 * float(np.linalg.norm(d)) / scenario.cruise_speed, 1.0) / dt))
        dur = n_seg * dt
        s = np.arange(n_seg) / n_seg
        sp, sv, sa = _min_jerk(s)
        pieces_t.append(t0 + s * dur)
        pieces_p.append(points[i - 1] + sp[:, None] * d)
        pieces_v.append(sv[:, None] * d / dur)
        pieces_a.append(sa[:, None] * d / dur**2)
        t0 += n_seg * dt
        wp_times.append(t0)
        n_h = int(round((hover if i + 1 < points.shape[0] else final) / dt))
        pieces_t.append(t0 + np.arange(n_h) * dt)
        pieces_p.append(np.repeat(points[i][None], n_h, axis=0))
        pieces_v.append(np.zeros((n_h, 3)))
        pieces_a.append(np.zeros((n_h, 3)))
        t0 += n_h * dt
    # One grid for everything: the k-th sample is at k dt exactly.
    t = np.arange(sum(p.shape[0] for p in pieces_p)) * dt
    return ReferenceTrajectory(
        t=t, pos=np.vstack(pieces_p), vel=np.vstack(pieces_v), acc=np.vstack(pieces_a),
        yaw=np.full(t.shape, scenario.yaw), waypoint_times=np.asarray(wp_times),
    )


@dataclass(frozen=True)
class ControllerGains:
    """LQR gains: position (kp, kv) [1/s^2, 1/s], attitude (ka, kw) [1/s^2, 1/s]
    per axis (3,), the paper's Euler-rate gain k_theta [1/s], and thrust limits
    [N] as a multiple of the controller's own weight estimate."""

    kp: Array
    kv: Array
    ka: Array
    kw: Array
    k_theta: float = 40.0
    max_tilt: float = math.radians(35.0)


def design_gains(pos_weights: tuple[float, float] = (10.0, 1.0),
                 att_weights: tuple[float, float] = (100.0, 6400.0),
                 k_theta: float = 40.0) -> ControllerGains:
    """LQR gains from ``control.lqr`` on the decoupled double integrators.

    For x = [e, e'], x' = [[0, 1], [0, 0]] x + [0, 1]^T u, cost integral of
    x^T diag(w) x + u^2: position weights (10, 1), attitude weights (100, 6400).
    The attitude rate weight is large so the rate loop (about 80 rad/s) is faster
    than the paper's K_theta = 40 angle loop that feeds it.
    """
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    b = np.array([[0.0], [1.0]])
    k_pos, _, _ = ct.lqr(a, b, np.diag(pos_weights), np.eye(1))
    k_att, _, _ = ct.lqr(a, b, np.diag(att_weights), np.eye(1))
    k_pos = np.asarray(k_pos).ravel()
    k_att = np.asarray(k_att).ravel()
    return ControllerGains(
        kp=np.full(3, k_pos[0]), kv=np.full(3, k_pos[1]),
        ka=np.full(3, k_att[0]), kw=np.full(3, k_att[1]), k_theta=k_theta,
    )


def flatness_attitude(acc_cmd: Array, yaw: float, gravity: float) -> tuple[Array, float]:
    """Reference Euler angles (3,) and |t| [m/s^2] from a desired acceleration (3,)."""
    t = acc_cmd + np.array([0.0, 0.0, gravity])
    norm = float(np.linalg.norm(t))
    z_b = t / max(norm, 1e-9)
    y_c = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    x_b = cross3(y_c, z_b)
    x_b /= max(float(np.linalg.norm(x_b)), 1e-9)
    y_b = cross3(z_b, x_b)
    rot = np.column_stack([x_b, y_b, z_b])
    return euler_from_rotation(rot), norm


@dataclass(frozen=True)
class ControlOutput:
    """Actuation u = [F (N), M (3, N m)] and what produced it (for logging)."""

    u: Array
    euler_ref: Array
    acc_cmd: Array


def control_step(x_est: Array, k: int, ref: ReferenceTrajectory, gains: ControllerGains,
                 mass: float, inertia: Array, gravity: float,
                 thrust_limits: tuple[float, float]) -> ControlOutput:
    """One LQG control step from the state estimate (12,) at reference index k."""
    kk = min(k, ref.t.shape[0] - 1)
    pos, vel = x_est[0:3], x_est[3:6]
    euler, omega = x_est[6:9], x_est[9:12]
    acc_cmd = (ref.acc[kk] - gains.kp * (pos - ref.pos[kk]) - gains.kv * (vel - ref.vel[kk]))
    # Keep the commanded tilt feasible: limit the horizontal part of t.
    horiz = float(np.linalg.norm(acc_cmd[:2]))
    vert = acc_cmd[2] + gravity
    max_h = max(vert, 0.2 * gravity) * math.tan(gains.max_tilt)
    if horiz > max_h:
        acc_cmd = acc_cmd.copy()
        acc_cmd[:2] *= max_h / horiz
    euler_ref, _ = flatness_attitude(acc_cmd, float(ref.yaw[kk]), gravity)
    err = np.asarray(wrap_angle(euler - euler_ref))
    omega_ref = euler_rate_matrix(euler) @ (-gains.k_theta * err)
    u_w = -gains.ka * err - gains.kw * (omega - omega_ref)
    cos_tilt = max(math.cos(euler[0]) * math.cos(euler[1]), 0.3)
    thrust = mass * (acc_cmd[2] + gravity) / cos_tilt
    thrust = min(max(thrust, thrust_limits[0]), thrust_limits[1])
    torque = inertia @ u_w + cross3(omega, inertia @ omega)
    return ControlOutput(np.concatenate([[thrust], torque]), euler_ref, acc_cmd)
