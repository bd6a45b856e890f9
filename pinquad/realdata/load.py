"""A measured log read from its file and turned into EM observations in one call."""

from __future__ import annotations

from pathlib import Path

from pinquad.io.logs import LogFormatError, read_log
from pinquad.io.sdlog import is_sdlog, read_sdflight
from pinquad.realdata.observation_options import RealDataOptions
from pinquad.realdata.observations import RealObservations, build_observations
from pinquad.realdata.raw import RawFlight, raw_from_sdflight
from pinquad.realdata.thrust import ThrustCoefficient


def load_real(path: str | Path, options: RealDataOptions | None = None,
              kf: ThrustCoefficient | None = None) -> RealObservations:
    """Observations of a measured log: a Crazyflie micro-SD file, or a CSV / Parquet log
    with ``rpm_1..4`` columns. Raises LogFormatError / ValueError with the file named."""
    path = Path(path)
    if is_sdlog(path):
        raw = raw_from_sdflight(read_sdflight(path))
    else:
        log = read_log(path)
        if log.rpm is None:
            raise LogFormatError(f"{path}: no rpm_1..rpm_4 columns; expected rotor speeds for "
                                 "the actuator model")
        raw = RawFlight(log=log)
    return build_observations(raw, options, kf)
