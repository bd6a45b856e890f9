"""``python -m pinquad.realdata``: entry point; the command is
``pinquad.realdata.flights.main``."""

import sys

from pinquad.realdata.flights import main

if __name__ == "__main__":
    sys.exit(main())
