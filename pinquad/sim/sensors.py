"""Sensors A, B and C of the paper, with their rates and the frozen noise levels.

A: position (motion capture), accelerometer specific force, gyro.
B: position, velocity, Euler angles, gyro ("full state").
C: position, velocity, gyro ("partial state", no attitude).

Each quantity q is measured as q + n, n ~ N(0, sigma_q^2 I), every ``every_q`` steps
(NaN in other rows). The accelerometer reads the body specific force
f_b = R^T (v' + g e3) [m/s^2] (+9.81 on z at hover).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import wrap_angle
from pinquad.core.params import FROZEN_SENSOR_NOISE, SensorNoise

Array = NDArray[np.float64]

SENSOR_NAMES = ("A", "B", "C")


@dataclass(frozen=True)
class SensorSuite:
    """Which quantities a sensor set measures, how often (every n steps; 0 = never) and
    how noisily. Steps are the simulator's (10 ms by default)."""

    name: str
    position_every: int
    velocity_every: int
    euler_every: int
    gyro_every: int
    accel_every: int
    noise: SensorNoise = FROZEN_SENSOR_NOISE


SENSOR_A = SensorSuite("A", position_every=2, velocity_every=0, euler_every=0, gyro_every=1,
                       accel_every=1)
SENSOR_B = SensorSuite("B", position_every=2, velocity_every=2, euler_every=2, gyro_every=1,
                       accel_every=0)
SENSOR_C = SensorSuite("C", position_every=2, velocity_every=2, euler_every=0, gyro_every=1,
                       accel_every=0)
SENSORS = {"A": SENSOR_A, "B": SENSOR_B, "C": SENSOR_C}


@dataclass(frozen=True)
class Measurements:
    """Measured streams, one row per step (NaN where not sampled). Each (N, 3):
    position [m], velocity [m/s], euler [rad], gyro [rad/s], accel [m/s^2]."""

    position: Array
    velocity: Array
    euler: Array
    gyro: Array
    accel: Array


def _sampled(values: Array, every: int, sigma: float, rng: np.random.Generator,
             offset: int = 0) -> Array:
    out = np.full(values.shape, np.nan)
    if every <= 0:
        return out
    rows = np.arange(offset, values.shape[0], every)
    out[rows] = values[rows] + sigma * rng.standard_normal((rows.size, values.shape[1]))
    return out


def measure(suite: SensorSuite, states: Array, specific_force: Array,
            rng: np.random.Generator) -> Measurements:
    """Noisy measurements of true states (N, 12) and true body specific force (N, 3)."""
    nz = suite.noise
    euler = _sampled(states[:, 6:9], suite.euler_every, nz.euler, rng)
    euler = np.where(np.isnan(euler), np.nan, wrap_angle(np.nan_to_num(euler)))
    return Measurements(
        position=_sampled(states[:, 0:3], suite.position_every, nz.position, rng),
        velocity=_sampled(states[:, 3:6], suite.velocity_every, nz.velocity, rng),
        euler=euler,
        gyro=_sampled(states[:, 9:12], suite.gyro_every, nz.gyro, rng),
        accel=_sampled(specific_force, suite.accel_every, nz.accel, rng),
    )


def measure_one(suite: SensorSuite, k: int, state: Array, specific_force: Array,
                rng: np.random.Generator) -> Measurements:
    """Measurements of a single step k (each field (3,), NaN if not sampled at k)."""
    nz = suite.noise

    def one(value: Array, every: int, sigma: float) -> Array:
        if every <= 0 or k % every:
            return np.full(3, np.nan)
        return value + sigma * rng.standard_normal(3)

    eul = one(state[6:9], suite.euler_every, nz.euler)
    if not np.isnan(eul).any():
        eul = np.asarray(wrap_angle(eul))
    return Measurements(
        position=one(state[0:3], suite.position_every, nz.position),
        velocity=one(state[3:6], suite.velocity_every, nz.velocity),
        euler=eul,
        gyro=one(state[9:12], suite.gyro_every, nz.gyro),
        accel=one(specific_force, suite.accel_every, nz.accel),
    )
