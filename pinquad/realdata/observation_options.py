"""How a measured log becomes EM observations (``realdata.observations``): the grid step,
the measurement channels, the fault handling, the mixer and the ground-contact and
glitch thresholds, by default the shipped crazyflie21 file's, for another vehicle its
file's (:func:`options_for_vehicle`), for a paper source name its channels
(:func:`options_for_sensor`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from pinquad.core.conventions import GRAVITY
from pinquad.core.vehicle_file import VehicleSpec
from pinquad.vehicle.actuators import (
    CRAZYFLIE_ARM,
    CRAZYFLIE_SPEC,
    SPIN_CRAZYFLIE,
    YAW_RATIO_CRAZYFLIE,
)

GRID_DT = 0.01
"""Resampled step [s]: 100 Hz."""

CRAZYFLIE_YAW_RATIO_SE = CRAZYFLIE_SPEC.actuators.yaw_ratio_se  # type: ignore[union-attr]
"""Standard error of the shipped crazyflie21 file's yaw torque ratio [m]."""
CRAZYFLIE_FAULTS = CRAZYFLIE_SPEC.faults
"""The shipped crazyflie21 file's ``[faults]``: flight_rpm, max_rpm, repair_rel_se."""
assert CRAZYFLIE_FAULTS.flight_rpm is not None and CRAZYFLIE_FAULTS.max_rpm is not None, \
    "pinquad/data/crazyflie21.toml: [faults] needs flight_rpm and max_rpm"


FAULT_MODES = ("repair", "repair-all", "exclude")
"""How implausible rotor readings are handled (``RealDataOptions.faults``)."""


@dataclass(frozen=True)
class RealDataOptions:
    """How a measured log becomes observations.

    dt [s]: grid step; channels: measurement blocks among ``pos`` (motion capture),
    ``vel`` (onboard estimate), ``euler`` (motion capture), ``gyro``; onboard_pos: take
    ``pos`` from the onboard estimate instead of the motion capture (source A);
    faults: ``repair`` (rebuild untrusted rotor speeds from PWM through a map learned on
    the diagonal partner, which spins the same way), ``repair-all`` (map learned on all
    trusted motors: ``faults.repair_log``), or ``exclude`` (skip flagged rows);
    kf [N/(rad/s)^2] or None for :func:`thrust_coefficient`; yaw_ratio [m] and its
    standard error yaw_ratio_se [m]; rotor_inertia [kg m^2]: J_r fixed at this value
    (0 included: no rotor inertia), its yaw torque J_r sum_i spin_i omega_i' added to
    the input, or None: not fixed (``identify_real`` fits it per flight when asked,
    else there is none); spin (n,) +-1; arm [m] and xy (n rotor (x, y) [m],
    None: the X layout of ``arm``): the mixer (``ActuatorModel``; defaults: the shipped
    crazyflie21 file, :func:`options_for_vehicle` for another);
    contact_height [m], contact_speed [m/s], flight_rpm [rev/min], contact_margin [s]:
    ground-contact detection (module docstring); outlier_m [m], outlier_rad [rad]:
    motion-capture glitch thresholds; max_rpm [rev/min]: a reading above is implausible
    (``faults.detect_actuation_faults``); repair_rel_se (4,) [1]: the uncertainty PWM
    repair adds to [m, I_xx, I_yy, I_zz] (``identify.total_standard_errors``). The
    defaults of these three are the shipped crazyflie21 file's ``[faults]``.
    ground_radius [m] or None: the ground-effect radius discovery evaluates
    (``Observations.ground_radius``); None: the mixer's rotor footprint, the largest
    centre-to-rotor distance (``VehicleSpec.ground_effect_radius``).
    """

    dt: float = GRID_DT
    channels: tuple[str, ...] = ("pos", "euler", "gyro")
    onboard_pos: bool = False
    faults: str = "repair"
    kf: float | None = None
    yaw_ratio: float = YAW_RATIO_CRAZYFLIE
    rotor_inertia: float | None = None
    spin: tuple[float, ...] = SPIN_CRAZYFLIE
    arm: float = CRAZYFLIE_ARM
    xy: tuple[tuple[float, float], ...] | None = None
    yaw_ratio_se: float = CRAZYFLIE_YAW_RATIO_SE
    contact_height: float = 0.03
    contact_speed: float = 0.2
    flight_rpm: float = CRAZYFLIE_FAULTS.flight_rpm  # type: ignore[assignment]
    contact_margin: float = 0.3
    outlier_m: float = 0.05
    outlier_rad: float = 0.2
    max_rpm: float = CRAZYFLIE_FAULTS.max_rpm  # type: ignore[assignment]
    repair_rel_se: tuple[float, ...] = CRAZYFLIE_FAULTS.repair_rel_se
    ground_radius: float | None = None

    def __post_init__(self) -> None:
        bad = [c for c in self.channels if c not in ("pos", "vel", "euler", "gyro")]
        if bad or not self.channels:
            raise ValueError(f"channels {self.channels}: expected some of pos, vel, euler, gyro")
        if self.faults not in FAULT_MODES:
            raise ValueError(f"faults {self.faults!r}: expected repair, repair-all or exclude")
        if not self.dt > 0:
            raise ValueError(f"dt must be positive; got {self.dt}")


