"""The paper's sensor-A extended Kalman filter (the "state estimation from EKF").

Accelerometer-driven prediction (the accelerometer reads the body specific force f_b,
so the world acceleration is R(Theta) f_b - g e3; the paper's printed model writes the
world acceleration directly as ``f``):

    p_{k+1}     = p_k + dt v_k
    v_{k+1}     = v_k + dt (R(Theta_k) f_b,k - g e3)
    Theta_{k+1} = Theta_k + dt E^{-1}(Theta_k) omega_k
    omega_{k+1} = omega_k

Measurement: y = [position (3), gyro (3)] = H x + v, H selecting p and omega (the
paper's H = diag[1,1,1,0,0,0,0,0,0,1,1,1]). Phi is the paper's Jacobian plus the
rotation terms d(R f_b)/dTheta that the body-frame accelerometer brings.

Two tunings: ``paper`` (P0 = I, Q0 = 0.0707 I, R0 = 0.00707 I as printed) and
``tuned`` (covariances from the frozen sensor noise levels), the default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.ekf import predict, update
from pinquad.core.conventions import GRAVITY, euler_rate_kinematics, rotation_and_derivatives
from pinquad.core.params import FROZEN_SENSOR_NOISE, SensorNoise
from pinquad.models.ssm import KinematicSSM, NoiseModel, Observations, QuadSSM, Theta, kinematic_floor

Array = NDArray[np.float64]


@dataclass(frozen=True)
class NavTuning:
    """P0 (12,), Q (12,) per step and R (6,) diagonals of the sensor-A filter."""

    name: str
    p0: Array
    q: Array
    r: Array

    @staticmethod
    def paper() -> NavTuning:
        return NavTuning("paper", np.ones(12), np.full(12, 0.0707), np.full(6, 0.00707))

    @staticmethod
    def tuned(dt: float, noise: SensorNoise = FROZEN_SENSOR_NOISE,
              angular_accel_rms: float = 20.0) -> NavTuning:
        """Q from the accelerometer noise (velocity rows) and the typical angular
        acceleration of the flight [rad/s^2] (rate rows, a random-walk model);
        position and Euler rows are exact given v and omega, so tiny."""
        q = np.empty(12)
        q[0:3] = 1e-10
        q[3:6] = (dt * noise.accel) ** 2
        q[6:9] = 1e-10
        q[9:12] = (dt * angular_accel_rms) ** 2
        r = np.concatenate([np.full(3, noise.position**2), np.full(3, noise.gyro**2)])
        p0 = np.concatenate([np.full(3, 0.05**2), np.full(3, 0.05**2), np.full(3, 0.05**2),
                             np.full(3, 0.05**2)])
        return NavTuning("tuned", p0, q, r)


@dataclass
class SensorANavModel:
    """StateSpaceModel of the sensor-A filter. ``accel`` (N, 3) [m/s^2] holds the
    measured specific force used as the input of step k -> k+1 (NaN: hold the last
    one); ``x0`` (12,) the prior mean."""

    accel: Array
    dt: float
    tuning: NavTuning
    x0: Array
    gravity: float = GRAVITY
    state_dim: int = 12
    meas_dim: int = 6

    def initial(self) -> tuple[Array, Array]:
        return self.x0, np.diag(self.tuning.p0)

    def _accel(self, k: int) -> Array:
        a = self.accel[k]
        if np.isnan(a).any():
            return np.array([0.0, 0.0, self.gravity])
        return a

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        dt = self.dt
        phi, theta = float(x[6]), float(x[7])
        fb = self._accel(k)
        rot, d_rot = rotation_and_derivatives(x[6:9])
        step, d_euler, e_inv = euler_rate_kinematics(
            math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta),
            float(x[9]), float(x[10]), float(x[11]), dt)
        nxt = x.copy()
        nxt[0:3] += dt * x[3:6]
        nxt[3:6] += dt * (rot @ fb - np.array([0.0, 0.0, self.gravity]))
        nxt[6:9] += step
        jac = np.eye(12)
        jac[0, 3] = jac[1, 4] = jac[2, 5] = dt
        jac[3:6, 6:9] = dt * np.einsum("ijk,j->ik", d_rot, fb)
        jac[6:9, 6:9] += d_euler
        jac[6:9, 9:12] = e_inv
        return nxt, jac

    def process_cov(self, x: Array, k: int) -> Array:
        return np.diag(self.tuning.q)

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        h = np.zeros((6, 12))
        h[0:3, 0:3] = np.eye(3)
        h[3:6, 9:12] = np.eye(3)
        return h @ x, h

    def meas_cov(self, k: int) -> Array:
        return np.diag(self.tuning.r)

    def residual(self, y: Array, y_pred: Array) -> Array:
        return y - y_pred


@dataclass
class StreamingNavFilter:
    """The sensor-A filter run one step at a time inside the closed loop."""

    model: SensorANavModel
    mean: Array
    cov: Array
    gate_sigma: float | None = None

    @staticmethod
    def start(model: SensorANavModel) -> StreamingNavFilter:
        m, p = model.initial()
        return StreamingNavFilter(model, np.array(m, float), np.array(p, float))

    def correct(self, k: int, position: Array, gyro: Array) -> Array:
        """Update with the step-k measurements; returns the filtered state (12,)."""
        res = update(self.model, k, self.mean, self.cov, np.concatenate([position, gyro]),
                     self.gate_sigma)
        self.mean, self.cov = res.mean, res.cov
        return self.mean

    def advance(self, k: int) -> None:
        """Predict to step k+1 with the accelerometer sample of step k."""
        self.mean, self.cov, _ = predict(self.model, k, self.mean, self.cov)


@dataclass
class ModelBasedNavFilter:
    """Onboard EKF for sensors B and C: the quadcopter model (``pinquad.models.ssm.QuadSSM``)
    driven by the commanded thrust and torques with the controller's current mass and
    inertia, corrected by the sensor's samples.

    inputs (N, 4) is filled by the simulator before each prediction; the process noise
    is the frozen wrench-noise level, the measurement noise the sensor's.
    """

    channels: tuple[str, ...]
    inputs: Array
    dt: float
    wrench_intensity: Array
    meas_var: Array
    x0: Array
    p0: Array
    mass: float
    inertia: Array
    gravity: float = GRAVITY
    mean: Array | None = None
    cov: Array | None = None

    def __post_init__(self) -> None:
        self.mean = np.array(self.x0, float)
        self.cov = np.diag(self.p0)
        self._rebuild()

    def _rebuild(self) -> None:

        n = self.inputs.shape[0]
        obs = Observations(t=np.arange(n) * self.dt, dt=self.dt, inputs=self.inputs,
                           channels=self.channels, ys=np.empty((0, 0)), x0=self.x0, p0=self.p0)
        noise = NoiseModel(wrench=self.wrench_intensity, q_kin=kinematic_floor(self.dt),
                           meas=self.meas_var)
        theta = Theta(self.mass, self.inertia, noise, self.gravity)
        self.model = QuadSSM(obs, theta)
        fixed = NoiseModel(wrench=noise.wrench, q_kin=noise.q_kin, meas=noise.meas,
                           fixed_q=np.concatenate([np.full(3, 1e-8), np.full(3, 1e-4),
                                                   np.full(3, 1e-6), np.full(3, 1e-2)]))
        self.ground_model = KinematicSSM(obs, Theta(self.mass, self.inertia, fixed,
                                                    self.gravity))

    grounded: bool = False

    def set_grounded(self, grounded: bool) -> None:
        """On the floor (take-off ramp) the model's forces are not those acting (the
        floor carries the rest): predict with the force-free kinematic model instead."""
        self.grounded = grounded

    def set_params(self, mass: float, inertia: Array) -> None:
        """Use new mass [kg] and inertia (3, 3) from step on."""
        self.mass, self.inertia = float(mass), np.asarray(inertia, float)
        self._rebuild()

    def correct(self, k: int, y: Array) -> Array:
        res = update(self.model, k, self.mean, self.cov, y)
        self.mean, self.cov = res.mean, res.cov
        return self.mean

    def advance(self, k: int) -> None:
        model = self.ground_model if self.grounded else self.model
        self.mean, self.cov, _ = predict(model, k, self.mean, self.cov)
