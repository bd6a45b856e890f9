"""A vehicle described by a TOML file (docs/vehicles.md): the rigid body, where EM starts, the
rotors and their constants, and what the vehicle is known to be independently of flight.

The file is read with the standard library's ``tomllib`` into one frozen
:class:`VehicleSpec`. It lives in ``core`` (not ``vehicle``) because the two vehicles
pinquad ships (``pinquad/data/paper.toml``, ``pinquad/data/crazyflie21.toml``) are such
files and ``core.params.VEHICLES`` is built from them. Units are SI throughout (kg, m,
kg m^2, N, rad/s); rotor speeds in the log are rev/min. The format, key by key, is in
``docs/vehicles.md``. Any mistake raises :class:`VehicleFileError` naming the file, the
key and what was expected.

Rotor geometry: either ``[[rotor]]`` tables (``x``, ``y`` [m, body: x forward, y left],
``spin`` = +-1, the sign of the rotor's yaw reaction torque about body z), listed in the
order the log numbers them (``rpm_1`` = first rotor), or ``[geometry]`` with ``arm``
[m], ``layout`` (``x`` or ``+``) and ``spin``: the rotors are then numbered clockwise
seen from above, starting front-right (``x``: (+h, -h), (-h, -h), (-h, +h), (+h, +h),
h = arm / sqrt 2, the Bitcraze M1..M4) or front (``+``: (a, 0), (0, -a), (-a, 0), (0, a)).
"""

from __future__ import annotations

import math
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

SHIPPED = ("paper", "crazyflie21")
"""The vehicles whose files ship as package data (``pinquad/data/<name>.toml``)."""


class VehicleFileError(ValueError):
    """A vehicle file that cannot be read or says something impossible (file, key,
    expected value in the message)."""


@dataclass(frozen=True)
class Reference:
    """What the vehicle is known to be without flight data, for comparison.

    mass [kg] (e.g. on a scale) or None; inertia (3,) [kg m^2] diagonal or None;
    mass_note / inertia_note: how each is known, in words; mass_rel_se / inertia_rel_se
    [-]: their relative standard uncertainty, or None (not stated: the values are shown
    beside an estimate but do not judge it).
    """

    mass: float | None = None
    inertia: Array | None = None
    mass_note: str = ""
    inertia_note: str = ""
    mass_rel_se: float | None = None
    inertia_rel_se: float | None = None


@dataclass(frozen=True)
class Actuators:
    """Rotor constants.

    kf [N/(rad/s)^2]: T_i = kf omega_i^2; kf_se [N/(rad/s)^2]: its standard error;
    thrust_stand: a CSV file or a directory of them to fit kf from instead (absolute,
    resolved against the vehicle file's folder), or None; yaw_ratio [m]: yaw torque per
    unit thrust, tau_z = sum_i spin_i yaw_ratio T_i; yaw_ratio_se [m];
    rotor_inertia [kg m^2] of one rotor about its axis, fixed at this value (0 included:
    no rotor inertia), or None when the file leaves it out (fitted per flight);
    max_thrust [N] per rotor, or None (not checked); pwm_to_rpm: polynomial coefficients,
    highest power first, rpm = polyval(c, pwm [0..1]), or empty; battery: the file's
    battery model (``voltage`` [V], ``capacity`` [mAh], ...), kept as given.
    """

    kf: float
    kf_se: float
    yaw_ratio: float
    yaw_ratio_se: float
    thrust_stand: Path | None = None
    rotor_inertia: float | None = None
    max_thrust: float | None = None
    pwm_to_rpm: tuple[float, ...] = ()
    battery: tuple[tuple[str, float], ...] = ()

    @property
    def kf_rel_se(self) -> float:
        """kf_se / kf [1]."""
        return self.kf_se / self.kf


@dataclass(frozen=True)
class FaultSettings:
    """How the measured-flight pipeline judges this vehicle's rotor readings (the file's
    optional ``[faults]`` table; ``realdata.faults``).

    flight_rpm [rev/min]: rotors at flight speed from here (None: half the hover speed,
    a quarter of the hover thrust); max_rpm [rev/min]: a reading above is beyond the
    motor's reach (None: the speed of ``max_thrust``, unchecked without one);
    repair_rel_se (4,) [1]: relative uncertainty of [m, I_xx, I_yy, I_zz] added when
    rotor speeds are rebuilt from PWM, as measured for this vehicle (empty: no PWM
    repair, implausible rows are excluded instead).
    """

    flight_rpm: float | None = None
    max_rpm: float | None = None
    repair_rel_se: tuple[float, ...] = ()


