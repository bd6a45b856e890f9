"""``python -m pinquad.actuators``: entry point; the command is
``pinquad.vehicle.actuators.main``."""

import sys

from pinquad.vehicle.actuators import main

if __name__ == "__main__":
    sys.exit(main())
