"""``python -m pinquad.flight``: entry point; the command is
``pinquad.cli.flight.main``."""

import sys

from pinquad.cli.flight import main

if __name__ == "__main__":
    sys.exit(main())
