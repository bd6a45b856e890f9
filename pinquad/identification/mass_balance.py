"""The model-free mass check: the mass that balances a flight's mean vertical force.

    m_bal = sum_k F_k R_k,zz / sum_k (g + a_z,k)

over the transitions k the M-step uses, with F_k [N] the applied thrust, R_k,zz =
cos(roll) cos(pitch) the vertical component of the body z axis and a_z,k =
(v_z,k+1 - v_z,k) / dt [m/s^2] the vertical acceleration of the smoothed states. The
accelerations telescope to (end - start) velocity over a flight, so m_bal reads the mean
thrust against gravity, whatever the vehicle's inertia and noise: no dynamic model is
fitted. Its standard error is the block jackknife's over ``BLOCKS`` contiguous blocks
(the thrust's slow wander between blocks counts, not only white noise).

A fitted mass that disagrees with it beyond both errors says that the two readings of the
same forces do not agree: an attitude stored in another convention, a thrust that is not
the vertical force, a model that leaves something out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from pinquad.models.ssm import Observations
from pinquad.mstep.stats import transition_mask

Array = NDArray[np.float64]

BLOCKS = 10
"""Contiguous blocks of the jackknife."""


def balance_mass(obs: Observations, mean: Array, gravity: float) -> tuple[float, float]:
    """(m_bal [kg], its standard error [kg]) on the smoothed means (N, 12) (module
    docstring); NaN, NaN with fewer than 2 * BLOCKS usable transitions or no lift."""
    used = np.flatnonzero(transition_mask(obs))
    thrust = np.asarray(obs.inputs[used, 0], dtype=float)
    keep = np.isfinite(thrust)
    used, thrust = used[keep], thrust[keep]
    if used.size < 2 * BLOCKS:
        return float("nan"), float("nan")
    roll, pitch = mean[used, 6], mean[used, 7]
    up = thrust * np.cos(roll) * np.cos(pitch)
    lift = gravity + (mean[used + 1, 5] - mean[used, 5]) / obs.dt
    if not np.sum(lift) > 0:
        return float("nan"), float("nan")
    m = float(np.sum(up) / np.sum(lift))
    blocks = np.array_split(np.arange(used.size), BLOCKS)
    leave_out = np.array([(np.sum(up) - np.sum(up[b])) / (np.sum(lift) - np.sum(lift[b]))
                          for b in blocks])
    se = float(np.sqrt((BLOCKS - 1) / BLOCKS * np.sum((leave_out - leave_out.mean()) ** 2)))
    return m, se


def balance_check(mass: float, se: float, model_free: tuple[float, float] | None,
                  balance_stderr: float | None) -> list[str]:
    """The reason the fitted mass [kg] disagrees with the model-free mass balance
    ``model_free`` (m_bal, se_bal) [kg], or none: they disagree when they differ by more
    than 2 combined standard errors, |m - m_bal| > 2 sqrt(se^2 + se_bal^2), with se the
    mass's error without what both readings of the thrust share (``balance_stderr``; a
    thrust calibration cancels between them; None: the mass's total ``se``)."""
    if balance_stderr is not None:
        se = balance_stderr
    if model_free is None or not np.isfinite(se):
        return []
    m_bal, se_bal = model_free
    if not (np.isfinite(m_bal) and np.isfinite(se_bal)):
        return []
    combined = float(np.hypot(se, se_bal))
    if abs(mass - m_bal) <= 2.0 * combined:
        return []
    return [f"the model-free mass balance (mean vertical thrust over gravity plus vertical "
            f"acceleration, no dynamic model) gives {m_bal * 1e3:.4g} +- {se_bal * 1e3:.2g} g, "
            f"{abs(mass - m_bal) / combined:.1f} combined standard errors away: the two "
            "readings of the same forces disagree"]