@dataclass(frozen=True)
class Aero:
    """What the effect vocabulary (``core.effect_vocabulary``) uses of this vehicle (the
    file's optional ``[aero]`` table).

    drag (3,) [N s/m] or None: linear rotor-drag coefficients D of f_b = -diag(D) v_b
    near hover; rotor_radius [m] or None: the propeller's; ground_effect_radius [m] or
    None: the effective radius r of the ground-effect law (None: the rotor footprint,
    ``VehicleSpec.ground_effect_radius``).
    """

    drag: Array | None = None
    rotor_radius: float | None = None
    ground_effect_radius: float | None = None


@dataclass(frozen=True)
class Uncertainty:
    """What the file says of the uncertainty of what a flight of this vehicle assumes (the
    optional ``[uncertainty]`` table), each a relative standard uncertainty [-] or None
    (not stated: pinquad's default, ``identification.budget``).

    arm: of the arm length that turns rotor thrust differences into roll and pitch
    torque; commanded_thrust / commanded_yaw_torque: of a log's commanded thrust and yaw
    torque (what the vehicle's controller believes it asks for) against what acts;
    model_error (4,) or empty: of [m, I_xx, I_yy, I_zz] between flights of this vehicle
    beyond their own errors (the model's error that one flight cannot see), as measured
    over several flights (``python -m pinquad.realdata`` prints it).
    """

    arm: float | None = None
    commanded_thrust: float | None = None
    commanded_yaw_torque: float | None = None
    model_error: tuple[float, ...] = ()


@dataclass(frozen=True)
class VehicleSpec:
    """A vehicle file, read.

    name; source: the file; mass [kg] and inertia (3, 3) [kg m^2]: the nominal rigid
    body (what a simulation of this vehicle flies); urdf: a URDF path given instead of
    or beside them, or None; guess_mass [kg], guess_inertia (3, 3) [kg m^2]: where EM
    starts, with guess_note in words; positions (n, 2) [m]: rotor (x, y) in the body
    frame, in log order; spin (n,): +-1 yaw-torque sign per rotor; arm [m]: the largest
    centre-to-rotor distance; layout: ``x``, ``+`` or ``custom``; actuators;
    reference; description; faults: the ``[faults]`` table; aero: the ``[aero]`` table.
    """

    name: str
    source: Path
    mass: float
    inertia: Array
    guess_mass: float
    guess_inertia: Array
    guess_note: str
    positions: Array
    spin: Array
    arm: float
    layout: str
    actuators: Actuators | None
    reference: Reference
    urdf: Path | None = None
    description: str = ""
    faults: FaultSettings = FaultSettings()
    aero: Aero = Aero()
    uncertainty: Uncertainty = Uncertainty()

    @property
    def ground_effect_radius(self) -> float:
        """Effective radius r [m] of the ground-effect law (``core.effect_vocabulary``):
        ``[aero] ground_effect_radius`` if the file gives it, else the rotor footprint,
        the largest centre-to-rotor distance (``arm``): the rotors together, not one
        propeller, make the cushion a multirotor feels."""
        r = self.aero.ground_effect_radius
        return self.arm if r is None else r

    @property
    def n_rotors(self) -> int:
        """Number of rotors."""
        return int(self.positions.shape[0])

    def max_total_thrust(self) -> float | None:
        """Sum of the rotors' maximum thrust [N], or None when the file gives none."""
        if self.actuators is None or self.actuators.max_thrust is None:
            return None
        return self.n_rotors * self.actuators.max_thrust


