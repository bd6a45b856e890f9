"""The effect library: physical effects the base rigid-body model leaves out (DESIGN 4.4).

Every effect exists twice:

* simulator side: a factory returning a ``pinquad.sim.simulator.simulator.Disturbance`` that injects the
  effect into the true vehicle with a documented coefficient;
* estimator side: an :class:`EffectSpec` whose ``features`` give the extra body wrench the
  effect adds to one transition k -> k+1 as a linear function of its coefficients
  (``wrench_k = Phi_k c``), evaluated at the smoothed state and the logged command, and
  whose ``correct`` folds identified coefficients back into the observations so the
  unchanged E-step / M-step can refit mass and inertia.

Forms (body frame: x forward, y left, z up; v_b = R^T v the body velocity [m/s]; F the
collective thrust [N]; all wrenches at the body origin):

====================  ===========================================  ==========================
name                  extra body wrench / effect                   coefficients (units)
====================  ===========================================  ==========================
``drag``              f = -diag(D) v_b                             D (3,) [N s/m]
``ground_effect``     f_z = k_ge F (r / (4 max(z, r/2)))^2         k_ge [-], r [m] fixed
``com_offset``        tau = (-c) x (F e3) = F [-c_y, c_x, 0]       c_x, c_y [m] (CoM)
``wind``              f = R^T [w_x, w_y, 0]                        w_x, w_y [N] (world)
``motor_lag``         tau_m du/dt = u_cmd - u  (all 4 channels)    tau_m [s]
``gyro_bias``         gyro = omega + b                             b (3,) [rad/s]
====================  ===========================================  ==========================

``ground_effect`` is the first-order Cheeseman-Bennett law T/T_inf = 1 + (r/4z)^2 with a
gain k_ge (k_ge = 1: one isolated rotor of radius r; measured multirotors show more) and
the height clipped at r/2 (at most +k_ge/4). ``wind`` is the steady aerodynamic force of a
constant wind, horizontal only: a vertical world force is indistinguishable from a
weight change over a flight at near-constant attitude, so it would trade off against the
mass. ``motor_lag`` is discretised by backward Euler:
u_k = u_{k-1} + dt / (tau_m + dt) (u_cmd,k - u_{k-1}).

Realistic Crazyflie 2.x magnitudes (used as the defaults): rotor drag from Foerster's
k_aero (-9.18e-7, -9.18e-7, -10.3e-7) N s/m per rad/s times the summed hover rotor speed
(about 4 x 1700 rad/s): D = (0.0062, 0.0062, 0.0070) N s/m; motor time constant about
0.03 s; a MEMS gyro bias of a few mrad/s to 0.05 rad/s; a battery a few mm off centre.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler  # noqa: F401 (re-exported for tests)
from pinquad.sim.simulator import Disturbance

Array = NDArray[np.float64]

EFFECT_NAMES = ("drag", "ground_effect", "com_offset", "wind", "motor_lag", "gyro_bias")
"""The discovery vocabulary of DESIGN 4.4."""

CRAZYFLIE_DRAG = (0.0062, 0.0062, 0.0070)
"""Linear rotor-drag coefficients of a hovering Crazyflie 2.x [N s/m] (module docstring)."""
CRAZYFLIE_ROTOR_RADIUS = 0.0235
"""Crazyflie 2.x propeller radius [m]."""
GROUND_EFFECT_RADIUS = 0.046
"""Effective radius r [m] of the ground-effect law: the Crazyflie's arm, i.e. the
footprint of the four rotors together (a single rotor's 0.0235 m reaches only ~1 cm)."""


# --------------------------------------------------------------------------------------
# simulator side
# --------------------------------------------------------------------------------------


def _disturbance(**kwargs) -> Disturbance:
    return Disturbance(**kwargs)


def ground_effect_gain(z: Array | float, radius: float = GROUND_EFFECT_RADIUS) -> Array:
    """g(z) = (r / (4 max(z, r/2)))^2 [-], the relative thrust gain per unit k_ge."""
    zc = np.maximum(np.asarray(z, dtype=float), 0.5 * radius)
    return (radius / (4.0 * zc)) ** 2


def drag(coefficients: tuple[float, float, float] | Array = CRAZYFLIE_DRAG) -> Disturbance:
    """Linear body drag f_b = -diag(D) R^T v [N] with D (3,) [N s/m]."""
    d = np.asarray(coefficients, dtype=float)

    def wrench(x: Array, u: Array, t: float) -> Array:
        v_b = rotation_from_euler(x[6:9]).T @ x[3:6]
        return np.concatenate([-d * v_b, np.zeros(3)])

    return _disturbance(name="drag", wrench=wrench)


def ground_effect(gain: float = 1.0, radius: float = GROUND_EFFECT_RADIUS) -> Disturbance:
    """Extra thrust f_z = k_ge F g(z) [N] near the floor, g from ``ground_effect_gain``."""

    def wrench(x: Array, u: Array, t: float) -> Array:
        out = np.zeros(6)
        out[2] = gain * u[0] * float(ground_effect_gain(x[2], radius))
        return out

    return _disturbance(name="ground_effect", wrench=wrench)


def com_offset(offset: tuple[float, float] | Array = (0.003, -0.002)) -> Disturbance:
    """The CoM at c = (c_x, c_y, 0) [m] from the thrust centre (body frame, the sign of
    ``Vehicle.com`` and of the ten-parameter model's CoM): the thrust, acting at the
    thrust centre, has the torque about the CoM tau = (-c) x (F e3) = F [-c_y, c_x, 0]
    [N m].

    Only this torque is modelled (the inertia shift of a few-mm offset is below 0.1 %).
    """
    cx, cy = (float(v) for v in np.asarray(offset, dtype=float)[:2])

    def wrench(x: Array, u: Array, t: float) -> Array:
        return np.array([0.0, 0.0, 0.0, -cy * u[0], cx * u[0], 0.0])

    return _disturbance(name="com_offset", wrench=wrench)


def wind(force: tuple[float, float] | Array = (0.01, -0.006)) -> Disturbance:
    """Constant horizontal world force [w_x, w_y, 0] [N], applied in the body frame."""
    f = np.zeros(3)
    f[:2] = np.asarray(force, dtype=float)[:2]

    def wrench(x: Array, u: Array, t: float) -> Array:
        return np.concatenate([rotation_from_euler(x[6:9]).T @ f, np.zeros(3)])

    return _disturbance(name="wind", wrench=wrench)


def motor_lag(time_constant: float = 0.03) -> Disturbance:
    """First-order lag of all four actuation channels, tau_m [s] (backward Euler)."""

    def actuation(u_cmd: Array, u_prev: Array, dt: float) -> Array:
        return u_prev + dt / (time_constant + dt) * (u_cmd - u_prev)

    return _disturbance(name="motor_lag", actuation=actuation)


def gyro_bias(bias: tuple[float, float, float] | Array = (0.03, -0.02, 0.015)) -> Disturbance:
    """Constant gyroscope offset b (3,) [rad/s] added to every gyro sample."""
    return _disturbance(name="gyro_bias", gyro_bias=np.asarray(bias, dtype=float))


SIMULATOR_FACTORIES: dict[str, Callable[..., Disturbance]] = {
    "drag": drag, "ground_effect": ground_effect, "com_offset": com_offset, "wind": wind,
    "motor_lag": motor_lag, "gyro_bias": gyro_bias,
}


def injected_coefficients(name: str, disturbance_args: dict | None = None) -> dict[str, float]:
    """The coefficients (by the estimator's names) of ``SIMULATOR_FACTORIES[name]`` called with
    ``disturbance_args`` (defaults when None); for scoring simulated discovery."""
    args = dict(disturbance_args or {})
    sig = inspect.signature(SIMULATOR_FACTORIES[name])
    full = {k: p.default for k, p in sig.parameters.items()}
    full.update(args)
    first = np.atleast_1d(np.asarray(next(iter(full.values())), dtype=float))
    names = SPECS[name].coefficient_names
    return {n: float(first[i]) for i, n in enumerate(names)}


# --------------------------------------------------------------------------------------
# estimator side
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TransitionData:
    """What an effect's features see of the transitions k -> k+1 used for fitting.

    x (K, 12): smoothed state at k; inputs (K, 4): logged command [F (N), M (N m)] at k;
    applied_history (N, 4): the whole logged command sequence (for lags); index (K,):
    the step k of each row; dt [s].
    """

    x: Array
    inputs: Array
    applied_history: Array
    index: NDArray[np.int64]
    dt: float


def lagged_inputs(inputs: Array, time_constant: float, dt: float) -> Array:
    """u_k = u_{k-1} + dt/(tau_m + dt) (u_cmd,k - u_{k-1}), u_0 = u_cmd,0: (N, 4)."""
    a = dt / (max(time_constant, 0.0) + dt)
    out = np.empty_like(inputs)
    out[0] = inputs[0]
    for k in range(1, inputs.shape[0]):
        out[k] = out[k - 1] + a * (inputs[k] - out[k - 1])
    return out


@dataclass(frozen=True)
class EffectSpec:
    """Estimator side of one effect.

    name: DESIGN 4.4 name; coefficient_names / units: one per coefficient; rows: the
    residual rows it explains (0-5: body force x, y, z, torque x, y, z; "gyro" effects
    use the gyro measurement residuals instead); feature_name: the explaining feature
    (for figures); nonlinear: coefficient enters nonlinearly (motor_lag: searched on a
    grid, ``features`` then takes the coefficient and returns the wrench itself).
    """

    name: str
    coefficient_names: tuple[str, ...]
    units: tuple[str, ...]
    rows: tuple[int, ...]
    feature_name: str
    nonlinear: bool = False

    @property
    def n_coefficients(self) -> int:
        return len(self.coefficient_names)


SPECS: dict[str, EffectSpec] = {
    "drag": EffectSpec("drag", ("D_x", "D_y", "D_z"), ("N s/m",) * 3, (0, 1, 2),
                       "body velocity [m/s]"),
    "ground_effect": EffectSpec("ground_effect", ("k_ge",), ("-",), (2,),
                                "thrust x ground gain F g(z) [N]"),
    "com_offset": EffectSpec("com_offset", ("c_x", "c_y"), ("m", "m"), (3, 4), "thrust [N]"),
    "wind": EffectSpec("wind", ("w_x", "w_y"), ("N", "N"), (0, 1, 2),
                       "world x/y axis in body frame [-]"),
    "motor_lag": EffectSpec("motor_lag", ("tau_m",), ("s",), (2, 3, 4, 5),
                            "command rate du/dt", nonlinear=True),
    "gyro_bias": EffectSpec("gyro_bias", ("b_x", "b_y", "b_z"), ("rad/s",) * 3, (),
                            "time [s]"),
}


def wrench_features(name: str, data: TransitionData,
                    ground_radius: float = GROUND_EFFECT_RADIUS) -> Array:
    """Phi (K, 6, p) with the effect's extra body wrench [N, N m] = Phi @ c (linear effects)."""
    k = data.x.shape[0]
    if name == "drag":
        v_b = np.einsum("kji,kj->ki", rotation_from_euler(data.x[:, 6:9]), data.x[:, 3:6])
        phi = np.zeros((k, 6, 3))
        for i in range(3):
            phi[:, i, i] = -v_b[:, i]
        return phi
    if name == "ground_effect":
        phi = np.zeros((k, 6, 1))
        phi[:, 2, 0] = data.inputs[:, 0] * ground_effect_gain(data.x[:, 2], ground_radius)
        return phi
    if name == "com_offset":
        phi = np.zeros((k, 6, 2))
        phi[:, 4, 0] = data.inputs[:, 0]
        phi[:, 3, 1] = -data.inputs[:, 0]
        return phi
    if name == "wind":
        rot = rotation_from_euler(data.x[:, 6:9])
        phi = np.zeros((k, 6, 2))
        phi[:, 0:3, 0] = rot[:, 0, :]  # R^T e_x: row 0 of R as a column
        phi[:, 0:3, 1] = rot[:, 1, :]
        return phi
    raise ValueError(f"{name!r} is not a linear wrench effect")


def lag_wrench(data: TransitionData, time_constant: float) -> Array:
    """(K, 6) extra wrench u_lagged - u_cmd of ``motor_lag`` (thrust and torque rows)."""
    lagged = lagged_inputs(data.applied_history, time_constant, data.dt)
    out = np.zeros((data.index.size, 6))
    out[:, 2:6] = lagged[data.index] - data.applied_history[data.index]
    return out


def explaining_feature(name: str, data: TransitionData, row: int) -> Array:
    """(K,) the scalar a figure plots residual row ``row`` against."""
    if name == "drag":
        v_b = np.einsum("kji,kj->ki", rotation_from_euler(data.x[:, 6:9]), data.x[:, 3:6])
        return v_b[:, min(row, 2)]
    if name == "ground_effect":
        return data.x[:, 2]
    if name == "com_offset":
        return data.inputs[:, 0]
    if name == "wind":
        rot = rotation_from_euler(data.x[:, 6:9])
        return rot[:, 0, min(row, 2)]
    if name == "motor_lag":
        hist = data.applied_history
        rate = np.gradient(hist, data.dt, axis=0)
        return rate[data.index, max(row - 2, 0)]
    return data.index * data.dt
