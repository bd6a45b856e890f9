"""``python -m pinquad.online``: entry point; the command is
``pinquad.cli.online.main``."""

import sys

from pinquad.cli.online import main

if __name__ == "__main__":
    sys.exit(main())