class _Reader:
    """Typed access to a parsed TOML table with located errors."""

    def __init__(self, path: Path, data: dict[str, Any]) -> None:
        self.path = path
        self.data = data

    def fail(self, key: str, expected: str, got: object) -> VehicleFileError:
        return VehicleFileError(f"{self.path}: key '{key}': expected {expected}; got {got!r}")

    def table(self, key: str, required: bool = False) -> dict[str, Any]:
        val = self.data.get(key)
        if val is None:
            if required:
                raise VehicleFileError(f"{self.path}: missing table [{key}]")
            return {}
        if not isinstance(val, dict):
            raise self.fail(key, "a table", val)
        return val

    def number(self, table: dict[str, Any], prefix: str, key: str, *, positive: bool = True,
               required: bool = True, unit: str = "") -> float | None:
        full = f"{prefix}.{key}" if prefix else key
        if key not in table:
            if required:
                raise VehicleFileError(f"{self.path}: missing key '{full}' "
                                       f"(a {'positive ' if positive else ''}number{unit})")
            return None
        val = table[key]
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) \
                or (positive and not val > 0):
            raise self.fail(full, f"a {'positive ' if positive else ''}number{unit}", val)
        return float(val)

    def inertia(self, table: dict[str, Any], prefix: str, key: str,
                required: bool = True) -> Array | None:
        full = f"{prefix}.{key}"
        if key not in table:
            if required:
                raise VehicleFileError(f"{self.path}: missing key '{full}' "
                                       "([Ixx, Iyy, Izz] in kg m^2)")
            return None
        val = table[key]
        ok = isinstance(val, list) and len(val) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 for v in val)
        if not ok:
            raise self.fail(full, "[Ixx, Iyy, Izz], three positive numbers in kg m^2", val)
        return np.asarray(val, dtype=float)

    def text(self, table: dict[str, Any], prefix: str, key: str, default: str = "") -> str:
        val = table.get(key, default)
        if not isinstance(val, str):
            raise self.fail(f"{prefix}.{key}" if prefix else key, "a string", val)
        return val

    def resolve(self, raw: str) -> Path:
        p = Path(raw).expanduser()
        return p if p.is_absolute() else (self.path.parent / p).resolve()


def layout_positions(arm: float, layout: str, n: int = 4) -> Array:
    """(n, 2) rotor (x, y) [m] of a symmetric layout (module docstring): ``x`` starts
    front-right, ``+`` starts front, both clockwise seen from above (body z up)."""
    start = -math.pi / n if layout == "x" else 0.0
    ang = start - 2.0 * math.pi * np.arange(n) / n
    return np.column_stack([arm * np.cos(ang), arm * np.sin(ang)])


def _rotors(r: _Reader) -> tuple[Array, Array, float, str]:
    rotors = r.data.get("rotor")
    geom = r.table("geometry")
    if rotors is not None:
        if not isinstance(rotors, list) or len(rotors) < 3:
            raise r.fail("rotor", "at least three [[rotor]] tables", rotors)
        pos, spin = [], []
        for i, rot in enumerate(rotors):
            pre = f"rotor[{i + 1}]"
            pos.append([r.number(rot, pre, "x", positive=False, unit=" [m]"),
                        r.number(rot, pre, "y", positive=False, unit=" [m]")])
            s = rot.get("spin")
            if s not in (1, -1) or isinstance(s, bool):
                raise r.fail(f"{pre}.spin", "+1 or -1 (sign of the yaw reaction torque)", s)
            spin.append(float(s))
        positions = np.asarray(pos, dtype=float)
        arm = float(np.max(np.hypot(positions[:, 0], positions[:, 1])))
        if not arm > 0:
            raise r.fail("rotor", "rotors away from the centre", pos)
        return positions, np.asarray(spin), arm, "custom"
    if not geom:
        raise VehicleFileError(f"{r.path}: give the rotors, either [geometry] with arm, layout "
                               "and spin, or [[rotor]] tables with x, y and spin")
    arm = r.number(geom, "geometry", "arm", unit=" [m]")
    layout = r.text(geom, "geometry", "layout", "x")
    if layout not in ("x", "+"):
        raise r.fail("geometry.layout", "'x' or '+'", layout)
    spin = geom.get("spin")
    if not isinstance(spin, list) or len(spin) < 3 or any(
            s not in (1, -1) or isinstance(s, bool) for s in spin):
        raise r.fail("geometry.spin", "a list of +1/-1, one per rotor in log order", spin)
    assert arm is not None
    return layout_positions(arm, layout, len(spin)), np.asarray(spin, float), arm, layout


