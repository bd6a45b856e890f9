"""What identifying a measured rotor-speed flight adds to its ``Identification``
(``Identification.measured``): the thrust coefficient it scales with, the kinds of standard
error, the nuisance moment, the model-free mass and its split by motor, and what was left
out. ``pinquad.realdata.identify.identify_real`` fills it; the verdicts, the report and the
between-flight table read it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.mstep.band import BandStats
from pinquad.vehicle.actuators import ThrustCoefficient

Array = NDArray[np.float64]


EXCLUSION_KINDS = ("contact", "attitude", "faulty rpm", "log gaps", "no actuation")
"""Why a measured flight's transitions are skipped: ground contact (with take-off and
landing), an attitude near the Euler angles' singularity, implausible rotor readings,
log gaps, bins with rows but no finite rotor speed."""


@dataclass(frozen=True)
class Exclusion:
    """One reason for skipping transitions: kind (one of ``EXCLUSION_KINDS``), reason
    (words), transitions (count; a transition may have several reasons) and detail (the
    log gaps in words for kind ``log gaps``, else empty)."""

    kind: str
    reason: str
    transitions: int
    detail: str = ""

    def __post_init__(self) -> None:
        if self.kind not in EXCLUSION_KINDS:
            raise ValueError(f"exclusion kind {self.kind!r}: expected one of "
                             f"{', '.join(EXCLUSION_KINDS)}")


@dataclass(frozen=True)
class MotorSplit:
    """``realdata.mass_balance.quasi_static_mass`` split by motor.

    share (n,) [-]: each of the n motors' part of the vertical thrust over the used
    transitions relative to the mean over the n motors, s_i = n sum_k F_k R_k,zz w_ik /
    sum_k F_k R_k,zz with w_ik = omega_ik^2 / sum_j omega_jk^2 (1 for all when they carry
    equal thrust);
    measured_mass [kg]:
    the part of m_qs the motors whose speeds were measured carry,
    m_meas = sum_k F_k R_k,zz sum_(i measured) w_ik / sum_k (g + a_z,k); rebuilt: the
    motors (0-based) whose speeds were rebuilt from PWM (in some or all rows);
    all_measured_mass [kg]: m_qs over only the transitions whose bin holds no reading
    from the PWM map (every motor measured, a pulse-divided channel multiplied back;
    NaN if there is none); all_measured_rows: their number.
    """

    share: Array
    measured_mass: float
    rebuilt: tuple[int, ...]
    all_measured_mass: float = float("nan")
    all_measured_rows: int = 0

    def mass_if(self, share: float) -> float:
        """The model-free mass [kg] if the rebuilt motors carried ``share`` each (of the
        mean over the n motors): m_meas / (1 - n_rebuilt share / n)."""
        return self.measured_mass / (1.0 - len(self.rebuilt) * share / self.share.size)

    def share_for(self, mass: float) -> float:
        """The share each rebuilt motor would carry if the mass were ``mass`` [kg]."""
        return self.share.size * (1.0 - self.measured_mass / mass) / max(len(self.rebuilt), 1)


@dataclass(frozen=True)
class MeasuredFit:
    """What identifying a measured rotor-speed flight adds to its ``Identification``
    (``Identification.measured``, as ``Identification.full`` holds what the ten-parameter
    fit adds).

    kf: the thrust coefficient; se_info (4,): standard errors of [m, I_xx, I_yy, I_zz]
    from the observed information (NaN if not computed or not positive definite);
    se_jack (4,): block-jackknife standard errors; se_stat (4,): the larger of the two
    (the statistical uncertainty with kf known; ``Identification.stderr`` combines it
    with kf's uncertainty, every estimate being proportional to kf, and for I_zz the yaw
    ratio's: ``realdata.identify.total_standard_errors``); moment_coef (3, 7): the
    nuisance moment (``TORQUE_FEATURES``); n_used / n_excluded transitions; excluded: exclusion notes;
    band: the torque band [Hz]; rotor_inertia: J_r [kg m^2] used (fitted or fixed; NaN:
    none); band_stats: the band-passed regression at the final posterior
    (``identify_real``'s ``keep_band_stats``); quasi_static_mass [kg]: the model-free check
    ``realdata.mass_balance.quasi_static_mass`` on the same transitions; motor_split: that
    check split by motor (``realdata.mass_balance.motor_split``); yaw_rel [-]: the yaw
    ratio's relative uncertainty and repair_rel (4,) [-] or None: the PWM repair's, both
    inside ``Identification.stderr``;
    exclusions: why transitions were skipped, each with its count (``excluded`` says the
    same in words, with the total).
    """

    kf: ThrustCoefficient
    se_info: Array
    se_jack: Array
    se_stat: Array
    moment_coef: Array
    n_used: int
    n_excluded: int
    excluded: tuple[str, ...]
    band: tuple[float, float] = (3.0, 8.0)
    rotor_inertia: float = float("nan")
    band_stats: BandStats | None = None
    quasi_static_mass: float = float("nan")
    motor_split: MotorSplit | None = None
    yaw_rel: float = 0.0
    repair_rel: Array | None = None
    exclusions: tuple[Exclusion, ...] = ()
