"""The zero-phase torque-band filter shared by the measured-flight M-step and the
verdict's torque share."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter

Array = NDArray[np.float64]


def passband(band: tuple[float, float], fs: float, top: float = 0.45) -> tuple[float, float]:
    """(lo, hi) [Hz] the filter of ``band`` at the sample rate ``fs`` [Hz] passes: hi
    capped at ``top`` * fs (below the Nyquist frequency 0.5 fs)."""
    return band[0], min(band[1], top * fs)


def band_sos(band: tuple[float, float], fs: float, top: float = 0.45, order: int = 2) -> Array:
    """Second-order sections of a Butterworth filter of ``order`` passing ``band`` =
    (lo, hi) [Hz] at the sample rate ``fs`` [Hz]: band-pass, or low-pass when lo = 0;
    hi is capped as ``passband`` says."""
    lo, hi = passband(band, fs, top)
    if lo > 0:
        return butter(order, [lo, hi], btype="band", fs=fs, output="sos")
    return butter(order, hi, btype="low", fs=fs, output="sos")