def _actuators(r: _Reader) -> Actuators | None:
    act = r.table("actuators")
    if not act:
        return None
    kf = r.number(act, "actuators", "kf", unit=" [N/(rad/s)^2]")
    kf_se = r.number(act, "actuators", "kf_se", unit=" [N/(rad/s)^2]")
    yaw = r.number(act, "actuators", "yaw_ratio", unit=" [m]")
    yaw_se = r.number(act, "actuators", "yaw_ratio_se", unit=" [m]", required=False)
    assert kf is not None and kf_se is not None and yaw is not None
    if kf > 1e-3 or kf < 1e-12:
        raise r.fail("actuators.kf", "a thrust coefficient in N/(rad/s)^2 (1e-12..1e-3; "
                     "rev/min or krpm units?)", kf)
    stand = act.get("thrust_stand")
    if stand is not None and not isinstance(stand, str):
        raise r.fail("actuators.thrust_stand", "a path (CSV file or folder of CSVs)", stand)
    pwm = act.get("pwm_to_rpm", [])
    if not isinstance(pwm, list) or any(not isinstance(c, (int, float)) for c in pwm):
        raise r.fail("actuators.pwm_to_rpm", "a list of polynomial coefficients", pwm)
    battery = r.table("battery")
    for k, v in battery.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise r.fail(f"battery.{k}", "a number", v)
    return Actuators(
        kf=kf, kf_se=kf_se, yaw_ratio=yaw, yaw_ratio_se=yaw_se if yaw_se is not None else 0.0,
        thrust_stand=r.resolve(stand) if stand else None,
        rotor_inertia=_rotor_inertia(r, act),
        max_thrust=r.number(act, "actuators", "max_thrust", unit=" [N] per rotor",
                            required=False),
        pwm_to_rpm=tuple(float(c) for c in pwm),
        battery=tuple((str(k), float(v)) for k, v in battery.items()))


def _rotor_inertia(r: _Reader, act: dict[str, Any]) -> float | None:
    """``[actuators] rotor_inertia`` [kg m^2]: None when the key is absent (J_r is fitted
    per flight), else the value J_r is fixed at, 0 included (a vehicle without rotor
    inertia, e.g. the simulated world's)."""
    val = r.number(act, "actuators", "rotor_inertia", positive=False, required=False,
                   unit=" [kg m^2]")
    if val is not None and val < 0:
        raise r.fail("actuators.rotor_inertia", "a number >= 0 [kg m^2] (0: no rotor inertia; "
                     "leave the key out to fit J_r per flight)", val)
    return val


def _faults(r: _Reader) -> FaultSettings:
    tab = r.table("faults")
    rel = tab.get("repair_rel_se", [])
    if not isinstance(rel, list) or (rel and len(rel) != 4) or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0 for v in rel):
        raise r.fail("faults.repair_rel_se", "[m, Ixx, Iyy, Izz]: four relative standard "
                     "errors >= 0", rel)
    return FaultSettings(
        flight_rpm=r.number(tab, "faults", "flight_rpm", unit=" [rev/min]", required=False),
        max_rpm=r.number(tab, "faults", "max_rpm", unit=" [rev/min]", required=False),
        repair_rel_se=tuple(float(v) for v in rel))


def _aero(r: _Reader) -> Aero:
    tab = r.table("aero")
    drag = tab.get("drag")
    if drag is not None and (not isinstance(drag, list) or len(drag) != 3 or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0 for v in drag)):
        raise r.fail("aero.drag", "[D_x, D_y, D_z], three numbers >= 0 in N s/m", drag)
    return Aero(
        drag=None if drag is None else np.asarray(drag, dtype=float),
        rotor_radius=r.number(tab, "aero", "rotor_radius", unit=" [m]", required=False),
        ground_effect_radius=r.number(tab, "aero", "ground_effect_radius", unit=" [m]",
                                      required=False))


def _uncertainty(r: _Reader) -> Uncertainty:
    table = r.table("uncertainty")
    rel = " [-], a relative standard uncertainty"
    values = {k: r.number(table, "uncertainty", k, required=False, positive=False, unit=rel)
              for k in ("arm", "commanded_thrust", "commanded_yaw_torque")}
    for k, v in values.items():
        if v is not None and not 0.0 <= v < 1.0:
            raise r.fail(f"uncertainty.{k}", "a relative uncertainty in [0, 1)", v)
    model = table.get("model_error", [])
    if not (isinstance(model, list) and len(model) in (0, 4) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 <= v < 1.0
            for v in model)):
        raise r.fail("uncertainty.model_error", "[m, Ixx, Iyy, Izz], four relative "
                     "uncertainties in [0, 1)", model)
    return Uncertainty(model_error=tuple(float(v) for v in model), **values)


