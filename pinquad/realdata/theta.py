"""A measured run's parameters as the plain E-step parameters other code takes."""

from __future__ import annotations

import numpy as np

from pinquad.models.ssm import Theta


def plain_theta(theta: Theta) -> Theta:
    """The plain :class:`~pinquad.models.ssm.Theta` (mass [kg], inertia (3, 3) [kg m^2],
    noise, gravity [m/s^2]; the centre of mass at the origin) of a measured run's
    ``realdata.flights.RealTheta``: its nuisance moment travels in
    ``realdata.flights.corrected`` observations instead."""
    return Theta(theta.mass, np.asarray(theta.inertia), theta.noise, theta.gravity)
