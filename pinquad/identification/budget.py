"""The error budget of an estimate: the statistical error and what the estimate assumed.

Every estimate of a recorded log rests on things no flight can check: the scale of the
logged thrust (a thrust-stand kf, or a controller's belief about its motors), the yaw
torque coefficient behind I_zz, the arm length behind I_xx and I_yy, how a sampled input
acted between rows, and how far the rigid-body model misses from flight to flight. Each
is a named part of the standard error of p = [m, I_xx, I_yy, I_zz]:

    statistical        the likelihood's (or the jackknife's) error with all else known
    thrust_calibration p * r_F                 (every force and torque scales with it)
    yaw_torque_coefficient  I_zz * r_yaw
    arm_length         I_xx * r_arm, I_yy * r_arm
    input_reading      |p - p_held| / 2        (a sampled log's two readings: each is
                                                the truth with equal odds)
    between_flights    p * r_model             (the vehicle file's measured model error)

and the total is their root sum of squares (the parts are independent). The relative
uncertainties r come from, in order: the log's sidecar (``calibration``: a simulator
declares 0, and then the vehicle's model error, measured on its real flights, does not
apply either), the vehicle file (``[actuators]`` kf_se, yaw_ratio_se; ``[uncertainty]``),
else the defaults below, which the report names as defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from pinquad.core.params import VEHICLES
from pinquad.core.vehicle_file import VehicleSpec, is_vehicle_file, load_vehicle
from pinquad.io.logs import LogMeta

Array = NDArray[np.float64]

DEFAULT_COMMANDED_THRUST = 0.05
"""Relative uncertainty of a commanded thrust no file calibrates [-]: a controller's
thrust map is typically a few per cent off its vehicle (its battery, propellers, build)."""
DEFAULT_YAW_TORQUE = 0.10
"""Relative uncertainty of a yaw torque coefficient no file gives [-] (the Crazyflie's
published yaw ratio spans 0.0060-0.0070 m)."""
DEFAULT_ARM = 0.02
"""Relative uncertainty of an arm length no file gives [-] (a millimetre in 5 cm)."""

PARTS = ("statistical", "thrust_calibration", "yaw_torque_coefficient", "arm_length",
         "input_reading", "between_flights")
"""The budget's parts, in report order."""
SHARED_WITH_THRUST = ("thrust_calibration", "between_flights", "rotor_speed_repair")
"""Parts that scale every reading of the log's thrust alike (its calibration, its rotor
speeds rebuilt from PWM, what changes from flight to flight: battery, propellers), so
that they cancel when two estimates from the same thrust are compared."""


@dataclass(frozen=True)
class Calibration:
    """The relative standard uncertainties [-] an estimate assumed: thrust, yaw_torque,
    arm, model_error (4,) of [m, I_xx, I_yy, I_zz]; sources: part -> where its value came
    from, in words."""

    thrust: float
    yaw_torque: float
    arm: float
    model_error: Array = field(default_factory=lambda: np.zeros(4))
    sources: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ErrorBudget:
    """Standard errors of [m, I_xx, I_yy, I_zz] by part (``PARTS``: name -> (4,) [kg, kg
    m^2]); calibration: what the systematic parts assumed."""

    parts: dict[str, Array]
    calibration: Calibration

    @property
    def total(self) -> Array:
        """sqrt(sum of the parts' squares) (4,); NaN where the statistical part is."""
        return self.total_without()

    def total_without(self, *parts: str) -> Array:
        """The total without the named parts (4,)."""
        return np.sqrt(sum(np.asarray(p, dtype=float) ** 2 for k, p in self.parts.items()
                           if k not in parts))

    def unshared_with_thrust(self) -> Array:
        """The total without the parts any other reading of the same logged thrust shares
        (``SHARED_WITH_THRUST``): what a model-free mass balance on the same thrust is
        compared with (4,)."""
        return self.total_without(*SHARED_WITH_THRUST)

    def to_report(self) -> dict:
        """report.json's ``stderr_parts``: per part, the mass's and the inertia
        diagonal's standard errors, and where each relative uncertainty came from."""
        out: dict = {name: {"mass": float(v[0]), "inertia_diag": [float(x) for x in v[1:]]}
                     for name, v in self.parts.items()}
        out["assumed"] = {"thrust": self.calibration.thrust,
                          "yaw_torque": self.calibration.yaw_torque,
                          "arm": self.calibration.arm,
                          "model_error": self.calibration.model_error.tolist(),
                          "sources": dict(self.calibration.sources)}
        return out


