"""The compiled rotation kernels (``pinquad.core.kernels``) against the conventions
module's NumPy forms, which every other path uses."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pinquad.core.conventions import rotation_and_derivatives
from pinquad.core.kernels import rotation_derivatives

ANGLE = st.floats(min_value=-np.pi, max_value=np.pi, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(ANGLE, st.floats(min_value=-1.5, max_value=1.5), ANGLE)
def test_rotation_derivatives_match_the_conventions(phi: float, theta: float, psi: float) -> None:
    """R and dR/d(phi, theta, psi) written out in the kernel equal the products
    Rz Ry Rx, Rz Ry dRx, Rz dRy Rx, dRz Ry Rx of the conventions module to rounding."""
    rot = np.full((3, 3), np.nan)
    d_rot = np.full((3, 3, 3), np.nan)
    rotation_derivatives(phi, theta, psi, rot, d_rot)
    want_rot, want_d = rotation_and_derivatives(np.array([phi, theta, psi]))
    np.testing.assert_allclose(rot, want_rot, rtol=0, atol=1e-15)
    np.testing.assert_allclose(d_rot, want_d, rtol=0, atol=1e-15)
