"""From the truth at the integrator rate to the log's rows (pinquad's log columns).

Log instants are every ``1 / log_rate`` s, each an integrator instant. At row j (time
t_j = integrator step k):

* ``thrust``, ``torque_*``: the controller's command of step k, SAMPLED (not averaged
  over the interval: the command moves between rows);
* ``gyro_*`` = omega(t_j) + b + n_g [rad/s, body]; ``acc_*`` = R^T (v'(t_j) + g e3) + n_a
  [m/s^2, body specific force], every row;
* ``pos_*``, ``vel_*``, ``quat_*``: motion capture at 100 Hz (rows j with t_j a
  multiple of 10 ms), empty cells in the rows between: p + n_p, v + n_v,
  q (x) exp(n_q / 2) (w >= 0);
* ``true_*``: the truth, every row: p, v, roll/pitch/yaw, omega (the gyro without bias
  or noise), named as pinquad's reader expects (``true_pos_x`` .. ``true_gyro_z``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from flightgen.effects import Effects
from flightgen.rotation import canonical, euler_from_quats, quat_from_axis_angle, quat_mul, quats_to_rots
from flightgen.spec import MOCAP_RATE, Noise
from flightgen.vehicle import GRAVITY, Vehicle

Array = NDArray[np.float64]

TRUE_NAMES = ("pos_x", "pos_y", "pos_z", "vel_x", "vel_y", "vel_z", "roll", "pitch", "yaw",
              "gyro_x", "gyro_y", "gyro_z")


def log_columns(t: Array, state: Array, command: Array, accel_world: Array, log_rate: int,
                effects: Effects, noise: Noise, rng: np.random.Generator) -> dict[str, Array]:
    """The log's columns (name -> (N,) array, NaN where no sample) from the truth at the
    integrator times t (M,)."""
    dt = float(t[1] - t[0])
    every = int(round(1.0 / (log_rate * dt)))
    idx = np.arange(0, t.size, every)
    n = idx.size
    x = state[idx]
    rot = quats_to_rots(x[:, 6:10])
    mocap = np.zeros(n, dtype=bool)
    mocap[:: int(round(log_rate / MOCAP_RATE))] = True
    nm = int(mocap.sum())

    cols: dict[str, Array] = {"t": np.round(t[idx], 9)}
    pos = np.full((n, 3), np.nan)
    vel = np.full((n, 3), np.nan)
    quat = np.full((n, 4), np.nan)
    pos[mocap] = x[mocap, 0:3] + noise.position * rng.standard_normal((nm, 3))
    vel[mocap] = x[mocap, 3:6] + noise.velocity * rng.standard_normal((nm, 3))
    rotvec = noise.attitude * rng.standard_normal((nm, 3))
    quat[mocap] = canonical(np.array([quat_mul(q, quat_from_axis_angle(e))
                                      for q, e in zip(x[mocap, 6:10], rotvec, strict=True)]))
    for name, arr in (("pos", pos), ("vel", vel)):
        for i, ax in enumerate("xyz"):
            cols[f"{name}_{ax}"] = arr[:, i]
    for i, ax in enumerate("wxyz"):
        cols[f"quat_{ax}"] = quat[:, i]

    bias = np.zeros(3) if effects.gyro_bias is None else np.asarray(effects.gyro_bias, float)
    gyro = x[:, 10:13] + bias + noise.gyro * rng.standard_normal((n, 3))
    specific = accel_world[idx].copy()
    specific[:, 2] += GRAVITY
    acc = np.einsum("nji,nj->ni", rot, specific) + noise.accel * rng.standard_normal((n, 3))
    for name, arr in (("gyro", gyro), ("acc", acc)):
        for i, ax in enumerate("xyz"):
            cols[f"{name}_{ax}"] = arr[:, i]
    cols["thrust"] = command[idx, 0]
    for i, ax in enumerate("xyz"):
        cols[f"torque_{ax}"] = command[idx, 1 + i]

    truth = np.column_stack([x[:, 0:6], euler_from_quats(x[:, 6:10]), x[:, 10:13]])
    for i, name in enumerate(TRUE_NAMES):
        cols[f"true_{name}"] = truth[:, i]
    return cols


def sidecar(vehicle: Vehicle, mass_guess: float | None = None,
            inertia_guess: Array | None = None) -> dict:
    """The JSON sidecar: vehicle name, guesses (None: the reader's
    default for that vehicle), gravity [m/s^2]."""
    return {"vehicle": vehicle.name, "mass_guess": mass_guess,
            "inertia_guess": None if inertia_guess is None
            else np.asarray(inertia_guess, dtype=float).tolist(),
            "gravity": GRAVITY,
            # the thrust and torque columns are the wrench the generator applied, exactly
            "calibration": {"thrust": 0.0, "yaw_torque": 0.0, "arm": 0.0}}
