"""``python -m pinquad.actuators``: entry point; the command is
``pinquad.cli.actuators.main``."""

import sys

from pinquad.cli.actuators import main

if __name__ == "__main__":
    sys.exit(main())
