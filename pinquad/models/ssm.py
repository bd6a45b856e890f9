"""The quadcopter as a StateSpaceModel for the E-step, with the parameters EM learns.

Transition (explicit Euler of the paper's model, inputs u_k = [F, M] from the log):

    x_{k+1} = x_k + dt f(x_k, u_k; m, I) + w_k

except on a continuous flight (``Observations.continuous``), where the kinematic rows
advance by the mean of their rates over the interval (``models.continuous``):

    Theta_{k+1} = Theta_k + dt E^{-1}(Theta_k) (omega_k + omega_{k+1}) / 2,
    v_{k+1} = v_k + dt [(R_k + R_{k+1}) a_b / 2 - g e3],  a_b = [0, 0, F / m] (body),
    p_{k+1} = p_k + dt (v_k + v_{k+1}) / 2

Process noise, structured as the paper's SDE (noise on the applied wrench, intensity
S = diag(S_f (3), S_tau (3)) [N^2 s, (N m)^2 s], body frame) plus small kinematic terms:

    Cov(w_k) = blockdiag(q_pos I3, dt (R/m) S_f (R/m)^T, q_euler I3, dt I^{-1} S_tau I^{-1})

or, for the paper's own configuration, a fixed diagonal ``fixed_q`` (Q0 = 0.0707 I). On a
continuous flight the structured covariance also carries the position's share of the
velocity noise, the Euler rows theirs of the rate noise (``continuous.kinematic_noise``).
On a transition marked in ``Observations.resets`` (touch-down on the floor: an impulse
the model does not have stops and levels the vehicle within a step) the covariance is
widened by diag(RESET_VAR), so that the smoother does not carry the flight dynamics
across the impulse and the states on either side follow their own data. A reset into a row
that measures nothing (inside a log gap: ``restart_mask``) restarts the filter instead:
neither the model nor the data say where the vehicle went, so the state is not
propagated through the dynamics (carried blind over a 2 s gap, the rates integrate
the torques to tens of rad/s, the attitude spins and the covariance overflows), but
re-initialised to a wide prior around the last estimate,

    x_{k+1} = x_k + w_k,  F_k = 0,  Cov(w_k) = diag(RESTART_VAR)

which makes the states after the restart independent of those before it: the RTS gain
over it is zero, so the smoother runs on each side of the gap as if the log were cut
there.

Measurements y_k: the rows of ``channels`` (pos, vel, euler, gyro, each 3 rows, world
or body as in the log), y = H x + v, v ~ N(0, diag(r)); Euler rows wrap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import euler_rate_kinematics, euler_rate_matrix_inv, wrap_angle
from pinquad.core.effect_vocabulary import DEFAULT_GROUND_RADIUS
from pinquad.models.contact import NO_FLOOR, FloorLevel
from pinquad.models.continuous import continuous_step, kinematic_noise
from pinquad.models.nuisance import NuisanceMoment
from pinquad.vehicle.model import RigidBodyParams, state_derivative_and_jacobian

Array = NDArray[np.float64]

CHANNEL_SLICES = {"pos": slice(0, 3), "vel": slice(3, 6), "euler": slice(6, 9),
                  "gyro": slice(9, 12)}

RESET_VAR = np.array([1e-4] * 3 + [1.0] * 3 + [0.1] * 3 + [4.0] * 3)
"""(12,) process variance added on a reset transition [m^2, (m/s)^2, rad^2, (rad/s)^2]:
what a floor contact can change in one 10 ms step at take-off speeds, as standard
deviations: position 1 cm (it is continuous), velocity 1 m/s, attitude 0.3 rad, body
rates 2 rad/s (it stops them)."""

RESTART_VAR = np.array([1.0] * 3 + [25.0] * 3 + [1.0] * 3 + [25.0] * 3)
"""(12,) prior variances of the state after a restart (``restart_mask``) [m^2, (m/s)^2,
rad^2, (rad/s)^2], about the last estimate: a hundred times the first row's prior
(realdata's p0), as standard deviations position 1 m, velocity 5 m/s, attitude 1 rad,
body rates 5 rad/s; wide against the measurements' noise, so the next measurements set
the state, yet not so wide that an update from it loses digits (against mocap's 5 mm,
P / R ~ 4e4: the compiled and generic passes still agree to 1e-11)."""


@dataclass(frozen=True)
class NoiseModel:
    """Noise parameters EM updates alongside mass and inertia.

    wrench (6,): S, body force and torque noise intensities [N^2 s, N^2 m^2 s];
    q_kin (6,): per-step variances of the position (3) [m^2] and Euler (3) [rad^2]
    rows; meas (m,): measurement variances, one per measurement row;
    fixed_q (12,) or None: if set, the per-step process variances used instead of the
    structured model (the paper's Q0).
    """

    wrench: Array
    q_kin: Array
    meas: Array
    fixed_q: Array | None = None


@dataclass(frozen=True)
class Theta:
    """Parameters of the E-step model: mass [kg], inertia (3, 3) about the centre of
    mass [kg m^2], noise, gravity [m/s^2], the centre of mass com (3,) in the body
    frame [m] (zero except in ``pinquad.identification.full_inertia``'s ten-parameter model)
    and the optional nuisance block (``models.nuisance.NuisanceMoment``: a measured
    flight's nuisance body moment and rotor inertia, which the model adds to the rotor
    torques, :func:`corrected`; None: the rotor torques alone)."""

    mass: float
    inertia: Array
    noise: NoiseModel
    gravity: float = 9.81
    com: Array = field(default_factory=lambda: np.zeros(3))
    nuisance: NuisanceMoment | None = None

    def body(self) -> RigidBodyParams:
        inertia = np.asarray(self.inertia, dtype=float)
        return RigidBodyParams(self.mass, inertia, np.linalg.inv(inertia), self.gravity)

    def with_noise(self, noise: NoiseModel) -> Theta:
        return replace(self, noise=noise)

    def without_nuisance(self) -> Theta:
        """theta without its nuisance block (the block then travels in
        :func:`corrected` observations instead)."""
        return self if self.nuisance is None else replace(self, nuisance=None)


@dataclass(frozen=True)
class Observations:
    """What the E-step sees of a flight.

    t (N,) [s]; dt [s] (uniform step); inputs (N, 4) [F (N), M (3, N m)];
    channels: names of the measured 3-row blocks, in the order of the columns of ys;
    ys (N, 3 * len(channels)) with NaN where not sampled; x0 (12,) prior mean and
    p0 (12,) prior variances; exclude (N,) bool: transitions k -> k+1 the M-step must
    not use (ground contact, implausible actuation); resets (N,) bool: transitions
    k -> k+1 that the flight dynamics do not describe because something outside the
    model changed the state (the floor stopping the vehicle as it touches down), whose
    process covariance is widened by ``RESET_VAR`` or, into a row without any
    measurement (inside a log gap), from which the filter restarts (``restart_mask``)
    (empty: none); ground_radius [m]: the
    flown vehicle's ground-effect radius, which discovery's ``ground_effect`` feature
    evaluates (``core.effect_vocabulary.vehicle_ground_radius``; the default is for
    observations built without a vehicle); samples (N, 4) or None: the logged thrust [N]
    and torques [N m] at each row's instant when ``inputs`` are their interval means (a
    ``sampled`` log, ``models.sources.interval_inputs``), None when the inputs are held
    over each interval (the motor lag of discovery is discretised on the samples then:
    ``discovery.library.applied_lag``); continuous: the vehicle moved continuously
    between rows (a recorded flight, or a simulator finer than its log), so the attitude,
    the thrust direction and the position advance by their mean rates over each interval
    (``models.continuous``); False for pinquad's own simulator, which moves by explicit
    Euler at the log's step, as the model then does; floor: where the log shows the floor
    (``models.contact.floor_level``), from which discovery's ``ground_effect`` feature
    measures the height (default: no contact seen, the floor at z = 0).
    """

    t: Array
    dt: float
    inputs: Array
    channels: tuple[str, ...]
    ys: Array
    x0: Array
    p0: Array
    exclude: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    resets: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    ground_radius: float = DEFAULT_GROUND_RADIUS
    samples: Array | None = None
    continuous: bool = False
    floor: FloorLevel = NO_FLOOR

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    def measurement_matrix(self) -> Array:
        """H (m, 12) selecting the measured state rows."""
        h = np.zeros((3 * len(self.channels), 12))
        for i, ch in enumerate(self.channels):
            sl = CHANNEL_SLICES[ch]
            h[3 * i:3 * i + 3, sl] = np.eye(3)
        return h

    def angle_rows(self) -> NDArray[np.int64]:
        """Indices of Euler rows in y (wrapped residuals)."""
        rows = [3 * i + j for i, ch in enumerate(self.channels) if ch == "euler" for j in range(3)]
        return np.asarray(rows, dtype=np.int64)


def corrected(obs: Observations, theta: Theta) -> Observations:
    """obs with the nuisance moment of ``theta.nuisance`` added to the torque inputs
    (and to the torque samples of a sampled log), tau_eff = tau + torque_offset [N m];
    obs itself when theta has no nuisance block."""
    if theta.nuisance is None:
        return obs
    off = theta.nuisance.torque_offset
    inputs = obs.inputs.copy()
    inputs[:, 1:4] += off
    samples = None
    if obs.samples is not None:
        samples = obs.samples.copy()
        samples[:, 1:4] += off
    return replace(obs, inputs=inputs, samples=samples)


class QuadSSM:
    """StateSpaceModel of the quadcopter for given observations and parameters; the
    torques it is driven by are the logged ones plus theta's nuisance moment, if any
    (:func:`corrected`; ``self.obs`` holds the corrected observations)."""

    state_dim = 12

    def __init__(self, obs: Observations, theta: Theta):
        obs = corrected(obs, theta)
        self.obs = obs
        self.theta = theta
        self.body = theta.body()
        self.meas_dim = 3 * len(obs.channels)
        self._h = obs.measurement_matrix()
        self._r = np.diag(theta.noise.meas)
        self._angle_rows = obs.angle_rows()
        self._eye = np.eye(12)
        nz = theta.noise
        self._fixed_q = None if nz.fixed_q is None else np.diag(nz.fixed_q)
        self._s_f = np.asarray(nz.wrench[0:3], dtype=float)
        self._q_tau = obs.dt * self.body.inertia_inv @ np.diag(nz.wrench[3:6]) @ self.body.inertia_inv
        self._resets = np.asarray(obs.resets, dtype=bool)
        self._reset_q = np.diag(RESET_VAR)
        self._restarts = restart_mask(obs)
        self._restart_q = np.diag(RESTART_VAR)

    def initial(self) -> tuple[Array, Array]:
        return self.obs.x0, np.diag(self.obs.p0)

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        """(x_{k+1}, F_k): ``euler_step``, with the kinematic rows by their mean rates
        over the interval on a continuous flight (``continuous.continuous_step``); on a
        restart (``restart_mask``), (x_k, 0)."""
        if self._restarts[k]:
            return x.copy(), np.zeros((12, 12))
        nxt, jac = self.euler_step(x, k)
        if self.obs.continuous:
            accel, d_accel = self.body_acceleration(x, k)
            return continuous_step(x, self.obs.dt, nxt, jac, accel, d_accel)
        return nxt, jac

    def body_acceleration(self, x: Array, k: int) -> tuple[Array, Array]:
        """a_b (3,) [m/s^2], the body-frame acceleration the inputs give at x (here the
        thrust's [0, 0, F / m]), and d a_b / d omega (3, 3) [m/s]."""
        return np.array([0.0, 0.0, float(self.obs.inputs[k, 0]) / self.body.mass]), np.zeros((3, 3))

    def euler_step(self, x: Array, k: int) -> tuple[Array, Array]:
        """x_k + dt f(x_k, u_k) (12,) and its Jacobian I + dt df/dx (12, 12)."""
        f, jac = state_derivative_and_jacobian(x, self.obs.inputs[k], self.body)
        dt = self.obs.dt
        return x + dt * f, self._eye + dt * jac

    def process_cov(self, x: Array, k: int) -> Array:
        if self._restarts[k]:
            return self._restart_q
        q = self._flight_process_cov(x)
        if self.obs.continuous and self._fixed_q is None:
            q = kinematic_noise(q, self.obs.dt, euler_rate_matrix_inv(x[6:9]))
        return q + self._reset_q if self.is_reset(k) else q

    def is_reset(self, k: int) -> bool:
        """Whether transition k -> k+1 is a reset (``Observations.resets``)."""
        return bool(k < self._resets.size and self._resets[k])

    def _flight_process_cov(self, x: Array) -> Array:
        if self._fixed_q is not None:
            return self._fixed_q
        dt = self.obs.dt
        q = np.zeros((12, 12))
        nz = self.theta.noise
        q[0, 0], q[1, 1], q[2, 2] = nz.q_kin[0:3]
        q[6, 6], q[7, 7], q[8, 8] = nz.q_kin[3:6]
        phi, theta, psi = float(x[6]), float(x[7]), float(x[8])
        sf, cf = math.sin(phi), math.cos(phi)
        st, ct = math.sin(theta), math.cos(theta)
        sp, cp = math.sin(psi), math.cos(psi)
        rot = np.array([
            [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp],
            [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp],
            [-st, sf * ct, cf * ct],
        ])
        g = rot / self.body.mass
        q[3:6, 3:6] = dt * (g * self._s_f) @ g.T
        q[9:12, 9:12] = self._q_tau
        return q

    def measure(self, x: Array, k: int) -> tuple[Array, Array]:
        return self._h @ x, self._h

    def meas_cov(self, k: int) -> Array:
        return self._r

    def residual(self, y: Array, y_pred: Array) -> Array:
        res = y - y_pred
        if self._angle_rows.size:
            res[self._angle_rows] = wrap_angle(res[self._angle_rows])
        return res


class KinematicSSM(QuadSSM):
    """The data-driven warm-up model of EM's first E-step: the same measurements, but a
    transition without forces (p' = v, v' = 0, Theta' = E^{-1} omega, omega' = 0) and the
    paper's process covariance, so the first posterior follows the data rather than a
    dynamic model evaluated at a guess that may be two orders of magnitude off (with
    m0 = 0.001 kg the force term alone is ~1800 m/s^2 and the EKF diverges). Its rates
    are constant over each interval, so a continuous flight moves it the same way."""

    def transition(self, x: Array, k: int) -> tuple[Array, Array]:
        if self._restarts[k]:
            return x.copy(), np.zeros((12, 12))
        return self.euler_step(x, k)

    def euler_step(self, x: Array, k: int) -> tuple[Array, Array]:
        dt = self.obs.dt
        phi, theta = float(x[6]), float(x[7])
        step, d_euler, e_inv = euler_rate_kinematics(
            math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta),
            float(x[9]), float(x[10]), float(x[11]), dt)
        nxt = x.copy()
        nxt[0:3] += dt * x[3:6]
        nxt[6:9] += step
        jac = np.eye(12)
        jac[0, 3] = jac[1, 4] = jac[2, 5] = dt
        jac[6:9, 6:9] += d_euler
        jac[6:9, 9:12] = e_inv
        return nxt, jac

    def _flight_process_cov(self, x: Array) -> Array:
        if self._fixed_q is None:
            raise ValueError("the kinematic warm-up model needs a fixed process covariance")
        return self._fixed_q


def restart_mask(obs: Observations) -> NDArray[np.bool_]:
    """(N,) whether transition k -> k+1 restarts the filter (module docstring): a reset
    (``Observations.resets``) into a row without any measurement in ``obs.ys``, as are
    the transitions inside a log gap longer than the grid's step. The last transition
    of a gap, into a measured row, stays a reset (from the restarted state), as do a
    touch-down's."""
    n = obs.n
    mask = np.zeros(n, dtype=bool)
    resets = np.asarray(obs.resets, dtype=bool)[:max(n - 1, 0)]
    if not resets.any():
        return mask
    blind = np.isnan(np.asarray(obs.ys, dtype=float)).all(axis=1)
    m = min(resets.size, blind.size - 1)  # ys may hold fewer rows than t (a bad call)
    mask[:m] = resets[:m] & blind[1:m + 1]
    return mask


def kinematic_floor(dt: float, accel: float = 1.0, angular_accel: float = 10.0) -> Array:
    """Fixed per-step variances (6,) of the position and Euler rows.

    The SDE has no noise there (p' = v, Theta' = E^{-1} omega are identities); what is
    left is the explicit-Euler truncation error (dt^2 / 2) x'' for accelerations of
    ``accel`` [m/s^2] and ``angular_accel`` [rad/s^2]. Keeping them fixed rather than
    estimated removes six slowly converging EM parameters.
    """
    return np.concatenate([np.full(3, (0.5 * dt * dt * accel) ** 2),
                           np.full(3, (0.5 * dt * dt * angular_accel) ** 2)])
