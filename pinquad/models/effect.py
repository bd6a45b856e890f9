"""QuadSSM with the lateral body forces of drag and wind in its transition (effect
discovery's extended model, the vocabulary's ``drag`` and ``wind``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.models.ssm import Observations, QuadSSM, Theta

Array = NDArray[np.float64]


class EffectSSM(QuadSSM):
    """QuadSSM whose transition includes the body x/y forces of drag and wind:

        f_b = -diag(D) R^T v + R^T [w_x, w_y, 0],
        v_{k+1} = v_k + dt [f(x_k, u_k) + R P f_b / m],   P = diag(1, 1, 0)

    D (3,) [N s/m] or None, wind (2,) [N, world] or None. The body z part travels in the
    thrust input (``corrected_observations``), where the M-step sees it too. The Jacobian
    adds -dt R P diag(D) R^T / m on the velocity block (the attitude dependence is left
    out). The compiled E-step has a kernel for it (``pinquad.estep.effect_kernels``, described
    by ``pinquad.models.kernel.kernel_description``)."""

    def __init__(self, obs: Observations, theta: Theta, drag: Array | None = None,
                 wind: Array | None = None):
        super().__init__(obs, theta)
        self._drag = np.zeros(3) if drag is None else np.asarray(drag, dtype=float)
        self._wind = np.zeros(3)
        if wind is not None:
            self._wind[:2] = np.asarray(wind, dtype=float)[:2]

    @property
    def drag(self) -> Array:
        """D (3,) [N s/m], the body-frame drag coefficients (D[2] travels in the thrust
        input, not in this transition); a copy."""
        return self._drag.copy()

    @property
    def wind(self) -> Array:
        """[w_x, w_y, 0] (3,) [N], the wind force in the world frame; a copy."""
        return self._wind.copy()

    def euler_step(self, x: Array, k: int) -> tuple[Array, Array]:
        nxt, jac = super().euler_step(x, k)
        dt, m = self.obs.dt, self.body.mass
        rot = rotation_from_euler(x[6:9])
        f_b = -self._drag * (rot.T @ x[3:6]) + rot.T @ self._wind
        f_b[2] = 0.0
        nxt = nxt.copy()
        nxt[3:6] += dt * rot @ f_b / m
        jac = jac.copy()
        d = self._drag.copy()
        d[2] = 0.0
        jac[3:6, 3:6] -= dt * (rot * d) @ rot.T / m
        return nxt, jac
