"""The physical effects the generator can inject into the truth, in the meanings and
coefficient names of the discovery vocabulary. Re-implemented here, not
imported: the generator shares no code with pinquad.

Body frame x forward, y left, z up; R body to world; v world velocity [m/s];
v_b = R^T v; F the applied collective thrust [N].

====================  =============================================  ===================
effect                what the truth gets                            coefficients
====================  =============================================  ===================
``drag``              world force -R diag(D) v_b                     D_x, D_y, D_z [N s/m]
``ground_effect``     thrust F (1 + k_ge (r / (4 max(z, r/2)))^2)    k_ge [-]
``com_offset``        body torque (-c) x (F e3) = F (-c_y, c_x, 0)   c_x, c_y [m]
``wind``              world force (w_x, w_y, 0)                      w_x, w_y [N]
``motor_lag``         tau_m du/dt = u_cmd - u on thrust and torques  tau_m [s]
``gyro_bias``         gyro reads omega + b                           b_x, b_y, b_z [rad/s]
====================  =============================================  ===================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Effects:
    """Which effects the truth carries (None: absent). Units as in the module table."""

    drag: tuple[float, float, float] | None = None
    ground_effect: float | None = None
    com_offset: tuple[float, float] | None = None
    wind: tuple[float, float] | None = None
    motor_lag: float | None = None
    gyro_bias: tuple[float, float, float] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        """The injected effects' names, in the vocabulary's order."""
        order = ("drag", "ground_effect", "com_offset", "wind", "motor_lag", "gyro_bias")
        return tuple(n for n in order if getattr(self, n) is not None)

    def coefficients(self) -> dict[str, float]:
        """Coefficient name -> injected value (D_x, k_ge, c_x, w_x, tau_m, b_x, ...)."""
        names = {"drag": ("D_x", "D_y", "D_z"), "ground_effect": ("k_ge",),
                 "com_offset": ("c_x", "c_y"), "wind": ("w_x", "w_y"),
                 "motor_lag": ("tau_m",), "gyro_bias": ("b_x", "b_y", "b_z")}
        out: dict[str, float] = {}
        for effect in self.names:
            values = np.atleast_1d(np.asarray(getattr(self, effect), dtype=float))
            out.update(zip(names[effect], values.tolist(), strict=True))
        return out


def ground_gain(z: float, radius: float) -> float:
    """g(z) = (r / (4 max(z, r/2)))^2 [-]: relative extra thrust per unit k_ge at the
    height z [m] of the body origin above the floor (Cheeseman-Bennett, first order)."""
    zc = max(z, 0.5 * radius)
    return (radius / (4.0 * zc)) ** 2


def lag_factor(time_constant: float | None, dt: float) -> float:
    """a = 1 - exp(-dt / tau_m): the exact first-order step u <- u + a (u_cmd - u) for a
    command held over dt [s]; 1 (no lag) when tau_m is None or 0."""
    if not time_constant:
        return 1.0
    return 1.0 - float(np.exp(-dt / time_constant))
