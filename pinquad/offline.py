"""``python -m pinquad.offline``: entry point; the command is
``pinquad.cli.offline.main``."""

import sys

from pinquad.cli.offline import main

if __name__ == "__main__":
    sys.exit(main())
