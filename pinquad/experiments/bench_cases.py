"""The E-step benchmark's cases (used by ``python -m pinquad.bench``).

A case is one long quadcopter E-step problem and its linearisation:

* ``obs``, ``theta``, ``model``: the quadcopter E-step model (:class:`~pinquad.models.ssm.QuadSSM`)
  on a simulated sensor-B flight whose inputs and measurements are repeated end to end
  (:func:`tile_observations`) up to N steps; ``ys`` (N, 12) its measurements, NaN where
  not sampled (position, velocity and Euler angles arrive every other step, the gyro
  every step).
* ``lin``: the same model linearised along the EKF's own filtered means m_k
  (:func:`linearise`), a linear time-varying Gaussian model

      x_{k+1} = F_k x_k + c_k + w_k,  w_k ~ N(0, Q_k),   y_k = H x_k + v_k,  v_k ~ N(0, R)

  with F_k = df/dx(m_k), c_k = f(m_k) - F_k m_k, Q_k = Q(m_k). The EKF linearises at
  exactly these points, so the Kalman filter and RTS smoother of ``lin`` are the EKF and
  RTS smoother of ``model`` to rounding: every linear smoother must then reproduce our
  compiled E-step's smoothed means, which is checked before anything is timed.
  ``ys_lin`` are the measurements with the Euler rows unwrapped onto the predicted angle
  (y + 2 pi j closest to it), since a linear model has no angle wrapping.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.ekf import run_filter
from pinquad.core.conventions import wrap_angle
from pinquad.core.params import FROZEN_SENSOR_NOISE, PAPER_PROCESS_NOISE, PAPER_VEHICLE
from pinquad.models.sources import observations
from pinquad.models.ssm import NoiseModel, Observations, QuadSSM, Theta

Array = NDArray[np.float64]

TOLERANCE = 1e-8
"""Largest allowed |peer - ours| of a smoothed mean, relative to the state's scale."""

BASE_SEED = 1
"""Seed of the simulated sensor-B flight every case is tiled from."""


@dataclass(frozen=True)
class LinearisedModel:
    """Linear time-varying Gaussian model (module docstring), a StateSpaceModel.

    m0 (n,), p0 (n, n): prior of x_0; f (N-1, n, n), c (N-1, n), q (N-1, n, n): F_k, c_k
    and Q_k of the step k -> k+1; h (m, n), r (m, m): measurement matrix and covariance.
    """

    m0: Array
    p0: Array
    f: Array
    c: Array
    q: Array
    h: Array
    r: Array

    @property
    def state_dim(self) -> int:
        return int(self.m0.shape[0])

    @property
    def meas_dim(self) -> int:
        return int(self.h.shape[0])

    @property
    def n_steps(self) -> int:
        return int(self.f.shape[0]) + 1

    def initial(self) -> tuple[Array, Array]:
        return self.m0, self.p0

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        return self.f[k] @ x + self.c[k], self.f[k]

    def process_cov(self, x: Array, k: int) -> Array:
        return self.q[k]

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        return self.h @ x, self.h

    def meas_cov(self, k: int) -> Array:
        return self.r

    def residual(self, y: Array, y_pred: Array) -> Array:
        return y - y_pred


@dataclass(frozen=True)
class EStepCase:
    """One benchmark problem (module docstring): the quadcopter model and data, and their
    linearisation with its (unwrapped) data."""

    obs: Observations
    theta: Theta
    ys: Array
    lin: LinearisedModel
    ys_lin: Array

    @property
    def n_steps(self) -> int:
        return int(self.ys.shape[0])

    @property
    def model(self) -> QuadSSM:
        return QuadSSM(self.obs, self.theta)

    def save(self, path: Path) -> None:
        """Write the case as one uncompressed .npz (read back by :func:`load_case`)."""
        obs, th, nz = self.obs, self.theta, self.theta.noise
        lin = self.lin
        np.savez(path, t=obs.t, dt=obs.dt, inputs=obs.inputs,
                 channels=np.array(obs.channels), ys=self.ys, x0=obs.x0, p0=obs.p0,
                 exclude=obs.exclude, mass=th.mass, inertia=th.inertia, gravity=th.gravity,
                 wrench=nz.wrench, q_kin=nz.q_kin, meas=nz.meas, lin_m0=lin.m0,
                 lin_p0=lin.p0, lin_f=lin.f, lin_c=lin.c, lin_q=lin.q, lin_h=lin.h,
                 lin_r=lin.r, ys_lin=self.ys_lin)


def load_case(path: Path) -> EStepCase:
    """Read a case written by :meth:`EStepCase.save`."""
    with np.load(path) as z:
        obs = Observations(t=z["t"], dt=float(z["dt"]), inputs=z["inputs"],
                           channels=tuple(str(c) for c in z["channels"]), ys=z["ys"],
                           x0=z["x0"], p0=z["p0"], exclude=z["exclude"])
        noise = NoiseModel(wrench=z["wrench"], q_kin=z["q_kin"], meas=z["meas"])
        theta = Theta(float(z["mass"]), z["inertia"], noise, float(z["gravity"]))
        lin = LinearisedModel(z["lin_m0"], z["lin_p0"], z["lin_f"], z["lin_c"], z["lin_q"],
                              z["lin_h"], z["lin_r"])
        return EStepCase(obs, theta, z["ys"], lin, z["ys_lin"])


