"""The compiled rotation and Euler-rate kernels (``pinquad.core.kernels``) against the
conventions module's Python forms, which every other path uses."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pinquad.core.conventions import (
    euler_rate_kinematics,
    euler_rate_matrix,
    euler_rate_matrix_inv,
    rotation_and_derivatives,
)
from pinquad.core.kernels import euler_rate_kinematics as compiled_euler_rate_kinematics
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


@settings(max_examples=300, deadline=None)
@given(ANGLE, st.floats(min_value=-1.5, max_value=1.5),
       st.lists(st.floats(min_value=-50.0, max_value=50.0), min_size=3, max_size=3),
       st.sampled_from([1.0, 0.01, 0.002, 1.0 / 3.0]))
def test_euler_rate_kinematics_twins_agree(phi: float, theta: float, rates: list[float],
                                           scale: float) -> None:
    """The compiled Euler-rate kinematics equal the Python twin to the last bit (every
    model's Euler rows, Python and compiled, come from these two), and both are
    scale E^{-1}(Theta) omega with E^{-1} the conventions module's (tan-based) matrix,
    the inverse of E, and the derivative by Theta that central differences give."""
    trig = (np.sin(phi), np.cos(phi), np.sin(theta), np.cos(theta))
    want_rates, want_d, want_e_inv = euler_rate_kinematics(*trig, *rates, scale)
    got_rates, got_d, got_e_inv = np.full(3, np.nan), np.full((3, 3), np.nan), np.full((3, 3), np.nan)
    compiled_euler_rate_kinematics(*trig, *rates, scale, got_rates, got_d, got_e_inv)
    assert np.array_equal(got_rates, want_rates)
    assert np.array_equal(got_d, want_d)
    assert np.array_equal(got_e_inv, want_e_inv)

    euler = np.array([phi, theta, 0.3])
    e_inv = euler_rate_matrix_inv(euler)
    np.testing.assert_allclose(want_e_inv, scale * e_inv, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(want_rates, scale * e_inv @ rates, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(euler_rate_matrix(euler) @ e_inv, np.eye(3), atol=1e-9)
    h = 1e-6
    for j in range(2):
        step = np.zeros(3)
        step[j] = h
        up = euler_rate_matrix_inv(euler + step) @ rates
        down = euler_rate_matrix_inv(euler - step) @ rates
        np.testing.assert_allclose(want_d[:, j], scale * (up - down) / (2 * h),
                                   rtol=1e-5, atol=1e-5 * scale * (1.0 + np.abs(rates).max()))
    assert np.all(want_d[:, 2] == 0.0)
