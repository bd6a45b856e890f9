"""``python -m pinquad.flight``: entry point; the command is
``pinquad.experiments.flight.main``."""

import sys

from pinquad.experiments.flight import main

if __name__ == "__main__":
    sys.exit(main())