def options_for_vehicle(spec: VehicleSpec, base: RealDataOptions | None = None
                        ) -> RealDataOptions:
    """Options whose mixer is a vehicle file's (rotor positions, spins, yaw ratio and its
    standard error, rotor inertia when the file fixes it) and whose fault thresholds are
    its ``[faults]``, else derived from it: flight_rpm half the hover speed of the
    reference (else body) mass, omega_h = sqrt(m g / (n kf)); max_rpm the speed of
    ``max_thrust``, sqrt(max_thrust / kf) (no limit without one); without
    ``repair_rel_se`` no PWM repair: implausible rows are excluded (the repair follows the
    rotor count: any n, with one PWM command per rotor). Raises ValueError if the file has
    no [actuators] table."""
    base = base or RealDataOptions()
    act = spec.actuators
    if act is None:
        raise ValueError(f"{spec.source}: no [actuators] table (kf, kf_se, yaw_ratio): rotor "
                         "speeds cannot be turned into thrust and torques")
    mass = spec.reference.mass if spec.reference.mass is not None else spec.mass
    rpm_per_rad_s = 60.0 / (2.0 * math.pi)
    hover = math.sqrt(mass * GRAVITY / (spec.n_rotors * act.kf)) * rpm_per_rad_s
    flt = spec.faults
    top = (flt.max_rpm if flt.max_rpm is not None else math.inf if act.max_thrust is None
           else math.sqrt(act.max_thrust / act.kf) * rpm_per_rad_s)
    repairable = bool(flt.repair_rel_se)
    return replace(base, yaw_ratio=act.yaw_ratio, yaw_ratio_se=act.yaw_ratio_se,
                   spin=tuple(float(v) for v in spec.spin), arm=spec.arm,
                   xy=tuple((float(x), float(y)) for x, y in spec.positions),
                   rotor_inertia=act.rotor_inertia if act.rotor_inertia is not None
                   else base.rotor_inertia,
                   flight_rpm=flt.flight_rpm if flt.flight_rpm is not None else 0.5 * hover,
                   max_rpm=top, repair_rel_se=flt.repair_rel_se,
                   faults=base.faults if repairable else "exclude",
                   ground_radius=spec.ground_effect_radius)


SENSOR_CHANNELS = {
    "A": (("pos", "vel", "gyro"), True),
    "B": (("pos", "vel", "euler", "gyro"), False),
    "C": (("pos", "vel", "gyro"), False),
}
"""--sensor on a measured log: B = everything, C = no attitude, A = the onboard
estimate's position and velocity with the gyro (the paper's sources)."""


def options_for_sensor(sensor: str | None, base: RealDataOptions | None = None
                       ) -> RealDataOptions:
    """Options for a paper source name (None: the default measured-log channels)."""
    base = base or RealDataOptions()
    if sensor is None:
        return base
    if sensor not in SENSOR_CHANNELS:
        raise ValueError(f"unknown sensor {sensor!r}; expected A, B or C")
    channels, onboard = SENSOR_CHANNELS[sensor]
    return replace(base, channels=channels, onboard_pos=onboard)
