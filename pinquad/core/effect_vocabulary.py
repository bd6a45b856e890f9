"""The effect vocabulary shared by the simulator and the estimator.

The simulator injects effects (``pinquad.sim.effects``) and discovery names and fits them
(``pinquad.discovery.library``); both speak through this module, so neither imports the
other: the names, each effect's coefficient names (the estimator's order, which scores
the injected coefficients of a simulated flight), the ground-effect law both evaluate,
and whose radius it takes. No vehicle's constant lives here: the ground-effect radius is
the vehicle's (``VehicleSpec.ground_effect_radius``, its rotor footprint unless its file
says otherwise), and the simulator's default drag is the shipped Crazyflie file's
``[aero]``, the vehicle the simulated effects are modelled on.

Forms (body frame: x forward, y left, z up; v_b = R^T v the body velocity [m/s]; F the
collective thrust [N]; all wrenches at the body origin; in ``ground_effect`` z is the
height above the floor: the simulators' z, whose floor is z = 0; a log's z less the
floor it shows, ``models.contact.floor_level``):

====================  ===========================================  ==========================
name                  extra body wrench / effect                   coefficients (units)
====================  ===========================================  ==========================
``drag``              f = -diag(D) v_b                             D (3,) [N s/m]
``ground_effect``     f_z = k_ge F (r / (4 max(z, r/2)))^2         k_ge [-], r [m] the vehicle's
``com_offset``        tau = (-c) x (F e3) = F [-c_y, c_x, 0]       c_x, c_y [m] (CoM)
``wind``              f = R^T [w_x, w_y, 0]                        w_x, w_y [N] (world)
``motor_lag``         tau_m du/dt = u_cmd - u  (all 4 channels)    tau_m [s]
``gyro_bias``         gyro = omega + b                             b (3,) [rad/s]
====================  ===========================================  ==========================
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.vehicle_file import SHIPPED, is_vehicle_file, load_vehicle

Array = NDArray[np.float64]

EFFECT_NAMES = ("drag", "ground_effect", "com_offset", "wind", "motor_lag", "gyro_bias")
"""The discovery vocabulary: every effect's name and coefficients."""

COEFFICIENT_NAMES: dict[str, tuple[str, ...]] = {
    "drag": ("D_x", "D_y", "D_z"),
    "ground_effect": ("k_ge",),
    "com_offset": ("c_x", "c_y"),
    "wind": ("w_x", "w_y"),
    "motor_lag": ("tau_m",),
    "gyro_bias": ("b_x", "b_y", "b_z"),
}
"""Effect name -> its coefficients' names, in the order of the estimator's coefficient
vector c and of the simulator factory's first argument: D [N s/m], k_ge [-], c [m],
w [N], tau_m [s], b [rad/s]."""

EFFECTS_VEHICLE = "crazyflie21"
"""The shipped vehicle whose aerodynamics the simulator's effects default to (its file's
``[aero]``; the discovery Monte Carlo flies it), and whose footprint a log that names no
vehicle is read with."""
_EFFECTS_AERO = load_vehicle(EFFECTS_VEHICLE).aero
if _EFFECTS_AERO.drag is None:
    raise ValueError(f"pinquad/data/{EFFECTS_VEHICLE}.toml: [aero] needs drag (the simulator's "
                     "default drag)")
SIMULATED_DRAG: tuple[float, float, float] = tuple(float(v) for v in _EFFECTS_AERO.drag)  # type: ignore[assignment]
"""The simulator's default linear rotor drag D (3,) [N s/m]: ``crazyflie21.toml``
``[aero] drag`` (Foerster's k_aero times the summed hover rotor speed)."""


def vehicle_ground_radius(vehicle: str | None) -> float:
    """Effective radius r [m] of the ground-effect law for a log's vehicle: a shipped
    name or a ``.toml`` vehicle file gives its ``VehicleSpec.ground_effect_radius`` (the
    rotor footprint unless the file says otherwise); None or a name pinquad does not know
    (a log that names no vehicle) gives ``EFFECTS_VEHICLE``'s, as before vehicle files.
    Raises VehicleFileError for an unreadable file."""
    known = vehicle is not None and (vehicle in SHIPPED or is_vehicle_file(vehicle))
    return load_vehicle(vehicle if known else EFFECTS_VEHICLE).ground_effect_radius  # type: ignore[arg-type]


DEFAULT_GROUND_RADIUS = vehicle_ground_radius(None)
"""r [m] of observations built without a vehicle (``models.ssm.Observations``'s
default): ``EFFECTS_VEHICLE``'s footprint."""


def ground_effect_gain(z: Array | float, radius: float) -> Array:
    """g(z) = (r / (4 max(z, r/2)))^2 [-], the relative thrust gain per unit k_ge at the
    height z [m] (first-order Cheeseman-Bennett law T/T_inf = 1 + (r/4z)^2, the height
    clipped at r/2); radius r [m]: the vehicle's (``vehicle_ground_radius``)."""
    zc = np.maximum(np.asarray(z, dtype=float), 0.5 * radius)
    return (radius / (4.0 * zc)) ** 2