def parse_vehicle(text: str, path: Path) -> VehicleSpec:
    """A :class:`VehicleSpec` from TOML ``text`` (``path`` names it in errors and anchors
    relative paths). Raises VehicleFileError."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise VehicleFileError(f"{path}: not valid TOML ({exc})") from None
    r = _Reader(path, data)
    name = r.text(data, "", "name")
    if not name:
        raise VehicleFileError(f"{path}: missing key 'name' (a string)")
    body = r.table("body", required=True)
    urdf_raw = body.get("urdf")
    if urdf_raw is not None and not isinstance(urdf_raw, str):
        raise r.fail("body.urdf", "a path to a URDF file", urdf_raw)
    urdf = r.resolve(urdf_raw) if urdf_raw else None
    mass = r.number(body, "body", "mass", unit=" [kg]", required=urdf is None)
    inertia = r.inertia(body, "body", "inertia", required=urdf is None)
    if urdf is not None and (mass is None or inertia is None):
        mass_u, inertia_u = _urdf_inertial(urdf, path)
        mass = mass if mass is not None else mass_u
        inertia = inertia if inertia is not None else inertia_u
    assert mass is not None and inertia is not None
    if mass > 100.0:
        raise r.fail("body.mass", "a mass in kg (grams given?)", mass)
    guess = r.table("guess")
    g_mass = r.number(guess, "guess", "mass", unit=" [kg]", required=False)
    g_inertia = r.inertia(guess, "guess", "inertia", required=False)
    g_note = r.text(guess, "guess", "note",
                    "" if guess else "the body's mass and inertia (no [guess] table)")
    positions, spin, arm, layout = _rotors(r)
    if abs(spin.sum()) > 0 and positions.shape[0] % 2 == 0:
        raise r.fail("spin", "as many +1 as -1 (rotors cancel in yaw at rest)", spin.tolist())
    ref = r.table("reference")
    return VehicleSpec(
        name=name, source=path, mass=mass, inertia=np.diag(inertia),
        guess_mass=g_mass if g_mass is not None else mass,
        guess_inertia=np.diag(g_inertia if g_inertia is not None else inertia),
        guess_note=g_note, positions=positions, spin=spin, arm=arm, layout=layout,
        actuators=_actuators(r),
        reference=Reference(
            mass=r.number(ref, "reference", "mass", unit=" [kg]", required=False),
            inertia=r.inertia(ref, "reference", "inertia", required=False),
            mass_note=r.text(ref, "reference", "mass_note"),
            inertia_note=r.text(ref, "reference", "inertia_note"),
            mass_rel_se=r.number(ref, "reference", "mass_rel_se", required=False,
                                 unit=" (relative uncertainty)"),
            inertia_rel_se=r.number(ref, "reference", "inertia_rel_se", required=False,
                                    unit=" (relative uncertainty)")),
        urdf=urdf, description=r.text(data, "", "description"), faults=_faults(r),
        aero=_aero(r), uncertainty=_uncertainty(r))


def _urdf_inertial(urdf: Path, path: Path) -> tuple[float, Array]:
    """(mass [kg], (3,) inertia diagonal [kg m^2]) of a URDF's first link (read with
    the standard library: no Pinocchio in ``core``)."""
    try:
        root = ET.parse(urdf).getroot()
        inertial = root.find("./link/inertial")
        assert inertial is not None
        mass = float(inertial.find("mass").attrib["value"])  # type: ignore[union-attr]
        ine = inertial.find("inertia").attrib  # type: ignore[union-attr]
        return mass, np.array([float(ine["ixx"]), float(ine["iyy"]), float(ine["izz"])])
    except (OSError, ET.ParseError, AssertionError, AttributeError, KeyError, ValueError):
        raise VehicleFileError(f"{path}: key 'body.urdf': {urdf} is not a readable URDF with "
                               "a link's <inertial> mass and inertia") from None


def read_vehicle_file(path: str | Path) -> VehicleSpec:
    """Read a vehicle file. Raises VehicleFileError (unreadable, bad TOML, bad key)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise VehicleFileError(f"{path}: cannot read the vehicle file ({exc})") from None
    return parse_vehicle(text, path)


def shipped_path(name: str) -> Path:
    """Path of a shipped vehicle file ``pinquad/data/<name>.toml``."""
    return Path(str(resources.files("pinquad") / "data" / f"{name}.toml"))


@lru_cache(maxsize=16)
def load_vehicle(name_or_path: str) -> VehicleSpec:
    """A shipped vehicle by name (``paper``, ``crazyflie21``) or a vehicle file by path.
    Raises VehicleFileError."""
    if name_or_path in SHIPPED:
        return read_vehicle_file(shipped_path(name_or_path))
    if not name_or_path.endswith(".toml"):
        raise VehicleFileError(f"vehicle {name_or_path!r}: expected one of "
                               f"{', '.join(SHIPPED)} or a path to a .toml vehicle file")
    return read_vehicle_file(Path(name_or_path).expanduser().resolve())


def is_vehicle_file(name: str) -> bool:
    """Whether a vehicle name is a path to a vehicle file (ends in ``.toml``)."""
    return name.endswith(".toml")
