"""Attitudes the E-step's Euler-angle state cannot follow: the measured pitch near +-90 deg.

pinquad's state carries the attitude as roll, pitch, yaw (``core.conventions``), whose
rates are E(phi, theta)^-1 omega with entries up to 1 / cos(theta). Near theta = +-90 deg
roll and yaw turn by radians while the body turns by little, and the EKF, linearised at
its own estimate, loses the attitude: on flightgen's 500 Hz floor-strike flight 7016 the
vehicle pitched to 68 deg and rolled over within 0.1 s, the smoother came out of it in
the other Euler branch, and its backward pass carried the error 11 s back to the
take-off: a smoothed roll 0.07-0.24 rad off the measured one, body rates 20 mrad/s off
the gyro, and discovery named a gyro offset that is not in the flight.

Such an excursion is treated as floor contact is (``sources.observations``): every
transition touching a row within ``margin`` seconds of a measured pitch beyond
``limit`` is a reset for the E-step (``ssm.RESET_VAR``: the states on either side
follow their own data, the attitude snaps to the next measurement) and is excluded from
the M-step; the report says how many and why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pinquad.models.contact import touching_transitions

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

PITCH_LIMIT = float(np.radians(60.0))
"""[rad] beyond it 1 / cos(theta) > 2: the Euler rates more than double the body rates."""

MARGIN_SECONDS = 0.05
"""[s] rows this close to a measured pitch beyond the limit go with it (five 100 Hz
motion-capture intervals: the excursion's entry and exit are between samples)."""


@dataclass(frozen=True)
class SingularAttitude:
    """The rows of a log whose attitude the Euler-angle state cannot follow.

    rows (N,) bool: within ``margin`` [s] of a measured |pitch| > ``limit`` [rad];
    max_pitch [rad]: the largest measured |pitch| (NaN without attitude)."""

    rows: BoolArray
    limit: float
    margin: float
    max_pitch: float

    def touching(self) -> BoolArray:
        """(N,) bool: transition k -> k+1 touches such a row at either end (the last
        entry, no transition, False)."""
        out = np.zeros(self.rows.size, dtype=bool)
        out[:-1] = touching_transitions(self.rows)
        return out

    def transitions(self) -> int:
        """Transitions k -> k+1 touching such a row at either end."""
        return int(self.touching().sum())

    def report_lines(self) -> tuple[str, ...]:
        """The report's exclusion line, none when no row is near the singularity."""
        return (f"{self.transitions()} transitions: {self.describe()}",) if self.rows.any() else ()

    def describe(self) -> str:
        """The report's exclusion line (without the count)."""
        return (f"the measured pitch beyond +-{np.degrees(self.limit):.0f} deg (at most "
                f"{np.degrees(self.max_pitch):.0f} deg; and {1e3 * self.margin:.0f} ms either "
                "side), where the Euler-angle state cannot follow the attitude: resets, "
                "excluded from the M-step")


def near_euler_singularity(t: Array, euler: Array, limit: float = PITCH_LIMIT,
                           margin: float = MARGIN_SECONDS) -> SingularAttitude:
    """The rows of a log (times t (N,) [s], measured roll, pitch, yaw (N, 3) [rad], NaN
    where not measured) within ``margin`` [s] of a measured |pitch| > ``limit`` [rad]."""
    t = np.asarray(t, dtype=float)
    pitch = np.abs(np.asarray(euler, dtype=float)[:, 1])
    measured = np.isfinite(pitch)
    beyond = measured & (pitch > limit)
    rows = np.zeros(t.size, dtype=bool)
    if beyond.any():
        times = t[beyond]
        # nearest excursion sample on either side of each row
        right = np.searchsorted(times, t, side="left")
        after = np.where(right < times.size, times[np.minimum(right, times.size - 1)] - t,
                         np.inf)
        before = np.where(right > 0, t - times[np.maximum(right - 1, 0)], np.inf)
        # 1 ns: grid times that differ by the margin exactly, up to rounding, are within it
        rows = np.minimum(after, before) <= margin + 1e-9
    max_pitch = float(pitch[measured].max()) if measured.any() else float("nan")
    return SingularAttitude(rows, limit, margin, max_pitch)
