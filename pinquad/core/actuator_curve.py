"""A vehicle's actuator curve: what a motor command does (docs/px4.md).

Thrust of rotor i [N] from its normalized command u_i in [0, 1] after a first-order motor
lag of time constant tau [s]:

    tau du'_i/dt = u_i - u'_i,     T_i = sum_{p=1..P} c_p u'_i^p

(``thrust`` = (c_1, ..., c_P) [N], lowest power first; no constant term: no command, no
thrust), and the yaw reaction torque tau_z = sum_i spin_i k_yaw T_i [N m] with
``yaw_ratio`` k_yaw [m]. The raw command r (PWM [us], or a normalized output) maps to
u = (r - lo) / (hi - lo) with ``command_range`` = (lo, hi).

In a vehicle file (TOML, docs/vehicles.md) these are the optional ``[actuator_curve]``
table's keys ``command_range``, ``thrust``, ``time_constant``, ``yaw_ratio`` and
``yaw_ratio_se`` (without them, the ``[actuators]`` table's ``yaw_ratio`` and
``yaw_ratio_se``); the
rotors are the file's ``[[rotor]]`` tables (x, y [m, body], spin). Any of the curve's
numbers may be left out: known-mass identification estimates the thrust polynomial and
the time constant (a given time constant is used as given; a given polynomial is kept
but not used by it).
:func:`toml_from_ddd_yaml` writes such a file from a PX4 data-driven-dynamics model
configuration (YAML, FRD body frame).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

from pinquad.core.conventions import NED_FRD_FLIP
from pinquad.core.vehicle_file import (
    SHIPPED,
    VehicleFileError,
    VehicleSpec,
    parse_vehicle,
    shipped_path,
)

Array = NDArray[np.float64]

PWM_RANGE = (1000.0, 2000.0)
"""PX4's default PWM range [us]: the command_range a file that says none gets."""


@dataclass(frozen=True)
class ActuatorCurve:
    """The ``[actuator_curve]`` table, read (module docstring).

    command_range (lo, hi): raw command of u = 0 and u = 1; thrust (P,) [N] or None: the
    polynomial's coefficients c_1..c_P (kept with the vehicle; known-mass identification
    fits its own); time_constant [s] or
    None; yaw_ratio [m] or None (I_zz cannot be identified without it); yaw_ratio_se [m]
    or None: its standard uncertainty (None: pinquad's default share,
    ``identification.budget``).
    """

    command_range: tuple[float, float] = PWM_RANGE
    thrust: Array | None = None
    time_constant: float | None = None
    yaw_ratio: float | None = None
    yaw_ratio_se: float | None = None


@dataclass(frozen=True)
class CurveVehicle:
    """A vehicle file with its actuator curve: spec (rotor positions (n, 2) [m, body],
    spin (n,), mass [kg], reference values) and curve."""

    spec: VehicleSpec
    curve: ActuatorCurve


def _number(path: Path, table: dict, key: str, positive: bool = True) -> float | None:
    value = table.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (
            positive and not value > 0):
        raise VehicleFileError(f"{path}: key 'actuator_curve.{key}' is {value!r}; expected "
                               f"a {'positive ' if positive else ''}number")
    return float(value)


def parse_curve(text: str, path: Path) -> CurveVehicle:
    """A :class:`CurveVehicle` from vehicle-file TOML ``text``. Raises VehicleFileError
    naming ``path`` and the key."""
    spec = parse_vehicle(text, path)
    table = tomllib.loads(text).get("actuator_curve", {})
    if not isinstance(table, dict):
        raise VehicleFileError(f"{path}: 'actuator_curve' is not a table")
    rng = table.get("command_range", list(PWM_RANGE))
    if not (isinstance(rng, list) and len(rng) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in rng)
            and rng[1] > rng[0]):
        raise VehicleFileError(f"{path}: key 'actuator_curve.command_range' is {rng!r}; "
                               "expected [lo, hi], the raw commands of 0 and full thrust")
    thrust = table.get("thrust")
    if thrust is not None and not (isinstance(thrust, list) and thrust and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in thrust)):
        raise VehicleFileError(f"{path}: key 'actuator_curve.thrust' is {thrust!r}; expected "
                               "[c1, c2, ...] [N], T = c1 u + c2 u^2 + ...")
    yaw_ratio = _number(path, table, "yaw_ratio")
    yaw_ratio_se = _number(path, table, "yaw_ratio_se")
    if yaw_ratio is None and spec.actuators is not None:
        # the file's rotor constants carry the same yaw torque per thrust
        yaw_ratio, yaw_ratio_se = spec.actuators.yaw_ratio, spec.actuators.yaw_ratio_se
    return CurveVehicle(spec, ActuatorCurve(
        command_range=(float(rng[0]), float(rng[1])),
        thrust=None if thrust is None else np.asarray(thrust, dtype=float),
        time_constant=_number(path, table, "time_constant"),
        yaw_ratio=yaw_ratio, yaw_ratio_se=yaw_ratio_se))


