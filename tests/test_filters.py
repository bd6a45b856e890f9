"""The torque-band filter (``core.filters.band_sos``) and the --band check."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import sosfreqz

from pinquad.cli import offline, realdata
from pinquad.core.filters import band_sos


def _gain(sos, f_hz: float, fs: float) -> float:
    return float(np.abs(sosfreqz(sos, worN=[f_hz], fs=fs)[1][0]))


def test_low_pass_when_lo_is_zero_band_pass_otherwise():
    fs = 100.0
    low, band = band_sos((0.0, 10.0), fs), band_sos((3.0, 8.0), fs)
    assert _gain(low, 0.0, fs) == pytest.approx(1.0, abs=1e-9)
    assert _gain(low, 40.0, fs) < 0.05
    assert _gain(band, 0.0, fs) < 1e-9
    assert _gain(band, 5.0, fs) > 0.9
    # the top corner is capped below the Nyquist frequency: 45 Hz at 100 Hz is 45 Hz,
    # 90 Hz is capped to it
    np.testing.assert_allclose(band_sos((0.0, 90.0), fs), band_sos((0.0, 45.0), fs))


@pytest.mark.parametrize("cli", [offline, realdata])
@pytest.mark.parametrize("band", [("5", "3"), ("-1", "3")])
def test_a_band_out_of_order_is_an_input_error(cli, band, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["--band", *band])
    assert stop.value.code == 2
    assert "--band LO HI: expected 0 <= LO < HI" in capsys.readouterr().err
