"""Where the Crazyflie data lives when the user does not say.

Order (the first that applies wins): ``--data DIR`` (each command's option, handled by the
caller), ``$PINQUAD_CRAZYFLIE_DATA``, ``../shared/data/crazyflie`` beside a source checkout
(the developers' copy the offline tests read), and the user's cache directory that
``python -m pinquad.data fetch crazyflie`` fills (``pinquad.io.datafetch``).
"""

from __future__ import annotations

import os
from pathlib import Path

import pooch

ENV_VAR = "PINQUAD_CRAZYFLIE_DATA"
"""Environment variable naming the Crazyflie data directory."""
FETCH_COMMAND = "python -m pinquad.data fetch crazyflie"
"""The command that downloads the public data set into ``cache_data_dir()``."""

# pinquad/io/datadir.py -> the checkout's parent holds shared/ beside the repository
_REPO_PARENT = Path(__file__).resolve().parents[3]


def checkout_data_dir() -> Path:
    """``../shared/data/crazyflie`` next to the repository (a source checkout's copy)."""
    return _REPO_PARENT / "shared" / "data" / "crazyflie"


def cache_data_dir() -> Path:
    """The user's cache directory for the data set: ``pooch.os_cache("pinquad")/crazyflie``
    (on Linux ``$XDG_CACHE_HOME/pinquad/crazyflie``, else ``~/.cache/pinquad/crazyflie``)."""
    return Path(pooch.os_cache("pinquad")) / "crazyflie"


def default_data_dir() -> Path:
    """The Crazyflie data directory: $PINQUAD_CRAZYFLIE_DATA, else ../shared/data/crazyflie
    next to the repository if it exists, else the fetched copy in ``cache_data_dir()``
    (returned even when nothing was fetched: callers report it with ``missing_data_hint``)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env)
    beside = checkout_data_dir()
    return beside if beside.is_dir() else cache_data_dir()


def missing_data_hint() -> str:
    """What to tell a user whose data directory holds no data: how to fetch or name it."""
    return (f"download the public data set with `{FETCH_COMMAND}` (into {cache_data_dir()}), "
            f"or give its directory with --data DIR or ${ENV_VAR}")


FLIGHT_FOLDERS = ("imrc_brushed", "imrc_brushless")
"""The data directory's folders of flight logs (brushed Crazyflie 2.1 ``jana*``, the
brushless prototype ``eckart*``)."""


def crazyflie_log(name: str, data: Path | None = None) -> Path:
    """The path of the public Crazyflie flight ``name`` (``"jana00"``, ``"eckart00"`` or
    ``"imrc_brushed/jana00"``) in ``data`` (default: ``default_data_dir()``: the copy
    ``python -m pinquad.data fetch crazyflie`` downloads, unless $PINQUAD_CRAZYFLIE_DATA or
    a checkout's ``../shared`` says otherwise). Raises FileNotFoundError naming where it
    looked and how to fetch the data when the file is not there."""
    base = default_data_dir() if data is None else Path(data)
    candidates = ([base / name] if "/" in name
                  else [base / folder / name for folder in FLIGHT_FOLDERS])
    for path in candidates:
        if path.is_file():
            return path
    raise FileNotFoundError(f"{name}: no such Crazyflie flight in {base}; "
                            f"{missing_data_hint()}")
