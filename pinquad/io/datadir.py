"""Where the shared Crazyflie data lives when the user does not say."""

from __future__ import annotations

import os
from pathlib import Path

# pinquad/io/datadir.py -> the checkout's parent holds shared/ beside the repository
_REPO_PARENT = Path(__file__).resolve().parents[3]


def default_data_dir() -> Path:
    """The Crazyflie data directory: $PINQUAD_CRAZYFLIE_DATA, else ../shared/data/crazyflie
    next to the repository."""
    env = os.environ.get("PINQUAD_CRAZYFLIE_DATA")
    if env:
        return Path(env)
    return _REPO_PARENT / "shared" / "data" / "crazyflie"
