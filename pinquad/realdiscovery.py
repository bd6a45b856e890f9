"""``python -m pinquad.realdiscovery``: entry point; the command is
``pinquad.experiments.realdiscovery.main``."""

import sys

from pinquad.experiments.realdiscovery import main

if __name__ == "__main__":
    sys.exit(main())
