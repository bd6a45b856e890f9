"""The simulator's side of the effect vocabulary: physical effects the base rigid-body
model leaves out (the effect vocabulary, ``pinquad.core.effect_vocabulary``), injected into the true vehicle.

Each factory returns a ``pinquad.sim.simulator.Disturbance`` with a documented
coefficient. The estimator's side (features of the extra wrench, folding identified
coefficients back into the observations) is ``pinquad.discovery.library``; the names and
constants both use are in ``pinquad.core.effect_vocabulary``, so neither side imports the
other.

The forms and coefficients of each effect are tabled in ``pinquad.core.effect_vocabulary``.

``ground_effect`` is the first-order Cheeseman-Bennett law T/T_inf = 1 + (r/4z)^2 with a
gain k_ge (k_ge = 1: one isolated rotor of radius r; measured multirotors show more) and
the height clipped at r/2 (at most +k_ge/4). ``wind`` is the steady aerodynamic force of a
constant wind, horizontal only: a vertical world force is indistinguishable from a
weight change over a flight at near-constant attitude, so it would trade off against the
mass. ``motor_lag`` is discretised by backward Euler:
u_k = u_{k-1} + dt / (tau_m + dt) (u_cmd,k - u_{k-1}).

Realistic Crazyflie 2.x magnitudes (used as the defaults): rotor drag from the shipped
``crazyflie21.toml`` ``[aero] drag`` (Foerster's k_aero times the summed hover rotor
speed, ``core.effect_vocabulary.SIMULATED_DRAG``); motor time constant about 0.03 s; a
MEMS gyro bias of a few mrad/s to 0.05 rad/s; a battery a few mm off centre. The ground
effect's radius is the flown vehicle's (``Vehicle.ground_effect_radius``: its rotor
footprint), so the simulator and discovery evaluate the same law for any vehicle.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.core.effect_vocabulary import (
    COEFFICIENT_NAMES,
    SIMULATED_DRAG,
    ground_effect_gain,
)
from pinquad.core.params import Vehicle
from pinquad.sim.simulator import Disturbance

Array = NDArray[np.float64]


def _disturbance(**kwargs) -> Disturbance:
    return Disturbance(**kwargs)


def drag(coefficients: tuple[float, float, float] | Array = SIMULATED_DRAG) -> Disturbance:
    """Linear body drag f_b = -diag(D) R^T v [N] with D (3,) [N s/m]."""
    d = np.asarray(coefficients, dtype=float)

    def wrench(x: Array, u: Array, t: float) -> Array:
        v_b = rotation_from_euler(x[6:9]).T @ x[3:6]
        return np.concatenate([-d * v_b, np.zeros(3)])

    return _disturbance(name="drag", wrench=wrench)


def ground_effect(gain: float = 1.0, radius: float | None = None) -> Disturbance:
    """Extra thrust f_z = k_ge F g(z) [N] near the floor, g from ``ground_effect_gain``
    with radius r [m] (None: the flown vehicle's, ``Vehicle.ground_effect_radius``)."""

    def at_radius(r: float) -> Disturbance:
        def wrench(x: Array, u: Array, t: float) -> Array:
            out = np.zeros(6)
            out[2] = gain * u[0] * float(ground_effect_gain(x[2], r))
            return out

        return _disturbance(name="ground_effect", wrench=wrench)

    if radius is not None:
        return at_radius(radius)

    def for_vehicle(vehicle: Vehicle) -> Disturbance:
        return at_radius(vehicle.ground_effect_radius)

    return _disturbance(name="ground_effect", for_vehicle=for_vehicle)


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
    names = COEFFICIENT_NAMES[name]
    return {n: float(first[i]) for i, n in enumerate(names)}
