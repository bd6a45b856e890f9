"""``python -m pinquad.discovery``: entry point; the command is
``pinquad.experiments.discovery_mc.main``."""

import sys

from pinquad.experiments.discovery_mc import main

if __name__ == "__main__":
    sys.exit(main())