class _DddLoader(yaml.SafeLoader):
    """A safe YAML loader that reads the ``!!python/tuple`` tag of data-driven-dynamics'
    parameter bounds as a list (nothing else beyond safe YAML)."""


_DddLoader.add_constructor("tag:yaml.org,2002:python/tuple",
                           lambda loader, node: loader.construct_sequence(node))


def toml_from_ddd_yaml(text: str, path: Path) -> str:
    """A vehicle file (TOML text) from a data-driven-dynamics model configuration:
    mass, inertia diagonal, and each ``vertical_`` rotor's position (FRD -> body:
    (x, -y)) and spin = turning_direction: data-driven-dynamics writes a rotor's drag
    moment about FRD z (down) as -turning_direction c u^2 with c >= 0, i.e.
    +turning_direction c u^2 about body z (up), which is what ``spin`` signs. Raises
    VehicleFileError naming the file and the key."""
    try:
        raw = yaml.load(text, Loader=_DddLoader)  # noqa: S506 - a safe loader subclass
        cfg = raw["model_config"]
        mass = float(cfg["mass"])
        moi = cfg["moment_of_inertia"]
        inertia = [float(moi[k]) for k in ("Ixx", "Iyy", "Izz")]
        rotors = []
        for group in cfg["actuators"]["rotors"].values():
            for entry in group:
                name = next(k for k in entry if k.startswith("rotor_"))
                body = np.asarray(entry["position"], dtype=float) * NED_FRD_FLIP
                axis = np.asarray(entry["rotor_axis"], dtype=float)
                if not np.allclose(axis, [0.0, 0.0, -1.0]):
                    raise VehicleFileError(f"{path}: {name}: rotor_axis {axis.tolist()}; "
                                           "expected [0, 0, -1] (thrust along body up)")
                rotors.append((entry.get("dataframe_name", name), body,
                               int(entry["turning_direction"])))
    except (yaml.YAMLError, KeyError, TypeError, ValueError, StopIteration) as exc:
        raise VehicleFileError(f"{path}: not a data-driven-dynamics model configuration "
                               f"({type(exc).__name__}: {exc}); expected model_config with "
                               "mass, moment_of_inertia and actuators.rotors") from None
    rotors.sort(key=lambda r: r[0])
    name = str(raw.get("model_name", path.stem)).replace('"', "'")
    lines = [f"# Converted from {path.name} (PX4 data-driven-dynamics model configuration):",
             "# rotor positions FRD -> body (x, -y), spin = turning_direction.",
             f'name = "{path.stem}"', f'description = "{name}"', "", "[body]",
             f"mass = {mass!r}", f"inertia = [{', '.join(repr(v) for v in inertia)}]", "",
             "[reference]", f"mass = {mass!r}",
             f"inertia = [{', '.join(repr(v) for v in inertia)}]",
             f'mass_note = "{path.name}"', f'inertia_note = "{path.name}"', "",
             "[actuator_curve]",
             f"command_range = [{PWM_RANGE[0]!r}, {PWM_RANGE[1]!r}]   # PWM [us] of 0 and 1"]
    for column, pos, spin in rotors:
        lines += ["", f"[[rotor]]   # {column}", f"x = {float(pos[0])!r}",
                  f"y = {float(pos[1])!r}", f"spin = {spin}"]
    return "\n".join(lines) + "\n"


def read_curve_vehicle(path: str | Path) -> CurveVehicle:
    """A vehicle file (``.toml``), a shipped vehicle's name (``crazyflie21``) or a
    data-driven-dynamics configuration (``.yaml``, converted by
    :func:`toml_from_ddd_yaml`) with its actuator curve. Raises VehicleFileError."""
    if str(path) in SHIPPED:
        path = shipped_path(str(path))
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise VehicleFileError(f"{path}: cannot read the vehicle file ({exc})") from None
    if path.suffix.lower() in (".yaml", ".yml"):
        text = toml_from_ddd_yaml(text, path)
    return parse_curve(text, path)
