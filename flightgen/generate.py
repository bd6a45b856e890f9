"""generate(spec) -> Flight: fly a FlightSpec closed-loop and log it.

Each integrator step k (dt, 0.5-1 ms): the geometric controller computes the command
u_cmd,k = (F, tau) from the true state and the reference at t_k; the motor model
(``motor_lag``) moves the applied wrench exactly for a held command,
u_k = u_{k-1} + (1 - exp(-dt / tau_m)) (u_cmd,k - u_{k-1}); process noise
n_k ~ N(0, sigma^2 reference_dt / dt) is added; RK4 advances the state with
u_k + n_k held over the step. All randomness comes from one numpy Generator seeded by
``spec.seed``.
"""

from __future__ import annotations

import numpy as np

from flightgen.controller import GeometricController
from flightgen.dynamics import derivative, make_body, rk4_step
from flightgen.effects import lag_factor
from flightgen.logrows import log_columns, sidecar
from flightgen.rotation import quat_to_rot
from flightgen.spec import Flight, FlightSpec
from flightgen.trajectory import reference
from flightgen.vehicle import GRAVITY


def generate(spec: FlightSpec) -> Flight:
    """Fly ``spec`` and log it (``Flight``: truth at the integrator rate, log columns)."""
    rng = np.random.default_rng(spec.seed)
    dt = spec.dt
    m_steps = int(round(spec.duration / dt)) + 1
    t = np.arange(m_steps) * dt
    ref = reference(t, spec.trajectory, spec.aggressive, spec.hover_height, rng,
                    spec.start_on_floor, spec.land, spec.floor_strikes)
    body = make_body(spec.vehicle, spec.effects, spec.floor)
    ctrl = GeometricController(spec.vehicle, spec.gains)
    sigma = spec.noise.wrench_sigma(spec.vehicle) * np.sqrt(spec.noise.reference_dt / dt)
    wrench_noise = sigma * rng.standard_normal((m_steps, 4))
    lag = lag_factor(spec.effects.motor_lag, dt)

    x = np.zeros(13)
    x[0:3] = ref.pos[0, 0]
    x[3:6] = ref.pos[1, 0]
    yaw0 = ref.yaw[0, 0]
    x[6:10] = (np.cos(0.5 * yaw0), 0.0, 0.0, np.sin(0.5 * yaw0))
    if spec.start_on_floor and spec.floor is not None:
        # at rest on the floor's spring under the first command F0: z = -(m g - F0) / (m w_c^2)
        x[2] = 0.0
        f0, _ = ctrl(x[0:3], x[3:6], quat_to_rot(x[6:10]), x[10:13], ref.pos[:, 0], yaw0, 0.0)
        m = spec.vehicle.mass
        x[2] = -max(m * GRAVITY - f0, 0.0) / (m * spec.floor.natural_frequency**2)
    state = np.empty((m_steps, 13))
    command = np.empty((m_steps, 4))
    applied = np.empty((m_steps, 4))
    accel = np.empty((m_steps, 3))
    contact = np.zeros(m_steps, dtype=bool)
    u = None
    for k in range(m_steps):
        rot = quat_to_rot(x[6:10])
        f, tau = ctrl(x[0:3], x[3:6], rot, x[10:13], ref.pos[:, k], ref.yaw[0, k], ref.yaw[1, k])
        cmd = np.array([f, tau[0], tau[1], tau[2]])
        u = cmd if u is None else u + lag * (cmd - u)
        w = u + wrench_noise[k]
        k1 = derivative(x, w[0], w[1:], body)
        state[k] = x
        command[k] = cmd
        applied[k] = w
        accel[k] = k1[3:6]
        contact[k] = spec.floor is not None and x[2] < 0.0
        if k + 1 < m_steps:
            x = rk4_step(x, dt, w[0], w[1:], body, k1)
    cols = log_columns(t, state, command, accel, spec.log_rate, spec.effects, spec.noise, rng)
    return Flight(spec=spec, t=t, state=state, command=command, applied=applied,
                  accel_world=accel, in_contact=contact, reference=ref.pos[0],
                  columns=cols, sidecar=sidecar(spec.vehicle))
