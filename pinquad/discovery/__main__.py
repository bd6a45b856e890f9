"""``python -m pinquad.discovery``: entry point; the command is
``pinquad.cli.discovery.main``."""

import sys

from pinquad.cli.discovery import main

if __name__ == "__main__":
    sys.exit(main())
