"""The ten-parameter EM's starting point, found with effect discovery's refit."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from pinquad.discovery.refit import refit
from pinquad.discovery.result import DiscoveryConfig
from pinquad.identification.em import initial_theta, run_em
from pinquad.models.ssm import Observations, Theta
from pinquad.mstep.protocol import REGRESSOR

Array = NDArray[np.float64]


def staged_start(obs: Observations, mass0: float, inertia0: Array, gravity: float,
                 smoother: Callable) -> Theta:
    """A start for ``identify_full`` near the ten-parameter optimum, from the paper's
    guess (mass0 [kg], inertia0 (3, 3) [kg m^2]) in two cheap stages:

    1. EM of the diagonal model (regressor M-step) from the paper's warm-up;
    2. its refit with the horizontal CoM as discovery's ``com_offset`` effect (thrust
       torque F [-c_y, c_x, 0] about the CoM; ``discovery.refit``), which undoes what
       the unmodelled CoM torque does to the diagonal inertia (on the test vehicle with
       the CoM 5 mm off: I_xx 1198 e-6 kg m^2 without it, 249 with it; truth 250).

    Returns Theta with that mass, diagonal inertia and noise and the CoM (c_x, c_y, 0) [m].
    From the paper's start itself the over-relaxed ten-parameter EM first inflates the
    inertia some thirty-fold to absorb the CoM torque and leaves that region after about
    twenty E-steps either towards the optimum or towards a local maximum several hundred
    nats lower; which one changed with 1e-13 relative perturbations of the data (two of
    four) and with the E-step's rounding, so that start made the answer a coin toss."""
    diag = run_em(obs, initial_theta(obs, mass0, inertia0, gravity), smoother, REGRESSOR,
                  max_iterations=100)
    theta, _, coefficients = refit(obs, diag.theta, diag.posterior, ["com_offset"], smoother,
                                   DiscoveryConfig(refit_passes=1, joint_iterations=0))
    c_x, c_y = (float(v) for v in coefficients["com_offset"])
    return Theta(mass=theta.mass, inertia=np.asarray(theta.inertia), noise=theta.noise,
                 gravity=gravity, com=np.array([c_x, c_y, 0.0]))
