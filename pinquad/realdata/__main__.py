"""``python -m pinquad.realdata``: entry point; the command is
``pinquad.cli.realdata.main``."""

import sys

from pinquad.cli.realdata import main

if __name__ == "__main__":
    sys.exit(main())
