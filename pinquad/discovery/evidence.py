"""The data of the report's discovery figures: for each selected effect, the held-out
residual of its main rows against the effect's explaining feature, before (base model)
and after (refit with the effects). ``pinquad.report.discovery`` draws them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pinquad.discovery.library import SPECS, explaining_feature
from pinquad.discovery.residuals import Residuals, effect_columns
from pinquad.discovery.result import AXES, GYRO_AXES, EffectEvidence, ScatterPanel, ScatterSeries

Array = NDArray[np.float64]


def effect_evidence(selected: Sequence[str], res0: Residuals, pi0: Array, res1: Residuals,
                    pi1: Array, coeffs: dict[str, Array], test: NDArray[np.bool_]
                    ) -> tuple[EffectEvidence, ...]:
    """One ``EffectEvidence`` per effect in ``selected``.

    res0 / pi0 (4,) [kg, kg m^2]: residuals and [m, I_xx, I_yy, I_zz] of the base model;
    res1 / pi1: of the refit; coeffs: the effects' coefficients (the "after" panel
    subtracts their wrench Phi_k c and the motor-lag wrench, or the gyro offset); test
    (B,) bool: the held-out blocks, the only transitions shown.

    A wrench effect plots rho_k,r = (Y_k pi - tau_k - fixed_k - Phi_k c)_r [N or N m] of
    its first two rows r (``EffectSpec.rows``) against ``explaining_feature``; gyro_bias
    plots the gyro residual y_gyro,k - omega_k|N (- b after) [rad/s] against time [s].
    """
    wrench = [e for e in coeffs if e not in ("motor_lag", "gyro_bias")]
    out = []
    for name in selected:
        spec = SPECS[name]
        panels = []
        for res, pi, label, with_eff in ((res0, pi0, "before (base model)", False),
                                         (res1, pi1, "after (refit + effects)", True)):
            sel = test[res.block] if name != "gyro_bias" else test[res.gyro_block]
            if name == "gyro_bias":
                g = res.gyro_res - (coeffs["gyro_bias"] if with_eff else 0.0)
                t = np.arange(g.shape[0]) * res.data.dt
                series = tuple(ScatterSeries(GYRO_AXES[i], t[sel], g[sel, i]) for i in range(3))
                panels.append(ScatterPanel(label, "time [s]", "gyro residual [rad/s]", series))
                continue
            use = {e: coeffs[e] for e in coeffs if with_eff and e != "gyro_bias"}
            phi, fixed = effect_columns(res, [e for e in wrench if e in use],
                                        float(use["motor_lag"][0]) if "motor_lag" in use else None)
            c = np.concatenate([use[e] for e in wrench if e in use]) if wrench and use else np.zeros(0)
            rho = np.einsum("kap,p->ka", res.y, pi) - res.tau - fixed
            if c.size:
                rho = rho - np.einsum("kap,p->ka", phi, c)
            series = tuple(ScatterSeries(AXES[r], explaining_feature(name, res.data, r)[sel],
                                         rho[sel, r]) for r in spec.rows[:2])
            panels.append(ScatterPanel(label, spec.feature_name, "wrench residual [N or N m]",
                                       series))
        out.append(EffectEvidence(name, panels[0], panels[1]))
    return tuple(out)
