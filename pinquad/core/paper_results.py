"""The paper's published numbers, for side-by-side tables (ranges over 20 cycles)."""

from __future__ import annotations

SOURCE_LABELS = {
    "A": "State estimation from EKF (A)",
    "B": "Full state observation (B)",
    "C": "Partial state observation (C)",
}

# Table II / Table III (offline) and the online tables: (low, high) per source.
OFFLINE_MASS = {"A": (0.1797, 0.1802), "B": (0.1788, 0.1801), "C": (0.1896, 0.196)}
OFFLINE_INERTIA = {
    "A": ((2.418e-4, 2.75e-4), (2.93e-4, 3.32e-4), (1.912e-4, 2.255e-4)),
    "B": ((2.383e-4, 2.755e-4), (3.037e-4, 3.286e-4), (1.955e-4, 2.214e-4)),
    "C": ((2.373e-4, 2.718e-4), (2.974e-4, 3.284e-4), (1.898e-4, 2.198e-4)),
}
ONLINE_MASS = {"A": (0.1795, 0.1806), "B": (0.1793, 0.1807), "C": (0.1825, 0.196)}
ONLINE_INERTIA = {
    "A": ((2.0e-4, 3.15e-4), (2.65e-4, 3.75e-4), (1.7e-4, 2.6e-4)),
    "B": ((2.0e-4, 3.2e-4), (2.5e-4, 4.0e-4), (1.65e-4, 2.6e-4)),
    "C": ((2.0e-4, 3.5e-4), (2.5e-4, 4.2e-4), (1.7e-4, 3.2e-4)),
}

# Table I: pose estimation of the sensor-A EKF.
EKF_TABLE = {
    "pos_mean": 1.02e-2, "pos_std": 0.77e-2, "pos_max": 5.24e-2,
    "euler_mean": 1.04e-2, "euler_std": 0.83e-2, "euler_max": 8.67e-2,
}

# The bounds pinquad's offline experiment (``python -m pinquad.offline``, the paper's
# scenario, 20 cycles x sensors A, B, C, regressor M-step; README and docs/paper.md)
# meets on every cycle: a vehicle from a file is held to them.
OFFLINE_MASS_BOUND = 0.00065
"""Largest relative mass error of any cycle (0.065 %)."""
OFFLINE_INERTIA_BOUND = 0.03
"""Largest relative error of any inertia entry of any cycle (3 %)."""
