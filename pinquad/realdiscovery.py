"""``python -m pinquad.realdiscovery``: entry point; the command is
``pinquad.cli.realdiscovery.main``."""

import sys

from pinquad.cli.realdiscovery import main

if __name__ == "__main__":
    sys.exit(main())