def base_observations(seed: int = BASE_SEED) -> Observations:
    """The sensor-B observations of one simulated flight of the paper's scenario
    (3,744 steps of 10 ms for seed 1)."""
    # deferred on purpose: every E-step worker process reads its case (load_case) from
    # this module, and importing the simulator costs it seconds and ~100 MB it never uses
    from pinquad.sim.simulator import SimConfig, flight_log, simulate

    flight = simulate(SimConfig(sensor="B"), np.random.default_rng(seed))
    return observations(flight_log(flight), "B")


def tile_observations(obs: Observations, n_steps: int) -> Observations:
    """``obs`` repeated end to end and cut to ``n_steps`` steps: inputs, measurements and
    exclusion flags of step k are those of step k mod N0; time runs on uniformly. At each
    seam the measured state jumps back to the start of the flight, which the filter
    absorbs within a few steps (it is just a large innovation)."""
    idx = np.arange(n_steps) % obs.n
    t = obs.t[0] + obs.dt * np.arange(n_steps)
    exclude = obs.exclude[idx] if obs.exclude.size == obs.n else np.zeros(n_steps, bool)
    return replace(obs, t=t, inputs=obs.inputs[idx], ys=obs.ys[idx], exclude=exclude)


def bench_theta(obs: Observations) -> Theta:
    """E-step parameters of the benchmark: the paper vehicle's true mass and inertia,
    its simulated wrench-noise intensity (the force noise on body x and y, which the
    simulator does not have, at 10 % of the thrust axis's so that every Q_k is positive
    definite, as GTSAM's whitening needs), small kinematic terms (1e-8 m^2, rad^2 per
    step) and the simulated sensors' variances."""
    wrench = np.array(PAPER_PROCESS_NOISE.wrench_intensity(), dtype=float)
    wrench[0:2] = 0.1 * wrench[2]
    sd = {"pos": FROZEN_SENSOR_NOISE.position, "vel": FROZEN_SENSOR_NOISE.velocity,
          "euler": FROZEN_SENSOR_NOISE.euler, "gyro": FROZEN_SENSOR_NOISE.gyro}
    meas = np.repeat([sd[ch] ** 2 for ch in obs.channels], 3)
    noise = NoiseModel(wrench=wrench, q_kin=np.full(6, 1e-8), meas=meas)
    return Theta(PAPER_VEHICLE.mass, np.array(PAPER_VEHICLE.inertia, dtype=float), noise,
                 PAPER_VEHICLE.gravity)


def linearise(model: QuadSSM, ys: Array) -> tuple[LinearisedModel, Array]:
    """The model linearised along its EKF's filtered means, and the data with Euler rows
    unwrapped onto the EKF's predicted angles (module docstring). Uses the generic EKF,
    the reference implementation of the E-step's forward pass."""
    filt = run_filter(model, ys)
    m = filt.filtered_mean
    f = filt.transition_jac
    c = filt.predicted_mean[1:] - np.einsum("kij,kj->ki", f, m[:-1])
    q = np.stack([model.process_cov(m[k], k) for k in range(m.shape[0] - 1)])
    h = model.obs.measurement_matrix()
    x0, p0 = model.initial()
    lin = LinearisedModel(np.array(x0, dtype=float), np.array(p0, dtype=float), f, c, q, h,
                          np.diag(model.theta.noise.meas))
    ys_lin = np.array(ys, dtype=float)
    rows = model.obs.angle_rows()
    if rows.size:
        state_rows = np.argmax(h[rows], axis=1)
        pred = filt.predicted_mean[:, state_rows]
        ys_lin[:, rows] = pred + wrap_angle(ys[:, rows] - pred)
    return lin, ys_lin


def build_case(base: Observations, n_steps: int) -> EStepCase:
    """The case of ``n_steps`` steps tiled from ``base`` (module docstring)."""
    obs = tile_observations(base, n_steps)
    theta = bench_theta(obs)
    model = QuadSSM(obs, theta)
    lin, ys_lin = linearise(model, obs.ys)
    return EStepCase(obs, theta, obs.ys, lin, ys_lin)


def mean_error(mean: Array, ref: Array) -> float:
    """max over k, i of |mean - ref| / scale_i, scale_i = max_k |ref_ki| (the state
    component's own scale; 1 if that is below 1e-3, for components that stay near 0)."""
    scale = np.max(np.abs(ref), axis=0)
    scale = np.where(scale < 1e-3, 1.0, scale)
    return float(np.max(np.abs(np.asarray(mean) - ref) / scale))
