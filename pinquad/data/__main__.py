"""``python -m pinquad.data``: entry point; the command is ``pinquad.cli.data.main``."""

import sys

from pinquad.cli.data import main

if __name__ == "__main__":
    sys.exit(main())