def vehicle_spec(vehicle: str | None) -> VehicleSpec | None:
    """The vehicle of a shipped name or a vehicle file, or None (no vehicle, or a name
    that is neither)."""
    if vehicle and (is_vehicle_file(vehicle) or vehicle in VEHICLES):
        return load_vehicle(vehicle)
    return None


def named_vehicle(meta: LogMeta) -> VehicleSpec | None:
    """The vehicle a log names (a shipped name or a vehicle file), or None."""
    return vehicle_spec(meta.vehicle if meta.vehicle_named else None)


def calibration_of(meta: LogMeta, measured_thrust: tuple[float, float] | None = None
                   ) -> Calibration:
    """What a log's estimates assume (module docstring). measured_thrust: (kf's, the yaw
    ratio's) relative uncertainty when the thrust and torques come from measured rotor
    speeds through a thrust-stand kf (None: the log's thrust and torque columns)."""
    spec = named_vehicle(meta)
    unc = None if spec is None else spec.uncertainty
    where = "the vehicle file" if spec is not None else ""
    sources: dict[str, str] = {}
    model = np.zeros(4)
    if unc is not None and unc.model_error:
        model = np.asarray(unc.model_error, dtype=float)
        sources["between_flights"] = f"{spec.name}'s [uncertainty] model_error"  # type: ignore[union-attr]
    else:
        sources["between_flights"] = "not measured for this vehicle: 0"
    if meta.calibration is not None:
        thrust, yaw, arm = meta.calibration
        for k in ("thrust", "yaw_torque", "arm"):
            sources[k] = "the log's sidecar (calibration)"
        if not any(meta.calibration):  # a simulator's log: the rigid-body model is its truth
            model = np.zeros(4)
            sources["between_flights"] = ("0: the log declares its wrench exact (a "
                                          "simulation), the vehicle's measured model error "
                                          "is that of its real flights")
        return Calibration(thrust, yaw, arm, model, sources)
    if measured_thrust is not None:
        thrust, yaw = measured_thrust
        sources["thrust"] = "the thrust coefficient kf's standard error"
        sources["yaw_torque"] = "the yaw ratio's standard error"
    else:
        thrust = DEFAULT_COMMANDED_THRUST
        yaw = DEFAULT_YAW_TORQUE
        sources["thrust"] = f"default for a commanded thrust ({100 * thrust:g} %)"
        sources["yaw_torque"] = f"default for a commanded yaw torque ({100 * yaw:g} %)"
        if unc is not None and unc.commanded_thrust is not None:
            thrust = unc.commanded_thrust
            sources["thrust"] = f"{where} ([uncertainty] commanded_thrust)"
        if unc is not None and unc.commanded_yaw_torque is not None:
            yaw = unc.commanded_yaw_torque
            sources["yaw_torque"] = f"{where} ([uncertainty] commanded_yaw_torque)"
    arm = DEFAULT_ARM
    sources["arm"] = f"default ({100 * arm:g} %)"
    if unc is not None and unc.arm is not None:
        arm = unc.arm
        sources["arm"] = f"{where} ([uncertainty] arm)"
    return Calibration(thrust, yaw, arm, model, sources)


def error_budget(values: Array, statistical: Array, calibration: Calibration,
                 held_alternative: Array | None = None,
                 repair_rel: Array | None = None) -> ErrorBudget:
    """The budget of p = [m, I_xx, I_yy, I_zz] (``values`` (4,)) with its statistical
    standard errors (4,) (module docstring); held_alternative (4,): the estimate with a
    sampled input read as held, or None (the log's reading is not in doubt); repair_rel
    (4,) [-]: rotor speeds rebuilt from PWM add a ``rotor_speed_repair`` part p *
    repair_rel (the vehicle file's ``[faults] repair_rel_se``)."""
    p = np.abs(np.asarray(values, dtype=float))
    c = calibration
    zero = np.zeros(4)
    parts = {
        "statistical": np.asarray(statistical, dtype=float),
        "thrust_calibration": p * c.thrust,
        "yaw_torque_coefficient": np.array([0.0, 0.0, 0.0, p[3] * c.yaw_torque]),
        "arm_length": np.array([0.0, p[1] * c.arm, p[2] * c.arm, 0.0]),
        "input_reading": zero if held_alternative is None else 0.5 * np.abs(
            np.asarray(held_alternative, dtype=float) - np.asarray(values, dtype=float)),
        "between_flights": p * c.model_error,
    }
    if repair_rel is not None:
        parts["rotor_speed_repair"] = p * np.asarray(repair_rel, dtype=float)
    return ErrorBudget(parts, c)
